#include "flatten/chart_rows.hpp"

namespace atlas {

int take_out_face(FlatChart& chart, int f, std::vector<int>& slot) {
  const int j = slot[f], last = static_cast<int>(chart.faces.size()) - 1;
  chart.faces[j] = chart.faces[last];
  chart.corner_uv.middleRows(3 * j, 3) = chart.corner_uv.middleRows(3 * last, 3);
  slot[chart.faces[j]] = j;
  chart.faces.pop_back();
  chart.corner_uv.conservativeResize(3 * last, 2);
  return j;
}

void append_faces(FlatChart& chart, const std::vector<int>& faces, const RowMatrixX2d& uv, std::vector<int>& slot) {
  const Eigen::Index rows = chart.corner_uv.rows();
  chart.corner_uv.conservativeResize(rows + uv.rows(), 2);
  chart.corner_uv.bottomRows(uv.rows()) = uv;
  for (int f : faces) {
    slot[f] = static_cast<int>(chart.faces.size());
    chart.faces.push_back(f);
  }
}

}  // namespace atlas
