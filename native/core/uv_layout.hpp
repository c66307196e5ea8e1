// One parameterization of a mesh as borrowed arrays, shaped like Mesh's: the
// view every stage takes of an atlas, old or new.
#pragma once
#include <string>
#include <vector>

#include "core/mesh.hpp"

namespace atlas {

// Farthest a UV may lie from its page's origin, in texels of that page: the
// bake and the metrics index texels with int, and pages repeat, so a UV this
// far out is a broken file, not a tiled layout.
constexpr double kMaxTexelCoordinate = 1 << 30;

struct UvLayout {
  const RowMatrixX2d* corner_uv = nullptr;        // 3F x 2, page units
  const Eigen::VectorXi* face_page = nullptr;     // F; -1 marks an untextured face
  const std::vector<PageSize>* pages = nullptr;   // texel size of each page

  // UV of corner k of face f in texels of that face's page.
  Eigen::Vector2d uv_texels(int f, int k) const {
    const PageSize& page = (*pages)[(*face_page)[f]];
    return {(*corner_uv)(3 * f + k, 0) * page.width, (*corner_uv)(3 * f + k, 1) * page.height};
  }
};

// The mesh's own layout.
inline UvLayout layout_of(const Mesh& mesh) { return {&mesh.corner_uv, &mesh.face_page, &mesh.pages}; }

enum class Untextured { allowed, refused };

// Checks that the layout describes face_count faces: every array present,
// 3 UV rows per face, every page of positive size,
// every face on an existing page (or -1 where allowed), finite UVs on
// textured faces, within 2^30 texels of their page's origin. Throws
// InputError whose message starts with `what`.
void require_layout(const UvLayout& layout, Eigen::Index face_count, const std::string& what, Untextured untextured);

// Sum of width * height over the pages p with used[p] (every page when used is empty).
long long page_texels(const std::vector<PageSize>& pages, const std::vector<char>& used = {});

}  // namespace atlas
