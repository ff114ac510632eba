#include "workcell/app/calibrate_command.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <tuple>

#include "shared/calib/evaluation.h"
#include "shared/plot/plot.h"
#include "shared/sim/workcell/workcell_twin.h"
#include "shared/util/atomic_file.h"
#include "workcell/procedures/calibration_files.h"
#include "workcell/procedures/calibration_procedures.h"

namespace idi::workcell {
namespace {

// Where the readings of an acquisition that ended early go: FILE.partial.csv beside `file` (the
// observations file, or else the result file), FILE.partial-2.csv etc. when an earlier stopped run
// left one there (it is never replaced).
std::string PartialPath(const std::string& file) {
  const std::filesystem::path p(file);
  std::filesystem::path candidate = p.parent_path() / (p.stem().string() + ".partial.csv");
  std::error_code ec;  // a folder that cannot be read: the write below fails and says so
  for (int k = 2; std::filesystem::exists(candidate, ec); ++k) {
    candidate = p.parent_path() / fmt::format("{}.partial-{}.csv", p.stem().string(), k);
  }
  return candidate.string();
}

// What SavePartial did: `note` is for the failure's message (where the readings are, or why they could
// not be saved; empty when there were none), `saved` whether a file now holds them.
struct PartialSave {
  std::string note;
  bool saved = false;
};

// `what`'s readings (n of them) written by `write` to PartialPath(beside).
PartialSave SavePartial(const char* what,
                        std::size_t n,
                        const std::string& beside,
                        const std::function<Status(const std::string&)>& write) {
  if (n == 0) return {};
  const std::string path = PartialPath(beside);
  const Status saved = write(path);
  if (!saved.ok()) return {fmt::format("; the {} {} measured could not be saved: {}", n, what, saved.message()), false};
  spdlog::warn("the {} {} measured before the acquisition ended are saved in {}", n, what, path);
  return {fmt::format("; the {} {} measured are saved in {}", n, what, path), true};
}

// AcquireRobotData; when it ends early, the readings it measured are saved beside the observations file
// (or `out`), the held-out ones beside the validation file (if one is named), and its error says where.
Result<RobotAcquisition> AcquireRobotKeepingPartial(ArmDevices& dev,
                                                    int arm,
                                                    const CellSetup& setup,
                                                    RobotAcquisitionOptions ao,
                                                    const std::string& observations,
                                                    const std::string& validate,
                                                    const std::string& out) {
  RobotAcquisition partial;
  ao.partial = &partial;
  auto acq = AcquireRobotData(dev, arm, setup, calib::ArmModel{}, ao);
  if (acq.ok()) return acq;
  const std::vector<calib::AimReading>& r = partial.data.readings;
  const PartialSave main =
      SavePartial("readings", r.size(), observations.empty() ? out : observations, [&](const std::string& path) {
        return WriteRobotObservations(path, r);
      });
  std::string note = main.note;
  // What a calibration from that file needs to be told (both sets are needed at all).
  if (main.saved && r.front().set == 1 && r.back().set == 2) {
    const bool translate = ao.method == calib::TranslationMethod::kTranslate;
    const double d = translate ? partial.rail_readings_mm[1] - partial.rail_readings_mm[0] : ao.distance_mm;
    note += fmt::format(
        " (calibrate from it with --method {} --distance-mm {:.3f})", translate ? "translate" : "two-points", d);
  }
  if (!validate.empty()) {
    std::vector<calib::AimReading> held;
    for (const Joints& q : partial.held_out) held.push_back({1, q, 0});
    note += SavePartial("held-out readings", held.size(), validate, [&](const std::string& path) {
              return WriteRobotObservations(path, held);
            }).note;
  }
  return Status(acq.status().code(), acq.status().message() + note);
}

// AcquireRailData; when it ends early, the readings it took are saved beside the observations file (or
// `out`), and its error says where.
Result<RailAcquisition> AcquireRailKeepingPartial(ArmDevices& d1,
                                                  ArmDevices& d2,
                                                  const CellSetup& setup,
                                                  const calib::ArmModel& arm1,
                                                  const calib::ArmModel& arm2,
                                                  RailAcquisitionOptions ao,
                                                  const std::string& observations,
                                                  const std::string& out) {
  RailAcquisition partial;
  ao.partial = &partial;
  auto acq = AcquireRailData(d1, d2, setup, arm1, arm2, ao);
  if (acq.ok()) return acq;
  const std::string note =
      SavePartial("readings",
                  partial.readings.size(),
                  observations.empty() ? out : observations,
                  [&](const std::string& path) { return WriteRailObservations(path, partial.readings); })
          .note;
  return Status(acq.status().code(), acq.status().message() + note);
}

nlohmann::json SpreadJson(const calib::SpreadStats& s) {
  return {{"max_mm", s.max_mm}, {"mean_mm", s.mean_mm}, {"std_mm", s.std_mm}, {"lines", s.projected.size()}};
}

CellSetup SetupFromTwin(const sim::WorkcellTwin& twin) {
  CellSetup s;
  const sim::WorkcellSetup ts = twin.Setup();
  for (const sim::Wall& w : ts.walls) {
    s.wall_names.push_back(w.name);
    s.world_from_wall.push_back(w.world_from_wall);
  }
  s.psi = ts.psi;
  return s;
}

ArmDevices DevicesFromTwin(sim::WorkcellTwin& twin, int k) {
  ArmDevices d;
  d.arm = &twin.arm(k);
  d.rail = &twin.rail(k);
  d.laser = &twin.laser(k);
  d.observe = [&twin, k](int wall) { return twin.ObserveSpot(k, wall); };
  return d;
}

// The largest noise std (mm) the command line may give. The spots, rail moves and distances it describes
// are a metre or two across, so a std of a metre is already no noise model: beyond it is a unit slip (µm
// or m for mm), and one near the largest double overflows the solve's residuals into NaN.
constexpr double kMaxSigmaMm = 1000.0;

// A noise level from the command line: finite, >= 0 (the twin's constructor refuses others by
// aborting, and the calibration's weights would be meaningless) and at most kMaxSigmaMm.
Status CheckSigma(double v, const char* option) {
  if (!(std::isfinite(v) && v >= 0)) {
    return InvalidArgument(fmt::format("{} must be a finite number >= 0, got {}", option, v));
  }
  if (v > kMaxSigmaMm) {
    return OutOfRange(fmt::format("{}: {} mm is out of range (a noise std is at most {} mm)", option, v, kMaxSigmaMm));
  }
  return Status::Ok();
}

sim::WorkcellTwinOptions TwinOptions(unsigned seed, double spot_sigma_mm) {
  sim::WorkcellTwinOptions o;
  o.seed = seed;
  o.spot_sigma_mm = spot_sigma_mm;
  return o;
}

Status SavePlots(const std::string& dir,
                 const std::string& prefix,
                 const std::vector<double>& cost,
                 const std::vector<int>& solve_starts,
                 const std::vector<std::string>& solve_labels,
                 const std::vector<std::pair<std::string, calib::SpreadStats>>& spreads) {
  if (dir.empty()) return Status::Ok();
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) return IoError(dir + ": cannot create the plot folder: " + ec.message());
  plot::Figure cf;
  cf.SetTitle(prefix + ": cost per iteration (Fig. 4.9)");
  cf.x_axis().label = "iteration";
  cf.y_axis().label = "cost";
  cf.y_axis().log = true;
  // One series per solve, labelled by the calibration (which start, and which solve of it: the robust
  // (Cauchy) one, the least-squares rounds that leave outliers out, the final fit of the readings kept).
  std::vector<int> starts = solve_starts.empty() ? std::vector<int>{0} : solve_starts;
  starts.push_back(static_cast<int>(cost.size()));
  const std::array<plot::Color, 4> cost_colors = {plot::kBlue, plot::kOrange, plot::kGreen, plot::kPurple};
  for (std::size_t k = 0; k + 1 < starts.size(); ++k) {
    std::vector<double> x, y;
    for (int i = starts[k]; i < starts[k + 1]; ++i) {
      x.push_back(static_cast<double>(i));
      y.push_back(std::max(cost[static_cast<std::size_t>(i)], 1e-300));
    }
    if (x.empty()) continue;
    const std::string label = solve_starts.empty()      ? "1/2 sum of whitened residuals^2"
                              : k < solve_labels.size() ? solve_labels[k]
                                                        : fmt::format("solve {}", k + 1);
    cf.AddLine(x, y, label, cost_colors[k % cost_colors.size()], plot::Marker::kCircle);
  }
  IDI_RETURN_IF_ERROR(cf.SavePng(dir + "/" + prefix + "_cost.png"));
  if (spreads.empty()) return Status::Ok();
  plot::Figure sf;
  sf.SetTitle(prefix + ": held-out laser lines on the plane through their closest point (Fig. 4.10)");
  sf.x_axis().label = "mm";
  sf.y_axis().label = "mm";
  sf.SetEqualAspect(true);
  const std::array<plot::Color, 3> spread_colors = {plot::kRed, plot::kBlue, plot::kGreen};
  for (std::size_t k = 0; k < spreads.size(); ++k) {
    std::vector<double> px, py;
    for (const Vec2d& p : spreads[k].second.projected) {
      px.push_back(p.x());
      py.push_back(p.y());
    }
    sf.AddScatter(px, py, fmt::format("{} (mean {:.3f} mm)", spreads[k].first, spreads[k].second.mean_mm),
                  spread_colors[k % spread_colors.size()], k == 0 ? plot::Marker::kCross : plot::Marker::kCircle);
  }
  return sf.SavePng(dir + "/" + prefix + "_spread.png");
}

// What the uncertainty of the known distance D does to each parameter (§4.4.3). D is the model's only
// scale: an error of D stretches every length in proportion to its size (on the RX-130 the long links
// a3 and d4, and the point), while the angles do not move.
// Per parameter: the std that D's uncertainty alone gives, and its share of the reported variance.
struct ScaleShare {
  std::string name, unit;
  double std_from_distance = 0, std_total = 0, share = 0;
};
std::vector<ScaleShare> ScaleShares(const calib::RobotCalibrationResult& r, double distance_sigma_mm) {
  std::vector<ScaleShare> out;
  if (r.distance_sensitivity.size() != static_cast<Eigen::Index>(r.params.size())) return out;
  for (std::size_t i = 0; i < r.params.size(); ++i) {
    ScaleShare s;
    s.name = r.params.spec(i).Key();
    s.unit = std::string(UnitSuffix(r.params.spec(i).unit));
    s.std_from_distance = std::abs(ToFileUnits(r.params.spec(i).unit, r.distance_sensitivity(static_cast<Eigen::Index>(i)))) *
                          distance_sigma_mm;
    s.std_total = r.params.file_stddev(i);
    s.share = std::isfinite(s.std_total) && s.std_total > 0 ? std::min(1.0, std::pow(s.std_from_distance / s.std_total, 2)) : 0.0;
    out.push_back(s);
  }
  return out;
}

nlohmann::json RobotReport(const calib::RobotCalibrationResult& r, const calib::RobotCalibrationData& data,
                           double distance_sigma_mm) {
  const std::vector<ParamSpec> specs = calib::RobotCalibrationSpecs();
  std::vector<std::string> names;
  for (const ParamSpec& s : specs) names.push_back(s.Key());
  nlohmann::json j;
  j["method"] = calib::MethodName(data.method);
  j["distance_mm"] = data.distance_mm;
  j["readings"] = data.readings.size();
  j["readings_used"] = r.residuals.readings;
  j["start"] = r.start;
  j["restarts"] = r.restarts;
  j["solver"] = {{"termination", r.summary.termination}, {"iterations", r.summary.iterations},
                 {"initial_cost", r.summary.initial_cost}, {"final_cost", r.summary.final_cost},
                 {"time_ms", r.summary.time_ms}};
  j["cost_per_iteration"] = r.cost_per_iteration;
  j["solve_starts"] = r.solve_starts;
  j["solve_labels"] = r.solve_labels;
  j["residuals"] = {{"rms_miss_mm", r.residuals.rms_miss_mm}, {"median_miss_mm", r.residuals.median_miss_mm},
                    {"max_miss_mm", r.residuals.max_miss_mm}, {"rms_normalized", r.residuals.rms_normalized},
                    {"variance_factor", r.residuals.variance_factor}};
  nlohmann::json out = nlohmann::json::array();
  for (const calib::OutlierReading& o : r.outliers) {
    out.push_back({{"reading", o.index}, {"line", o.row}, {"set", o.set}, {"miss_mm", o.miss_mm}, {"sigmas", o.sigmas}});
  }
  j["outliers"] = out;
  nlohmann::json corr = nlohmann::json::array();
  for (const optim::CorrelatedPair& p : r.identifiability.correlated) {
    corr.push_back({{"a", names[static_cast<std::size_t>(p.i)]}, {"b", names[static_cast<std::size_t>(p.j)]}, {"correlation", p.correlation}});
  }
  nlohmann::json undetermined = nlohmann::json::array();
  for (int i : r.identifiability.undetermined) undetermined.push_back(names[static_cast<std::size_t>(i)]);
  std::vector<double> sv(r.identifiability.singular_values.data(),
                         r.identifiability.singular_values.data() + r.identifiability.singular_values.size());
  j["identifiability"] = {{"singular_values_scaled", sv},
                          {"condition_number", r.identifiability.condition_number},
                          {"condition_number_unscaled", r.identifiability.condition_number_unscaled},
                          {"rank", r.identifiability.rank},
                          {"undetermined", undetermined},
                          {"correlated_above_0_95", corr}};
  j["params"] = ParamsJson(r.params);
  nlohmann::json scale = nlohmann::json::array();
  for (const ScaleShare& sh : ScaleShares(r, distance_sigma_mm)) {
    scale.push_back({{"param", sh.name}, {"unit", sh.unit}, {"std_from_distance", sh.std_from_distance},
                     {"std_total", sh.std_total}, {"share_of_variance", sh.share}});
  }
  j["scale_from_distance"] = {
      {"distance_sigma_mm", distance_sigma_mm},
      {"note", "D, the known distance (two rail moves), is the model's only scale: its uncertainty stretches every "
               "length in proportion to its size (the long links and the point) and leaves the angles alone"},
      {"params", scale}};
  return j;
}

}  // namespace

// The outputs of a calibration are checked before its acquisition and solve (minutes), not after.
Status CheckOutputs(const std::vector<std::pair<std::string, std::string>>& files,
                    const std::string& plots,
                    const std::string& command) {
  for (const auto& [path, option] : files) IDI_RETURN_IF_ERROR(CheckOutputFile(path, command + ": " + option));
  return CheckOutputFolder(plots, command + ": --plots");
}

Status RunCalibrateRobot(const RobotCommandOptions& o) {
  IDI_RETURN_IF_ERROR(CheckOutputs({{o.out, "--out"},
                                    {o.report, "--report"},
                                    {o.sim ? o.observations : "", "--observations"},
                                    {o.sim ? o.validate : "", "--validate"}},
                                   o.plots,
                                   "calibrate robot"));
  // With --sim the observations and validation files are outputs too.
  IDI_RETURN_IF_ERROR(
      CheckDistinctFiles({{"--observations", o.sim ? "" : o.observations}, {"--validate", o.sim ? "" : o.validate}},
                         {{"--out", o.out},
                          {"--report", o.report},
                          {"--observations", o.sim ? o.observations : ""},
                          {"--validate", o.sim ? o.validate : ""}},
                         "calibrate robot"));
  IDI_RETURN_IF_ERROR(CheckSigma(o.spot_sigma_mm, "calibrate robot: --spot-sigma-mm"));
  IDI_RETURN_IF_ERROR(CheckSigma(o.distance_sigma_mm, "calibrate robot: --distance-sigma-mm"));
  // 0 (not given): the twin's 1000 mm, or an error below for observations.
  if (o.distance_mm != 0 && !(std::isfinite(o.distance_mm) && o.distance_mm > 0)) {
    return InvalidArgument(
        fmt::format("calibrate robot: --distance-mm must be a positive distance, got {}", o.distance_mm));
  }
  IDI_ASSIGN_OR_RETURN(const calib::TranslationMethod method, calib::ParseMethod(o.method));
  calib::RobotCalibrationData data;
  std::vector<std::vector<Joints>> held_out;  // per set of the validation file
  calib::RobotCalibrationOptions co;
  co.noise.spot_sigma_mm = o.spot_sigma_mm;
  co.noise.distance_sigma_mm = o.distance_sigma_mm;
  std::unique_ptr<sim::WorkcellTwin> twin;
  nlohmann::json report;
  const int arm = o.arm - 1;
  if (o.sim) {
    twin = std::make_unique<sim::WorkcellTwin>(TwinOptions(o.seed, o.spot_sigma_mm));
    ArmDevices dev = DevicesFromTwin(*twin, arm);
    RobotAcquisitionOptions ao;
    ao.method = method;
    ao.distance_mm = o.distance_mm > 0 ? o.distance_mm : 1000.0;
    ao.per_set = o.readings / 2;
    ao.seed = o.seed;
    ao.cancelled = o.cancelled;
    spdlog::info("digital twin (seed {}): calibrating robot {} by the {} method, {} readings", o.seed, o.arm, o.method,
                 2 * ao.per_set);
    IDI_ASSIGN_OR_RETURN(
        const RobotAcquisition acq,
        AcquireRobotKeepingPartial(dev, arm, SetupFromTwin(*twin), ao, o.observations, o.validate, o.out));
    data = acq.data;
    held_out.push_back(acq.held_out);
    co.noise.plane_normal = acq.plane_normal_in_base;
    report["acquisition"] = {{"condition_number", acq.selection.condition_number},
                             {"condition_number_without_selection", acq.selection.condition_number_first},
                             {"mean_loop_iterations", acq.mean_loop_iterations},
                             {"loop_failures", acq.loop_failures},
                             {"held_out", acq.held_out.size()},
                             {"simulated_time_s", hal::NsToSec(twin->clock().NowNs())}};
    if (!o.observations.empty()) IDI_RETURN_IF_ERROR(WriteRobotObservations(o.observations, data.readings));
    if (!o.validate.empty()) {
      std::vector<calib::AimReading> v;
      for (const Joints& q : acq.held_out) v.push_back({1, q, 0});
      IDI_RETURN_IF_ERROR(WriteRobotObservations(o.validate, v));
    }
  } else {
    if (o.observations.empty()) return InvalidArgument("calibrate robot: --observations FILE.csv is required (or --sim)");
    if (!(o.distance_mm > 0)) return InvalidArgument("calibrate robot: --distance-mm must be a positive distance");
    IDI_ASSIGN_OR_RETURN(data.readings, ReadRobotObservations(o.observations));
    data.distance_mm = o.distance_mm;
    data.method = method;
    if (!o.validate.empty()) {
      IDI_ASSIGN_OR_RETURN(const std::vector<calib::AimReading> v, ReadRobotObservations(o.validate));
      std::map<int, std::vector<Joints>> by_set;
      for (const calib::AimReading& r : v) by_set[r.set].push_back(r.q);
      for (auto& [set, q] : by_set) held_out.push_back(q);
    }
  }
  auto calibrated = calib::CalibrateRobot(data, co);
  // Readings too few or too alike: say which file they came from.
  if (!calibrated.ok()) return o.sim ? calibrated.status() : calibrated.status().WithContext(o.observations);
  const calib::RobotCalibrationResult& r = *calibrated;
  spdlog::info("{}", r.Summary());
  for (const calib::OutlierReading& out : r.outliers) {
    spdlog::warn("outlier left out: reading {} (set {}{}) misses the point by {:.3f} mm ({:.1f} sigma)", out.index + 1,
                 out.set, out.row > 0 ? fmt::format(", line {}", out.row) : "", out.miss_mm, out.sigmas);
  }
  if (!r.identifiability.correlated.empty()) {
    std::vector<std::string> names;
    for (const ParamSpec& s : calib::RobotCalibrationSpecs()) names.push_back(s.Key());
    spdlog::info("parameters correlated above 0.95: {}", optim::DescribeCorrelations(r.identifiability, names));
  }
  IDI_RETURN_IF_ERROR(WriteRobotCalibration(o.out, r, data, o.sim ? std::optional<unsigned>(o.seed) : std::nullopt));
  spdlog::info("wrote {}", o.out);

  const nlohmann::json acquisition = report.contains("acquisition") ? report["acquisition"] : nlohmann::json();
  report = RobotReport(r, data, co.noise.distance_sigma_mm);
  {
    std::string dominated;
    for (const ScaleShare& sh : ScaleShares(r, co.noise.distance_sigma_mm)) {
      if (sh.unit == "mm" && sh.share >= 0.5) {
        dominated += fmt::format("{}{} ({:.0f} %)", dominated.empty() ? "" : ", ", sh.name, 100 * sh.share);
      }
    }
    if (!dominated.empty()) {
      spdlog::info("the known distance D (std {:.3f} mm, the model's only scale) sets most of the uncertainty of: {}",
                   co.noise.distance_sigma_mm, dominated);
    }
  }
  if (!acquisition.is_null()) report["acquisition"] = acquisition;
  std::vector<std::pair<std::string, calib::SpreadStats>> spreads;
  nlohmann::json validation = nlohmann::json::array();
  for (const std::vector<Joints>& q : held_out) {
    const calib::ArmModel nominal;
    auto s_nominal = calib::LaserSpread(calib::LaserLines(nominal.robot, nominal.laser, q));
    auto s_cal = calib::LaserSpread(calib::LaserLines(r.robot, r.laser, q));
    if (!s_nominal.ok() || !s_cal.ok()) {
      spdlog::warn("validation: {}", (s_nominal.ok() ? s_cal : s_nominal).status().message());
      continue;
    }
    nlohmann::json v = {{"readings", q.size()}, {"nominal", SpreadJson(*s_nominal)}, {"calibrated", SpreadJson(*s_cal)}};
    spdlog::info("held-out spread radius (§4.5.4): nominal max/mean/std {:.3f}/{:.3f}/{:.3f} mm, calibrated {:.3f}/{:.3f}/{:.3f} mm",
                 s_nominal->max_mm, s_nominal->mean_mm, s_nominal->std_mm, s_cal->max_mm, s_cal->mean_mm, s_cal->std_mm);
    if (spreads.empty()) {
      spreads.emplace_back("nominal", *s_nominal);
      spreads.emplace_back("calibrated", *s_cal);
    }
    if (twin) {
      const auto s_true = calib::LaserSpread(calib::LaserLines(twin->true_robot(arm), twin->true_laser(arm), q));
      if (s_true.ok()) v["twin_truth"] = SpreadJson(*s_true);
    }
    validation.push_back(v);
  }
  report["validation"] = validation;
  if (twin) {
    // The twin's truth, for the report only: the calibration never saw it.
    const ParamSet truth = calib::PackRobotCalibration(twin->true_robot(arm), twin->true_laser(arm), r.point_mm, twin->true_rail(arm));
    nlohmann::json errors;
    for (std::size_t i = 0; i < kRx130ParamCount + kLaserParamCount; ++i) {
      errors[truth.spec(i).Key()] = r.params.file_value(i) - truth.file_value(i);
    }
    errors["phi_l_deg"] = RadToDeg(r.rail.value(kPhiL) - twin->true_rail(arm).value(kPhiL));
    errors["phi_m_deg"] = RadToDeg(r.rail.value(kPhiM) - twin->true_rail(arm).value(kPhiM));
    report["twin_truth_errors"] = errors;
  }
  if (!o.report.empty()) {
    IDI_RETURN_IF_ERROR(WriteJson(o.report, report));
    spdlog::info("wrote {}", o.report);
  }
  return SavePlots(
      o.plots, fmt::format("robot{}", o.arm), r.cost_per_iteration, r.solve_starts, r.solve_labels, spreads);
}


namespace {

// Robot k's model for the rail calibration: from its file, or (--sim) calibrated in the twin first
// (readings of an acquisition that ends early saved beside `file`, or else beside `out`, the rail's).
Result<calib::ArmModel> ArmForRtu(const std::string& file,
                                  bool sim,
                                  sim::WorkcellTwin* twin,
                                  int k,
                                  unsigned seed,
                                  double spot_sigma_mm,
                                  const CancelCheck& cancelled,
                                  const std::string& out) {
  if (!file.empty() && (!sim || std::filesystem::exists(file))) {
    if (sim) {
      // The rail is solved with this twin's arms: a file from another twin's (or from the real cell)
      // would give the rail the wrong arm.
      IDI_ASSIGN_OR_RETURN(const std::optional<unsigned> made_in, RobotCalibrationSimSeed(file));
      if (made_in && *made_in != seed) {
        return InvalidArgument(fmt::format(
            "calibrate rtu: robot {}'s calibration {} was made in the twin of seed {}, this run's twin is seed {}: "
            "its arm is not this twin's (calibrate robot {} in this twin first; from the command line, a --robot{} "
            "file name that does not exist yet has --sim do it)",
            k + 1,
            file,
            *made_in,
            seed,
            k + 1,
            k + 1));
      }
      if (!made_in) {
        spdlog::warn(
            "calibrate rtu: --robot{} {} records no twin seed (not made by `calibrate robot --sim`, or by an "
            "older version): the twin of seed {} may have another arm {}",
            k + 1,
            file,
            seed,
            k + 1);
      }
    }
    return LoadRobotCalibration(file);
  }
  if (!sim) return InvalidArgument(fmt::format("calibrate rtu: --robot{} FILE.yaml is required (or --sim)", k + 1));
  ArmDevices dev = DevicesFromTwin(*twin, k);
  RobotAcquisitionOptions ao;
  ao.seed = seed + static_cast<unsigned>(k) * 101u;
  ao.held_out = 0;
  ao.cancelled = cancelled;
  spdlog::info("digital twin: calibrating robot {} first (chapter 4)", k + 1);
  IDI_ASSIGN_OR_RETURN(
      const RobotAcquisition acq,
      AcquireRobotKeepingPartial(
          dev,
          k,
          SetupFromTwin(*twin),
          ao,
          "",
          "",
          file.empty() ? (std::filesystem::path(out).parent_path() / fmt::format("robot{}.yaml", k + 1)).string()
                       : file));
  calib::RobotCalibrationOptions co;
  co.noise.spot_sigma_mm = spot_sigma_mm;
  co.noise.plane_normal = acq.plane_normal_in_base;
  IDI_ASSIGN_OR_RETURN(const calib::RobotCalibrationResult r, calib::CalibrateRobot(acq.data, co));
  spdlog::info("robot {}: {}", k + 1, r.Summary());
  if (!file.empty()) {
    IDI_RETURN_IF_ERROR(WriteRobotCalibration(file, r, acq.data, seed));
    spdlog::info("wrote {}", file);
  }
  return calib::ArmFromRobotCalibration(r);
}

}  // namespace

Status RunCalibrateRtu(const RtuCommandOptions& o) {
  IDI_RETURN_IF_ERROR(
      CheckOutputs({{o.out, "--out"}, {o.report, "--report"}, {o.sim ? o.observations : "", "--observations"}},
                   o.plots,
                   "calibrate rtu"));
  {
    // An arm's file is read, or (--sim, when it does not exist yet) written by calibrating the arm first.
    std::vector<NamedFile> inputs = {{"--observations", o.sim ? "" : o.observations}};
    std::vector<NamedFile> outputs = {
        {"--out", o.out}, {"--report", o.report}, {"--observations", o.sim ? o.observations : ""}};
    for (const NamedFile& arm : {NamedFile{"--robot1", o.robot1}, NamedFile{"--robot2", o.robot2}}) {
      std::error_code ec;
      (o.sim && !arm.path.empty() && !std::filesystem::exists(arm.path, ec) ? outputs : inputs).push_back(arm);
    }
    IDI_RETURN_IF_ERROR(CheckDistinctFiles(inputs, outputs, "calibrate rtu"));
    if (!o.robot1.empty() && !o.robot2.empty() && SameFile(o.robot1, o.robot2)) {
      return InvalidArgument("calibrate rtu: --robot1 " + o.robot1 + " and --robot2 " + o.robot2 +
                             " are the same file: each arm has its own calibration");
    }
  }
  IDI_RETURN_IF_ERROR(CheckSigma(o.spot_sigma_mm, "calibrate rtu: --spot-sigma-mm"));
  IDI_RETURN_IF_ERROR(CheckSigma(o.rail_sigma_mm, "calibrate rtu: --rail-sigma-mm"));
  std::unique_ptr<sim::WorkcellTwin> twin;
  if (o.sim) twin = std::make_unique<sim::WorkcellTwin>(TwinOptions(o.seed, o.spot_sigma_mm));
  IDI_ASSIGN_OR_RETURN(const calib::ArmModel arm1,
                       ArmForRtu(o.robot1, o.sim, twin.get(), 0, o.seed, o.spot_sigma_mm, o.cancelled, o.out));
  IDI_ASSIGN_OR_RETURN(const calib::ArmModel arm2,
                       ArmForRtu(o.robot2, o.sim, twin.get(), 1, o.seed, o.spot_sigma_mm, o.cancelled, o.out));
  std::vector<calib::RailReading> readings, held_out;
  nlohmann::json acquisition;
  if (o.sim) {
    ArmDevices d1 = DevicesFromTwin(*twin, 0), d2 = DevicesFromTwin(*twin, 1);
    const CellSetup setup = SetupFromTwin(*twin);
    RailAcquisitionOptions ao;
    ao.readings = o.readings;
    ao.seed = o.seed;
    ao.cancelled = o.cancelled;
    IDI_ASSIGN_OR_RETURN(const RailAcquisition acq,
                         AcquireRailKeepingPartial(d1, d2, setup, arm1, arm2, ao, o.observations, o.out));
    readings = acq.readings;
    // Saved before the held-out acquisition, which may end early too.
    if (!o.observations.empty()) IDI_RETURN_IF_ERROR(WriteRailObservations(o.observations, readings));
    acquisition = {{"points", acq.points_world.size()},
                   {"point_walls", acq.point_walls},
                   {"condition_number", acq.condition_number},
                   {"condition_number_points_on_one_wall", acq.condition_number_one_wall},
                   {"loop_failures", acq.loop_failures}};
    RailAcquisitionOptions ho;
    ho.readings = 40;
    ho.points = 2;
    ho.walls = {0};
    ho.seed = o.seed + 17u;
    ho.cancelled = o.cancelled;
    const auto held = AcquireRailData(d1, d2, setup, arm1, arm2, ho);
    if (!held.ok()) {
      // The main acquisition is complete: its readings are in the observations file, or saved now.
      const std::string where =
          o.observations.empty()
              ? SavePartial("readings of the complete acquisition",
                            readings.size(),
                            o.out,
                            [&](const std::string& path) { return WriteRailObservations(path, readings); })
                    .note
              : fmt::format("; the {} readings of the complete acquisition are in {}", readings.size(), o.observations);
      return Status(held.status().code(), held.status().message() + " (the held-out readings)" + where);
    }
    // One held-out point: the readings of the first chosen point.
    for (std::size_t i = 0; i < held->readings.size(); i += 2) held_out.push_back(held->readings[i]);
  } else {
    if (o.observations.empty()) return InvalidArgument("calibrate rtu: --observations FILE.csv is required (or --sim)");
    IDI_ASSIGN_OR_RETURN(readings, ReadRailObservations(o.observations));
  }
  for (const auto& [k, arm, file] : {std::tuple{1, &arm1, &o.robot1}, std::tuple{2, &arm2, &o.robot2}}) {
    if (arm->covariance.size() > 0) continue;
    spdlog::warn(
        "rail calibration: robot {}'s calibration {} has no correlation matrix (written by an older version): "
        "psi's std takes both arms as exact and understates psi_x's uncertainty; recalibrate robot {} to "
        "include it",
        k,
        *file,
        k);
  }
  calib::RailCalibrationOptions co;
  co.noise.spot_sigma_mm = o.spot_sigma_mm;
  co.noise.rail_sigma_mm = o.rail_sigma_mm;
  IDI_ASSIGN_OR_RETURN(const calib::RailCalibrationResult r, calib::CalibrateRail(readings, arm1, arm2, co));
  spdlog::info("{}", r.Summary());
  IDI_RETURN_IF_ERROR(WriteRailCalibration(o.out, r));
  spdlog::info("wrote {}", o.out);
  nlohmann::json report;
  report["readings"] = readings.size();
  report["readings_used"] = r.readings_used;
  report["outliers"] = r.outliers;
  report["start"] = r.start;
  report["solver"] = {{"termination", r.summary.termination}, {"iterations", r.summary.iterations}, {"time_ms", r.summary.time_ms}};
  report["cost_per_iteration"] = r.cost_per_iteration;
  report["rms_distance_mm"] = r.rms_distance_mm;
  report["rms_normalized"] = r.rms_normalized;
  report["variance_factor"] = r.variance_factor;
  report["condition_number"] = r.identifiability.condition_number;
  report["params"] = ParamsJson(r.psi);
  report["arms_uncertainty_included"] = r.arms_uncertainty_included;
  {
    nlohmann::json given = nlohmann::json::object();
    for (std::size_t k = 0; k < 4; ++k)
      given[r.psi.spec(k).Key()] = ToFileUnits(r.psi.spec(k).unit, r.std_given_arms[k]);
    report["std_given_arms"] = given;
  }
  if (!acquisition.is_null()) report["acquisition"] = acquisition;
  std::vector<std::pair<std::string, calib::SpreadStats>> spreads;
  if (!held_out.empty()) {
    std::array<double, 4> psi;
    for (std::size_t k = 0; k < 4; ++k) psi[k] = r.psi.value(k);
    const auto s_nom = calib::RailTransferSpread(held_out, arm1, arm2, calib::NominalPsi());
    const auto s_cal = calib::RailTransferSpread(held_out, arm1, arm2, psi);
    if (s_nom.ok() && s_cal.ok()) {
      report["validation"] = {{"nominal", SpreadJson(*s_nom)}, {"calibrated", SpreadJson(*s_cal)}};
      spdlog::info("held-out transfer spread (§5.4.4): nominal psi mean {:.3f} mm, calibrated {:.3f} mm", s_nom->mean_mm,
                   s_cal->mean_mm);
      spreads = {{"nominal psi", *s_nom}, {"calibrated psi", *s_cal}};
    }
  }
  if (twin) {
    nlohmann::json err;
    for (std::size_t k = 0; k < 4; ++k) {
      err[r.psi.spec(k).Key()] = ToFileUnits(r.psi.spec(k).unit, r.psi.value(k) - twin->true_psi()[k]);
    }
    report["twin_truth_errors"] = err;
  }
  if (!o.report.empty()) {
    IDI_RETURN_IF_ERROR(WriteJson(o.report, report));
    spdlog::info("wrote {}", o.report);
  }
  return SavePlots(o.plots, "rtu", r.cost_per_iteration, {}, {}, spreads);
}

void AddCalibrateCommand(CliApp& cli) {
  CLI::App* cal = cli.app.add_subcommand("calibrate", "calibrations: the arms (chapter 4), the rail (chapter 5), the pan-tilt cameras");
  cal->require_subcommand(1);

  auto ro = std::make_shared<RobotCommandOptions>();
  CLI::App* robot = cli.AddCommand(cal, "robot",
                                   "calibrate an RX-130 with its laser tool from joint readings aimed at a fixed point",
                                   [ro] { return RunCalibrateRobot(*ro); });
  robot->add_option("--observations",
                    ro->observations,
                    "CSV 'set,j1_deg,...,j6_deg' (set 1/2: before/after the translation, or first/second point); "
                    "with --sim: where to save the acquired readings (an acquisition that ends early saves what "
                    "it measured in FILE.partial.csv)");
  robot->add_option("--distance-mm", ro->distance_mm, "the known distance D: rail move or spacing of the two points");
  robot->add_option("--method", ro->method, "translate (rail move by D) or two-points (second point D away)")
      ->check(CLI::IsMember({"translate", "two-points"}))
      ->capture_default_str();
  robot->add_option("--out", ro->out, "result YAML (written atomically)")->required();
  robot->add_option("--validate",
                    ro->validate,
                    "held-out readings (same CSV) aimed at one point per set: spread before/after (§4.5.4); "
                    "with --sim: where to save them (FILE.partial.csv if the acquisition ends early)");
  robot->add_option("--report", ro->report, "JSON report");
  robot->add_option("--plots", ro->plots, "folder for PNG plots (cost per iteration, held-out spread)");
  robot
      ->add_option(
          "--spot-sigma-mm", ro->spot_sigma_mm, "spot noise on the wall per axis (noise model; twin camera), [0, 1000]")
      ->capture_default_str();
  robot
      ->add_option("--distance-sigma-mm",
                   ro->distance_sigma_mm,
                   "std of D (translate: two rail moves, sqrt(2) x their repeatability), [0, 1000]")
      ->capture_default_str();
  robot->add_flag("--sim", ro->sim, "run the whole procedure, acquisition included, in the digital twin");
  robot->add_option("--seed", ro->seed, "digital twin seed")->capture_default_str();
  robot->add_option("--arm", ro->arm, "which robot (--sim)")->check(CLI::Range(1, 2))->capture_default_str();
  // The solve needs 5 readings per unknown (§4.3.2), and the two sets are equal: fewer would be
  // refused only after the acquisition.
  const int min_readings =
      2 * ((calib::RobotCalibrationOptions{}.min_readings_per_unknown * calib::kRobotCalibrationUnknowns + 1) / 2);
  robot
      ->add_option(
          "--readings",
          ro->readings,
          fmt::format("readings to acquire (--sim), both sets; at least {} (5 per unknown, §4.3.2)", min_readings))
      ->check(CLI::Range(min_readings, 100000))
      ->capture_default_str();

  auto to = std::make_shared<RtuCommandOptions>();
  CLI::App* rtu = cli.AddCommand(cal, "rtu", "calibrate the robot-to-robot transform on the rail from both lasers on one point",
                                 [to] { return RunCalibrateRtu(*to); });
  rtu->add_option(
      "--observations",
      to->observations,
      "CSV 'r1_j1_deg..r1_j6_deg,r1_rail_mm,r2_j1_deg..r2_j6_deg,r2_rail_mm'; with --sim: where to save them "
      "(FILE.partial.csv if the acquisition ends early)");
  rtu->add_option("--robot1", to->robot1, "robot 1's calibration (calibrate robot output); with --sim: made if missing");
  rtu->add_option("--robot2", to->robot2, "robot 2's calibration; with --sim: made if missing");
  rtu->add_option("--out", to->out, "result YAML (psi_x_mm, psi_y_mm, psi_z_mm, psi_alpha_deg with std)")->required();
  rtu->add_option("--report", to->report, "JSON report");
  rtu->add_option("--plots", to->plots, "folder for PNG plots");
  rtu->add_option("--spot-sigma-mm", to->spot_sigma_mm, "spot noise per axis, [0, 1000]")->capture_default_str();
  rtu->add_option("--rail-sigma-mm", to->rail_sigma_mm, "rail repeatability (std), [0, 1000]")->capture_default_str();
  rtu->add_flag("--sim", to->sim, "run the whole procedure in the digital twin");
  rtu->add_option("--seed", to->seed, "digital twin seed")->capture_default_str();
  rtu->add_option("--readings", to->readings, "readings to acquire (--sim)")->check(CLI::Range(20, 100000))->capture_default_str();
}

}  // namespace idi::workcell
