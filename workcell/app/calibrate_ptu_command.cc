#include "workcell/app/calibrate_ptu_command.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <filesystem>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>

#include "shared/util/atomic_file.h"
#include "workcell/procedures/calibration_files.h"
#include "workcell/procedures/ptu_files.h"
#include "workcell/procedures/ptu_procedure.h"
#include "workcell/procedures/ptu_twin.h"

namespace idi::workcell {
namespace {

// Scores a twin run against its truth (for reports only).
nlohmann::json PtuTwinTruthJson(PtuTwin& twin, const calib::PtuCalibrationResult& r) {
  nlohmann::json j;
  const auto point = twin.true_point_in_base();
  if (point) {
    j["point_mm"] = {point->x(), point->y(), point->z()};
    j["point_error_mm"] = (r.point_mm - *point).norm();
  }
  nlohmann::json cams = nlohmann::json::array();
  for (const auto& c : r.cameras) {
    const calib::PtuCameraModel& t = twin.true_camera(c.side);
    nlohmann::json errs;
    double worst = 0;
    for (std::size_t k = 0; k < kPtuParamCount + 4; ++k) {
      const bool ptu = k < kPtuParamCount;
      const ParamSet& est = ptu ? c.model.ptu : c.model.intrinsics;
      const ParamSet& tru = ptu ? t.ptu : t.intrinsics;
      const std::size_t i = ptu ? k : k - kPtuParamCount;
      const double err = est.file_value(i) - tru.file_value(i);
      const double sd = est.file_stddev(i);
      errs[est.spec(i).Key()] = {{"error", err}, {"sigmas", err / sd}};
      if (std::isfinite(sd)) worst = std::max(worst, std::abs(err / sd));
    }
    cams.push_back({{"camera", BiclopsSideName(c.side)}, {"errors", errs}, {"max_sigmas", worst}});
  }
  j["cameras"] = cams;
  return j;
}

Status WritePtuOutputs(const CalibratePtuOptions& o, const calib::PtuCalibrationResult& r,
                       const calib::PtuValidation* v, nlohmann::json report) {
  IDI_RETURN_IF_ERROR(WritePtuCalibration(o.out, r, v));
  if (!o.plots.empty()) IDI_RETURN_IF_ERROR(SavePtuResidualHistograms(o.plots, r, v));
  if (!o.report.empty()) IDI_RETURN_IF_ERROR(WriteJson(o.report, report));
  if (o.json) std::cout << report.dump() << "\n";
  spdlog::info("PTU calibration written to {}", o.out);
  return Status::Ok();
}

Status RunFromFiles(const CalibratePtuOptions& o) {
  if (o.observations.empty()) return InvalidArgument("calibrate ptu: --observations is required (or --sim)");
  IDI_ASSIGN_OR_RETURN(const std::vector<calib::PtuObservation> obs, ReadPtuObservations(o.observations));
  std::vector<calib::PtuCameraModel> start;
  if (!o.start.empty()) {
    IDI_ASSIGN_OR_RETURN(start, LoadPtuCalibration(o.start));
  }
  calib::PtuCalibrationOptions co;
  co.estimate_distortion = o.distortion;
  co.robust_scale_px = o.robust_scale_px;
  co.source = o.observations;
  // Everything is read and checked before anything is written.
  std::vector<calib::PtuObservation> held_out;
  if (!o.validate.empty()) {
    IDI_ASSIGN_OR_RETURN(held_out, ReadPtuObservations(o.validate));
  }
  IDI_ASSIGN_OR_RETURN(const calib::PtuCalibrationResult r, calib::CalibratePtu(obs, start, co));
  spdlog::info("{}", r.Summary());
  std::optional<calib::PtuValidation> v;
  if (!o.validate.empty()) {
    IDI_ASSIGN_OR_RETURN(v, calib::ValidatePtu(r, held_out, co.range, o.validate));
    spdlog::info("validation: RMS {:.3f} px per axis over {} held-out images", v->rms_px, held_out.size());
  }
  nlohmann::json report = PtuReportJson(r, v ? &*v : nullptr);
  report["observations_file"] = o.observations;
  return WritePtuOutputs(o, r, v ? &*v : nullptr, report);
}

Status RunInTwin(const CalibratePtuOptions& o) {
  PtuTwinOptions to;
  to.seed = o.seed;
  to.mode = o.image ? PtuSpotMode::kImage : PtuSpotMode::kGeometric;
  to.spot_noise_px = o.noise_px;
  if (!o.lens_k1_k2.empty()) {
    IDI_ASSIGN_OR_RETURN(const std::vector<double> k, ParseNumberList(o.lens_k1_k2, 2, "--lens-k1-k2"));
    to.truth.k1 = k[0];
    to.truth.k2 = k[1];
  }
  IDI_RETURN_IF_ERROR(to.Check());
  PtuTwin twin(to);
  IDI_RETURN_IF_ERROR(twin.AimLaser());
  PtuDevices devices = twin.Devices();
  PtuProcedureOptions po;
  po.robot = twin.arm_model();
  po.approx_point_mm = twin.approx_point_in_base();
  po.plan.poses = o.poses;
  po.plan.validation_poses = o.validation_poses;
  po.calibration.estimate_distortion = o.distortion;
  po.calibration.robust_scale_px = o.robust_scale_px;
  po.seed = o.seed;
  po.cancelled = o.cancelled;
  if (!o.start.empty()) {
    IDI_ASSIGN_OR_RETURN(const std::vector<calib::PtuCameraModel> start, LoadPtuCalibration(o.start));
    for (const auto& m : start) po.start[m.side == BiclopsSide::kLeft ? 0 : 1] = m;
  }
  IDI_ASSIGN_OR_RETURN(const PtuProcedureResult res, RunPtuCalibrationProcedure(devices, po));
  spdlog::info("{}", res.Summary());
  if (!o.observations.empty()) IDI_RETURN_IF_ERROR(WritePtuObservations(o.observations, res.calibration));
  if (!o.validate.empty()) IDI_RETURN_IF_ERROR(WritePtuObservations(o.validate, res.validation));
  const calib::PtuValidation* v = res.validation.empty() ? nullptr : &res.validation_errors;
  nlohmann::json report = PtuReportJson(res.result, v);
  report["twin"] = PtuTwinTruthJson(twin, res.result);
  report["twin"]["seed"] = o.seed;
  report["twin"]["mode"] = o.image ? "image" : "geometric";
  report["survey"] = {{"images_with_spot", res.survey.size()}, {"images_missed", res.survey_missed}};
  report["plan"] = {{"poses", res.plan.calibration.size()},
                    {"validation_poses", res.plan.validation.size()},
                    {"candidates", res.plan.candidates},
                    {"log_det", res.plan.log_det}};
  nlohmann::json coverage = nlohmann::json::array();
  for (const auto& c : res.plan.coverage) {
    coverage.push_back({{"axis", c.axis}, {"min_deg", c.min_deg}, {"max_deg", c.max_deg}});
  }
  report["plan"]["coverage"] = coverage;
  return WritePtuOutputs(o, res.result, v, report);
}

}  // namespace

Status RunCalibratePtu(const CalibratePtuOptions& o) {
  if (o.out.empty()) return InvalidArgument("calibrate ptu: --out is required");
  // The outputs are checked before the acquisition and solve, not after.
  IDI_RETURN_IF_ERROR(CheckOutputFile(o.out, "calibrate ptu: --out"));
  IDI_RETURN_IF_ERROR(CheckOutputFile(o.report, "calibrate ptu: --report"));
  if (o.sim) {
    IDI_RETURN_IF_ERROR(CheckOutputFile(o.observations, "calibrate ptu: --observations"));
    IDI_RETURN_IF_ERROR(CheckOutputFile(o.validate, "calibrate ptu: --validate"));
  }
  IDI_RETURN_IF_ERROR(CheckOutputFolder(o.plots, "calibrate ptu: --plots"));
  // With --sim the observations and validation files are outputs too. (--out may be the --start file:
  // refining a result in place is asked for, and the start is read before anything is written.)
  IDI_RETURN_IF_ERROR(
      CheckDistinctFiles({{"--observations", o.sim ? "" : o.observations}, {"--validate", o.sim ? "" : o.validate}},
                         {{"--out", o.out},
                          {"--report", o.report},
                          {"--observations", o.sim ? o.observations : ""},
                          {"--validate", o.sim ? o.validate : ""}},
                         "calibrate ptu"));
  return o.sim ? RunInTwin(o) : RunFromFiles(o);
}

void AddCalibratePtuCommand(CliApp& cli) {
  // Share the `calibrate` parent with `calibrate robot|rtu` (calibrate_command.cc) when it exists.
  CLI::App* cal = nullptr;
  for (CLI::App* sub : cli.app.get_subcommands([](CLI::App* a) { return a->get_name() == "calibrate"; })) cal = sub;
  if (cal == nullptr) {
    cal = cli.app.add_subcommand("calibrate", "calibration of the arms, the rail and the pan-tilt cameras");
    cal->require_subcommand(1);
  }
  auto o = std::make_shared<CalibratePtuOptions>();
  CLI::App* ptu = cli.AddCommand(cal, "ptu",
                                 "calibrate the Biclops pan-tilt cameras from images of one unknown laser spot (chapter 6)",
                                 [o] { return RunCalibratePtu(*o); });
  ptu->add_option("--observations", o->observations,
                  "CSV 'camera,x_mm,y_mm,z_mm,alpha_deg,beta_deg,gamma_deg,pan_deg,tilt_deg,u_px,v_px' (TCF pose of "
                  "eq. 3.10, camera left or right); with --sim: where to save the acquired data");
  ptu->add_option("--out", o->out, "result YAML (every parameter with unit, value and std; written atomically)")
      ->required();
  ptu->add_option("--validate", o->validate, "held-out observations (same CSV); with --sim: where to save them");
  ptu->add_option("--report", o->report, "JSON report (point_mm, residual and validation RMS in px, ...)");
  ptu->add_flag("--json", o->json, "print the JSON report on stdout");
  ptu->add_option("--plots", o->plots, "folder for the residual histograms (PNG, like Figs. 6.3-6.4)");
  ptu->add_option("--start", o->start, "start values from a previous result YAML (default: as designed)");
  ptu->add_flag("--distortion", o->distortion, "also estimate the radial distortion k1, k2");
  ptu->add_option("--robust-scale-px", o->robust_scale_px, "Cauchy loss scale")->check(CLI::PositiveNumber)
      ->capture_default_str();
  ptu->add_flag("--sim", o->sim, "run the whole procedure, acquisition included, in the digital twin");
  ptu->add_option("--seed", o->seed, "digital twin seed")->capture_default_str();
  ptu->add_flag("--image", o->image, "--sim: render each image and find the spot in it (default: geometric spots)");
  ptu->add_option("--noise-px", o->noise_px, "--sim: geometric spot noise per axis")->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  ptu->add_option("--lens-k1-k2", o->lens_k1_k2, "--sim: the twin lens' radial distortion, 'k1,k2'");
  ptu->add_option("--poses", o->poses, "--sim: calibration poses (§6.4.4: 60)")
      ->check(CLI::Range(calib::kPtuMinObservationsPerCamera, 10000))
      ->capture_default_str();
  ptu->add_option("--validation-poses", o->validation_poses, "--sim: held-out poses")->check(CLI::Range(0, 10000))
      ->capture_default_str();
}

}  // namespace idi::workcell
