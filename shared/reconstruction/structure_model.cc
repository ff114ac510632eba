#include "shared/reconstruction/structure_model.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <sstream>
#include <string>

#include "shared/util/units.h"

namespace idi {

namespace {

// The largest angle between two of the views' camera centres about the 3D edge a-b: each centre's
// direction from the edge's line, perpendicular to it.
double EdgeViewSpread(const Vec3d& a,
                      const Vec3d& b,
                      const std::vector<int>& voters,
                      const std::vector<CorrespondenceView>& views) {
  const Vec3d axis = (b - a).normalized();
  std::vector<Vec3d> around;
  for (const int v : voters) {
    const Rigid3d& cam_from_world = views[static_cast<std::size_t>(v)].cam_from_world;
    const Vec3d from_a = -(cam_from_world.rotation.transpose() * cam_from_world.translation) - a;
    const Vec3d across = from_a - from_a.dot(axis) * axis;
    if (across.norm() > 1e-9) around.push_back(across.normalized());
  }
  double spread = 0;
  for (std::size_t i = 0; i < around.size(); ++i) {
    for (std::size_t j = i + 1; j < around.size(); ++j) {
      spread = std::max(spread, std::acos(std::clamp(around[i].dot(around[j]), -1.0, 1.0)));
    }
  }
  return spread;
}

}  // namespace

Status ModelOptions::Check() const {
  if (min_views_for_edge < 1) {
    return InvalidArgument("model: min_views_for_edge must be 1 or more, got " + std::to_string(min_views_for_edge));
  }
  if (!(segment_margin_px >= 0) || !std::isfinite(segment_margin_px)) {
    return InvalidArgument("model: segment_margin_px must be a finite 0 px or more, got " +
                           FormatNumber(segment_margin_px));
  }
  if (!(min_edge_spread_deg >= 0 && min_edge_spread_deg <= 180)) {
    return InvalidArgument("model: min_edge_spread_deg must be in [0, 180], got " + FormatNumber(min_edge_spread_deg));
  }
  return Status::Ok();
}

StructureModel BuildModel(const Correspondences& corr, const std::vector<CorrespondenceView>& views,
                          const ModelOptions& options) {
  StructureModel model;
  // (view, point index) -> model point
  std::map<std::pair<int, int>, int> owner;
  for (std::size_t k = 0; k < corr.points.size(); ++k) {
    ModelPoint mp;
    mp.id = static_cast<int>(k);
    mp.xyz = corr.points[k].xyz;
    mp.observations = corr.points[k].observations;
    mp.reprojection_rms_px = corr.points[k].reprojection_rms_px;
    for (const Observation& o : mp.observations) owner[{o.view, o.index}] = static_cast<int>(k);
    model.points.push_back(std::move(mp));
  }
  // For every image line, the model points on it, ordered along the line; adjacent pairs vote.
  std::map<std::pair<int, int>, std::vector<int>> votes;  // edge -> the views that vote for it
  for (std::size_t v = 0; v < views.size(); ++v) {
    const ViewFeatures& f = *views[v].features;
    for (const ViewLine& line : f.lines) {
      std::vector<std::pair<double, int>> on_line;
      for (const int pi : line.points) {
        const auto it = owner.find({static_cast<int>(v), pi});
        if (it == owner.end()) continue;
        on_line.emplace_back(SegmentFraction(line, f.points[static_cast<std::size_t>(pi)].xy), it->second);
      }
      std::sort(on_line.begin(), on_line.end());
      for (std::size_t k = 0; k + 1 < on_line.size(); ++k) {
        const int a = on_line[k].second, b = on_line[k + 1].second;
        if (a == b) continue;
        // The edge between them must be confirmed in the image: its midpoint on the confirmed segment.
        const Vec2d mid = line.end1 + (line.end2 - line.end1) * (0.5 * (on_line[k].first + on_line[k + 1].first));
        ViewLine confirmed = line;
        confirmed.extension_px = 0;
        if (!WithinExtendedSegment(confirmed, mid, options.segment_margin_px)) continue;
        votes[{std::min(a, b), std::max(a, b)}].push_back(static_cast<int>(v));
      }
    }
  }
  for (const auto& [edge, voters] : votes) {
    if (static_cast<int>(voters.size()) < options.min_views_for_edge) continue;
    if (EdgeViewSpread(model.points[static_cast<std::size_t>(edge.first)].xyz,
                       model.points[static_cast<std::size_t>(edge.second)].xyz,
                       voters,
                       views) < DegToRad(options.min_edge_spread_deg)) {
      continue;
    }
    model.edges.push_back(edge);
  }
  return model;
}

std::string ModelToPly(const StructureModel& model) {
  std::ostringstream out;
  out.precision(10);
  out << "ply\nformat ascii 1.0\ncomment idi structure model (section 8.10), units mm\n";
  out << "element vertex " << model.points.size() << "\nproperty double x\nproperty double y\nproperty double z\n";
  out << "element edge " << model.edges.size() << "\nproperty int vertex1\nproperty int vertex2\nend_header\n";
  for (const ModelPoint& p : model.points) out << p.xyz.x() << " " << p.xyz.y() << " " << p.xyz.z() << "\n";
  for (const auto& [a, b] : model.edges) out << a << " " << b << "\n";
  return out.str();
}

}  // namespace idi
