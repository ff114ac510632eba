#include "shared/calib/ptu/ptu_calibration.h"

#include <fmt/format.h>

#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <array>
#include <cmath>
#include <limits>
#include <memory>

#include "shared/optim/least_squares.h"
#include "shared/optim/ptu/ptu_cost.h"

namespace idi::calib {
namespace {

constexpr int kPtuCameraParams = kPtuParamCount + kCameraParamCount;  // 23 per camera

// The parameter values the solver works on, one slot per camera present in the data. The arrays are
// never resized after setup: the optim::Problem holds pointers into them.
struct PtuSolveState {
  std::vector<BiclopsSide> sides;
  std::vector<std::array<double, kPtuParamCount>> ptu;
  std::vector<std::array<double, kCameraParamCount>> intrinsics;
  std::vector<std::array<double, 3>> points;         // one, or one per camera
  std::vector<std::array<bool, kPtuCameraParams>> fixed;  // per camera: PTU then intrinsics
  std::vector<int> slot_of_observation;               // camera slot of each observation

  int PointSlot(int camera_slot) const { return points.size() == 1 ? 0 : camera_slot; }
  double* Param(int slot, int k) {
    return k < kPtuParamCount ? &ptu[static_cast<std::size_t>(slot)][static_cast<std::size_t>(k)]
                              : &intrinsics[static_cast<std::size_t>(slot)][static_cast<std::size_t>(k - kPtuParamCount)];
  }
};

// What each free column of the Jacobian is.
struct PtuColumn {
  int slot = -1;   // camera slot, or -1 for a point coordinate
  int param = 0;   // 0..22 within the camera, or the coordinate 0..2
  int point = 0;   // point slot for a coordinate
};

std::string PtuParamName(BiclopsSide side, int k) {
  static const std::vector<ParamSpec> kPtu = PtuParamSpecs(BiclopsSide::kLeft);
  static const std::vector<ParamSpec> kCam = CameraParamSpecs(BiclopsNominalCamera(BiclopsSide::kLeft));
  const std::string& name = k < kPtuParamCount ? kPtu[static_cast<std::size_t>(k)].name
                                               : kCam[static_cast<std::size_t>(k - kPtuParamCount)].name;
  return std::string(BiclopsSideName(side)) + "." + name;
}

std::string PtuColumnName(const PtuSolveState& s, const PtuColumn& c) {
  if (c.slot >= 0) return PtuParamName(s.sides[static_cast<std::size_t>(c.slot)], c.param);
  const std::string prefix = s.points.size() == 1 ? "" : std::string(BiclopsSideName(s.sides[static_cast<std::size_t>(c.point)])) + ".";
  return prefix + "point." + std::string(1, "xyz"[c.param]);
}

// Builds the problem over the observations with `use[i]`, with one loss for all residuals. Returns the
// free columns in Jacobian order.
std::vector<PtuColumn> BuildPtuProblem(PtuSolveState& s, const std::vector<PtuObservation>& obs,
                                       const std::vector<bool>& use, const optim::Loss& loss, optim::Problem* problem) {
  std::vector<PtuColumn> columns;
  for (std::size_t slot = 0; slot < s.sides.size(); ++slot) {
    for (int k = 0; k < kPtuCameraParams; ++k) {
      double* p = s.Param(static_cast<int>(slot), k);
      problem->AddParameterBlock(p, 1);
      if (s.fixed[slot][static_cast<std::size_t>(k)]) {
        problem->SetConstant(p);
      } else {
        columns.push_back({static_cast<int>(slot), k, 0});
      }
    }
  }
  for (std::size_t pt = 0; pt < s.points.size(); ++pt) {
    problem->AddParameterBlock(s.points[pt].data(), 3);
    for (int k = 0; k < 3; ++k) columns.push_back({-1, k, static_cast<int>(pt)});
  }
  for (std::size_t i = 0; i < obs.size(); ++i) {
    if (!use[i]) continue;
    const PtuObservation& o = obs[i];
    const int slot = s.slot_of_observation[i];
    auto f = std::make_shared<optim::PtuSpotResidual>(BaseFromTcf(o.tcf), o.pan_rad, o.tilt_rad, o.pixel_px, 1.0);
    problem->AddResidual(f,
                         optim::PtuSpotBlocks(s.ptu[static_cast<std::size_t>(slot)].data(),
                                              s.intrinsics[static_cast<std::size_t>(slot)].data(),
                                              s.points[static_cast<std::size_t>(s.PointSlot(slot))].data()),
                         loss);
  }
  return columns;
}

// Pixel error vector of every observation under the current values (NaN when behind the camera).
std::vector<Vec2d> PtuResiduals(const PtuSolveState& s, const std::vector<PtuObservation>& obs) {
  std::vector<Vec2d> out(obs.size(), Vec2d::Constant(std::numeric_limits<double>::quiet_NaN()));
  for (std::size_t i = 0; i < obs.size(); ++i) {
    const int slot = s.slot_of_observation[i];
    const auto& pt = s.points[static_cast<std::size_t>(s.PointSlot(slot))];
    Vec2d px;
    if (ProjectThroughBiclops(BaseFromTcf(obs[i].tcf), s.ptu[static_cast<std::size_t>(slot)].data(),
                              s.intrinsics[static_cast<std::size_t>(slot)].data(), obs[i].pan_rad, obs[i].tilt_rad,
                              Vec3d(pt[0], pt[1], pt[2]), &px)) {
      out[i] = px - obs[i].pixel_px;
    }
  }
  return out;
}

double MedianOf(std::vector<double> v) {
  if (v.empty()) return 0;
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

// Finds the directions the data cannot see (column-scaled Jacobian at the current values) and fixes the
// largest camera parameter of each. FailedPrecondition when a direction involves only the point.
Status FixPtuGauges(PtuSolveState& s, const std::vector<PtuObservation>& obs, const std::vector<bool>& use,
                    double rank_tolerance, std::vector<PtuGaugeFix>* fixes) {
  for (int round = 0; round < kPtuCameraParams * 2; ++round) {
    optim::Problem problem;
    const std::vector<PtuColumn> columns = BuildPtuProblem(s, obs, use, {}, &problem);
    IDI_ASSIGN_OR_RETURN(const optim::DenseEvaluation eval, optim::EvaluateDense(problem));
    const Eigen::Index n = eval.jacobian.cols();
    Eigen::VectorXd scale(n);
    for (Eigen::Index j = 0; j < n; ++j) {
      const double norm = eval.jacobian.col(j).norm();
      scale(j) = norm > 0 ? 1.0 / norm : 0.0;  // a column of zeros: a parameter the data never touch
    }
    const Eigen::MatrixXd js = eval.jacobian * scale.asDiagonal();
    Eigen::JacobiSVD<Eigen::MatrixXd> svd(js, Eigen::ComputeThinV);
    const Eigen::VectorXd& sv = svd.singularValues();
    if (!(sv(0) > 0)) return FailedPrecondition("the observations do not constrain the parameters");
    const double s_max = sv(0);
    Eigen::VectorXd v;
    double rel = 1;
    // A parameter with no effect at all is the plainest gauge.
    for (Eigen::Index j = 0; j < n; ++j) {
      if (scale(j) == 0) {
        v = Eigen::VectorXd::Unit(n, j);
        rel = 0;
        break;
      }
    }
    if (v.size() == 0) {
      // Fewer residuals than parameters (after the untouched ones were fixed above): the data cannot
      // determine them, and the SVD has fewer singular values than columns.
      if (js.rows() < n) {
        return InvalidArgument(fmt::format(
            "too few observations: {} residuals (2 per observation) for {} free parameters; take more poses",
            js.rows(),
            n));
      }
      rel = sv(n - 1) / s_max;
      if (rel >= rank_tolerance) return Status::Ok();
      v = svd.matrixV().col(n - 1);
    }
    // Fix the camera parameter with the largest share of the invisible direction.
    Eigen::Index best = -1;
    for (Eigen::Index j = 0; j < n; ++j) {
      if (columns[static_cast<std::size_t>(j)].slot < 0) continue;
      if (best < 0 || std::abs(v(j)) > std::abs(v(best))) best = j;
    }
    if (best < 0 || std::abs(v(best)) < 1e-3) {
      return FailedPrecondition(
          "the data cannot determine the point: the TCF poses give no parallax (vary the arm's position and "
          "orientation)");
    }
    std::string combination;
    for (Eigen::Index j = 0; j < n; ++j) {
      if (std::abs(v(j)) < 0.05) continue;
      const double c = v(j) * (v(best) < 0 ? -1 : 1);
      combination += fmt::format("{}{:.2f} {}", combination.empty() ? (c < 0 ? "-" : "") : (c < 0 ? " - " : " + "),
                                 std::abs(c), PtuColumnName(s, columns[static_cast<std::size_t>(j)]));
    }
    const PtuColumn& c = columns[static_cast<std::size_t>(best)];
    s.fixed[static_cast<std::size_t>(c.slot)][static_cast<std::size_t>(c.param)] = true;
    fixes->push_back({PtuColumnName(s, c), combination, rel});
  }
  return Internal("gauge fixing did not terminate");
}

Result<optim::SolverSummary> RunPtuStage(PtuSolveState& s, const std::vector<PtuObservation>& obs,
                                         const std::vector<bool>& use, const optim::Loss& loss, int max_iterations) {
  optim::Problem problem;
  BuildPtuProblem(s, obs, use, loss, &problem);
  optim::SolverOptions so;
  so.max_iterations = max_iterations;
  so.function_tolerance = 1e-12;
  so.parameter_tolerance = 1e-12;
  so.gradient_tolerance = 1e-14;
  return optim::SolveLevenbergMarquardt(problem, so);
}

}  // namespace

PtuCameraModel PtuCameraModel::Nominal(BiclopsSide side) {
  PtuCameraModel m;
  m.side = side;
  m.ptu = ParamSet(PtuParamSpecs(side));
  const CameraModel cam = BiclopsNominalCamera(side);
  m.intrinsics = CameraToParamSet(cam);
  m.width = cam.width;
  m.height = cam.height;
  return m;
}

Rigid3d PtuCameraModel::BaseFromCamera(const TcfPose& tcf, double pan_rad, double tilt_rad) const {
  return BaseFromTcf(tcf) * TcfFromCamera(ptu.data(), pan_rad, tilt_rad);
}

std::optional<Vec2d> PtuCameraModel::Project(const TcfPose& tcf, double pan_rad, double tilt_rad,
                                             const Vec3d& point_mm) const {
  Vec2d px;
  if (!ProjectThroughBiclops(BaseFromTcf(tcf), ptu.data(), intrinsics.data(), pan_rad, tilt_rad, point_mm, &px)) {
    return std::nullopt;
  }
  return px;
}

Status PtuCalibrationOptions::Check() const {
  if (!(robust_scale_px > 0) || !(outlier_sigmas > 0) || !(outlier_floor_px >= 0) || max_iterations <= 0 ||
      min_observations_per_camera < 1) {
    return InvalidArgument(
        "PtuCalibrationOptions: robust_scale_px, outlier_sigmas, max_iterations, min_observations_per_camera must "
        "be positive, outlier_floor_px >= 0");
  }
  if (initial_point_mm && !initial_point_mm->allFinite()) {
    return InvalidArgument("PtuCalibrationOptions: initial_point_mm is not finite");
  }
  IDI_RETURN_IF_ERROR(identifiability.Check());
  return range.Check();
}

const PtuCameraCalibration* PtuCalibrationResult::Camera(BiclopsSide side) const {
  for (const auto& c : cameras) {
    if (c.side == side) return &c;
  }
  return nullptr;
}

const PtuCameraValidation* PtuValidation::Camera(BiclopsSide side) const {
  for (const auto& c : cameras) {
    if (c.side == side) return &c;
  }
  return nullptr;
}

std::vector<std::string> PtuCameraParameterNames(BiclopsSide side) {
  std::vector<std::string> names;
  for (int k = 0; k < kPtuCameraParams; ++k) names.push_back(PtuParamName(side, k));
  return names;
}

std::string PtuCalibrationResult::Summary() const {
  std::string s = fmt::format("point ({:.3f}, {:.3f}, {:.3f}) mm, std ({:.3f}, {:.3f}, {:.3f}) mm\n", point_mm.x(),
                              point_mm.y(), point_mm.z(), point_std_mm.x(), point_std_mm.y(), point_std_mm.z());
  for (const auto& c : cameras) {
    s += fmt::format("{}: {} observations, {} inliers, RMS {:.3f} px per axis, mean error {:.3f} px, max {:.3f} px\n",
                     BiclopsSideName(c.side), c.observations, c.inliers, c.rms_px, c.mean_error_px, c.max_error_px);
  }
  s += fmt::format("{} iterations ({}), {:.1f} ms, condition number {:.3g}, sigma0 {:.3f} px",
                   iterations,
                   termination,
                   time_ms,
                   condition_number,
                   std::sqrt(variance_factor));
  if (termination != "convergence") {
    s += "\nwarning: the last solve stopped before converging (max_iterations); the parameters and their std may "
         "not be at the optimum";
  }
  for (const auto& g : gauge) {
    s += fmt::format("\ngauge: the data cannot separate {}; fixed {}", g.combination, g.fixed_parameter);
  }
  if (!correlated.empty()) s += "\ncorrelated: " + correlated;
  return s;
}

Result<Vec3d> TriangulatePtuPoint(const std::vector<PtuObservation>& observations,
                                  const std::vector<PtuCameraModel>& models) {
  std::vector<Vec3d> origins, directions;
  for (const PtuObservation& o : observations) {
    const PtuCameraModel* m = nullptr;
    for (const auto& c : models) {
      if (c.side == o.camera) m = &c;
    }
    if (m == nullptr) return InvalidArgument(std::string("no model for the ") + BiclopsSideName(o.camera) + " camera");
    const Rigid3d base_from_cam = m->BaseFromCamera(o.tcf, o.pan_rad, o.tilt_rad);
    const Vec3d ray = PixelToRay(m->Camera(), o.pixel_px);
    origins.push_back(base_from_cam.translation);
    directions.push_back(base_from_cam.rotation * ray.normalized());
  }
  if (origins.size() < 2) return FailedPrecondition("triangulating the point needs at least two observations");
  std::vector<double> w(origins.size(), 1.0);
  Vec3d x = Vec3d::Zero();
  for (int pass = 0; pass < 6; ++pass) {
    Mat3d a = Mat3d::Zero();
    Vec3d b = Vec3d::Zero();
    for (std::size_t i = 0; i < origins.size(); ++i) {
      const Mat3d p = Mat3d::Identity() - directions[i] * directions[i].transpose();
      a += w[i] * p;
      b += w[i] * p * origins[i];
    }
    Eigen::SelfAdjointEigenSolver<Mat3d> eig(a);
    if (!(eig.eigenvalues()(0) > 1e-6 * eig.eigenvalues()(2))) {
      return FailedPrecondition("the rays to the spot are (nearly) parallel: the poses give no parallax");
    }
    x = a.ldlt().solve(b);
    std::vector<double> d(origins.size());
    for (std::size_t i = 0; i < origins.size(); ++i) {
      d[i] = ((Mat3d::Identity() - directions[i] * directions[i].transpose()) * (x - origins[i])).norm();
    }
    const double scale = std::max(1.0, 1.4826 * MedianOf(d));
    for (std::size_t i = 0; i < origins.size(); ++i) {
      const double u = d[i] / (3 * scale);
      w[i] = 1.0 / (1.0 + u * u);
    }
  }
  int in_front = 0;
  for (std::size_t i = 0; i < origins.size(); ++i) {
    if ((x - origins[i]).dot(directions[i]) > 0) ++in_front;
  }
  if (2 * in_front < static_cast<int>(origins.size())) {
    return FailedPrecondition("the triangulated point lies behind most cameras: the start model or the data are wrong");
  }
  return x;
}

Result<PtuCalibrationResult> CalibratePtu(const std::vector<PtuObservation>& observations,
                                          const std::vector<PtuCameraModel>& start,
                                          const PtuCalibrationOptions& options) {
  IDI_RETURN_IF_ERROR(options.Check());
  IDI_RETURN_IF_ERROR(CheckPtuObservations(observations, options.range, options.source));
  const auto t0 = std::chrono::steady_clock::now();

  // Cameras present, their start models, and enough data for each.
  PtuSolveState s;
  std::vector<PtuCameraModel> models;
  for (BiclopsSide side : {BiclopsSide::kLeft, BiclopsSide::kRight}) {
    const int n = static_cast<int>(SelectCamera(observations, side).size());
    if (n == 0) continue;
    if (n < options.min_observations_per_camera) {
      return InvalidArgument(fmt::format(
          "{}: too few poses: the {} camera has {} observations, at least {} are needed (2 constraints each for up "
          "to 26 unknowns; §6.4.4 uses 60)",
          options.source, BiclopsSideName(side), n, options.min_observations_per_camera));
    }
    PtuCameraModel m = PtuCameraModel::Nominal(side);
    for (const auto& st : start) {
      if (st.side == side) m = st;
    }
    if (m.ptu.size() != kPtuParamCount || m.intrinsics.size() != kCameraParamCount) {
      return InvalidArgument(fmt::format("start model of the {} camera has the wrong parameter count",
                                         BiclopsSideName(side)));
    }
    models.push_back(m);
    s.sides.push_back(side);
    std::array<double, kPtuParamCount> p{};
    std::array<double, kCameraParamCount> c{};
    std::copy(m.ptu.values().begin(), m.ptu.values().end(), p.begin());
    std::copy(m.intrinsics.values().begin(), m.intrinsics.values().end(), c.begin());
    s.ptu.push_back(p);
    s.intrinsics.push_back(c);
    std::array<bool, kPtuCameraParams> fixed{};
    fixed[kPtuParamCount + kP1] = fixed[kPtuParamCount + kP2] = fixed[kPtuParamCount + kK3] = true;
    if (!options.estimate_distortion) fixed[kPtuParamCount + kK1] = fixed[kPtuParamCount + kK2] = true;
    s.fixed.push_back(fixed);
  }
  if (s.sides.empty()) {
    return InvalidArgument(options.source + ": no observations");
  }
  for (const std::string& name : options.fixed) {
    bool found = false;
    for (std::size_t slot = 0; slot < s.sides.size(); ++slot) {
      for (int k = 0; k < kPtuCameraParams; ++k) {
        if (PtuParamName(s.sides[slot], k) == name) {
          s.fixed[slot][static_cast<std::size_t>(k)] = true;
          found = true;
        }
      }
    }
    if (!found) {
      return InvalidArgument(fmt::format("fixed parameter '{}' is not a parameter of a camera in the data (expected "
                                         "e.g. left.theta_z, right.k1)",
                                         name));
    }
  }
  for (const PtuObservation& o : observations) {
    s.slot_of_observation.push_back(o.camera == s.sides[0] ? 0 : 1);
  }

  PtuCalibrationResult result;
  // Start point: given, or triangulated from the start models (per camera when not shared).
  const int num_points = options.shared_point ? 1 : static_cast<int>(s.sides.size());
  for (int pt = 0; pt < num_points; ++pt) {
    Vec3d x;
    if (options.initial_point_mm) {
      x = *options.initial_point_mm;
    } else {
      const std::vector<PtuObservation> subset =
          num_points == 1 ? observations : SelectCamera(observations, s.sides[static_cast<std::size_t>(pt)]);
      auto tri = TriangulatePtuPoint(subset, models);
      if (!tri.ok()) return tri.status().WithContext(options.source);
      x = *tri;
    }
    s.points.push_back({x.x(), x.y(), x.z()});
    if (pt == 0) result.initial_point_mm = x;
  }

  std::vector<bool> use(observations.size(), true);
  IDI_RETURN_IF_ERROR(FixPtuGauges(s, observations, use, options.identifiability.rank_tolerance, &result.gauge)
                          .WithContext(options.source));

  // Stage 1 (Huber, wide) and stage 2 (Cauchy): robust; stage 3: least squares on the inliers.
  const optim::Loss stage_losses[] = {{optim::LossKind::kHuber, 10 * options.robust_scale_px},
                                      {optim::LossKind::kCauchy, options.robust_scale_px}};
  for (const optim::Loss& loss : stage_losses) {
    auto st = RunPtuStage(s, observations, use, loss, options.max_iterations);
    if (!st.ok()) return st.status().WithContext(options.source);
    result.iterations += st->iterations;
    result.cost_per_iteration.insert(result.cost_per_iteration.end(), st->cost_per_iteration.begin(),
                                     st->cost_per_iteration.end());
  }
  std::vector<Vec2d> res = PtuResiduals(s, observations);
  {
    std::vector<double> components;
    for (const Vec2d& r : res) {
      if (r.allFinite()) {
        components.push_back(std::abs(r.x()));
        components.push_back(std::abs(r.y()));
      }
    }
    const double sigma = 1.4826 * MedianOf(components);
    const double threshold = std::max(options.outlier_sigmas * sigma, options.outlier_floor_px);
    for (std::size_t i = 0; i < observations.size(); ++i) {
      use[i] = res[i].allFinite() && res[i].norm() <= threshold;
      if (!use[i]) ++result.rejected;
    }
  }
  for (std::size_t slot = 0; slot < s.sides.size(); ++slot) {
    int n = 0;
    for (std::size_t i = 0; i < observations.size(); ++i) {
      if (use[i] && s.slot_of_observation[i] == static_cast<int>(slot)) ++n;
    }
    if (n < options.min_observations_per_camera) {
      return InvalidArgument(fmt::format(
          "{}: too few consistent poses: {} of the {} camera's observations remain after rejecting outliers, at least "
          "{} are needed",
          options.source, n, BiclopsSideName(s.sides[slot]), options.min_observations_per_camera));
    }
  }
  {
    auto st = RunPtuStage(s, observations, use, {}, options.max_iterations);
    if (!st.ok()) return st.status().WithContext(options.source);
    result.termination = st->termination;
    result.iterations += st->iterations;
    result.cost_per_iteration.insert(result.cost_per_iteration.end(), st->cost_per_iteration.begin(),
                                     st->cost_per_iteration.end());
  }

  // Covariance and identifiability at the solution.
  optim::Problem final_problem;
  const std::vector<PtuColumn> columns = BuildPtuProblem(s, observations, use, {}, &final_problem);
  for (const PtuColumn& c : columns) result.free_parameters.push_back(PtuColumnName(s, c));
  auto eval = optim::EvaluateDense(final_problem);
  if (!eval.ok()) return eval.status().WithContext(options.source);
  result.variance_factor = optim::VarianceFactor(eval->residuals, static_cast<int>(columns.size()));
  auto cov = optim::AnalyzeJacobian(eval->jacobian, result.variance_factor, options.identifiability);
  if (!cov.ok()) return cov.status().WithContext(options.source);
  result.singular_values = cov->singular_values;
  result.condition_number = cov->condition_number;
  result.correlated = optim::DescribeCorrelations(*cov, result.free_parameters);
  if (!cov->undetermined.empty()) {
    std::vector<std::string> names;
    for (int i : cov->undetermined) names.push_back(result.free_parameters[static_cast<std::size_t>(i)]);
    return FailedPrecondition(fmt::format("{}: the data do not determine {} at the solution", options.source,
                                          fmt::join(names, ", ")));
  }

  // Results per camera.
  res = PtuResiduals(s, observations);
  for (std::size_t slot = 0; slot < s.sides.size(); ++slot) {
    PtuCameraCalibration cc;
    cc.side = s.sides[slot];
    cc.model = models[slot];
    for (int k = 0; k < kPtuCameraParams; ++k) {
      ParamSet& set = k < kPtuParamCount ? cc.model.ptu : cc.model.intrinsics;
      const std::size_t idx = static_cast<std::size_t>(k < kPtuParamCount ? k : k - kPtuParamCount);
      set.set_value(idx, *s.Param(static_cast<int>(slot), k));
      set.set_stddev(idx, std::numeric_limits<double>::quiet_NaN());
      if (s.fixed[slot][static_cast<std::size_t>(k)]) {
        result.held_fixed.push_back(PtuParamName(cc.side, k));
      }
    }
    const int pt = s.PointSlot(static_cast<int>(slot));
    cc.point_mm = Vec3d(s.points[static_cast<std::size_t>(pt)][0], s.points[static_cast<std::size_t>(pt)][1],
                        s.points[static_cast<std::size_t>(pt)][2]);
    for (std::size_t j = 0; j < columns.size(); ++j) {
      const PtuColumn& c = columns[j];
      const double sd = cov->stddev(static_cast<Eigen::Index>(j));
      if (c.slot == static_cast<int>(slot)) {
        ParamSet& set = c.param < kPtuParamCount ? cc.model.ptu : cc.model.intrinsics;
        set.set_stddev(static_cast<std::size_t>(c.param < kPtuParamCount ? c.param : c.param - kPtuParamCount), sd);
      } else if (c.slot < 0 && c.point == pt) {
        cc.point_std_mm(c.param) = sd;
      }
    }
    double sum_sq = 0, sum = 0;
    for (std::size_t i = 0; i < observations.size(); ++i) {
      if (s.slot_of_observation[i] != static_cast<int>(slot)) continue;
      const double e = res[i].allFinite() ? res[i].norm() : std::numeric_limits<double>::infinity();
      ++cc.observations;
      cc.errors_px.push_back(e);
      cc.inlier.push_back(use[i]);
      if (use[i]) {
        ++cc.inliers;
        sum_sq += res[i].squaredNorm();
        sum += e;
        cc.max_error_px = std::max(cc.max_error_px, e);
      }
    }
    cc.rms_px = std::sqrt(sum_sq / (2.0 * cc.inliers));
    cc.mean_error_px = sum / cc.inliers;
    result.cameras.push_back(std::move(cc));
  }
  result.point_mm = result.cameras[0].point_mm;
  result.point_std_mm = result.cameras[0].point_std_mm;
  result.time_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  return result;
}

Result<PtuValidation> ValidatePtu(const PtuCalibrationResult& calibration,
                                  const std::vector<PtuObservation>& observations, const PtuRange& range,
                                  const std::string& source) {
  IDI_RETURN_IF_ERROR(CheckPtuObservations(observations, range, source));
  if (observations.empty()) return InvalidArgument(source + ": no validation observations");
  PtuValidation v;
  double total_sq = 0;
  int total = 0;
  for (const auto& cc : calibration.cameras) {
    PtuCameraValidation cv;
    cv.side = cc.side;
    double sum_sq = 0, sum = 0;
    for (std::size_t i = 0; i < observations.size(); ++i) {
      const PtuObservation& o = observations[i];
      if (o.camera != cc.side) continue;
      const auto px = cc.model.Project(o.tcf, o.pan_rad, o.tilt_rad, cc.point_mm);
      if (!px) {
        return InvalidArgument(fmt::format("{}: observation {} (line {}): the point is behind the {} camera", source,
                                           i, o.source_line, BiclopsSideName(o.camera)));
      }
      const Vec2d r = *px - o.pixel_px;
      ++cv.observations;
      cv.errors_px.push_back(r.norm());
      sum_sq += r.squaredNorm();
      sum += r.norm();
      cv.max_error_px = std::max(cv.max_error_px, r.norm());
    }
    if (cv.observations == 0) continue;
    cv.rms_px = std::sqrt(sum_sq / (2.0 * cv.observations));
    cv.mean_error_px = sum / cv.observations;
    total_sq += sum_sq;
    total += cv.observations;
    v.cameras.push_back(std::move(cv));
  }
  for (const PtuObservation& o : observations) {
    if (calibration.Camera(o.camera) == nullptr) {
      return InvalidArgument(fmt::format("{}: line {}: the {} camera was not calibrated", source, o.source_line,
                                         BiclopsSideName(o.camera)));
    }
  }
  v.rms_px = std::sqrt(total_sq / (2.0 * total));
  return v;
}

}  // namespace idi::calib
