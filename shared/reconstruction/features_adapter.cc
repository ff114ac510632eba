#include "shared/reconstruction/features_adapter.h"

#include <Eigen/Eigenvalues>
#include <cmath>
#include <map>

namespace idi {

AdaptedFeatures FromFeatureResult(const FeatureResult& r) {
  AdaptedFeatures out;
  std::map<int, int> line_index, point_index;
  for (const EmplLine& l : r.lines) {
    line_index[l.id] = static_cast<int>(out.features.lines.size());
    ViewLine v;
    v.line.normal = l.normal;
    v.line.offset = l.offset;
    v.end1 = l.p1;
    v.end2 = l.p2;
    v.extension_px = std::max((l.extension1 - l.p1).norm(), (l.extension2 - l.p2).norm());
    out.features.lines.push_back(v);
    out.line_sigma_px.push_back(std::sqrt(std::max(l.covariance(1, 1), 1e-8)));
  }
  for (const IdiPoint& p : r.points) {
    if (p.kind != IdiPointKind::kLines) continue;  // curve-line points have no line topology to match
    point_index[p.id] = static_cast<int>(out.features.points.size());
    ViewPoint v;
    v.xy = p.xy;
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(p.covariance);
    v.sigma_px = std::sqrt(std::max(eig.eigenvalues().maxCoeff(), 1e-8));
    out.features.points.push_back(v);
  }
  for (const IdiPoint& p : r.points) {
    const auto pi = point_index.find(p.id);
    if (pi == point_index.end()) continue;
    for (const int lid : p.line_ids) {
      const auto li = line_index.find(lid);
      if (li == line_index.end()) continue;
      out.features.points[static_cast<std::size_t>(pi->second)].lines.push_back(li->second);
      out.features.lines[static_cast<std::size_t>(li->second)].points.push_back(pi->second);
    }
  }
  return out;
}

}  // namespace idi
