// Monte Carlo study of the ViCKi calibrations in the digital twin (issue 5 acceptance).
//
// Robot (chapter 4), three data qualities, each over N trials with different true arms, walls and points:
//   precise    spot within +-0.0005 mm of the point (uniform camera error), joints not quantized
//   encoder    joints realised at Table 4.2 encoder counts, perfect camera (the dissertation's model)
//   realistic  encoders + 0.05 mm camera noise per axis + 0.1 mm rail repeatability
// Every trial runs the whole procedure (planning, selection, closed-loop aiming, solve). The floor is
// the covariance at the true parameters for the noise model (Cramer-Rao bound), computed per trial.
// Rail (chapter 5): encoder-only and realistic, with the true arm models (as §5.4.1-5.4.2), then the
// realistic case with chapter-4-calibrated arms, separately and solved together with the rail.
//
// Usage: calib_bench_mc [trials=20] [robot|rail|joint|all] [readings=540]
// Environment: IDI_MC_SCENARIO=precise|encoder|realistic (robot: only that one), IDI_MC_POOL (candidates
// per reading), IDI_MC_NEAR (planning cone, deg), IDI_MC_DOPT=1 (D-optimal selection only), IDI_MC_LOOP_TOL
// (the aiming loop's tolerance, mm), IDI_MC_FINAL (the loop's corrections after reaching tolerance),
// IDI_MC_SPOT (the camera's spot noise, mm, replacing the scenario's), IDI_MC_MISS=1 (print each trial's
// true spot miss per set: mean and RMS over the readings, wall x/y, mm),
// IDI_MC_WALL_MIN / IDI_MC_WALL_MAX (wall distances, mm).
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <set>
#include <string>

#include "shared/calib/evaluation.h"
#include "shared/calib/rail_calibration.h"
#include "shared/calib/robot_calibration.h"
#include "shared/sim/workcell/workcell_twin.h"
#include "workcell/procedures/calibration_procedures.h"

namespace idi {
namespace {

using workcell::ArmDevices;
using workcell::CellSetup;

// Forwards to the twin's rail and remembers where each move truly landed (truth for the study only).
class RecordingRail final : public hal::RailDevice {
 public:
  RecordingRail(sim::WorkcellTwin* twin, int k) : twin_(twin), k_(k) {}
  Status MoveTo(double position_mm, const hal::MoveOptions& o) override {
    IDI_RETURN_IF_ERROR(twin_->rail(k_).MoveTo(position_mm, o));
    landed.push_back(twin_->true_rail_position(k_));
    return Status::Ok();
  }
  Result<hal::RailState> Read() override { return twin_->rail(k_).Read(); }
  Status Stop() override { return twin_->rail(k_).Stop(); }
  std::vector<double> landed;

 private:
  sim::WorkcellTwin* twin_;
  int k_;
};

CellSetup SetupOf(const sim::WorkcellTwin& twin) {
  CellSetup s;
  for (const sim::Wall& w : twin.Setup().walls) {
    s.wall_names.push_back(w.name);
    s.world_from_wall.push_back(w.world_from_wall);
  }
  return s;
}

struct Scenario {
  std::string name;
  bool quantize;
  double spot_sigma;
  sim::SpotNoise spot_noise;
  double rail_rep;
  double loop_tolerance;
  calib::RobotNoiseModel model;  // what the solver assumes
  double bound_spot_sigma;       // per-axis std of the spot error for the bound
};

std::vector<Scenario> RobotScenarios() {
  std::vector<Scenario> s;
  calib::RobotNoiseModel precise;
  precise.spot_sigma_mm = 0.0005 / std::sqrt(3.0);  // uniform in +-0.0005
  precise.encoder_rounding = false;
  precise.distance_sigma_mm = 0;
  s.push_back({"precise", false, 0.0005, sim::SpotNoise::kUniform, 0.0, 0.001, precise, 0.0005 / std::sqrt(3.0)});
  calib::RobotNoiseModel encoder;
  encoder.spot_sigma_mm = 1e-6;
  encoder.encoder_rounding = true;
  encoder.distance_sigma_mm = 0;
  s.push_back({"encoder", true, 0.0, sim::SpotNoise::kGaussian, 0.0, 0.01, encoder, 1e-6});
  calib::RobotNoiseModel realistic;  // defaults: 0.05 mm spot, encoders, sqrt(2) x 0.1 mm on D
  s.push_back({"realistic", true, 0.05, sim::SpotNoise::kGaussian, 0.1, 0.15, realistic, 0.05});
  return s;
}

struct RobotTrial {
  Eigen::VectorXd error, bound_sd, solver_sd;
  double spread_nominal = 0, spread_cal = 0, spread_true = 0;
  int restarts = 0, outliers = 0;
  double cond_info = 0, cond_jac = 0;
  double solve_ms = 0;
  std::set<std::pair<int, int>> correlated;
  double variance_factor = 0;
};

// Truth of one trial's unknowns: the point in robot 1's base at its set-1 true rail position.
Result<RobotTrial> RunRobotTrial(const Scenario& sc, unsigned seed, int readings, calib::RobotCalibrationResult* keep = nullptr,
                                 calib::RobotCalibrationData* keep_data = nullptr, sim::WorkcellTwin* external = nullptr,
                                 int arm = 0) {
  sim::WorkcellTwinOptions to;
  to.seed = seed;
  to.quantize_joints = sc.quantize;
  to.spot_sigma_mm = sc.spot_sigma;
  if (const char* e = std::getenv("IDI_MC_SPOT")) to.spot_sigma_mm = std::atof(e);
  to.spot_noise = sc.spot_noise;
  to.rail_repeatability_mm = sc.rail_rep;
  if (const char* e = std::getenv("IDI_MC_WALL_MIN")) to.wall_distance_min_mm = std::atof(e);
  if (const char* e = std::getenv("IDI_MC_WALL_MAX")) to.wall_distance_max_mm = std::atof(e);
  std::unique_ptr<sim::WorkcellTwin> own;
  sim::WorkcellTwin* twin = external;
  if (!twin) {
    own = std::make_unique<sim::WorkcellTwin>(to);
    twin = own.get();
  }
  RecordingRail rail(twin, arm);
  ArmDevices dev{&twin->arm(arm), &rail, &twin->laser(arm), [twin, arm](int w) { return twin->ObserveSpot(arm, w); }};
  workcell::RobotAcquisitionOptions ao;
  ao.per_set = readings / 2;
  ao.seed = seed;
  ao.loop.tolerance_mm = sc.loop_tolerance;
  ao.loop.round_to_encoder_counts = sc.quantize;  // the precise scenario's arm has no encoder counts
  if (const char* e = std::getenv("IDI_MC_LOOP_TOL")) ao.loop.tolerance_mm = std::atof(e);
  if (const char* e = std::getenv("IDI_MC_FINAL")) ao.loop.final_corrections = std::atoi(e);
  if (const char* e = std::getenv("IDI_MC_POOL")) ao.pool_factor = std::atof(e);
  if (const char* e = std::getenv("IDI_MC_NEAR")) ao.plan.near_deg = std::atof(e);
  if (const char* e = std::getenv("IDI_MC_DOPT")) ao.a_optimal = std::atoi(e) == 0;
  const CellSetup setup = SetupOf(*twin);
  IDI_ASSIGN_OR_RETURN(const workcell::RobotAcquisition acq, workcell::AcquireRobotData(dev, arm, setup, calib::ArmModel{}, ao));
  calib::RobotCalibrationOptions co;
  co.noise = sc.model;
  co.noise.plane_normal = acq.plane_normal_in_base;
  IDI_ASSIGN_OR_RETURN(const calib::RobotCalibrationResult r, calib::CalibrateRobot(acq.data, co));
  // Truth.
  const sim::Wall& wall = twin->walls()[static_cast<std::size_t>(acq.wall)];
  const Vec3d p_world = wall.world_from_wall * Vec3d(acq.targets_on_wall[0].x(), acq.targets_on_wall[0].y(), 0.0);
  const ParamSet& tr = twin->true_rail(arm);
  auto world_from_base = [&](double rail_mm) {
    const Rigid3d rfb = RailFromBase(tr.value(kPhiL), tr.value(kPhiM), rail_mm);
    return arm == 0 ? rfb : Rail1FromRail2(twin->true_psi().data()) * rfb;
  };
  const Rigid3d base1_from_world = world_from_base(rail.landed.at(0)).Inverse();
  const Vec3d p_base = base1_from_world * p_world;
  const ParamSet truth = calib::PackRobotCalibration(twin->true_robot(arm), twin->true_laser(arm), p_base, tr);
  if (std::getenv("IDI_MC_MISS")) {
    Vec2d sum[2] = {Vec2d::Zero(), Vec2d::Zero()};
    double ss[2] = {0, 0};
    int cnt[2] = {0, 0};
    for (const calib::AimReading& rd : acq.data.readings) {
      const int si = rd.set - 1;
      const Rigid3d base_from_wall = world_from_base(rail.landed.at(static_cast<std::size_t>(si))).Inverse() * wall.world_from_wall;
      const auto sp = calib::SpotOnPlane(twin->true_robot(arm), twin->true_laser(arm), base_from_wall, rd.q);
      if (!sp) continue;
      const Vec2d m = *sp - acq.targets_on_wall[static_cast<std::size_t>(si)];
      sum[si] += m;
      ss[si] += m.squaredNorm();
      ++cnt[si];
    }
    for (int si = 0; si < 2; ++si) {
      fmt::print("miss set {}: mean ({:.2e}, {:.2e}) rms {:.2e} n {}\n", si + 1, sum[si].x() / cnt[si], sum[si].y() / cnt[si],
                 std::sqrt(ss[si] / cnt[si]), cnt[si]);
    }
  }
  RobotTrial t;
  const int n = calib::kRobotCalibrationUnknowns;
  t.error.resize(n);
  t.solver_sd.resize(n);
  t.bound_sd.resize(n);
  for (int i = 0; i < n; ++i) {
    t.error(i) = ToFileUnits(truth.spec(static_cast<std::size_t>(i)).unit, r.params.value(static_cast<std::size_t>(i)) - truth.value(static_cast<std::size_t>(i)));
    t.solver_sd(i) = r.params.file_stddev(static_cast<std::size_t>(i));
  }
  // The bound: the same readings with the true distance and the true noise geometry.
  calib::RobotCalibrationData bd = acq.data;
  bd.distance_mm = rail.landed.at(1) - rail.landed.at(0);
  calib::RobotNoiseModel bn = sc.model;
  bn.spot_sigma_mm = sc.bound_spot_sigma;
  bn.plane_normal = base1_from_world.rotation * wall.world_from_wall.rotation.col(2);
  bn.distance_sigma_mm = sc.rail_rep * std::sqrt(2.0);
  IDI_ASSIGN_OR_RETURN(const Eigen::MatrixXd bound, calib::RobotCovarianceAt(bd, truth, bn));
  for (int i = 0; i < n; ++i) {
    t.bound_sd(i) = ToFileUnits(truth.spec(static_cast<std::size_t>(i)).unit, std::sqrt(bound(i, i)));
  }
  // §4.5.4 on the held-out readings.
  const calib::ArmModel nominal;
  const auto sn = calib::LaserSpread(calib::LaserLines(nominal.robot, nominal.laser, acq.held_out));
  const auto sc_ = calib::LaserSpread(calib::LaserLines(r.robot, r.laser, acq.held_out));
  const auto st = calib::LaserSpread(calib::LaserLines(twin->true_robot(arm), twin->true_laser(arm), acq.held_out));
  if (sn.ok() && sc_.ok() && st.ok()) {
    t.spread_nominal = sn->mean_mm;
    t.spread_cal = sc_->mean_mm;
    t.spread_true = st->mean_mm;
  }
  t.restarts = r.restarts;
  t.outliers = static_cast<int>(r.outliers.size());
  t.cond_info = acq.selection.condition_number;
  t.cond_jac = r.identifiability.condition_number;
  t.solve_ms = r.summary.time_ms;
  t.variance_factor = r.residuals.variance_factor;
  for (const optim::CorrelatedPair& p : r.identifiability.correlated) t.correlated.insert({p.i, p.j});
  if (keep) *keep = r;
  if (keep_data) *keep_data = acq.data;
  return t;
}

double Rms(const std::vector<double>& v) {
  double s = 0;
  for (double x : v) s += x * x;
  return std::sqrt(s / static_cast<double>(v.size()));
}
double Std(const std::vector<double>& v) {
  double m = 0;
  for (double x : v) m += x;
  m /= static_cast<double>(v.size());
  double s = 0;
  for (double x : v) s += (x - m) * (x - m);
  return std::sqrt(s / static_cast<double>(v.size() - 1));
}

void RobotStudy(int trials, int readings) {
  const std::vector<ParamSpec> specs = calib::RobotCalibrationSpecs();
  const char* only = std::getenv("IDI_MC_SCENARIO");  // e.g. "realistic": run just that one
  for (const Scenario& sc : RobotScenarios()) {
    if (only != nullptr && sc.name != only) continue;
    std::vector<RobotTrial> ts;
    int failures = 0;
    for (int k = 0; k < trials; ++k) {
      const auto t = RunRobotTrial(sc, 1000u + static_cast<unsigned>(k), readings);
      if (!t.ok()) {
        ++failures;
        fmt::print("  {} trial {}: FAILED: {}\n", sc.name, k, t.status().ToString());
        continue;
      }
      ts.push_back(*t);
    }
    if (ts.size() < 2) continue;
    fmt::print("\n=== robot calibration, {} data: {} trials ({} failed), {} readings each ===\n", sc.name, ts.size(), failures, readings);
    fmt::print("{:<14} {:>11} {:>11} {:>11} {:>11} {:>8} {:>11} {:>8}\n", "parameter", "max|err|", "MC std", "MC rms", "bound", "rms/bnd",
               "solver sd", "sd/MC");
    double worst_ratio = 0, worst_honest = 0, best_honest = 1e9, max_err_table = 0;
    for (int i = 0; i < calib::kRobotCalibrationUnknowns; ++i) {
      std::vector<double> e, b, s;
      for (const RobotTrial& t : ts) {
        e.push_back(t.error(i));
        b.push_back(t.bound_sd(i));
        s.push_back(t.solver_sd(i));
      }
      double max_abs = 0;
      for (double x : e) max_abs = std::max(max_abs, std::abs(x));
      const double ratio = Rms(e) / Rms(b);
      const double honest = Rms(s) / Std(e);
      fmt::print("{:<14} {:>11.3e} {:>11.3e} {:>11.3e} {:>11.3e} {:>8.2f} {:>11.3e} {:>8.2f}\n", specs[static_cast<std::size_t>(i)].Key(),
                 max_abs, Std(e), Rms(e), Rms(b), ratio, Rms(s), honest);
      if (i < 22 || i >= 25) {
        worst_ratio = std::max(worst_ratio, ratio);
        worst_honest = std::max(worst_honest, honest);
        best_honest = std::min(best_honest, honest);
        max_err_table = std::max(max_err_table, max_abs);
      }
    }
    std::vector<double> sn, scal, st, ms, cond_i, cond_j, vf;
    int restarts = 0, outliers = 0;
    std::map<std::pair<int, int>, int> corr;
    for (const RobotTrial& t : ts) {
      sn.push_back(t.spread_nominal);
      scal.push_back(t.spread_cal);
      st.push_back(t.spread_true);
      ms.push_back(t.solve_ms);
      cond_i.push_back(t.cond_info);
      cond_j.push_back(t.cond_jac);
      vf.push_back(t.variance_factor);
      restarts += t.restarts;
      outliers += t.outliers;
      for (const auto& p : t.correlated) ++corr[p];
    }
    auto mean = [](const std::vector<double>& v) {
      double m = 0;
      for (double x : v) m += x;
      return m / static_cast<double>(v.size());
    };
    fmt::print("robot+laser+phi (25 params): max |error| {:.3e}; worst MC rms / bound {:.2f}; solver sd / MC std in [{:.2f}, {:.2f}]\n",
               max_err_table, worst_ratio, best_honest, worst_honest);
    fmt::print("held-out spread radius mean: nominal {:.4f} mm, calibrated {:.4f} mm, true parameters {:.4f} mm; "
               "nominal/calibrated {:.1f}x, calibrated/true {:.3f}\n",
               mean(sn), mean(scal), mean(st), mean(sn) / mean(scal), mean(scal) / mean(st));
    fmt::print("restarts needed: {} in {} trials; outliers flagged: {}; sigma0^2 mean {:.3f}; info-matrix condition number "
               "(scaled) mean {:.3g}; Jacobian condition number (scaled) mean {:.3g}; solve time mean {:.1f} ms\n",
               restarts, ts.size(), outliers, mean(vf), mean(cond_i), mean(cond_j), mean(ms));
    fmt::print("pairs correlating above 0.95 (trials out of {}):", ts.size());
    for (const auto& [p, c] : corr) fmt::print(" {}/{} ({})", specs[static_cast<std::size_t>(p.first)].Key(), specs[static_cast<std::size_t>(p.second)].Key(), c);
    fmt::print("\n");
  }
}

// Rail study: trials with the true arms (the dissertation's §5.4.1-5.4.2 set-up).
void RailStudy(int trials, int readings) {
  struct RailScenario {
    std::string name;
    bool quantize;
    double spot, rail;
    calib::RailNoiseModel model;
  };
  calib::RailNoiseModel enc;
  enc.spot_sigma_mm = 1e-6;
  enc.rail_sigma_mm = 0;
  const std::vector<RailScenario> scs = {{"encoder", true, 0.0, 0.0, enc}, {"realistic", true, 0.05, 0.1, {}}};
  const std::vector<ParamSpec> specs = RobotToRobotParamSpecs();
  for (const RailScenario& sc : scs) {
    std::vector<Eigen::Vector4d> err, bound, sd;
    std::vector<double> cond, cond_one, ms;
    for (int k = 0; k < trials; ++k) {
      sim::WorkcellTwinOptions to;
      to.seed = 5000u + static_cast<unsigned>(k);
      to.quantize_joints = sc.quantize;
      to.spot_sigma_mm = sc.spot;
      to.rail_repeatability_mm = sc.rail;
      sim::WorkcellTwin twin(to);
      calib::ArmModel a1, a2;
      a1.robot = twin.true_robot(0), a1.laser = twin.true_laser(0), a1.rail = twin.true_rail(0);
      a2.robot = twin.true_robot(1), a2.laser = twin.true_laser(1), a2.rail = twin.true_rail(1);
      ArmDevices d1{&twin.arm(0), &twin.rail(0), &twin.laser(0), [&twin](int w) { return twin.ObserveSpot(0, w); }};
      ArmDevices d2{&twin.arm(1), &twin.rail(1), &twin.laser(1), [&twin](int w) { return twin.ObserveSpot(1, w); }};
      workcell::RailAcquisitionOptions ao;
      ao.readings = readings;
      ao.seed = to.seed;
      ao.loop.tolerance_mm = sc.spot > 0 ? 0.15 : 0.01;
      const auto acq = workcell::AcquireRailData(d1, d2, SetupOf(twin), a1, a2, ao);
      if (!acq.ok()) {
        fmt::print("  rail {} trial {}: FAILED {}\n", sc.name, k, acq.status().ToString());
        continue;
      }
      calib::RailCalibrationOptions co;
      co.noise = sc.model;
      const auto r = calib::CalibrateRail(acq->readings, a1, a2, co);
      if (!r.ok()) {
        fmt::print("  rail {} trial {}: FAILED {}\n", sc.name, k, r.status().ToString());
        continue;
      }
      calib::RailNoiseModel bn;
      bn.spot_sigma_mm = std::max(sc.spot, 1e-6);
      bn.rail_sigma_mm = sc.rail;
      const auto b = calib::RailCovarianceAt(acq->readings, a1, a2, twin.true_psi(), bn);
      if (!b.ok()) continue;
      Eigen::Vector4d e, bs, s;
      for (int i = 0; i < 4; ++i) {
        e(i) = ToFileUnits(specs[static_cast<std::size_t>(i)].unit, r->psi.value(static_cast<std::size_t>(i)) - twin.true_psi()[static_cast<std::size_t>(i)]);
        bs(i) = ToFileUnits(specs[static_cast<std::size_t>(i)].unit, std::sqrt((*b)(i, i)));
        s(i) = r->psi.file_stddev(static_cast<std::size_t>(i));
      }
      err.push_back(e);
      bound.push_back(bs);
      sd.push_back(s);
      cond.push_back(r->identifiability.condition_number);
      cond_one.push_back(acq->condition_number_one_wall);
      ms.push_back(r->summary.time_ms);
    }
    if (err.size() < 2) continue;
    fmt::print("\n=== rail calibration (true arm models), {} data: {} trials, {} readings each ===\n", sc.name, err.size(), readings);
    fmt::print("{:<14} {:>11} {:>11} {:>11} {:>8} {:>11} {:>8}\n", "parameter", "max|err|", "MC std", "bound", "rms/bnd", "solver sd", "sd/MC");
    for (int i = 0; i < 4; ++i) {
      std::vector<double> e, b, s;
      for (std::size_t k = 0; k < err.size(); ++k) {
        e.push_back(err[k](i));
        b.push_back(bound[k](i));
        s.push_back(sd[k](i));
      }
      double mx = 0;
      for (double x : e) mx = std::max(mx, std::abs(x));
      fmt::print("{:<14} {:>11.3e} {:>11.3e} {:>11.3e} {:>8.2f} {:>11.3e} {:>8.2f}\n", specs[static_cast<std::size_t>(i)].Key(), mx,
                 Std(e), Rms(b), Rms(e) / Rms(b), Rms(s), Rms(s) / Std(e));
    }
    double mc = 0, mo = 0, mm = 0;
    for (std::size_t k = 0; k < cond.size(); ++k) {
      mc += cond[k];
      mo += cond_one[k];
      mm += ms[k];
    }
    const double nk = static_cast<double>(cond.size());
    fmt::print("condition number (scaled Jacobian) mean {:.3g}; predicted info-matrix condition number with points on one wall "
               "only {:.3g}; solve time mean {:.1f} ms\n",
               mc / nk, mo / nk, mm / nk);
  }
}

// Realistic: both arms calibrated (chapter 4) in the twin, then the rail separately and together.
void JointStudy(int trials, int robot_readings, int rail_readings) {
  const Scenario sc = RobotScenarios()[2];
  const std::vector<ParamSpec> specs = RobotToRobotParamSpecs();
  std::vector<Eigen::Vector4d> e_sep, e_joint, e_true_arms;
  std::vector<double> arm_err_sep, arm_err_joint;
  for (int k = 0; k < trials; ++k) {
    sim::WorkcellTwinOptions to;
    to.seed = 9000u + static_cast<unsigned>(k);
    sim::WorkcellTwin twin(to);
    std::array<calib::RobotCalibrationResult, 2> rr;
    std::array<calib::RobotCalibrationData, 2> rd;
    bool ok = true;
    for (int a = 0; a < 2 && ok; ++a) {
      const auto t = RunRobotTrial(sc, to.seed + static_cast<unsigned>(a), robot_readings, &rr[static_cast<std::size_t>(a)],
                                   &rd[static_cast<std::size_t>(a)], &twin, a);
      ok = t.ok();
      if (!ok) fmt::print("  joint trial {}: robot {} FAILED {}\n", k, a + 1, t.status().ToString());
    }
    if (!ok) continue;
    std::array<calib::ArmModel, 2> cal;
    for (std::size_t a = 0; a < 2; ++a) {
      cal[a].robot = rr[a].robot;
      cal[a].laser = rr[a].laser;
      cal[a].rail = rr[a].rail;
    }
    ArmDevices d1{&twin.arm(0), &twin.rail(0), &twin.laser(0), [&twin](int w) { return twin.ObserveSpot(0, w); }};
    ArmDevices d2{&twin.arm(1), &twin.rail(1), &twin.laser(1), [&twin](int w) { return twin.ObserveSpot(1, w); }};
    workcell::RailAcquisitionOptions ao;
    ao.readings = rail_readings;
    ao.seed = to.seed;
    const auto acq = workcell::AcquireRailData(d1, d2, SetupOf(twin), cal[0], cal[1], ao);
    if (!acq.ok()) continue;
    const auto sep = calib::CalibrateRail(acq->readings, cal[0], cal[1], {});
    if (!sep.ok()) continue;
    const auto joint = calib::CalibrateArmsAndRail(rd[0], rd[1], acq->readings, rr[0], rr[1], *sep, sc.model, {});
    if (!joint.ok()) {
      fmt::print("  joint trial {}: joint solve FAILED {}\n", k, joint.status().ToString());
      continue;
    }
    calib::ArmModel t1, t2;
    t1.robot = twin.true_robot(0), t1.laser = twin.true_laser(0), t1.rail = twin.true_rail(0);
    t2.robot = twin.true_robot(1), t2.laser = twin.true_laser(1), t2.rail = twin.true_rail(1);
    const auto with_true = calib::CalibrateRail(acq->readings, t1, t2, {});
    Eigen::Vector4d es, ej, et;
    for (int i = 0; i < 4; ++i) {
      const auto u = specs[static_cast<std::size_t>(i)].unit;
      const double truth = twin.true_psi()[static_cast<std::size_t>(i)];
      es(i) = ToFileUnits(u, sep->psi.value(static_cast<std::size_t>(i)) - truth);
      ej(i) = ToFileUnits(u, joint->psi.value(static_cast<std::size_t>(i)) - truth);
      et(i) = with_true.ok() ? ToFileUnits(u, with_true->psi.value(static_cast<std::size_t>(i)) - truth) : 0.0;
    }
    e_sep.push_back(es);
    e_joint.push_back(ej);
    e_true_arms.push_back(et);
    // Arm 1 theta_y and a3 errors, separate vs joint.
    arm_err_sep.push_back(RadToDeg(rr[0].laser.value(kLaserThetaY) - twin.true_laser(0).value(kLaserThetaY)));
    arm_err_joint.push_back(RadToDeg(joint->arm1.laser.value(kLaserThetaY) - twin.true_laser(0).value(kLaserThetaY)));
  }
  if (e_sep.size() < 2) return;
  fmt::print("\n=== rail with chapter-4-calibrated arms, realistic data: {} trials ({} + {} robot readings, {} rail readings) ===\n",
             e_sep.size(), robot_readings, robot_readings, rail_readings);
  fmt::print("{:<14} {:>14} {:>14} {:>14}\n", "RMS error", "separate", "arms+rail", "true arms");
  for (int i = 0; i < 4; ++i) {
    std::vector<double> a, b, c;
    for (std::size_t k = 0; k < e_sep.size(); ++k) {
      a.push_back(e_sep[k](i));
      b.push_back(e_joint[k](i));
      c.push_back(e_true_arms[k](i));
    }
    fmt::print("{:<14} {:>14.4e} {:>14.4e} {:>14.4e}\n", specs[static_cast<std::size_t>(i)].Key(), Rms(a), Rms(b), Rms(c));
  }
  fmt::print("{:<14} {:>14.4e} {:>14.4e}\n", "arm1 theta_y", Rms(arm_err_sep), Rms(arm_err_joint));
}

}  // namespace
}  // namespace idi

int main(int argc, char** argv) {
  spdlog::set_level(spdlog::level::warn);
  const std::string first = argc > 1 ? argv[1] : "";
  const std::string what = argc > 2 ? argv[2] : "all";
  const bool help = first == "--help" || first == "-h";
  const bool bad_number = (argc > 1 && std::atoi(argv[1]) < 1) || (argc > 3 && std::atoi(argv[3]) < 1);
  const bool bad_what = what != "robot" && what != "rail" && what != "joint" && what != "all";
  if (help || bad_number || bad_what || argc > 4) {
    if (!help) std::fprintf(stderr, "calib_bench_mc: bad arguments\n");
    std::fprintf(help ? stdout : stderr,
                 "usage: calib_bench_mc [TRIALS=20] [robot|rail|joint|all] [READINGS=540]\n"
                 "  Monte Carlo study of the ViCKi calibrations in the twin: the robot (chapter 4) at three\n"
                 "  data qualities against the Cramer-Rao bound, the rail (chapter 5), and both solved\n"
                 "  together (joint). TRIALS below 2 is raised to 2, READINGS per robot trial below 140 to 140.\n");
    return help ? 0 : 2;
  }
  const int trials = argc > 1 ? std::max(2, std::atoi(argv[1])) : 20;
  const int readings = argc > 3 ? std::max(140, std::atoi(argv[3])) : 540;
  const auto t0 = std::chrono::steady_clock::now();
  if (what == "robot" || what == "all") idi::RobotStudy(trials, readings);
  if (what == "rail" || what == "all") idi::RailStudy(trials, 500);
  if (what == "joint" || what == "all") idi::JointStudy(std::max(2, trials / 2), readings, 500);
  fmt::print("\ntotal {:.1f} s\n", std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  return 0;
}
