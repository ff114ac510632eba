#include "rmp/perception/track_perception.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <string>
#include <thread>

#include "shared/camera/pinhole.h"
#include "shared/geometry/lines.h"
#include "shared/reconstruction/epipolar.h"
#include "shared/reconstruction/features_adapter.h"
#include "shared/reconstruction/triangulation.h"
#include "shared/util/units.h"

namespace idi::rmp {
namespace {

using Clock = std::chrono::steady_clock;
double MsSince(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }

CameraModel WithoutDistortion(const CameraModel& c) {
  CameraModel out = c;
  for (int k = kK1; k <= kK3; ++k) out.params[static_cast<std::size_t>(k)] = 0.0;
  return out;
}

double SampleBilinear(const cv::Mat& gray, const Vec2d& px) {
  const double x = std::clamp(px.x(), 0.0, gray.cols - 1.001), y = std::clamp(px.y(), 0.0, gray.rows - 1.001);
  const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
  const double fx = x - x0, fy = y - y0;
  auto at = [&](int r, int c) { return static_cast<double>(gray.at<uint8_t>(r, c)); };
  return (1 - fy) * ((1 - fx) * at(y0, x0) + fx * at(y0, x0 + 1)) + fy * ((1 - fx) * at(y0 + 1, x0) + fx * at(y0 + 1, x0 + 1));
}

}  // namespace

// One camera's data during Process().
struct TrackPerception::View {
  const RigCamera* camera = nullptr;
  CameraModel pinhole;  // undistorted coordinates
  Rigid3d cam_from_vehicle;
  Vec3d centre = Vec3d::Zero();  // body frame
  ProjectionMatrix34 projection;
  cv::Mat gray;
  FeatureResult result;
  AdaptedFeatures adapted;

  Vec3d Ray(const Vec2d& px) const {
    const Vec3d r((px.x() - pinhole.cx()) / pinhole.fx(), (px.y() - pinhole.cy()) / pinhole.fy(), 1.0);
    return camera->vehicle_from_camera.RotateVector(r).normalized();
  }
  // Undistorted pixel -> pixel in the raw image.
  Vec2d RawPixel(const Vec2d& px) const {
    const Vec3d pn((px.x() - pinhole.cx()) / pinhole.fx(), (px.y() - pinhole.cy()) / pinhole.fy(), 1.0);
    return ProjectToPixel(camera->intrinsics.params.data(), pn);
  }
  bool Inside(const Vec2d& px, double margin) const { return camera->intrinsics.InImage(RawPixel(px), margin); }
};

Status StereoRig::Check() const {
  for (const RigCamera* c : {&left, &right}) {
    const char* name = c == &left ? "left" : "right";
    if (!(c->intrinsics.fx() > 0 && c->intrinsics.fy() > 0) || c->intrinsics.width < 16 || c->intrinsics.height < 16) {
      return InvalidArgument(std::string("rig: ") + name + " camera needs positive focal lengths and at least 16x16 px");
    }
    for (double p : c->intrinsics.params) {
      if (!std::isfinite(p)) return InvalidArgument(std::string("rig: ") + name + " camera has a non-finite intrinsic");
    }
    // Checked here, when the configuration is read, not first when the features detector is built.
    IDI_RETURN_IF_ERROR(CheckDistortionCoversImage(c->intrinsics).WithContext(std::string("rig: ") + name + " camera"));
    if (!c->vehicle_from_camera.rotation.allFinite() || !c->vehicle_from_camera.translation.allFinite()) {
      return InvalidArgument(std::string("rig: ") + name + " camera pose is not finite");
    }
    if (c->vehicle_from_camera.translation.z() <= 0) {
      return InvalidArgument(std::string("rig: ") + name + " camera must be above the ground (z > 0)");
    }
  }
  if ((left.vehicle_from_camera.translation - right.vehicle_from_camera.translation).norm() < 1e-3) {
    return InvalidArgument("rig: the two cameras coincide (no stereo baseline)");
  }
  return Status::Ok();
}

FeatureOptions PerceptionOptions::DefaultFeatureOptions() {
  FeatureOptions f;
  f.curves.enabled = false;
  f.empl.photometric_refinement = false;
  f.hough.max_lines = 80;
  return f;
}

Status PerceptionOptions::Check() const {
  IDI_RETURN_IF_ERROR(tape.Check());
  IDI_RETURN_IF_ERROR(features.Check());
  IDI_RETURN_IF_ERROR(ground.Check());
  if (!correspondence.Check()) return InvalidArgument("perception: invalid correspondence options");
  // At most the track model's limit on observed points (TrackModel::Update refuses points beyond 100 m).
  if (!(max_range_m > 0 && max_range_m <= 100)) return InvalidArgument("perception: max_range_m must be in (0, 100] m");
  if (!(border_margin_px >= 0)) return InvalidArgument("perception: border_margin_px must be >= 0");
  if (!(line_transfer_tolerance_px > 0) || !(line_transfer_angle_deg > 0)) {
    return InvalidArgument("perception: line transfer tolerances must be positive");
  }
  if (!(min_line_triangulation_deg >= 0) || !(max_point_reprojection_px > 0) || !(polarity_min_contrast >= 0)) {
    return InvalidArgument("perception: triangulation and polarity thresholds must be non-negative");
  }
  return Status::Ok();
}

TrackPerception::TrackPerception(const StereoRig& rig, const PerceptionOptions& options)
    : rig_(rig), options_(options), ground_(options.ground) {}
TrackPerception::~TrackPerception() = default;

Result<std::unique_ptr<TrackPerception>> TrackPerception::Create(const StereoRig& rig, const PerceptionOptions& options) {
  IDI_RETURN_IF_ERROR(rig.Check());
  IDI_RETURN_IF_ERROR(options.Check());
  std::unique_ptr<TrackPerception> p(new TrackPerception(rig, options));
  for (const RigCamera* c : {&rig.left, &rig.right}) {
    IDI_ASSIGN_OR_RETURN(FeatureDetector det, FeatureDetector::Create(options.features, c->intrinsics));
    p->detectors_.push_back(std::make_unique<FeatureDetector>(std::move(det)));
    p->footprints_.push_back(GroundFootprint(*c, 16.0, options.max_range_m));
  }
  const ProjectionMatrix34 pl = MakeProjection(WithoutDistortion(rig.left.intrinsics).K(), rig.left.vehicle_from_camera.Inverse());
  const ProjectionMatrix34 pr = MakeProjection(WithoutDistortion(rig.right.intrinsics).K(), rig.right.vehicle_from_camera.Inverse());
  const auto f = FundamentalFromProjections(pl, pr);
  if (!f) return InvalidArgument("rig: no epipolar geometry between the cameras");
  p->fundamental_ = *f;
  return p;
}

void TrackPerception::Reset() { ground_.Reset(); }

Result<PerceptionResult> TrackPerception::Process(const cv::Mat& left, const cv::Mat& right, int64_t timestamp_ns) {
  const auto t_start = Clock::now();
  PerceptionResult out;
  PerceptionStats& st = out.stats;
  View views[2];
  const cv::Mat* images[2] = {&left, &right};
  const RigCamera* cams[2] = {&rig_.left, &rig_.right};
  for (int v = 0; v < 2; ++v) {
    const char* name = v == 0 ? "left" : "right";
    const cv::Mat& img = *images[v];
    if (img.empty()) return InvalidArgument(std::string("perception: the ") + name + " image is empty");
    if (img.cols != cams[v]->intrinsics.width || img.rows != cams[v]->intrinsics.height) {
      return InvalidArgument(std::string("perception: the ") + name + " image is " + std::to_string(img.cols) + "x" +
                             std::to_string(img.rows) + ", the calibration says " +
                             std::to_string(cams[v]->intrinsics.width) + "x" + std::to_string(cams[v]->intrinsics.height));
    }
    if (img.type() == CV_8UC3) {
      cv::cvtColor(img, views[v].gray, cv::COLOR_BGR2GRAY);
    } else if (img.type() == CV_8UC1) {
      views[v].gray = img;
    } else {
      return InvalidArgument(std::string("perception: the ") + name + " image must be 8-bit grey or BGR");
    }
    View& view = views[v];
    view.camera = cams[v];
    view.pinhole = WithoutDistortion(cams[v]->intrinsics);
    view.cam_from_vehicle = cams[v]->vehicle_from_camera.Inverse();
    view.centre = cams[v]->vehicle_from_camera.translation;
    view.projection = MakeProjection(view.pinhole.K(), view.cam_from_vehicle);
  }
  // 1. Features of each image, each with its own detector: the right image on a second thread when
  // parallel_views is set (the results do not depend on it).
  Result<FeatureResult> detected[2] = {FeatureResult{}, FeatureResult{}};
  // An exception (out of memory, OpenCV) becomes this pair's error: escaping the second thread, or
  // unwinding past it unjoined, would end the process without the driver's last zero command.
  auto detect = [&](int v) {
    const auto t0 = Clock::now();
    try {
      detected[v] = detectors_[static_cast<std::size_t>(v)]->Detect(views[v].gray);
    } catch (const std::exception& e) {
      detected[v] = Internal(std::string("feature detection threw: ") + e.what());
    }
    st.features_ms[static_cast<std::size_t>(v)] = MsSince(t0);
  };
  if (options_.parallel_views) {
    std::thread right_view([&] { detect(1); });
    detect(0);
    right_view.join();
  } else {
    detect(0);
    detect(1);
  }
  for (int v = 0; v < 2; ++v) {
    View& view = views[v];
    if (!detected[v].ok())
      return detected[v].status().WithContext(std::string("perception: the ") + (v == 0 ? "left" : "right") + " image");
    view.result = std::move(*detected[v]);
    st.feature_stages[static_cast<std::size_t>(v)] = view.result.timing;
    view.adapted = FromFeatureResult(view.result);
    st.lines[static_cast<std::size_t>(v)] = static_cast<int>(view.adapted.features.lines.size());
    st.points[static_cast<std::size_t>(v)] = static_cast<int>(view.adapted.features.points.size());
  }
  const ViewFeatures& fl = views[0].adapted.features;
  const ViewFeatures& fr = views[1].adapted.features;

  // 2. Correspondence: points and lines by the epipolar constraint and topology (§8.8).
  const PairMatches matches = MatchViewPair(fl, fr, fundamental_, options_.correspondence);
  st.point_matches = static_cast<int>(matches.points.size());
  // Tape lies on the ground: a line match the ground plane contradicts is a wrong one. Near an acute
  // corner two edges pass through one IDI point in both images, and the topology may pair the wrong
  // two; the left line carried through the plane into the right image must lie on the right line (within
  // a loose tolerance, the plane being an estimate). Rejected lines go on to the plane transfer below.
  std::vector<std::pair<int, int>> line_pairs;
  for (const auto& [a, b] : matches.lines) {
    const ViewLine& l = fl.lines[static_cast<std::size_t>(a)];
    const ViewLine& r = fr.lines[static_cast<std::size_t>(b)];
    Vec3d h1, h2;
    bool consistent = true;
    if (ground_.IntersectRay(views[0].centre, views[0].Ray(l.end1), &h1) &&
        ground_.IntersectRay(views[0].centre, views[0].Ray(l.end2), &h2)) {
      const auto q1 = Project(views[1].pinhole, views[1].cam_from_vehicle * h1);
      const auto q2 = Project(views[1].pinhole, views[1].cam_from_vehicle * h2);
      if (q1 && q2 && (*q2 - *q1).norm() >= 5.0) {
        const Vec2d u = (*q2 - *q1).normalized();
        const Vec2d ur = (r.end2 - r.end1).normalized();
        const double tol_px = 3.0 * options_.line_transfer_tolerance_px;
        consistent = std::abs(u.dot(ur)) >= std::cos(DegToRad(3.0 * options_.line_transfer_angle_deg)) &&
                     std::abs(r.line.SignedDistance(*q1)) <= tol_px && std::abs(r.line.SignedDistance(*q2)) <= tol_px;
      }
    }
    if (consistent) {
      line_pairs.emplace_back(a, b);
    } else {
      ++st.line_matches_rejected_by_plane;
    }
  }
  st.line_matches_topology = static_cast<int>(line_pairs.size());
  std::vector<char> left_used(fl.lines.size(), 0), right_used(fr.lines.size(), 0);
  for (const auto& [a, b] : line_pairs) {
    left_used[static_cast<std::size_t>(a)] = 1;
    right_used[static_cast<std::size_t>(b)] = 1;
  }
  // ... completed by transferring each remaining left line through the ground plane into the right
  // image (the homography the plane induces), matched mutually best within the tolerances.
  {
    struct Transfer {
      double score = std::numeric_limits<double>::infinity();
      int other = -1;
      double second = std::numeric_limits<double>::infinity();
    };
    std::vector<Transfer> best_left(fl.lines.size()), best_right(fr.lines.size());
    const double cos_tol = std::cos(DegToRad(options_.line_transfer_angle_deg));
    for (std::size_t i = 0; i < fl.lines.size(); ++i) {
      if (left_used[i]) continue;
      const ViewLine& l = fl.lines[i];
      Vec3d h1, h2;
      if (!ground_.IntersectRay(views[0].centre, views[0].Ray(l.end1), &h1) ||
          !ground_.IntersectRay(views[0].centre, views[0].Ray(l.end2), &h2)) {
        continue;
      }
      const auto q1 = Project(views[1].pinhole, views[1].cam_from_vehicle * h1);
      const auto q2 = Project(views[1].pinhole, views[1].cam_from_vehicle * h2);
      if (!q1 || !q2 || (*q2 - *q1).norm() < 5.0) continue;
      const Vec2d u = (*q2 - *q1).normalized();
      const double len = (*q2 - *q1).norm();
      for (std::size_t j = 0; j < fr.lines.size(); ++j) {
        if (right_used[j]) continue;
        const ViewLine& r = fr.lines[j];
        const Vec2d ur = (r.end2 - r.end1).normalized();
        if (std::abs(u.dot(ur)) < cos_tol) continue;
        const double t1 = (r.end1 - *q1).dot(u), t2 = (r.end2 - *q1).dot(u);
        const double a = std::max(0.0, std::min(t1, t2)), b = std::min(len, std::max(t1, t2));
        if (b - a < std::min(10.0, 0.3 * std::min(len, (r.end2 - r.end1).norm()))) continue;
        const double score = 0.5 * (std::abs(r.line.SignedDistance(*q1 + a * u)) + std::abs(r.line.SignedDistance(*q1 + b * u)));
        if (score > options_.line_transfer_tolerance_px) continue;
        for (auto [t, other, self] : {std::tuple{&best_left[i], static_cast<int>(j), 0}, std::tuple{&best_right[j], static_cast<int>(i), 1}}) {
          (void)self;
          if (score < t->score) {
            t->second = t->score;
            t->score = score;
            t->other = other;
          } else if (score < t->second) {
            t->second = score;
          }
        }
      }
    }
    for (std::size_t i = 0; i < fl.lines.size(); ++i) {
      const int j = best_left[i].other;
      if (j < 0 || best_right[static_cast<std::size_t>(j)].other != static_cast<int>(i)) continue;
      // Unambiguous: the runner-up (the tape's other edge) is clearly worse.
      if (best_left[i].second < 2.0 * best_left[i].score + 0.5 || best_right[static_cast<std::size_t>(j)].second < 2.0 * best_left[i].score + 0.5) {
        continue;
      }
      line_pairs.emplace_back(static_cast<int>(i), j);
      left_used[i] = 1;
      right_used[static_cast<std::size_t>(j)] = 1;
      ++st.line_matches_transfer;
    }
  }

  // IDI points the topology left ambiguous (the four corners of a tape's turn look alike along the
  // epipolar lines) are told apart the same way: transferred through the plane, on the epipolar line.
  std::vector<std::pair<int, int>> point_pairs = matches.points;
  {
    std::vector<char> lp(fl.points.size(), 0), rp(fr.points.size(), 0);
    for (const auto& [a, b] : point_pairs) {
      lp[static_cast<std::size_t>(a)] = 1;
      rp[static_cast<std::size_t>(b)] = 1;
    }
    std::vector<std::pair<int, double>> best_for_right(fr.points.size(), {-1, std::numeric_limits<double>::infinity()});
    std::vector<std::pair<int, int>> proposals;
    for (std::size_t i = 0; i < fl.points.size(); ++i) {
      if (lp[i]) continue;
      Vec3d h;
      if (!ground_.IntersectRay(views[0].centre, views[0].Ray(fl.points[i].xy), &h)) continue;
      const auto q = Project(views[1].pinhole, views[1].cam_from_vehicle * h);
      if (!q) continue;
      double best = std::numeric_limits<double>::infinity(), second = best;
      int best_j = -1;
      for (std::size_t j = 0; j < fr.points.size(); ++j) {
        if (rp[j]) continue;
        if (EpipolarDistance(fundamental_, fl.points[i].xy, fr.points[j].xy) > options_.correspondence.epipolar_tolerance_px + 1.0) continue;
        const double d = (fr.points[j].xy - *q).norm();
        if (d < best) {
          second = best;
          best = d;
          best_j = static_cast<int>(j);
        } else if (d < second) {
          second = d;
        }
      }
      if (best_j < 0 || best > options_.line_transfer_tolerance_px || second < 2.0 * best + 1.0) continue;
      auto& slot = best_for_right[static_cast<std::size_t>(best_j)];
      if (best < slot.second) slot = {static_cast<int>(i), best};
      proposals.emplace_back(static_cast<int>(i), best_j);
    }
    for (const auto& [i, j] : proposals) {
      if (best_for_right[static_cast<std::size_t>(j)].first != i) continue;
      point_pairs.emplace_back(i, j);
      ++st.point_matches;
    }
  }

  // 3. Triangulation (body frame) of the matched points and lines: samples of the ground.
  std::vector<GroundSample> samples;
  const Vec3d rig_centre = 0.5 * (views[0].centre + views[1].centre);
  for (const auto& [a, b] : point_pairs) {
    const std::vector<PointObservation> obs = {
        {&views[0].pinhole, views[0].cam_from_vehicle, fl.points[static_cast<std::size_t>(a)].xy},
        {&views[1].pinhole, views[1].cam_from_vehicle, fr.points[static_cast<std::size_t>(b)].xy}};
    const auto x = TriangulatePoint(obs);
    if (!x || x->reprojection_rms_px > options_.max_point_reprojection_px) continue;
    samples.push_back({x->xyz, (x->xyz - rig_centre).norm()});
    ++st.points_triangulated;
  }
  for (const auto& [a, b] : line_pairs) {
    const ViewLine& l = fl.lines[static_cast<std::size_t>(a)];
    const ViewLine& r = fr.lines[static_cast<std::size_t>(b)];
    const auto line3 = TriangulateLine({{views[0].projection, l.line}, {views[1].projection, r.line}},
                                       DegToRad(options_.min_line_triangulation_deg));
    if (!line3) continue;
    // The segment's extent on the 3D line, from both views' confirmed ends.
    double s_min = std::numeric_limits<double>::infinity(), s_max = -s_min;
    for (int v = 0; v < 2; ++v) {
      const ViewLine& vl = v == 0 ? l : r;
      for (const Vec2d& e : {vl.end1, vl.end2}) {
        const Line3d ray{views[v].centre, views[v].Ray(e)};
        const auto st_pair = ClosestPointsBetweenLines(*line3, ray, 1e-9);
        if (!st_pair) continue;
        s_min = std::min(s_min, st_pair->first);
        s_max = std::max(s_max, st_pair->first);
      }
    }
    if (!(s_max > s_min)) continue;
    for (const double f : {0.0, 0.5, 1.0}) {
      const Vec3d p = line3->PointAt(s_min + f * (s_max - s_min));
      if ((p - rig_centre).head<2>().norm() > options_.max_range_m + 0.5) continue;
      samples.push_back({p, (p - rig_centre).norm()});
    }
    ++st.lines_triangulated;
  }

  // 4. The ground plane, refined from what was triangulated.
  const GroundPlaneUpdate gu = ground_.Update(samples);
  st.ground_samples_used = gu.used;
  st.ground_samples_rejected = gu.rejected;
  st.plane = ground_.plane();
  const Rigid3d ground_from_body = ground_.GroundFromBody();

  // 5. Tape edges on the ground, per view.
  struct ViewEdge {
    GroundEdge edge;
    int view, line;
    bool valid = false;
  };
  std::vector<ViewEdge> view_edges[2];
  auto to_ground = [&](int v, const Vec2d& px, Vec2d* g) {
    Vec3d hit;
    if (!ground_.IntersectRay(views[v].centre, views[v].Ray(px), &hit)) return false;
    *g = (ground_from_body * hit).head<2>();
    return true;
  };
  for (int v = 0; v < 2; ++v) {
    const ViewFeatures& vf = views[v].adapted.features;
    view_edges[v].resize(vf.lines.size());
    for (std::size_t i = 0; i < vf.lines.size(); ++i) {
      const ViewLine& l = vf.lines[i];
      ViewEdge& ve = view_edges[v][i];
      ve.view = v;
      ve.line = static_cast<int>(i);
      Vec2d ga, gb;
      if (!to_ground(v, l.end1, &ga) || !to_ground(v, l.end2, &gb)) continue;
      std::array<bool, 2> inside = {views[v].Inside(l.end1, options_.border_margin_px),
                                    views[v].Inside(l.end2, options_.border_margin_px)};
      // Clip at the range limit.
      const double ra = ga.norm(), rb = gb.norm();
      if (ra > options_.max_range_m && rb > options_.max_range_m) continue;
      auto clip = [&](Vec2d* far, const Vec2d& near, bool* in) {
        // Point on near->far at range max_range_m (bisection; the range grows monotonically enough).
        double lo = 0.0, hi = 1.0;
        for (int k = 0; k < 30; ++k) {
          const double mid = 0.5 * (lo + hi);
          if ((near + mid * (*far - near)).norm() > options_.max_range_m) hi = mid; else lo = mid;
        }
        *far = near + lo * (*far - near);
        *in = false;
      };
      if (ra > options_.max_range_m) clip(&ga, gb, &inside[0]);
      if (rb > options_.max_range_m) clip(&gb, ga, &inside[1]);
      if ((gb - ga).norm() < 0.01) continue;
      ve.edge.a = ga;
      ve.edge.b = gb;
      ve.edge.end_inside = inside;
      // Polarity: which side of the edge is brighter in the image, carried onto the ground.
      const Vec2d n = l.line.normal;
      double diff = 0.0;
      for (const double f : {0.25, 0.5, 0.75}) {
        const Vec2d p = l.end1 + f * (l.end2 - l.end1);
        diff += SampleBilinear(views[v].gray, views[v].RawPixel(p + 2.5 * n)) - SampleBilinear(views[v].gray, views[v].RawPixel(p - 2.5 * n));
      }
      diff /= 3.0;
      Vec2d g_mid, g_off;
      const Vec2d mid = 0.5 * (l.end1 + l.end2);
      if (std::abs(diff) >= options_.polarity_min_contrast && to_ground(v, mid, &g_mid) && to_ground(v, mid + 3.0 * n, &g_off)) {
        const Vec2d d = gb - ga, s = g_off - g_mid;
        const int plus_side = d.x() * s.y() - d.y() * s.x() > 0 ? +1 : -1;  // +n in the image is left/right on the ground
        const bool tape_on_plus = (diff > 0) == options_.tape_brighter;
        ve.edge.tape_side = tape_on_plus ? plus_side : -plus_side;
      }
      ve.valid = true;
    }
  }
  // Merge the two views' edges: matched pairs, then any two that coincide on the ground.
  auto merge = [](const GroundEdge& x, const GroundEdge& y_in) {
    GroundEdge y = y_in;
    if ((y.b - y.a).dot(x.b - x.a) < 0) {
      std::swap(y.a, y.b);
      std::swap(y.end_inside[0], y.end_inside[1]);
      y.tape_side = -y.tape_side;
    }
    const Vec2d u = ((x.b - x.a).normalized() + (y.b - y.a).normalized()).normalized();
    const Vec2d c = 0.25 * (x.a + x.b + y.a + y.b);
    auto along = [&](const Vec2d& p) { return (p - c).dot(u); };
    GroundEdge m;
    auto pick = [&](const Vec2d& px, bool ix, const Vec2d& py, bool iy, bool low, bool* inside) {
      const double sx = along(px), sy = along(py);
      if (ix && iy) {
        *inside = true;
        return 0.5 * (sx + sy);
      }
      if (ix != iy) {
        *inside = true;
        return ix ? sx : sy;  // the view that sees the end
      }
      *inside = false;
      return low ? std::min(sx, sy) : std::max(sx, sy);
    };
    bool in0 = false, in1 = false;
    const double s0 = pick(x.a, x.end_inside[0], y.a, y.end_inside[0], true, &in0);
    const double s1 = pick(x.b, x.end_inside[1], y.b, y.end_inside[1], false, &in1);
    m.a = c + s0 * u;
    m.b = c + s1 * u;
    m.end_inside = {in0, in1};
    m.tape_side = x.tape_side == y.tape_side ? x.tape_side : (x.tape_side == 0 ? y.tape_side : (y.tape_side == 0 ? x.tape_side : 0));
    return m;
  };
  std::vector<GroundEdge> edges;
  std::vector<char> right_merged(view_edges[1].size(), 0), left_merged(view_edges[0].size(), 0);
  for (const auto& [a, b] : line_pairs) {
    const ViewEdge& x = view_edges[0][static_cast<std::size_t>(a)];
    const ViewEdge& y = view_edges[1][static_cast<std::size_t>(b)];
    if (!x.valid || !y.valid) continue;
    edges.push_back(merge(x.edge, y.edge));
    left_merged[static_cast<std::size_t>(a)] = 1;
    right_merged[static_cast<std::size_t>(b)] = 1;
  }
  auto coincide = [&](const GroundEdge& x, const GroundEdge& y) {
    const Vec2d ux = (x.b - x.a).normalized(), uy = (y.b - y.a).normalized();
    if (std::abs(ux.dot(uy)) < std::cos(DegToRad(3.0))) return false;
    const Vec2d nx(-ux.y(), ux.x());
    const double tol = 0.3 * options_.tape.tape_width_m;
    if (std::abs((y.a - x.a).dot(nx)) > tol || std::abs((y.b - x.a).dot(nx)) > tol) return false;
    const double t1 = (y.a - x.a).dot(ux), t2 = (y.b - x.a).dot(ux);
    return std::min((x.b - x.a).norm(), std::max(t1, t2)) - std::max(0.0, std::min(t1, t2)) > 0.0;
  };
  std::vector<GroundEdge> left_only;
  for (std::size_t i = 0; i < view_edges[0].size(); ++i) {
    if (view_edges[0][i].valid && !left_merged[i]) left_only.push_back(view_edges[0][i].edge);
  }
  std::vector<char> left_only_merged(left_only.size(), 0);
  for (std::size_t j = 0; j < view_edges[1].size(); ++j) {
    if (!view_edges[1][j].valid || right_merged[j]) continue;
    bool done = false;
    for (std::size_t i = 0; i < left_only.size() && !done; ++i) {
      if (left_only_merged[i] || !coincide(left_only[i], view_edges[1][j].edge)) continue;
      edges.push_back(merge(left_only[i], view_edges[1][j].edge));
      left_only_merged[i] = 1;
      done = true;
    }
    if (!done) edges.push_back(view_edges[1][j].edge);
  }
  for (std::size_t i = 0; i < left_only.size(); ++i) {
    if (!left_only_merged[i]) edges.push_back(left_only[i]);
  }
  st.edges = static_cast<int>(edges.size());

  // 6. Strips of the tape's width, their midlines joined at corners.
  const std::vector<CentreSegment> strips = PairTapeEdges(edges, options_.tape);
  st.strips = static_cast<int>(strips.size());
  out.observation.pieces = ChainCentreSegments(strips, options_.tape);
  st.pieces = static_cast<int>(out.observation.pieces.size());
  out.observation.timestamp_ns = timestamp_ns;
  out.observation.footprints_m = footprints_;
  out.edges = std::move(edges);
  st.total_ms = MsSince(t_start);
  return out;
}

}  // namespace idi::rmp
