#include "workcell/procedures/scan.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <map>
#include <random>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "shared/kinematics/aiming.h"
#include "shared/kinematics/biclops.h"
#include "shared/kinematics/rx130.h"
#include "shared/util/atomic_file.h"
#include "shared/util/units.h"
#include "workcell/procedures/calibration_procedures.h"

namespace idi::workcell {
namespace {

namespace fs = std::filesystem;
constexpr std::chrono::milliseconds kPtuTimeout{10'000};
constexpr std::chrono::milliseconds kGrabTimeout{2'000};

double Seconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// R1 from robot k's base at a rail position, with the calibrated rail directions and psi (eq. 3.4).
Rigid3d WorldFromBase(const calib::ArmModel& model, int arm_index, const std::array<double, 4>& psi, double rail_mm) {
  CellSetup setup;
  setup.psi = psi;
  return NominalWorldFromBase(arm_index, model, setup, rail_mm);
}

// The head pose for a station: the TCF's camera diagonal (the nominal cameras look along the TCF's
// (1, 1, 0) with image-down along its z, Biclops as mounted, §3.4) along `view_dir`, the cameras' midpoint
// `camera_mid` (nominally 40, 40, 275 mm from the TCF).
Rigid3d WorldFromTcfForView(const Vec3d& camera_mid, const Vec3d& view_dir) {
  const Vec3d axis_tcf = Vec3d(1, 1, 0).normalized(), down_tcf = Vec3d::UnitZ();
  Vec3d down = Vec3d(0, 0, -1) - Vec3d(0, 0, -1).dot(view_dir) * view_dir;
  down.normalize();
  Mat3d a, b;
  a << axis_tcf, down_tcf, axis_tcf.cross(down_tcf);
  b << view_dir, down, view_dir.cross(down);
  Rigid3d out;
  out.rotation = b * a.transpose();
  out.translation = camera_mid - out.rotation * Vec3d(40, 40, 275);
  return out;
}

// The projection of the object region (a cylinder on the table) into a view: the convex hull of its rims.
cv::Mat ObjectRegionMask(const StructureView& v, const ScanOptions& o) {
  std::vector<cv::Point> pts;
  for (int k = 0; k < 72; ++k) {
    const double a = 2 * kPi * k / 72.0;
    for (const double h : {0.0, o.object_region_height_mm}) {
      const Vec3d p = o.table_centre_world + Vec3d(o.object_region_radius_mm * std::cos(a),
                                                   o.object_region_radius_mm * std::sin(a), h);
      const Vec3d pc = v.cam_from_world * p;
      if (pc.z() <= 1.0) return cv::Mat();  // a camera inside the region: no mask
      const Vec2d px = ProjectToPixel(v.camera.params.data(), pc);
      if (!px.allFinite() || px.cwiseAbs().maxCoeff() > 1e6) return cv::Mat();
      pts.emplace_back(static_cast<int>(std::lround(px.x())), static_cast<int>(std::lround(px.y())));
    }
  }
  std::vector<cv::Point> hull;
  cv::convexHull(pts, hull);
  cv::Mat mask = cv::Mat::zeros(v.image.size(), CV_8UC1);
  cv::fillConvexPoly(mask, hull, cv::Scalar(255));
  return mask;
}

// A standing cylinder (no corners, so no IDI points) from its silhouettes: each view's outline edges are
// EMPL lines whose back-projected planes are vertical and tangent to the cylinder, n.(x, y) - d = +-r
// about its axis (x0, y0). RANSAC over triples of such planes and the signs, then least squares on the
// inliers; the top is where the silhouettes' upper ends meet their tangent lines.
struct CylinderFit {
  Vec2d axis = Vec2d::Zero();
  double radius = 0, top_z = 0;
  int planes = 0;
};
// The top rim, a horizontal circle (axis, radius) at top_z, is the outline of the cylinder's top face in
// every view: its strongest edge (the face is lit from above; the limbs are the dark side against the dark
// table, and their lines stop short of the rim). The limbs' fit is refined by maximising the image
// gradient along the projected rim, summed over the views: first the height alone, then all four.
// Returns the mean gradient along the rim (0 when it falls outside every image).
// The views' gradient magnitudes (Gaussian sigma 1 px, gray levels per pixel), for RefineOnTopRim.
std::vector<cv::Mat> GradientMagnitudes(const std::vector<StructureView>& views) {
  std::vector<cv::Mat> grad;
  for (const StructureView& v : views) {
    cv::Mat gray = v.image;
    if (gray.channels() == 3) cv::cvtColor(v.image, gray, cv::COLOR_BGR2GRAY);
    cv::Mat f, gx, gy, mag;
    gray.convertTo(f, CV_32F);
    cv::GaussianBlur(f, f, cv::Size(0, 0), 1.0);
    cv::Sobel(f, gx, CV_32F, 1, 0, 3, 0.125);
    cv::Sobel(f, gy, CV_32F, 0, 1, 3, 0.125);
    cv::magnitude(gx, gy, mag);
    grad.push_back(mag);
  }
  return grad;
}

double RefineOnTopRim(const std::vector<StructureView>& views,
                      const std::vector<cv::Mat>& grad,
                      const ScanOptions& o,
                      CylinderFit* fit) {
  auto sample = [](const cv::Mat& m, const Vec2d& px) {
    const int x0 = static_cast<int>(std::floor(px.x())), y0 = static_cast<int>(std::floor(px.y()));
    if (x0 < 0 || y0 < 0 || x0 + 1 >= m.cols || y0 + 1 >= m.rows) return -1.0;
    const double fx = px.x() - x0, fy = px.y() - y0;
    return (1 - fy) * ((1 - fx) * m.at<float>(y0, x0) + fx * m.at<float>(y0, x0 + 1)) +
           fy * ((1 - fx) * m.at<float>(y0 + 1, x0) + fx * m.at<float>(y0 + 1, x0 + 1));
  };
  // p: axis x, axis y, radius, top z.
  auto score = [&](const Eigen::Vector4d& p) {
    if (!(p[2] > 5)) return 0.0;
    double sum = 0;
    int n = 0;
    for (std::size_t v = 0; v < views.size(); ++v) {
      for (int k = 0; k < 60; ++k) {
        const double a = 2 * kPi * k / 60.0;
        const Vec3d x(p[0] + p[2] * std::cos(a), p[1] + p[2] * std::sin(a), p[3]);
        const auto px = Project(views[v].camera, views[v].cam_from_world * x);
        if (!px) continue;
        const double g = sample(grad[v], *px);
        if (g < 0) continue;
        sum += g;
        ++n;
      }
    }
    return n > 0 ? sum / n : 0.0;
  };
  Eigen::Vector4d best(fit->axis.x(), fit->axis.y(), fit->radius, fit->top_z);
  double best_score = score(best);
  for (double z = o.table_centre_world.z() + 10; z <= o.table_centre_world.z() + o.object_region_height_mm; z += 2.0) {
    Eigen::Vector4d p = best;
    p[3] = z;
    const double sc = score(p);
    if (sc > best_score) {
      best_score = sc;
      best[3] = z;
    }
  }
  for (double step = 2.0; step >= 0.05; step *= 0.5) {
    bool moved = true;
    for (int it = 0; moved && it < 20; ++it) {
      moved = false;
      for (int c = 0; c < 4; ++c) {
        for (const double sgn : {1.0, -1.0}) {
          Eigen::Vector4d p = best;
          p[c] += sgn * step;
          const double sc = score(p);
          if (sc > best_score) {
            best_score = sc;
            best = p;
            moved = true;
          }
        }
      }
    }
  }
  fit->axis = best.head<2>();
  fit->radius = best[2];
  fit->top_z = best[3];
  return best_score;
}

std::optional<CylinderFit> FitCylinder(const std::vector<StructureView>& views, const std::vector<FeatureResult>& features,
                                       const ScanOptions& o) {
  struct Plane {
    Vec2d n;
    double d;
    Vec3d centre;
    std::array<Vec3d, 2> end_rays;
  };
  std::vector<Plane> planes;
  for (std::size_t v = 0; v < views.size() && v < features.size(); ++v) {
    const CameraModel& k = views[v].camera;
    const Rigid3d world_from_cam = views[v].cam_from_world.Inverse();
    auto ray = [&](const Vec2d& px) {
      return Vec3d(world_from_cam.rotation * Vec3d((px.x() - k.cx()) / k.fx(), (px.y() - k.cy()) / k.fy(), 1.0));
    };
    for (const EmplLine& l : features[v].lines) {
      if (l.length_px < 30) continue;
      if (!views[v].roi.empty()) {
        const Vec2d mid = 0.5 * (l.p1 + l.p2);
        const int x = static_cast<int>(mid.x()), y = static_cast<int>(mid.y());
        if (x < 0 || y < 0 || x >= views[v].roi.cols || y >= views[v].roi.rows || views[v].roi.at<uint8_t>(y, x) == 0) continue;
      }
      const Vec3d r1 = ray(l.p1), r2 = ray(l.p2);
      Vec3d n = r1.cross(r2);
      if (n.norm() < 1e-12) continue;
      n.normalize();
      if (std::abs(n.z()) > std::sin(DegToRad(2.0))) continue;  // not a vertical plane
      const Vec2d nh = n.head<2>().normalized();
      planes.push_back({nh, nh.dot(world_from_cam.translation.head<2>()), world_from_cam.translation, {r1, r2}});
    }
  }
  if (planes.size() < 3) return std::nullopt;
  const double tol = 1.5;
  auto solve = [&](const std::vector<std::pair<int, double>>& set) -> std::optional<Vec3d> {
    Eigen::MatrixXd a(set.size(), 3);
    Eigen::VectorXd b(set.size());
    for (std::size_t i = 0; i < set.size(); ++i) {
      const Plane& p = planes[static_cast<std::size_t>(set[i].first)];
      a.row(static_cast<Eigen::Index>(i)) << p.n.x(), p.n.y(), -set[i].second;
      b(static_cast<Eigen::Index>(i)) = p.d;
    }
    const Vec3d x = a.colPivHouseholderQr().solve(b);
    if (!x.allFinite() || x.z() < 5 || x.z() > 100) return std::nullopt;
    if ((x.head<2>() - o.table_centre_world.head<2>()).norm() > o.object_region_radius_mm) return std::nullopt;
    return x;
  };
  auto inliers = [&](const Vec3d& x) {
    std::vector<std::pair<int, double>> in;
    for (std::size_t i = 0; i < planes.size(); ++i) {
      const double sd = planes[i].n.dot(x.head<2>()) - planes[i].d;
      if (std::abs(std::abs(sd) - x.z()) < tol) in.emplace_back(static_cast<int>(i), sd > 0 ? 1.0 : -1.0);
    }
    return in;
  };
  std::mt19937 rng(7);
  std::uniform_int_distribution<std::size_t> pick(0, planes.size() - 1);
  // Every consensus found, largest first: the largest can be wrong (lines of the top face's shading or of
  // the table taken for limbs), so the few largest distinct ones are each refined on the top rim and the
  // one whose rim the images show best is taken.
  std::vector<std::vector<std::pair<int, double>>> sets;
  for (int it = 0; it < 400; ++it) {
    const std::size_t i = pick(rng), j = pick(rng), k = pick(rng);
    if (i == j || j == k || i == k) continue;
    for (int signs = 0; signs < 8; ++signs) {
      const auto x = solve({{static_cast<int>(i), signs & 1 ? 1.0 : -1.0},
                            {static_cast<int>(j), signs & 2 ? 1.0 : -1.0},
                            {static_cast<int>(k), signs & 4 ? 1.0 : -1.0}});
      if (!x) continue;
      auto in = inliers(*x);
      // Outlines from at least three views' worth of planes (two per view).
      if (in.size() < 4) continue;
      std::sort(in.begin(), in.end());
      if (std::find(sets.begin(), sets.end(), in) == sets.end()) sets.push_back(std::move(in));
    }
  }
  std::stable_sort(sets.begin(), sets.end(), [](const auto& a, const auto& b) { return a.size() > b.size(); });
  std::optional<CylinderFit> chosen;
  double chosen_score = -1;
  std::vector<cv::Mat> grad;
  std::vector<CylinderFit> tried;
  for (const auto& set : sets) {
    if (tried.size() >= 6) break;
    const auto x = solve(set);
    if (!x) continue;
    CylinderFit fit;
    fit.axis = x->head<2>();
    fit.radius = x->z();
    fit.planes = static_cast<int>(set.size());
    if (std::any_of(tried.begin(), tried.end(), [&](const CylinderFit& t) {
          return (t.axis - fit.axis).norm() < 10.0 && std::abs(t.radius - fit.radius) < 5.0;
        })) {
      continue;
    }
    tried.push_back(fit);
    std::vector<double> tops;
    for (const auto& [i, sign] : set) {
      const Plane& p = planes[static_cast<std::size_t>(i)];
      // The tangent line: vertical, through the axis point moved r along -sign n.
      const Vec2d foot = fit.axis - sign * fit.radius * p.n;
      double top = -1e9;
      for (const Vec3d& r : p.end_rays) {
        // Closest approach of the ray c + t r to the vertical line (foot, z): solve in the horizontal plane.
        const Vec2d rh = r.head<2>();
        if (rh.squaredNorm() < 1e-12) continue;
        const double t = (foot - p.centre.head<2>()).dot(rh) / rh.squaredNorm();
        top = std::max(top, p.centre.z() + t * r.z());
      }
      tops.push_back(top);
    }
    std::sort(tops.begin(), tops.end());
    fit.top_z = tops[tops.size() / 2];
    if (grad.empty()) grad = GradientMagnitudes(views);
    const double score = RefineOnTopRim(views, grad, o, &fit);
    if (!(fit.top_z > o.table_centre_world.z() + 5 &&
          fit.top_z < o.table_centre_world.z() + o.object_region_height_mm)) {
      continue;
    }
    if ((fit.axis - o.table_centre_world.head<2>()).norm() > o.object_region_radius_mm) continue;
    if (score > chosen_score) {
      chosen_score = score;
      chosen = fit;
    }
  }
  return chosen;
}

Status StopArms(ScanDevices& d) {
  Status s = Status::Ok();
  for (hal::ArmDevice* a : {d.arm1, d.arm2}) {
    if (a == nullptr) continue;
    const Status st = a->Stop();
    if (!st.ok() && s.ok()) s = st;
  }
  return s;
}

// Pose of the flange in robot k's base for a palm pose in the world.
Rigid3d BaseFromFlangeForPalm(const Rigid3d& base_from_world, const Rigid3d& world_from_palm, const Rigid3d& flange_from_palm) {
  return base_from_world * world_from_palm * flange_from_palm.Inverse();
}

Result<Joints> SolveArm(const ParamSet& robot, const Joints& start, const Rigid3d& base_from_flange,
                        const std::vector<Joints>& fallbacks) {
  auto ik = SolveFlangePose(robot, start, base_from_flange, Rx130JointLimits());
  for (std::size_t i = 0; !(ik.ok() && ik->residual_mm < 0.05) && i < fallbacks.size(); ++i) {
    ik = SolveFlangePose(robot, fallbacks[i], base_from_flange, Rx130JointLimits());
  }
  if (!ik.ok()) return ik.status();
  if (ik->residual_mm >= 0.05) {
    return NotFound(fmt::format("pose not reachable (residual {:.2f} mm)", ik->residual_mm));
  }
  return ik->q;
}

bool IsCancelled(const ScanOptions& o) { return o.cancelled && o.cancelled(); }

void Progress(const ScanOptions& o, double f, const std::string& what) {
  spdlog::info("scan: {} ({:.0f} %)", what, 100 * f);
  if (o.progress) o.progress(f, what);
}

}  // namespace

// Stray points: a floor tile's or the table rim's corner matched wrongly across wide baselines lands
// inside the object region, alone. The object is the largest group of points joined by edges; a point
// joined by edges to no other point of the region is kept when it lies within object_link_mm of that
// group's box (a corner whose edges were not reconstructed; the box reaches down to the table, so a
// bottom corner under the top face stays), else it is dropped: it must not widen the grasp's silhouette.
std::vector<int> DropStrayPoints(const StructureModel& model, const std::vector<int>& object_points, const ScanOptions& o) {
  if (object_points.size() <= 3) return object_points;
  std::vector<int> parent(model.points.size());
  for (std::size_t i = 0; i < parent.size(); ++i) parent[i] = static_cast<int>(i);
  auto root = [&](int i) {
    while (parent[static_cast<std::size_t>(i)] != i) i = parent[static_cast<std::size_t>(i)];
    return i;
  };
  for (const auto& [a, b] : model.edges) parent[static_cast<std::size_t>(root(a))] = root(b);
  std::map<int, int> size;  // group root -> its points in the region
  for (const int i : object_points) ++size[root(i)];
  const auto biggest = std::max_element(size.begin(), size.end(), [](const auto& x, const auto& y) { return x.second < y.second; });
  if (biggest->second < 3) return object_points;
  Eigen::AlignedBox3d box;
  for (const int i : object_points) {
    if (root(i) == biggest->first) box.extend(model.points[static_cast<std::size_t>(i)].xyz);
  }
  box.min().array() -= o.object_link_mm;
  box.max().array() += o.object_link_mm;
  box.min().z() = std::min(box.min().z(), o.table_centre_world.z() - o.table_tolerance_mm);
  std::vector<int> kept;
  for (const int i : object_points) {
    if (size[root(i)] > 1 || box.contains(model.points[static_cast<std::size_t>(i)].xyz)) kept.push_back(i);
  }
  return kept;
}

Status ScanOptions::Check() const {
  if (!table_centre_world.allFinite()) return InvalidArgument("scan: the table centre must be finite");
  if (!(table_radius_mm > 0)) return InvalidArgument("scan: the table radius must be positive");
  if (azimuths_deg.empty()) return InvalidArgument("scan: at least one station (azimuth) is needed");
  for (double a : azimuths_deg) {
    if (!std::isfinite(a)) return InvalidArgument("scan: station azimuths must be finite");
  }
  for (double a : extra_azimuths_deg) {
    if (!std::isfinite(a)) return InvalidArgument("scan: the second round's station azimuths must be finite");
  }
  if (!(object_region_radius_mm > 0 && object_region_height_mm > 0) || !std::isfinite(object_region_radius_mm) ||
      !std::isfinite(object_region_height_mm)) {
    return InvalidArgument("scan: the object region's radius and height must be positive and finite");
  }
  if (!(rail1_max_mm > 0 && std::isfinite(rail1_max_mm)) || !(rail2_max_mm > 0 && std::isfinite(rail2_max_mm))) {
    return InvalidArgument("scan: the rails' travel (rail1_max_mm, rail2_max_mm) must be positive and finite");
  }
  if (!(station_step_deg > 0 && station_step_deg <= 90) || station_retries < 0) {
    return InvalidArgument("scan: station_step_deg must be in (0, 90] and station_retries >= 0");
  }
  if (grasp_alternatives < 1 || grasp_alternatives > 100) {
    return InvalidArgument("scan: grasp_alternatives must be 1 to 100");
  }
  if (!(object_link_mm >= 0) || !std::isfinite(object_link_mm)) {
    return InvalidArgument("scan: object_link_mm must be a finite distance >= 0");
  }
  if (!(view_distance_mm > 200 && view_distance_mm < 3000)) {
    return InvalidArgument(fmt::format("scan: view distance {} mm is outside (200, 3000)", view_distance_mm));
  }
  if (!(elevation_deg > 5 && elevation_deg < 89)) return InvalidArgument("scan: elevation must be in (5, 89) deg");
  if (!std::isfinite(aim_height_mm) || !(table_tolerance_mm >= 0) || !std::isfinite(table_tolerance_mm)) {
    return InvalidArgument("scan: the aim height and the table tolerance must be finite, the tolerance non-negative");
  }
  if (!(table_height_prior_mm >= 0 && std::isfinite(table_height_prior_mm)) ||
      !(table_flatness_mm > 0 && std::isfinite(table_flatness_mm))) {
    return InvalidArgument("scan: the table height prior must be >= 0 and its flatness > 0 (mm)");
  }
  if (!place_offset_world.allFinite()) return InvalidArgument("scan: the place offset must be finite");
  if (rail2_candidates_mm.empty()) return InvalidArgument("scan: robot 2 needs at least one rail position to try");
  if (!grasp.Check()) return InvalidArgument("scan: invalid grasp options");
  return Status::Ok();
}

Rigid3d ChainWorldFromCamera(const ScanCalibration& c, int camera, const Joints& q, double rail_mm, double pan_rad,
                             double tilt_rad) {
  const Rigid3d base_from_flange = Rx130BaseFromFlange(c.robot1.robot.data(), q.data());
  const calib::PtuCameraModel& m = c.cameras[static_cast<std::size_t>(camera)];
  return WorldFromBase(c.robot1, 0, c.psi, rail_mm) *
         m.BaseFromCamera(TcfPoseFromTransform(base_from_flange), pan_rad, tilt_rad);
}

Result<std::array<double, 2>> FixatePtu(const ScanCalibration& c, int camera, const Joints& q, double rail_mm,
                                        const Vec3d& target_world, const hal::PanTiltLimits& limits) {
  const calib::PtuCameraModel& m = c.cameras[static_cast<std::size_t>(camera)];
  const CameraModel k = m.Camera();
  const Vec2d centre(k.cx(), k.cy());
  auto residual = [&](const Vec2d& pt) -> std::optional<Vec2d> {
    const Rigid3d cam_from_world = ChainWorldFromCamera(c, camera, q, rail_mm, pt.x(), pt.y()).Inverse();
    const Vec3d p = cam_from_world * target_world;
    if (p.z() <= 1.0) return std::nullopt;
    const auto px = Project(k, p);
    if (!px) return std::nullopt;
    return Vec2d(*px - centre);
  };
  Vec2d pt(0.5 * (limits.pan_min_rad + limits.pan_max_rad), 0.5 * (limits.tilt_min_rad + limits.tilt_max_rad));
  // Start from the direction of the target in the pan frame, roughly: a coarse grid of 9 x 5 starts.
  double best = 1e18;
  for (int i = 0; i <= 8; ++i) {
    for (int j = 0; j <= 4; ++j) {
      const Vec2d s(limits.pan_min_rad + (limits.pan_max_rad - limits.pan_min_rad) * i / 8.0,
                    limits.tilt_min_rad + (limits.tilt_max_rad - limits.tilt_min_rad) * j / 4.0);
      const auto r = residual(s);
      if (r && r->norm() < best) {
        best = r->norm();
        pt = s;
      }
    }
  }
  if (best > 1e17) return NotFound("the target is behind the camera at every pan and tilt");
  for (int it = 0; it < 30; ++it) {
    const auto r = residual(pt);
    if (!r) return NotFound("the target went behind the camera while fixating");
    if (r->norm() < 0.05) break;
    Eigen::Matrix2d j;
    const double h = 1e-6;
    for (int a = 0; a < 2; ++a) {
      Vec2d d = pt;
      d[a] += h;
      const auto rd = residual(d);
      if (!rd) return NotFound("the target went behind the camera while fixating");
      j.col(a) = (*rd - *r) / h;
    }
    if (std::abs(j.determinant()) < 1e-9) return NotFound("pan and tilt do not move the target in the image");
    pt -= j.inverse() * *r;
  }
  const auto r = residual(pt);
  if (!r || r->norm() > 1.0) return NotFound("the pan-tilt unit cannot bring the target to the image centre");
  if (!limits.Contains(pt.x(), pt.y())) {
    return NotFound(fmt::format("fixating needs pan {:.1f} deg, tilt {:.1f} deg: outside the unit's range",
                                RadToDeg(pt.x()), RadToDeg(pt.y())));
  }
  return std::array<double, 2>{pt.x(), pt.y()};
}

Result<ScanReport> ScanAndPick(ScanDevices& d, const ScanCalibration& c, const ScanOptions& o) {
  IDI_RETURN_IF_ERROR(o.Check());
  if (d.arm1 == nullptr || d.rail1 == nullptr || d.ptu[0] == nullptr || d.ptu[1] == nullptr || d.camera[0] == nullptr ||
      d.camera[1] == nullptr) {
    return InvalidArgument("scan: arm 1, its rail, both pan-tilt units and both cameras are needed");
  }
  if (o.pick && (d.arm2 == nullptr || d.rail2 == nullptr || d.hand == nullptr)) {
    return InvalidArgument("scan: picking needs arm 2, its rail and the hand");
  }
  auto fail = [&](Status s, const std::string& step) -> Status {
    const Status stop = StopArms(d);
    if (!stop.ok()) spdlog::error("scan: stopping the arms after a failure: {}", stop.ToString());
    return s.WithContext("scan: " + step);
  };
  auto cancelled = [&]() -> Status {
    const Status stop = StopArms(d);
    if (stop.ok()) {
      spdlog::warn("scan: cancelled; both arms commanded to stop (the hand keeps what it holds)");
    } else {
      spdlog::error("scan: stopping the arms on cancel: {}", stop.ToString());
    }
    return Cancelled("scan: cancelled by the operator");
  };
  if (!o.out_dir.empty()) {
    std::error_code ec;
    fs::create_directories(o.out_dir, ec);
    if (ec) return IoError(o.out_dir + ": cannot create the output folder: " + ec.message());
  }

  ScanReport report;
  const double t0 = Seconds();
  // 1. Views: stations around the table, both cameras fixating it.
  std::array<hal::PanTiltLimits, 2> limits;
  for (int k = 0; k < 2; ++k) {
    auto l = d.ptu[static_cast<std::size_t>(k)]->Limits();
    if (!l.ok()) return fail(l.status(), "reading the pan-tilt limits");
    limits[static_cast<std::size_t>(k)] = *l;
    hal::CameraSettings cs;
    cs.width = c.cameras[static_cast<std::size_t>(k)].width;
    cs.height = c.cameras[static_cast<std::size_t>(k)].height;
    const Status st = d.camera[static_cast<std::size_t>(k)]->Start(cs);
    if (!st.ok()) return fail(st, "starting the cameras");
  }
  const Vec3d aim = o.table_centre_world + Vec3d(0, 0, o.aim_height_mm);
  const double el = DegToRad(o.elevation_deg);
  Joints q_prev = JointsFromDeg({0, -40, 110, 0, 20, 0});
  // Station s (numbered from 0 over both rounds) at the set azimuth: the head pose, both cameras fixating
  // the table, their images and projection matrices appended to report.views.
  auto take_station = [&](std::size_t s, std::size_t stations, double set_azimuth_deg, double progress) -> Status {
    if (IsCancelled(o)) return cancelled();
    Progress(o, progress, fmt::format("station {}/{} (azimuth {:.0f} deg)", s + 1, stations, set_azimuth_deg));
    // The station's head pose; a station the arm cannot reach is moved towards azimuth 0 in steps of
    // station_step_deg (up to station_retries times), since a narrower view beats no view.
    std::optional<std::pair<double, Joints>> pose;
    Status last = NotFound("no rail position tried");
    double az_deg = set_azimuth_deg;
    for (int retry = 0; !pose && retry <= o.station_retries; ++retry) {
      if (retry > 0) {
        const double inward = std::min(o.station_step_deg, std::abs(az_deg));
        if (inward <= 0) break;
        const double before = az_deg;
        az_deg -= std::copysign(inward, az_deg);
        spdlog::warn("scan: station {} cannot be reached at azimuth {:.0f} deg; trying {:.0f} deg", s + 1, before, az_deg);
      }
      const double az = DegToRad(az_deg);
      const Vec3d v(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), -std::sin(el));
      const Vec3d mid = aim - o.view_distance_mm * v;
      const Rigid3d world_from_tcf = WorldFromTcfForView(mid, v);
      // Robot 1's rail position: the base a little behind the head along the rail, else nearby positions.
      for (const double shift : {0.0, -250.0, 250.0, -500.0, 500.0, -750.0}) {
        const double rail = std::clamp(world_from_tcf.translation.x() - 250.0 + shift, 0.0, o.rail1_max_mm);
        const Rigid3d base_from_tcf = WorldFromBase(c.robot1, 0, c.psi, rail).Inverse() * world_from_tcf;
        Joints start = q_prev;
        start[0] = std::atan2(base_from_tcf.translation.y(), base_from_tcf.translation.x());
        // Fallback starts facing the view point: the usual elbow-up posture, wrist bent either way, and
        // steeper and flatter upper arms.
        std::vector<Joints> fallbacks;
        for (const auto& deg : {std::array<double, 6>{0, -40, 110, 0, 20, 0}, {0, -40, 110, 0, -20, 0}, {0, -70, 130, 0, 30, 0},
                                {0, -10, 80, 0, 30, 0}, {0, -40, 110, 90, 20, -90}, {0, -40, 110, -90, 20, 90}}) {
          Joints f = JointsFromDeg({deg[0], deg[1], deg[2], deg[3], deg[4], deg[5]});
          f[0] = start[0];
          fallbacks.push_back(f);
        }
        auto q = SolveArm(c.robot1.robot, start, base_from_tcf, fallbacks);
        if (q.ok()) {
          pose = std::make_pair(rail, *q);
          break;
        }
        last = q.status();
      }
    }
    if (!pose) return fail(last, fmt::format("station {}: no reachable head pose", s + 1));
    Status st = d.rail1->MoveTo(pose->first, o.move);
    if (st.ok()) st = d.arm1->MoveJoints(pose->second, o.move);
    if (!st.ok()) return fail(st, fmt::format("station {}: moving arm 1", s + 1));
    q_prev = pose->second;
    // What the encoders say now (the projection matrices use readings, not commands).
    auto js = d.arm1->ReadJoints();
    auto rs = d.rail1->Read();
    if (!js.ok()) return fail(js.status(), "reading arm 1's joints");
    if (!rs.ok()) return fail(rs.status(), "reading rail 1");
    for (int k = 0; k < 2; ++k) {
      const std::size_t ki = static_cast<std::size_t>(k);
      auto pt = FixatePtu(c, k, js->q_rad, rs->position_mm, aim, limits[ki]);
      if (!pt.ok()) return fail(pt.status(), fmt::format("station {}, {} camera", s + 1, k == 0 ? "left" : "right"));
      st = d.ptu[ki]->MoveTo((*pt)[0], (*pt)[1], kPtuTimeout);
      if (!st.ok()) return fail(st, "moving the pan-tilt unit");
      auto ps = d.ptu[ki]->Read();
      if (!ps.ok()) return fail(ps.status(), "reading the pan-tilt unit");
      auto image = d.camera[ki]->Grab(kGrabTimeout);
      if (!image.ok()) return fail(image.status(), "grabbing an image");
      ScanView sv;
      sv.station = static_cast<int>(s);
      sv.azimuth_deg = az_deg;
      sv.arm1_q = js->q_rad;
      sv.rail1_mm = rs->position_mm;
      sv.pan_rad = ps->pan_rad;
      sv.tilt_rad = ps->tilt_rad;
      sv.view.name = fmt::format("s{}_{}", s + 1, k == 0 ? "left" : "right");
      if (image->pixels.channels() == 3) {
        cv::cvtColor(image->pixels, sv.view.image, cv::COLOR_BGR2GRAY);
      } else {
        sv.view.image = image->pixels;
      }
      sv.view.camera = c.cameras[ki].Camera();
      sv.view.cam_from_world = ChainWorldFromCamera(c, k, js->q_rad, rs->position_mm, ps->pan_rad, ps->tilt_rad).Inverse();
      // Both cameras of a station share where the rail really stopped (within its repeatability).
      sv.view.mount = static_cast<int>(s);
      sv.view.mount_axis = (WorldFromBase(c.robot1, 0, c.psi, rs->position_mm + 1.0).translation -
                            WorldFromBase(c.robot1, 0, c.psi, rs->position_mm).translation)
                               .normalized();
      sv.view.roi = ObjectRegionMask(sv.view, o);
      if (!o.out_dir.empty()) {
        const fs::path file = fs::path(o.out_dir) / (sv.view.name + ".png");
        if (!cv::imwrite(file.string(), sv.view.image)) return IoError(file.string() + ": cannot write the image");
        const fs::path roi_file = fs::path(o.out_dir) / (sv.view.name + "_roi.png");
        if (!sv.view.roi.empty() && !cv::imwrite(roi_file.string(), sv.view.roi)) {
          return IoError(roi_file.string() + ": cannot write the object region");
        }
      }
      report.views.push_back(std::move(sv));
    }
    return Status::Ok();
  };
  for (std::size_t s = 0; s < o.azimuths_deg.size(); ++s) {
    const Status st = take_station(s,
                                   o.azimuths_deg.size(),
                                   o.azimuths_deg[s],
                                   0.05 + 0.4 * static_cast<double>(s) / static_cast<double>(o.azimuths_deg.size()));
    if (!st.ok()) return st;
  }
  report.acquisition_s = Seconds() - t0;

  // 2. Structure, and 3. the grasps (§8.11) in the world, best first. When no grasp fits the model of
  // the first round's views, the object's faces a grasp needs were not all seen: a second round of
  // stations (extra_azimuths_deg) is taken and the model rebuilt from all views.
  bool no_grasp_fits = false;
  auto model_and_grasps = [&]() -> Result<std::vector<GraspPlan>> {
    const double t1 = Seconds();
    if (IsCancelled(o)) return cancelled();
    Progress(o, report.second_round ? 0.65 : 0.5, fmt::format("reconstructing from {} views", report.views.size()));
    report.object_points.clear();
    report.cylinder = false;
    std::vector<StructureView> views;
    for (const ScanView& v : report.views) views.push_back(v.view);
    StructureOptions structure_options = o.structure;
    if (o.points_on_table && !structure_options.support) {
      optim::BaPlane table;
      table.normal = Vec3d::UnitZ();
      table.offset = o.table_centre_world.z();
      table.offset_prior_mm = o.table_height_prior_mm;
      table.sigma_mm = o.table_flatness_mm;
      structure_options.support = table;
    }
    auto structure = ReconstructStructure(views, structure_options);
    if (!structure.ok()) return fail(structure.status(), "reconstruction");
    report.structure = std::move(*structure);
    const StructureModel& model = report.structure.model;
    std::vector<Vec3d> object;
    for (std::size_t i = 0; i < model.points.size(); ++i) {
      const Vec3d& p = model.points[i].xyz;
      const Vec3d rel = p - o.table_centre_world;
      if (rel.head<2>().norm() < o.object_region_radius_mm && rel.z() > -o.table_tolerance_mm &&
          rel.z() < o.object_region_height_mm) {
        report.object_points.push_back(static_cast<int>(i));
        object.push_back(p);
      }
    }
    {
      const std::size_t before = report.object_points.size();
      report.object_points = DropStrayPoints(model, report.object_points, o);
      if (report.object_points.size() < before) {
        spdlog::info(
            "scan: {} stray point(s) in the object region dropped (joined to no other point, away from the object)",
            before - report.object_points.size());
        object.clear();
        for (const int i : report.object_points) object.push_back(model.points[static_cast<std::size_t>(i)].xyz);
      }
    }
    const Correspondences& cc = report.structure.correspondences;
    spdlog::info(
        "scan: {} points, {} edges, {} on the object; reprojection RMS {:.3f} -> {:.3f} px; {} view pairs, "
        "{} tracks split, {} observations rejected, {} more after the adjustment",
        model.points.size(),
        model.edges.size(),
        object.size(),
        report.structure.adjustment.initial_rms_px,
        report.structure.adjustment.final_rms_px,
        cc.pairs_matched,
        cc.conflicts_split,
        cc.observations_rejected,
        report.structure.adjusted_observations_dropped);
    if (!report.structure.on_support.empty() && !report.structure.adjustment.plane_offset.empty()) {
      spdlog::info(
          "scan: {} point(s) held on the table top; its height as the adjustment found it: {:+.3f} mm from the setup's",
          report.structure.on_support.size(),
          report.structure.adjustment.plane_offset.front() - o.table_centre_world.z());
    }
    if (!report.structure.adjustment.mount_shift_mm.empty()) {
      spdlog::info("scan: the stations' rail stops, as the adjustment found them: {:.3f} mm from their readings",
                   fmt::join(report.structure.adjustment.mount_shift_mm, ", "));
    }
    if (!o.out_dir.empty()) {
      IDI_RETURN_IF_ERROR(WriteFileAtomically((fs::path(o.out_dir) / "model.ply").string(), ModelToPly(model)));
      for (std::size_t v = 0; v < views.size(); ++v) {
        const fs::path file = fs::path(o.out_dir) / (views[v].name + "_model.png");
        if (!cv::imwrite(file.string(), DrawModelOverlay(views[v], model, &report.structure.features[v]))) {
          return IoError(file.string() + ": cannot write the overlay");
        }
      }
    }
    // No corners on the object: a cylinder, from its silhouettes. Its model for the grasp is the top and
    // bottom rims (48 points each).
    if (object.size() < 3) {
      if (const auto cyl = FitCylinder(views, report.structure.features, o)) {
        spdlog::info(
            "scan: no corners; a cylinder from {} silhouette planes: axis ({:.1f}, {:.1f}), radius {:.1f} mm, top "
            "{:.1f} mm",
            cyl->planes,
            cyl->axis.x(),
            cyl->axis.y(),
            cyl->radius,
            cyl->top_z);
        report.cylinder = true;
        report.cylinder_axis_xy = cyl->axis;
        report.cylinder_radius_mm = cyl->radius;
        report.cylinder_top_z = cyl->top_z;
        object.clear();
        for (const double z : {o.table_centre_world.z(), cyl->top_z}) {
          for (int k = 0; k < 48; ++k) {
            const double a = 2 * kPi * k / 48.0;
            object.emplace_back(
                cyl->axis.x() + cyl->radius * std::cos(a), cyl->axis.y() + cyl->radius * std::sin(a), z);
          }
        }
      }
    }
    report.reconstruction_s += Seconds() - t1;
    if (object.size() < 3) {
      return fail(NotFound(fmt::format("only {} reconstructed points on the table: no object found", object.size())),
                  "finding the object");
    }
    // The object's edges, renumbered into `object` (the planner's cross-sections come from them).
    std::vector<int> index_in_object(model.points.size(), -1);
    for (std::size_t k = 0; k < report.object_points.size(); ++k) {
      index_in_object[static_cast<std::size_t>(report.object_points[k])] = static_cast<int>(k);
    }
    std::vector<std::pair<int, int>> object_edges;
    for (const auto& [a, b] : model.edges) {
      const int ia = index_in_object[static_cast<std::size_t>(a)], ib = index_in_object[static_cast<std::size_t>(b)];
      if (ia >= 0 && ib >= 0) object_edges.emplace_back(ia, ib);
    }
    if (report.cylinder) object_edges.clear();
    auto plans = PlanTopGrasps(object, o.table_centre_world.z(), o.grasp, object_edges, o.grasp_alternatives);
    no_grasp_fits = !plans.ok() && plans.status().code() == StatusCode::kNotFound;
    return plans;
  };
  auto plans = model_and_grasps();
  // More views help a polyhedron that lacks faces, not a cylinder (its model is two fitted rims).
  if (no_grasp_fits && !report.cylinder && !o.extra_azimuths_deg.empty()) {
    spdlog::warn("scan: {}; taking {} more station(s) for the faces the model lacks",
                 plans.status().message(),
                 o.extra_azimuths_deg.size());
    const double t_more = Seconds();
    for (std::size_t k = 0; k < o.extra_azimuths_deg.size(); ++k) {
      const Status st =
          take_station(o.azimuths_deg.size() + k,
                       o.azimuths_deg.size() + o.extra_azimuths_deg.size(),
                       o.extra_azimuths_deg[k],
                       0.5 + 0.1 * static_cast<double>(k) / static_cast<double>(o.extra_azimuths_deg.size()));
      if (!st.ok()) return st;
    }
    report.acquisition_s += Seconds() - t_more;
    report.second_round = true;
    plans = model_and_grasps();
  }
  if (!plans.ok()) {
    if (!no_grasp_fits) return plans.status();  // already named by its step
    if (!o.pick) {
      // A scan without a pick asked for the model, which is there: that no grasp fits it is part of
      // the report, not a failure of the scan.
      spdlog::warn("scan: {}; the model is reported without a grasp", plans.status().message());
      report.no_grasp_reason = std::string(plans.status().message());
      return report;
    }
    return fail(plans.status(),
                report.second_round ? "with the second round's views too" : "with the first round's views");
  }
  // 4. The pick: the grasp in robot 2's base (eq. 3.4).
  report.grasp_found = true;
  report.grasp = plans->front();
  if (!o.pick) return report;
  // The model and its grasps go to disk before the arms move: a pick that fails (nothing in reach, a
  // hand or arm fault) returns only its status, and the scan is not lost with it.
  if (!o.out_dir.empty()) {
    const std::string file = (fs::path(o.out_dir) / "scan_before_pick.json").string();
    if (const Status w = WriteFileAtomically(file, ScanReportJson(report).dump(2) + "\n"); !w.ok()) {
      spdlog::warn("scan: {}", w.ToString());
    }
  }

  const double t2 = Seconds();
  if (IsCancelled(o)) return cancelled();
  Progress(o, 0.7, "picking");
  PickReport& pick = report.pick;
  pick.attempted = true;
  const Rigid3d place = Translation(o.place_offset_world);
  const std::vector<Joints> fallbacks = {JointsFromDeg({180, -40, 120, 0, 10, 0}), JointsFromDeg({150, -30, 110, 0, 20, 0}),
                                         JointsFromDeg({-150, -30, 110, 0, 20, 0})};
  std::vector<Joints> qs;
  Status last = NotFound("no rail position tried");
  // The best grasp robot 2 can reach (approach, grasp, lift, carry, put down, retreat) from some rail
  // position: a grasp planned from the model alone may need a pose out of the arm's reach.
  for (std::size_t g = 0; g < plans->size() && qs.empty(); ++g) {
    const GraspPlan& plan = (*plans)[g];
    // The palm above the contacts: the thumb's pad meets its face at the plan's half width.
    double reading = 0, depth = 0;
    if (!BarrettTipOnFace(c.hand, 2, plan.spread_rad, 0.5 * plan.width_mm, &reading, &depth)) {
      last = NotFound(fmt::format("the hand cannot close on {:.1f} mm", plan.width_mm));
      continue;
    }
    const Rigid3d palm_from_grasp_at = Translation(0.0, 0.0, depth);  // grasp z points down, out of the palm
    const Rigid3d world_from_palm_grasp = plan.world_from_grasp * palm_from_grasp_at.Inverse();
    const Rigid3d world_from_palm_approach = plan.world_from_approach * palm_from_grasp_at.Inverse();
    const Rigid3d world_from_palm_lift = plan.world_from_lift * palm_from_grasp_at.Inverse();
    const std::vector<Rigid3d> palms = {world_from_palm_approach,
                                        world_from_palm_grasp,
                                        world_from_palm_lift,
                                        place * world_from_palm_lift,
                                        place * world_from_palm_grasp * Translation(0.0, 0.0, -2.0),
                                        place * world_from_palm_approach};
    for (const double rail2 : o.rail2_candidates_mm) {
      if (rail2 < 0 || rail2 > o.rail2_max_mm) continue;
      const Rigid3d base_from_world = WorldFromBase(c.robot2, 1, c.psi, rail2).Inverse();
      std::vector<Joints> sol;
      Joints start = fallbacks[0];
      for (const Rigid3d& palm : palms) {
        auto q = SolveArm(
            c.robot2.robot, start, BaseFromFlangeForPalm(base_from_world, palm, c.flange_from_palm), fallbacks);
        if (!q.ok()) {
          last = q.status();
          break;
        }
        sol.push_back(*q);
        start = *q;
      }
      if (sol.size() == palms.size()) {
        qs = std::move(sol);
        pick.rail2_mm = rail2;
        pick.grasp_rank = static_cast<int>(g);
        report.grasp = plan;
        report.base2_from_grasp = base_from_world * plan.world_from_grasp;
        if (g > 0) {
          spdlog::info("scan: robot 2 reaches grasp {} of {} (quality {:.3f}; the best, {:.3f}, is out of its reach)",
                       g + 1,
                       plans->size(),
                       plan.quality,
                       plans->front().quality);
        }
        break;
      }
    }
  }
  if (qs.empty()) {
    return fail(last, fmt::format("no rail position of robot 2 reaches any of the {} grasps planned", plans->size()));
  }
  auto step = [&](const Status& st, const std::string& what) -> Status {
    if (st.ok()) return st;
    return fail(st, what);
  };
  auto hs = d.hand->Read();
  if (!hs.ok()) return fail(hs.status(), "reading the hand");
  if (!hs->initialized) IDI_RETURN_IF_ERROR(step(d.hand->Initialize(), "initialising the hand"));
  IDI_RETURN_IF_ERROR(step(d.hand->Open(), "opening the hand"));
  IDI_RETURN_IF_ERROR(step(d.hand->SetSpread(report.grasp.spread_rad), "spreading the fingers"));
  IDI_RETURN_IF_ERROR(step(d.rail2->MoveTo(pick.rail2_mm, o.move), "moving rail 2"));
  IDI_RETURN_IF_ERROR(step(d.arm2->MoveJoints(qs[0], o.move), "approach"));
  if (IsCancelled(o)) return cancelled();
  Progress(o, 0.75, "descending to the grasp");
  IDI_RETURN_IF_ERROR(step(d.arm2->MoveJoints(qs[1], o.move), "descending to the grasp"));
  if (IsCancelled(o)) return cancelled();
  IDI_RETURN_IF_ERROR(step(d.hand->Close(), "closing the hand"));
  const double closed = DegToRad(c.hand.closed_deg);
  auto stalled = [&](const hal::GripperState& g) {
    int n = 0;
    for (double f : g.finger_rad) n += f < closed - DegToRad(5.0) ? 1 : 0;
    return n;
  };
  hs = d.hand->Read();
  if (!hs.ok()) return fail(hs.status(), "reading the hand");
  pick.finger_rad = hs->finger_rad;
  pick.grasped = stalled(*hs) >= 2;
  if (!pick.grasped) {
    pick.outcome = "missed: the fingers closed without meeting the object";
    IDI_RETURN_IF_ERROR(step(d.hand->Open(), "opening the hand"));
    IDI_RETURN_IF_ERROR(step(d.arm2->MoveJoints(qs[0], o.move), "retreating"));
    report.pick_s = Seconds() - t2;
    return report;
  }
  if (IsCancelled(o)) return cancelled();
  Progress(o, 0.8, "lifting");
  IDI_RETURN_IF_ERROR(step(d.arm2->MoveJoints(qs[2], o.move), "lifting"));
  hs = d.hand->Read();
  if (!hs.ok()) return fail(hs.status(), "reading the hand");
  pick.lifted = stalled(*hs) >= 2;
  if (IsCancelled(o)) return cancelled();
  Progress(o, 0.85, "placing");
  IDI_RETURN_IF_ERROR(step(d.arm2->MoveJoints(qs[3], o.move), "carrying to the place position"));
  if (IsCancelled(o)) return cancelled();
  IDI_RETURN_IF_ERROR(step(d.arm2->MoveJoints(qs[4], o.move), "putting down"));
  IDI_RETURN_IF_ERROR(step(d.hand->Open(), "opening the hand"));
  IDI_RETURN_IF_ERROR(step(d.arm2->MoveJoints(qs[5], o.move), "retreating"));
  pick.placed = true;
  pick.outcome = pick.lifted ? "picked and placed" : "grasped, but the fingers lost it while lifting";
  report.pick_s = Seconds() - t2;
  Progress(o, 1.0, pick.outcome);
  return report;
}

nlohmann::json ScanReportJson(const ScanReport& r) {
  nlohmann::json j = StructureModelJson(r.structure.model);
  std::vector<bool> on_object(r.structure.model.points.size(), false);
  for (int i : r.object_points) on_object[static_cast<std::size_t>(i)] = true;
  for (std::size_t i = 0; i < on_object.size(); ++i) j["points"][i]["object"] = static_cast<bool>(on_object[i]);
  for (const int i : r.structure.on_support) j["points"][static_cast<std::size_t>(i)]["on_table"] = true;
  if (!r.structure.adjustment.plane_offset.empty()) {
    j["table_top_z_mm"] = r.structure.adjustment.plane_offset.front();  // the adjustment's estimate
  }
  j["second_round"] = r.second_round;
  j["views"] = nlohmann::json::array();
  for (const ScanView& v : r.views) {
    j["views"].push_back({{"name", v.view.name}, {"station", v.station}, {"azimuth_deg", v.azimuth_deg}, {"rail1_mm", v.rail1_mm},
                          {"pan_deg", RadToDeg(v.pan_rad)}, {"tilt_deg", RadToDeg(v.tilt_rad)}});
  }
  if (r.cylinder) {
    j["cylinder"] = {{"axis_xy_mm", {r.cylinder_axis_xy.x(), r.cylinder_axis_xy.y()}},
                     {"radius_mm", r.cylinder_radius_mm},
                     {"top_z_mm", r.cylinder_top_z}};
  }
  j["reprojection_rms_px"] = {{"before", r.structure.adjustment.initial_rms_px}, {"after", r.structure.adjustment.final_rms_px}};
  j["rail_stop_shift_mm"] = r.structure.adjustment.mount_shift_mm;  // per station, the adjustment's estimate
  if (r.grasp_found) {
    const Vec3d g = r.grasp.world_from_grasp.translation;
    j["grasp"] = {{"centre_mm", {g.x(), g.y(), g.z()}},
                  {"width_mm", r.grasp.width_mm},
                  {"spread_deg", RadToDeg(r.grasp.spread_rad)},
                  {"friction_margin_deg", RadToDeg(r.grasp.friction_margin_rad)},
                  {"quality", r.grasp.quality}};
  } else {
    j["grasp"] = nullptr;
    j["no_grasp_reason"] = r.no_grasp_reason;
  }
  j["pick"] = {
      {"attempted", r.pick.attempted},
      {"grasped", r.pick.grasped},
      {"lifted", r.pick.lifted},
      {"placed", r.pick.placed},
      {"rail2_mm", r.pick.rail2_mm},
      {"grasp_rank", r.pick.grasp_rank},
      {"outcome", r.pick.outcome},
      {"finger_deg", {RadToDeg(r.pick.finger_rad[0]), RadToDeg(r.pick.finger_rad[1]), RadToDeg(r.pick.finger_rad[2])}}};
  j["seconds"] = {{"acquisition", r.acquisition_s}, {"reconstruction", r.reconstruction_s}, {"pick", r.pick_s}};
  j["timing_ms"] = {{"features", r.structure.features_ms}, {"correspondence", r.structure.correspondence_ms},
                    {"adjustment", r.structure.adjustment_ms}, {"total", r.structure.total_ms}};
  return j;
}

}  // namespace idi::workcell
