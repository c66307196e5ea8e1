#include "core/uv_layout.hpp"

#include <algorithm>
#include <sstream>

namespace atlas {
namespace {

// Throws InputError "what: parts..." (no prefix when what is empty).
template <class... Parts>
[[noreturn]] void refuse(const std::string& what, const Parts&... parts) {
  std::ostringstream msg;
  if (!what.empty()) msg << what << ": ";
  (msg << ... << parts);
  throw InputError(msg.str());
}

void require_pages(const std::vector<PageSize>& pages, const std::string& what) {
  for (std::size_t p = 0; p < pages.size(); ++p)
    if (pages[p].width <= 0 || pages[p].height <= 0)
      refuse(what, "page ", p, " has non-positive size ", pages[p].width, "x", pages[p].height);
}

}  // namespace

void require_layout(const UvLayout& layout, Eigen::Index face_count, const std::string& what, Untextured untextured) {
  if (!layout.corner_uv || !layout.face_page || !layout.pages) refuse(what, "layout is missing an array");
  if (layout.corner_uv->rows() != 3 * face_count)
    refuse(what, "uvs must hold 3 corners per triangle: expected ", 3 * face_count, " rows, got ", layout.corner_uv->rows());
  if (layout.face_page->size() != face_count)
    refuse(what, "face_page must hold one page per triangle: expected ", face_count, ", got ", layout.face_page->size());
  require_pages(*layout.pages, what);
  const int lowest = untextured == Untextured::allowed ? -1 : 0;
  const int page_count = static_cast<int>(layout.pages->size());
  for (Eigen::Index f = 0; f < face_count; ++f) {
    const int page = (*layout.face_page)[f];
    if (page < lowest || page >= page_count)
      refuse(what, "triangle ", f, " uses page ", page, " but only ", page_count, " page(s) were given");
    if (page < 0) continue;
    const auto uv = layout.corner_uv->middleRows(3 * f, 3);
    if (!uv.allFinite()) refuse(what, "triangle ", f, " has a non-finite uv");
    const PageSize& size = (*layout.pages)[page];
    if (uv.cwiseAbs().maxCoeff() * std::max(size.width, size.height) > kMaxTexelCoordinate)
      refuse(what, "triangle ", f, " has a uv more than ", kMaxTexelCoordinate, " texels from its page");
  }
}

long long page_texels(const std::vector<PageSize>& pages, const std::vector<char>& used) {
  long long total = 0;
  for (size_t p = 0; p < pages.size(); ++p)
    if (used.empty() || used[p]) total += static_cast<long long>(pages[p].width) * pages[p].height;
  return total;
}

}  // namespace atlas
