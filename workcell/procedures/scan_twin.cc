#include "workcell/procedures/scan_twin.h"

#include <fmt/format.h>

#include <algorithm>
#include <limits>
#include <map>
#include <optional>
#include <set>

#include "shared/camera/pinhole.h"
#include "shared/reconstruction/epipolar.h"
#include "workcell/procedures/ptu_twin.h"

namespace idi::workcell {

Status ScanTwinOptions::Check() const {
  if (!(max_offset_mm >= 0 && max_offset_mm <= 150)) {
    return InvalidArgument(fmt::format("scan twin: the object's offset {} mm is outside [0, 150]", max_offset_mm));
  }
  if (clutter_objects < 0 || clutter_objects > 40) return InvalidArgument("scan twin: clutter must be 0 to 40 objects");
  if (!(rail_repeatability_mm == -1 || (rail_repeatability_mm >= 0 && rail_repeatability_mm <= 5))) {
    return InvalidArgument(fmt::format("scan twin: rail repeatability {} mm is outside [0, 5] (or -1: the cell's)",
                                       rail_repeatability_mm));
  }
  return Status::Ok();
}

ScanTwin::ScanTwin(const ScanTwinOptions& options) : options_(options) {
  const Status ok = options_.Check();
  IDI_CHECK(ok.ok(), ok.ToString());
  head_ = SampleHeadTruth(options.seed, calib::PtuTruthOptions{});
  sim::CellTwinOptions o;
  o.seed = options.seed;
  o.keep_truth = options.keep_truth;
  o.clutter_objects = options.clutter_objects;
  if (options.rail_repeatability_mm >= 0) o.workcell.rail_repeatability_mm = options.rail_repeatability_mm;
  for (std::size_t i = 0; i < 2; ++i) o.head[i] = {head_[i].ptu, head_[i].Camera()};
  cell_ = std::make_unique<sim::CellTwin>(o);
  for (std::size_t i = 0; i < 2; ++i) {
    SimPtuOptions po;
    po.name = std::string("sim-ptu-") + (i == 0 ? "left" : "right");
    ptu_[i] = std::make_unique<SimPanTilt>(po, &cell_->clock());
    cell_->AttachPanTilt(i == 0 ? BiclopsSide::kLeft : BiclopsSide::kRight, ptu_[i].get());
  }
  hand_ = std::make_unique<SimGripper>(SimGripperOptions{}, &cell_->clock());
  cell_->AttachHand(hand_.get(), [this](const std::array<std::optional<double>, 3>& s) { hand_->SetObject(s); });
  std::mt19937_64 rng(static_cast<uint64_t>(options.seed) * 2654435761ULL + 977ULL * options.scene +
                      static_cast<uint64_t>(options.kind) * 7919ULL + 5);
  target_ = sim::SampleObject(options.kind, o.table.top_centre_world, options.max_offset_mm, rng);
  cell_->AddObject(target_);
}

ScanTwin::~ScanTwin() = default;

ScanDevices ScanTwin::Devices() {
  ScanDevices d;
  d.arm1 = &cell_->arm(0);
  d.rail1 = &cell_->rail(0);
  d.arm2 = &cell_->arm(1);
  d.rail2 = &cell_->rail(1);
  d.ptu = {ptu_[0].get(), ptu_[1].get()};
  d.camera = {&cell_->camera(BiclopsSide::kLeft), &cell_->camera(BiclopsSide::kRight)};
  d.hand = &cell_->gripper();
  return d;
}

ScanOptions ScanTwin::SetupOptions() const {
  ScanOptions o;
  o.table_centre_world = cell_->options().table.top_centre_world;
  o.table_radius_mm = cell_->options().table.radius_mm;
  o.rail1_max_mm = cell_->options().workcell.rail_length_mm;
  o.rail2_max_mm = cell_->options().workcell.rail_length_mm;
  return o;
}

ScanCalibration ScanTwin::TrueCalibration() const {
  const sim::WorkcellTwin& w = cell_->workcell();
  ScanCalibration c;
  c.robot1 = {w.true_robot(0), w.true_laser(0), w.true_rail(0), {}};
  c.robot2 = {w.true_robot(1), w.true_laser(1), w.true_rail(1), {}};
  c.psi = w.true_psi();
  c.cameras = head_;
  c.flange_from_palm = cell_->options().hand.flange_from_palm;
  c.hand = cell_->options().hand.fingers;
  return c;
}

ScanTruth ScanTwin::Evaluate(const ScanReport& report, const ScanOptions& options) const {
  ScanTruth t;
  const sim::ObjectWireframe wire = sim::ObjectCorners(target_.shape);
  std::vector<Vec3d> corners;
  for (const Vec3d& v : wire.vertices) corners.push_back(target_.world_from_object * v);
  t.true_vertices = static_cast<int>(corners.size());
  const auto& pts = report.structure.model.points;
  double sum = 0;
  for (const Vec3d& c : corners) {
    double best = std::numeric_limits<double>::infinity();
    int nearest = -1;
    for (int i : report.object_points) {
      const double d = (pts[static_cast<std::size_t>(i)].xyz - c).norm();
      if (d < best) {
        best = d;
        nearest = i;
      }
    }
    t.vertex_error_mm.push_back(best <= t.match_mm ? best : -1.0);
    t.vertex_views.push_back(
        best <= t.match_mm ? static_cast<int>(pts[static_cast<std::size_t>(nearest)].observations.size()) : 0);
    t.vertex_height_mm.push_back(c.z() - options.table_centre_world.z());
    if (best <= t.match_mm) {
      ++t.matched_vertices;
      sum += best;
      t.max_vertex_error_mm = std::max(t.max_vertex_error_mm, best);
    }
  }
  if (t.matched_vertices > 0) t.mean_vertex_error_mm = sum / t.matched_vertices;
  t.object_points = static_cast<int>(report.object_points.size());
  if (!corners.empty()) {
    // Each object point's corner within match_mm (-1: a spurious point), then each model edge between
    // object points.
    std::map<int, int> corner_of;
    for (int i : report.object_points) {
      int nearest = -1;
      double best = t.match_mm;
      for (std::size_t c = 0; c < corners.size(); ++c) {
        const double d = (pts[static_cast<std::size_t>(i)].xyz - corners[c]).norm();
        if (d <= best) {
          best = d;
          nearest = static_cast<int>(c);
        }
      }
      corner_of[i] = nearest;
      if (nearest < 0) ++t.spurious_points;
    }
    for (const auto& [a, b] : report.structure.model.edges) {
      const auto ia = corner_of.find(a), ib = corner_of.find(b);
      if (ia == corner_of.end() || ib == corner_of.end()) continue;
      const int ca = ia->second, cb = ib->second;
      const bool is_edge = ca >= 0 && cb >= 0 && std::any_of(wire.edges.begin(), wire.edges.end(), [&](const auto& w) {
                             return (w.first == ca && w.second == cb) || (w.first == cb && w.second == ca);
                           });
      if (is_edge) {
        ++t.true_edges;
      } else {
        ++t.false_edges;
        t.false_edge_list.push_back(fmt::format("model points {}-{} (corners {}-{})", a, b, ca, cb));
      }
    }
  }
  if (report.cylinder && target_.shape.kind == sim::ObjectKind::kCylinder) {
    const Vec3d base = target_.world_from_object.translation;
    t.cylinder_axis_error_mm = (report.cylinder_axis_xy - base.head<2>()).norm();
    t.cylinder_radius_error_mm = std::abs(report.cylinder_radius_mm - target_.shape.radius);
    t.cylinder_top_error_mm = std::abs(report.cylinder_top_z - (base.z() + sim::ObjectHeight(target_.shape)));
  }
  for (const sim::CellEvent& e : cell_->events()) {
    if (e.what.rfind("grasped ", 0) == 0) t.held = true;
  }
  t.grasp_reason = cell_->last_grasp().reason;
  t.collisions = cell_->collisions();
  const std::vector<sim::CellObject> now = cell_->objects();
  if (!now.empty() && report.pick.attempted) {
    const Vec3d start = target_.world_from_object.translation;
    const Vec3d end = now[0].world_from_object.translation;
    const Vec3d want = start + options.place_offset_world;
    t.placed = !cell_->held_object() && (end - want).head<2>().norm() < 20.0 && std::abs(end.z() - start.z()) < 1.0;
    t.lifted = t.held && (t.placed || (end - start).norm() > 20.0);
  }
  return t;
}

namespace {
// An IDI point is labelled with the true corner whose image lies this close (else it is a T-junction, a
// texture corner or a stray point).
constexpr double kLabelTolerancePx = 1.5;

// One line about an IDI point far from its corner (CorrespondenceTruth::far_points).
std::string DescribeFarPoint(const std::string& view,
                             const CameraModel& camera,
                             const sim::GroundTruth& t,
                             const ViewFeatures& features,
                             const ViewPoint& p,
                             int corner,
                             const std::map<std::pair<std::string, int>, int>& ids) {
  const sim::TruthJunction* junction = nullptr;
  for (const sim::TruthJunction& j : t.junctions) {
    const auto it = ids.find({j.object, j.vertex});
    if (j.is_vertex && it != ids.end() && it->second == corner) junction = &j;
  }
  if (junction == nullptr) return view + ": corner not in this view's truth";
  const Vec2d truth = UndistortPixel(camera, junction->xy_px);
  std::string out = fmt::format(
      "{}: {} vertex {} ({} junction, {} true edges) at ({:.1f}, {:.1f}): point {:.2f} px off, own sigma {:.3f} px;",
      view,
      junction->object,
      junction->vertex,
      junction->type,
      junction->lines.size(),
      truth.x(),
      truth.y(),
      (p.xy - truth).norm(),
      p.sigma_px);
  for (const int li : p.lines) {
    const ViewLine& l = features.lines[static_cast<std::size_t>(li)];
    // The true edge nearest in angle among those meeting at the corner.
    double best_angle = 180;
    for (const int tid : junction->lines) {
      for (const sim::TruthLine& tl : t.lines) {
        if (tl.id != tid) continue;
        const double c = std::clamp(std::abs(tl.normal.dot(l.line.normal)), 0.0, 1.0);
        best_angle = std::min(best_angle, std::acos(c) * 180.0 / 3.14159265358979323846);
      }
    }
    const double off = l.line.normal.dot(truth) - l.line.offset;
    const double length = (l.end2 - l.end1).norm();
    const double to_end = std::min((l.end1 - truth).norm(), (l.end2 - truth).norm());
    out += fmt::format(
        " line {}: corner {:+.2f} px off it, {:.2f} deg from the nearest true edge, {:.0f} px long, nearest end {:.1f} "
        "px from the corner;",
        li,
        off,
        best_angle,
        length,
        to_end);
  }
  return out;
}

}  // namespace

CorrespondenceTruth ScanTwin::EvaluateCorrespondence(const ScanReport& r, double list_over_px) const {
  CorrespondenceTruth score;
  const auto& left = cell_->Truths(BiclopsSide::kLeft);
  const auto& right = cell_->Truths(BiclopsSide::kRight);
  const std::size_t n = r.views.size();
  if (left.size() + right.size() != n || r.structure.matched_features.size() != n) return score;
  std::map<std::pair<std::string, int>, int> ids;
  std::vector<std::vector<std::vector<int>>> label(n);  // per view, per matched IDI point: its corners
  std::vector<std::set<int>> seen(n), found(n);
  std::size_t li = 0, ri = 0;
  for (std::size_t v = 0; v < n; ++v) {
    const StructureView& sv = r.views[v].view;
    const bool is_left = sv.name.size() >= 4 && sv.name.compare(sv.name.size() - 4, 4, "left") == 0;
    if ((is_left && li >= left.size()) || (!is_left && ri >= right.size())) return score;
    const sim::GroundTruth& t = is_left ? left[li++] : right[ri++];
    std::vector<std::pair<int, Vec2d>> corners;  // id, undistorted pixel in the view's (calibrated) model
    for (const sim::TruthJunction& j : t.junctions) {
      if (!j.is_vertex) continue;
      const int x = static_cast<int>(std::lround(j.xy_px.x())), y = static_cast<int>(std::lround(j.xy_px.y()));
      if (x < 0 || y < 0 || x >= sv.roi.cols || y >= sv.roi.rows || sv.roi.at<uint8_t>(y, x) == 0) continue;
      const int id = ids.emplace(std::make_pair(j.object, j.vertex), static_cast<int>(ids.size())).first->second;
      corners.emplace_back(id, UndistortPixel(sv.camera, j.xy_px));
      seen[v].insert(id);
    }
    for (const ViewPoint& p : r.structure.matched_features[v].points) {
      // Every corner whose image lies within the tolerance: two corners less than a pixel apart in the
      // image meet in one IDI point, which is then the image of both.
      std::vector<int> within;
      double error = 0;
      for (const auto& [id, xy] : corners) {
        if ((xy - p.xy).norm() < kLabelTolerancePx) {
          within.push_back(id);
          error = (xy - p.xy).norm();
        }
      }
      if (within.size() == 1) {
        score.point_error_px.push_back(error);
        score.point_sigma_px.push_back(p.sigma_px);
        if (list_over_px > 0 && error > list_over_px) {
          score.far_points.push_back(
              DescribeFarPoint(sv.name, sv.camera, t, r.structure.matched_features[v], p, within[0], ids));
        }
      }
      found[v].insert(within.begin(), within.end());
      label[v].push_back(std::move(within));
    }
  }
  // The target's box (world frame, grown by kBackgroundMarginMm): a track whose points are at no true
  // corner in either view and whose 3D point lies outside it is background the truth has no corners for
  // (floor tiles and texture seen past the table inside the object region), not a false match of the
  // object's corners.
  const sim::ObjectWireframe wire = sim::ObjectCorners(target_.shape);
  Vec3d box_min = Vec3d::Constant(std::numeric_limits<double>::infinity()), box_max = -box_min;
  for (const Vec3d& v : wire.vertices) {
    const Vec3d w = target_.world_from_object * v;
    box_min = box_min.cwiseMin(w);
    box_max = box_max.cwiseMax(w);
  }
  auto background = [&](const Vec3d& x) {
    if (wire.vertices.empty()) return false;
    return ((x - box_min).array() < -kBackgroundMarginMm).any() || ((x - box_max).array() > kBackgroundMarginMm).any();
  };
  auto common = [](const std::set<int>& a, const std::set<int>& b) {
    long c = 0;
    for (const int x : a) c += b.count(x) ? 1 : 0;
    return c;
  };
  for (std::size_t a = 0; a < n; ++a) {
    for (std::size_t b = a + 1; b < n; ++b) {
      score.found_in_both += common(found[a], found[b]);
      score.visible_in_both += common(seen[a], seen[b]);
      const StructureView& va = r.views[a].view;
      const StructureView& vb = r.views[b].view;
      const auto f = FundamentalFromProjections(MakeProjection(va.camera.K(), va.cam_from_world),
                                                MakeProjection(vb.camera.K(), vb.cam_from_world));
      const std::vector<Rigid3d>& adjusted = r.structure.adjusted_cam_from_world;
      std::optional<Mat3d> f_adjusted;
      if (adjusted.size() == n) {
        f_adjusted = FundamentalFromProjections(MakeProjection(va.camera.K(), adjusted[a]),
                                                MakeProjection(vb.camera.K(), adjusted[b]));
      }
      std::set<int> matched;  // corners matched between the two views
      for (const PointTrack& track : r.structure.correspondences.points) {
        int ia = -1, ib = -1;
        for (const Observation& o : track.observations) {
          if (o.view == static_cast<int>(a)) ia = o.index;
          if (o.view == static_cast<int>(b)) ib = o.index;
        }
        if (ia < 0 || ib < 0) continue;
        const std::vector<int>& la = label[a][static_cast<std::size_t>(ia)];
        const std::vector<int>& lb = label[b][static_cast<std::size_t>(ib)];
        const auto same =
            std::find_if(la.begin(), la.end(), [&](int x) { return std::count(lb.begin(), lb.end(), x) > 0; });
        if (same != la.end()) {
          ++score.true_matches;
          matched.insert(*same);
        } else if (la.empty() && lb.empty() && background(track.xyz)) {
          ++score.background_matches;
        } else {
          ++score.false_matches;
        }
        const Vec2d& xa = r.structure.matched_features[a].points[static_cast<std::size_t>(ia)].xy;
        const Vec2d& xb = r.structure.matched_features[b].points[static_cast<std::size_t>(ib)].xy;
        if (f) {
          const double d = EpipolarDistance(*f, xa, xb);
          score.epipolar_px.push_back(d);
          if (f_adjusted) score.epipolar_adjusted_px.push_back(EpipolarDistance(*f_adjusted, xa, xb));
          (r.views[a].station == r.views[b].station ? score.epipolar_same_station_px
                                                    : score.epipolar_across_stations_px)
              .push_back(d);
        }
      }
      score.corners_matched += static_cast<long>(matched.size());
    }
  }
  score.scored = true;
  return score;
}

void CorrespondenceTruth::Add(const CorrespondenceTruth& other) {
  true_matches += other.true_matches;
  background_matches += other.background_matches;
  false_matches += other.false_matches;
  corners_matched += other.corners_matched;
  found_in_both += other.found_in_both;
  visible_in_both += other.visible_in_both;
  auto append = [](std::vector<double>& to, const std::vector<double>& from) {
    to.insert(to.end(), from.begin(), from.end());
  };
  append(epipolar_px, other.epipolar_px);
  append(epipolar_adjusted_px, other.epipolar_adjusted_px);
  append(epipolar_same_station_px, other.epipolar_same_station_px);
  append(epipolar_across_stations_px, other.epipolar_across_stations_px);
  append(point_error_px, other.point_error_px);
  append(point_sigma_px, other.point_sigma_px);
  scored = scored || other.scored;
}

}  // namespace idi::workcell
