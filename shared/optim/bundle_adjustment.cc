#include "shared/optim/bundle_adjustment.h"

#include <ceres/autodiff_cost_function.h>
#include <ceres/rotation.h>

#include <cmath>
#include <map>

#include "shared/optim/least_squares.h"
#include "shared/util/units.h"

namespace idi::optim {
namespace {

// Wraps a Ceres autodiff cost as the Ceres-free ResidualFunction of least_squares.h.
class CeresResidual final : public ResidualFunction {
 public:
  CeresResidual(std::unique_ptr<ceres::CostFunction> cost)
      : ResidualFunction(cost->num_residuals(), std::vector<int>(cost->parameter_block_sizes().begin(),
                                                                  cost->parameter_block_sizes().end())),
        cost_(std::move(cost)) {}
  bool Evaluate(const double* const* parameters, double* residuals, double** jacobians) const override {
    return cost_->Evaluate(parameters, residuals, jacobians);
  }

 private:
  std::unique_ptr<ceres::CostFunction> cost_;
};

// Pose block: angle-axis (3) and translation (3) of cam_from_world. Intrinsics block: the 9 of pinhole.h.
template <typename T>
Vec3<T> ToCamera(const T* pose, const T* x) {
  T p[3];
  ceres::AngleAxisRotatePoint(pose, x, p);
  return Vec3<T>(p[0] + pose[3], p[1] + pose[4], p[2] + pose[5]);
}

// The point as its view's mount sees it: a mount shifted by s along its axis sees x at x - s * axis.
template <typename T>
Vec3<T> ToCamera(const T* pose, const T* x, const T* shift, const Vec3d& axis) {
  const T xs[3] = {x[0] - shift[0] * T(axis.x()), x[1] - shift[0] * T(axis.y()), x[2] - shift[0] * T(axis.z())};
  return ToCamera(pose, xs);
}

struct PointReprojection {
  Vec2d pixel;
  double inv_sigma;
  Vec3d axis;
  template <typename T>
  bool operator()(const T* point, const T* pose, const T* intrinsics, const T* shift, T* r) const {
    const Vec3<T> pc = ToCamera(pose, point, shift, axis);
    if (!(pc.z() > T(1e-9))) return false;
    const Vec2<T> px = ProjectToPixel(intrinsics, pc);
    r[0] = (px.x() - T(pixel.x())) * T(inv_sigma);
    r[1] = (px.y() - T(pixel.y())) * T(inv_sigma);
    return true;
  }
};

struct PointOnLine {
  Line2d line;
  double inv_sigma;
  Vec3d axis;
  template <typename T>
  bool operator()(const T* point, const T* pose, const T* intrinsics, const T* shift, T* r) const {
    const Vec3<T> pc = ToCamera(pose, point, shift, axis);
    if (!(pc.z() > T(1e-9))) return false;
    const T u = intrinsics[kFx] * pc.x() / pc.z() + intrinsics[kCx];
    const T v = intrinsics[kFy] * pc.y() / pc.z() + intrinsics[kCy];
    r[0] = (T(line.normal.x()) * u + T(line.normal.y()) * v - T(line.offset)) * T(inv_sigma);
    return true;
  }
};

// A point on a plane of known normal and estimated offset: r = (n . x - offset) / sigma.
struct PointOnPlane {
  Vec3d normal;
  double inv_sigma;
  template <typename T>
  bool operator()(const T* point, const T* offset, T* r) const {
    r[0] = (T(normal.x()) * point[0] + T(normal.y()) * point[1] + T(normal.z()) * point[2] - offset[0]) * T(inv_sigma);
    return true;
  }
};

// A Gaussian prior keeping a block near its start: r = (x - x0) / sigma, per component.
struct BlockPrior {
  std::vector<double> x0, inv_sigma;
  template <typename T>
  bool operator()(const T* x, T* r) const {
    for (std::size_t k = 0; k < x0.size(); ++k) r[k] = (x[k] - T(x0[k])) * T(inv_sigma[k]);
    return true;
  }
};

std::array<double, 6> PoseBlock(const Rigid3d& t) {
  std::array<double, 6> b{};
  const Eigen::Matrix<double, 3, 3, Eigen::ColMajor> r = t.rotation;
  ceres::RotationMatrixToAngleAxis(ceres::ColumnMajorAdapter3x3(r.data()), b.data());
  b[3] = t.translation.x();
  b[4] = t.translation.y();
  b[5] = t.translation.z();
  return b;
}

Rigid3d PoseFromBlock(const std::array<double, 6>& b) {
  Eigen::Matrix<double, 3, 3, Eigen::ColMajor> r;
  ceres::AngleAxisToRotationMatrix(b.data(), ceres::ColumnMajorAdapter3x3(r.data()));
  Rigid3d t;
  t.rotation = r;
  t.translation = Vec3d(b[3], b[4], b[5]);
  return t;
}

double ReprojectionError(const Vec3d& x, const BaView& v, const Vec2d& pixel) {
  const auto px = Project(v.camera, v.cam_from_world * x);
  return px ? (*px - pixel).norm() : std::numeric_limits<double>::infinity();
}

}  // namespace

Status BundleAdjustmentOptions::Check() const {
  if (!(pose_prior_mm > 0) || !(pose_prior_deg > 0) || !(huber_sigmas > 0) || max_iterations <= 0) {
    return InvalidArgument("bundle adjustment: priors, robust scale and iterations must be positive");
  }
  if (!(mount_prior_mm >= 0 && std::isfinite(mount_prior_mm))) {
    return InvalidArgument("bundle adjustment: mount_prior_mm must be >= 0 (0: mounts as given)");
  }
  return Status::Ok();
}

Result<BundleAdjustmentSummary> BundleAdjust(std::vector<Vec3d>* points,
                                             std::vector<BaView>* views,
                                             const std::vector<BaPointObservation>& obs,
                                             const std::vector<BaLineObservation>& line_obs,
                                             const BundleAdjustmentOptions& options,
                                             const std::vector<BaPlane>& planes) {
  IDI_RETURN_IF_ERROR(options.Check());
  const int np = static_cast<int>(points->size()), nv = static_cast<int>(views->size());
  for (const Vec3d& p : *points) {
    if (!p.allFinite()) return InvalidArgument("bundle adjustment: a 3D point is not finite");
  }
  auto check_index = [&](int point, int view, const char* what, std::size_t k) -> Status {
    if (point < 0 || point >= np || view < 0 || view >= nv) {
      return InvalidArgument(std::string("bundle adjustment: ") + what + " " + std::to_string(k) +
                             " refers to point " + std::to_string(point) + " / view " + std::to_string(view) +
                             " (have " + std::to_string(np) + " points, " + std::to_string(nv) + " views)");
    }
    return Status::Ok();
  };
  for (std::size_t k = 0; k < obs.size(); ++k) {
    IDI_RETURN_IF_ERROR(check_index(obs[k].point, obs[k].view, "observation", k));
    if (!obs[k].pixel.allFinite() || !(obs[k].sigma_px > 0)) {
      return InvalidArgument("bundle adjustment: observation " + std::to_string(k) + " has a bad pixel or sigma");
    }
    const Vec3d pc = (*views)[static_cast<std::size_t>(obs[k].view)].cam_from_world * (*points)[static_cast<std::size_t>(obs[k].point)];
    if (!(pc.z() > 0)) {
      return InvalidArgument("bundle adjustment: point " + std::to_string(obs[k].point) + " is behind view " +
                             std::to_string(obs[k].view) + " that observes it");
    }
  }
  for (std::size_t k = 0; k < line_obs.size(); ++k) {
    IDI_RETURN_IF_ERROR(check_index(line_obs[k].point, line_obs[k].view, "line observation", k));
    if (!(line_obs[k].sigma_px > 0)) return InvalidArgument("bundle adjustment: line observation with sigma <= 0");
  }

  for (std::size_t k = 0; k < planes.size(); ++k) {
    const BaPlane& pl = planes[k];
    if (!pl.normal.allFinite() || std::abs(pl.normal.norm() - 1.0) > 1e-6 || !std::isfinite(pl.offset) ||
        !(pl.sigma_mm > 0) || !(pl.offset_prior_mm >= 0 && std::isfinite(pl.offset_prior_mm))) {
      return InvalidArgument("bundle adjustment: plane " + std::to_string(k) +
                             " needs a unit normal, a finite offset, sigma_mm > 0 and offset_prior_mm >= 0");
    }
    for (const int i : pl.points) {
      if (i < 0 || i >= np) {
        return InvalidArgument("bundle adjustment: plane " + std::to_string(k) + " refers to point " +
                               std::to_string(i) + " (have " + std::to_string(np) + " points)");
      }
    }
  }

  std::vector<std::array<double, 6>> poses(static_cast<std::size_t>(nv));
  std::map<int, std::array<double, kCameraParamCount>> intrinsics;
  for (int v = 0; v < nv; ++v) {
    const BaView& bv = (*views)[static_cast<std::size_t>(v)];
    poses[static_cast<std::size_t>(v)] = PoseBlock(bv.cam_from_world);
    const auto [it, first] = intrinsics.emplace(bv.intrinsics_group, bv.camera.params);
    // A group is one physical camera: its views project with one set of intrinsics, so they must
    // come with the same ones (before, every view was projected with its group's first view's).
    if (!first && it->second != bv.camera.params) {
      return InvalidArgument("bundle adjustment: view " + std::to_string(v) + " is in intrinsics group " +
                             std::to_string(bv.intrinsics_group) +
                             " but its camera parameters differ from the group's first view's; give each camera "
                             "its own group");
    }
  }
  // One shift per mount index (estimated with mount_prior_mm > 0), and a held zero for views without one.
  const bool mounts = options.mount_prior_mm > 0;
  std::vector<Vec3d> mount_axis;  // per mount index; zero for an index no view uses
  for (int v = 0; v < nv; ++v) {
    const BaView& bv = (*views)[static_cast<std::size_t>(v)];
    if (!mounts || bv.mount < 0) continue;
    if (bv.mount > 1000 || !bv.mount_axis.allFinite() || std::abs(bv.mount_axis.norm() - 1.0) > 1e-6) {
      return InvalidArgument("bundle adjustment: view " + std::to_string(v) + " has mount " + std::to_string(bv.mount) +
                             " with an axis that is not a unit vector (or a mount index over 1000)");
    }
    if (static_cast<std::size_t>(bv.mount) >= mount_axis.size()) {
      mount_axis.resize(static_cast<std::size_t>(bv.mount) + 1, Vec3d::Zero());
    }
    Vec3d& axis = mount_axis[static_cast<std::size_t>(bv.mount)];
    if (axis.isZero()) {
      axis = bv.mount_axis;
    } else if ((axis - bv.mount_axis).norm() > 1e-6) {
      return InvalidArgument("bundle adjustment: the views of mount " + std::to_string(bv.mount) +
                             " give it different axes");
    }
  }
  const int n_mounts = static_cast<int>(mount_axis.size());
  std::vector<double> shift(mount_axis.size() + 1, 0.0);  // the last one: no mount, held
  auto shift_of = [&](const BaView& bv) -> double* {
    return mounts && bv.mount >= 0 ? &shift[static_cast<std::size_t>(bv.mount)] : &shift.back();
  };
  auto axis_of = [&](const BaView& bv) -> Vec3d {
    return mounts && bv.mount >= 0 ? mount_axis[static_cast<std::size_t>(bv.mount)] : Vec3d::Zero();
  };
  Problem problem;
  std::vector<std::array<double, 3>> xyz(static_cast<std::size_t>(np));
  for (int i = 0; i < np; ++i) {
    const Vec3d& p = (*points)[static_cast<std::size_t>(i)];
    xyz[static_cast<std::size_t>(i)] = {p.x(), p.y(), p.z()};
    problem.AddParameterBlock(xyz[static_cast<std::size_t>(i)].data(), 3);
  }
  for (auto& pose : poses) {
    problem.AddParameterBlock(pose.data(), 6);
    problem.SetConstant(pose.data(), !options.refine_poses);
  }
  for (auto& [group, k] : intrinsics) {
    problem.AddParameterBlock(k.data(), kCameraParamCount);
    problem.SetConstant(k.data(), !options.refine_intrinsics);
  }
  for (std::size_t m = 0; m < shift.size(); ++m) {
    problem.AddParameterBlock(&shift[m], 1);
    problem.SetConstant(&shift[m], m + 1 == shift.size() || mount_axis[m].isZero());
  }
  const Loss loss{LossKind::kHuber, options.huber_sigmas};
  double initial_sq = 0;
  for (const BaPointObservation& o : obs) {
    const BaView& v = (*views)[static_cast<std::size_t>(o.view)];
    const double e = ReprojectionError((*points)[static_cast<std::size_t>(o.point)], v, o.pixel);
    initial_sq += e * e;
    auto cost = std::make_unique<ceres::AutoDiffCostFunction<PointReprojection, 2, 3, 6, kCameraParamCount, 1>>(
        new PointReprojection{o.pixel, 1.0 / o.sigma_px, axis_of(v)});
    problem.AddResidual(std::make_shared<CeresResidual>(std::move(cost)),
                        {xyz[static_cast<std::size_t>(o.point)].data(),
                         poses[static_cast<std::size_t>(o.view)].data(),
                         intrinsics[v.intrinsics_group].data(),
                         shift_of(v)},
                        loss);
  }
  for (const BaLineObservation& o : line_obs) {
    const BaView& v = (*views)[static_cast<std::size_t>(o.view)];
    auto cost = std::make_unique<ceres::AutoDiffCostFunction<PointOnLine, 1, 3, 6, kCameraParamCount, 1>>(
        new PointOnLine{o.line, 1.0 / o.sigma_px, axis_of(v)});
    problem.AddResidual(std::make_shared<CeresResidual>(std::move(cost)),
                        {xyz[static_cast<std::size_t>(o.point)].data(),
                         poses[static_cast<std::size_t>(o.view)].data(),
                         intrinsics[v.intrinsics_group].data(),
                         shift_of(v)},
                        loss);
  }
  if (options.refine_poses) {
    const double rs = 1.0 / DegToRad(options.pose_prior_deg), ts = 1.0 / options.pose_prior_mm;
    for (auto& pose : poses) {
      auto cost = std::make_unique<ceres::AutoDiffCostFunction<BlockPrior, 6, 6>>(
          new BlockPrior{{pose.begin(), pose.end()}, {rs, rs, rs, ts, ts, ts}});
      problem.AddResidual(std::make_shared<CeresResidual>(std::move(cost)), {pose.data()});
    }
  }
  if (mounts) {
    for (int m = 0; m < n_mounts; ++m) {
      if (mount_axis[static_cast<std::size_t>(m)].isZero()) continue;  // no view has this index
      auto cost = std::make_unique<ceres::AutoDiffCostFunction<BlockPrior, 1, 1>>(
          new BlockPrior{{0.0}, {1.0 / options.mount_prior_mm}});
      problem.AddResidual(std::make_shared<CeresResidual>(std::move(cost)), {&shift[static_cast<std::size_t>(m)]});
    }
  }
  std::vector<double> plane_offset;
  for (const BaPlane& pl : planes) plane_offset.push_back(pl.offset);
  for (std::size_t k = 0; k < planes.size(); ++k) {
    const BaPlane& pl = planes[k];
    problem.AddParameterBlock(&plane_offset[k], 1);
    problem.SetConstant(&plane_offset[k], !(pl.offset_prior_mm > 0));
    if (pl.offset_prior_mm > 0) {
      auto cost = std::make_unique<ceres::AutoDiffCostFunction<BlockPrior, 1, 1>>(
          new BlockPrior{{pl.offset}, {1.0 / pl.offset_prior_mm}});
      problem.AddResidual(std::make_shared<CeresResidual>(std::move(cost)), {&plane_offset[k]});
    }
    for (const int i : pl.points) {
      auto cost = std::make_unique<ceres::AutoDiffCostFunction<PointOnPlane, 1, 3, 1>>(
          new PointOnPlane{pl.normal, 1.0 / pl.sigma_mm});
      problem.AddResidual(std::make_shared<CeresResidual>(std::move(cost)),
                          {xyz[static_cast<std::size_t>(i)].data(), &plane_offset[k]});
    }
  }
  if (options.refine_intrinsics) {
    for (auto& [group, k] : intrinsics) {
      std::vector<double> inv(kCameraParamCount, 1e6);  // p1, p2, k3 held
      inv[kFx] = 1.0 / (0.01 * k[kFx]);
      inv[kFy] = 1.0 / (0.01 * k[kFy]);
      inv[kCx] = inv[kCy] = 0.5;
      inv[kK1] = inv[kK2] = 20.0;
      auto cost = std::make_unique<ceres::AutoDiffCostFunction<BlockPrior, kCameraParamCount, kCameraParamCount>>(
          new BlockPrior{{k.begin(), k.end()}, inv});
      problem.AddResidual(std::make_shared<CeresResidual>(std::move(cost)), {k.data()});
    }
  }
  BundleAdjustmentSummary summary;
  summary.initial_rms_px = obs.empty() ? 0 : std::sqrt(initial_sq / static_cast<double>(obs.size()));
  if (problem.num_residuals() == 0) {
    summary.message = "nothing to adjust";
    summary.converged = true;
    return summary;
  }
  SolverOptions so;
  so.max_iterations = options.max_iterations;
  IDI_ASSIGN_OR_RETURN(const SolverSummary s, SolveLevenbergMarquardt(problem, so));
  for (int i = 0; i < np; ++i) {
    const auto& b = xyz[static_cast<std::size_t>(i)];
    (*points)[static_cast<std::size_t>(i)] = Vec3d(b[0], b[1], b[2]);
  }
  for (int v = 0; v < nv; ++v) {
    BaView& bv = (*views)[static_cast<std::size_t>(v)];
    bv.cam_from_world = PoseFromBlock(poses[static_cast<std::size_t>(v)]);
    // The mount's shift s moves the camera by s * axis: x_cam = R (x - s axis) + t.
    const double s_mm = *shift_of(bv);
    bv.cam_from_world.translation -= bv.cam_from_world.rotation * (s_mm * axis_of(bv));
    if (options.refine_intrinsics) bv.camera.params = intrinsics[bv.intrinsics_group];
  }
  if (mounts) summary.mount_shift_mm.assign(shift.begin(), shift.end() - 1);
  summary.plane_offset = plane_offset;
  std::vector<double> sum2(static_cast<std::size_t>(np), 0.0);
  std::vector<int> count(static_cast<std::size_t>(np), 0);
  double final_sq = 0;
  for (const BaPointObservation& o : obs) {
    const double e = ReprojectionError((*points)[static_cast<std::size_t>(o.point)],
                                       (*views)[static_cast<std::size_t>(o.view)], o.pixel);
    final_sq += e * e;
    sum2[static_cast<std::size_t>(o.point)] += e * e;
    ++count[static_cast<std::size_t>(o.point)];
  }
  summary.final_rms_px = obs.empty() ? 0 : std::sqrt(final_sq / static_cast<double>(obs.size()));
  for (int i = 0; i < np; ++i) {
    summary.point_rms_px.push_back(count[static_cast<std::size_t>(i)] > 0
                                       ? std::sqrt(sum2[static_cast<std::size_t>(i)] / count[static_cast<std::size_t>(i)])
                                       : 0.0);
  }
  summary.iterations = s.iterations;
  summary.converged = s.converged;
  summary.message = s.BriefReport();
  return summary;
}

}  // namespace idi::optim
