#include "workcell/app/scan_command.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <filesystem>
#include <iostream>

#include "shared/util/atomic_file.h"
#include "workcell/app/calibrate_command.h"
#include "workcell/app/calibrate_ptu_command.h"
#include "workcell/procedures/calibration_files.h"
#include "workcell/procedures/ptu_files.h"
#include "workcell/procedures/scan_twin.h"

namespace idi::workcell {
namespace {

namespace fs = std::filesystem;

Result<sim::ObjectKind> ParseObject(const std::string& name) {
  if (name == "box") return sim::ObjectKind::kBox;
  if (name == "prism") return sim::ObjectKind::kTriangularPrism;
  if (name == "bracket") return sim::ObjectKind::kLBracket;
  if (name == "cylinder") return sim::ObjectKind::kCylinder;
  return InvalidArgument("scan: unknown object '" + name + "' (box, prism, bracket or cylinder)");
}

struct ScanCliOptions {
  SimScanOptions scan;
  bool sim = false;
  std::string calibration_dir;
  bool json = false;
};

Status RunScanCli(ScanCliOptions& o) {
  if (!o.sim) {
    return FailedPrecondition(
        "scan: only --sim in this version (on the real cell the scan needs the head cameras, which the hardware "
        "backend does not serve yet)");
  }
  IDI_RETURN_IF_ERROR(ParseObject(o.scan.object).status());
  // A new or empty run folder: images, overlays and reports of two runs would mix. It may hold the
  // calibration folder (OUT/calibration without --calibration, or a --calibration inside OUT), which is
  // reused, as documented.
  const std::string cal_dir = o.calibration_dir.empty() ? (fs::path(o.scan.out) / "calibration").string() : o.calibration_dir;
  std::vector<std::string> may_hold;
  {
    std::error_code ec;
    const fs::path out = fs::weakly_canonical(fs::absolute(o.scan.out, ec), ec);
    const fs::path rel = fs::weakly_canonical(fs::absolute(cal_dir, ec), ec).lexically_relative(out);
    if (!ec && !rel.empty() && *rel.begin() != ".." && *rel.begin() != ".") may_hold.push_back(rel.begin()->string());
  }
  IDI_RETURN_IF_ERROR(CheckNewOutputFolder(o.scan.out, "scan: --out", may_hold));
  IDI_ASSIGN_OR_RETURN(const CalibrationFiles files, EnsureSimCalibration(cal_dir, o.scan.seed));
  IDI_ASSIGN_OR_RETURN(const ScanCalibration cal, LoadScanCalibration(files));
  IDI_ASSIGN_OR_RETURN(const nlohmann::json report, RunSimScan(o.scan, cal));
  if (o.json) {
    std::cout << report.dump() << "\n";
    return Status::Ok();
  }
  const auto& t = report.at("truth");
  std::cout << fmt::format("{}: {} views, {} model points ({} on the object), {} edges\n", o.scan.object,
                           report.at("views").size(), report.at("points").size(), t.at("object_points").get<int>(),
                           report.at("edges").size());
  std::cout << fmt::format("  twin truth: {} of {} corners found, error mean {:.3f} mm, max {:.3f} mm, {} spurious\n",
                           t.at("matched_vertices").get<int>(), t.at("true_vertices").get<int>(),
                           t.at("mean_vertex_error_mm").get<double>(), t.at("max_vertex_error_mm").get<double>(),
                           t.at("spurious_points").get<int>());
  std::cout << fmt::format("  pick: {}; twin truth: held {}, placed {}, collisions {}\n",
                           report.at("pick").at("outcome").get<std::string>(), t.at("held").get<bool>(),
                           t.at("placed").get<bool>(), t.at("collisions").get<int>());
  std::cout << fmt::format("  report {}/report.json, model {}/model.ply, overlays {}/*_model.png\n", o.scan.out,
                           o.scan.out, o.scan.out);
  return Status::Ok();
}

}  // namespace

Result<ScanCalibration> LoadScanCalibration(const CalibrationFiles& f) {
  ScanCalibration c;
  IDI_ASSIGN_OR_RETURN(c.robot1, LoadRobotCalibration(f.robot1));
  IDI_ASSIGN_OR_RETURN(c.robot2, LoadRobotCalibration(f.robot2));
  IDI_ASSIGN_OR_RETURN(c.psi, LoadRailCalibration(f.rail));
  IDI_ASSIGN_OR_RETURN(const std::vector<calib::PtuCameraModel> cams, LoadPtuCalibration(f.ptu));
  bool have[2] = {false, false};
  for (const calib::PtuCameraModel& m : cams) {
    const std::size_t i = m.side == BiclopsSide::kLeft ? 0 : 1;
    c.cameras[i] = m;
    have[i] = true;
  }
  if (!have[0] || !have[1]) {
    return InvalidArgument(f.ptu + ": the scan needs both cameras (left and right) calibrated");
  }
  return c;
}

Result<CalibrationFiles> EnsureSimCalibration(const std::string& dir, unsigned seed) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) return IoError(dir + ": cannot create the calibration folder: " + ec.message());
  CalibrationFiles f{(fs::path(dir) / "robot1.yaml").string(), (fs::path(dir) / "robot2.yaml").string(),
                     (fs::path(dir) / "rail.yaml").string(), (fs::path(dir) / "ptu.yaml").string()};
  // The twin's seed makes its arms, rail and head: files made for another seed are another cell's
  // calibration. The folder says which seed made its files (twin.json); files without it are taken as
  // given (a calibration from elsewhere), with a warning.
  const std::string marker = (fs::path(dir) / "twin.json").string();
  const bool any = fs::exists(f.robot1) || fs::exists(f.robot2) || fs::exists(f.rail) || fs::exists(f.ptu);
  if (fs::exists(marker)) {
    IDI_ASSIGN_OR_RETURN(const std::string text, ReadFile(marker));
    const nlohmann::json m = nlohmann::json::parse(text, nullptr, false);
    if (m.is_discarded() || !m.is_object() || !m.contains("seed") || !m["seed"].is_number_unsigned()) {
      return ParseError(marker + ": expected {\"seed\": N}");
    }
    if (m["seed"].get<uint64_t>() != seed) {
      if (any) {
        return InvalidArgument(
            fmt::format("{}: the calibration there was made in the twin of seed {}, not {}; give "
                        "another --out or --calibration folder",
                        dir,
                        m["seed"].get<uint64_t>(),
                        seed));
      }
      // A run of another seed that made no file yet (interrupted): the folder is this seed's now.
      IDI_RETURN_IF_ERROR(WriteFileAtomically(marker, nlohmann::json{{"seed", seed}}.dump() + "\n"));
    }
  } else if (any) {
    spdlog::warn("scan: {} does not say which twin seed made its calibration (no twin.json); using its files as given",
                 dir);
  } else {
    IDI_RETURN_IF_ERROR(WriteFileAtomically(marker, nlohmann::json{{"seed", seed}}.dump() + "\n"));
  }
  for (int arm = 1; arm <= 2; ++arm) {
    const std::string& out = arm == 1 ? f.robot1 : f.robot2;
    if (fs::exists(out)) continue;
    spdlog::info("scan: no {}; calibrating robot {} in the twin first", out, arm);
    RobotCommandOptions r;
    r.sim = true;
    r.seed = seed;
    r.arm = arm;
    r.out = out;
    r.report = (fs::path(dir) / fmt::format("robot{}.json", arm)).string();
    IDI_RETURN_IF_ERROR(RunCalibrateRobot(r));
  }
  if (!fs::exists(f.rail)) {
    spdlog::info("scan: no {}; calibrating the rail in the twin first", f.rail);
    RtuCommandOptions r;
    r.sim = true;
    r.seed = seed;
    r.robot1 = f.robot1;
    r.robot2 = f.robot2;
    r.out = f.rail;
    r.report = (fs::path(dir) / "rail.json").string();
    IDI_RETURN_IF_ERROR(RunCalibrateRtu(r));
  }
  if (!fs::exists(f.ptu)) {
    spdlog::info("scan: no {}; calibrating the pan-tilt cameras in the twin first (rendered images)", f.ptu);
    CalibratePtuOptions p;
    p.sim = true;
    p.seed = seed;
    p.image = true;
    p.out = f.ptu;
    p.report = (fs::path(dir) / "ptu.json").string();
    IDI_RETURN_IF_ERROR(RunCalibratePtu(p));
  }
  return f;
}

Result<nlohmann::json> RunSimScan(const SimScanOptions& o, const ScanCalibration& calibration) {
  IDI_ASSIGN_OR_RETURN(const sim::ObjectKind kind, ParseObject(o.object));
  ScanTwinOptions to;
  to.seed = o.seed;
  to.kind = kind;
  to.scene = o.scene;
  ScanTwin twin(to);
  ScanDevices devices = twin.Devices();
  ScanOptions so = twin.SetupOptions();
  so.pick = o.pick;
  so.out_dir = o.out;
  so.cancelled = o.cancelled;
  so.progress = o.progress;
  spdlog::info("scan: twin seed {}, {} (scene {}), {}", o.seed, o.object, o.scene, o.pick ? "scan and pick" : "scan only");
  IDI_ASSIGN_OR_RETURN(const ScanReport r, ScanAndPick(devices, calibration, so));
  const ScanTruth t = twin.Evaluate(r, so);
  nlohmann::json j = ScanReportJson(r);
  j["object"] = o.object;
  j["scene"] = o.scene;
  j["seed"] = o.seed;
  j["truth"] = {{"true_vertices", t.true_vertices},
                {"matched_vertices", t.matched_vertices},
                {"mean_vertex_error_mm", t.mean_vertex_error_mm},
                {"max_vertex_error_mm", t.max_vertex_error_mm},
                {"object_points", t.object_points},
                {"spurious_points", t.spurious_points},
                {"held", t.held},
                {"lifted", t.lifted},
                {"placed", t.placed},
                {"collisions", t.collisions},
                {"grasp", t.grasp_reason},
                {"match_mm", t.match_mm}};
  if (r.cylinder) {
    j["truth"]["cylinder_axis_error_mm"] = t.cylinder_axis_error_mm;
    j["truth"]["cylinder_radius_error_mm"] = t.cylinder_radius_error_mm;
    j["truth"]["cylinder_top_error_mm"] = t.cylinder_top_error_mm;
  }
  if (!o.out.empty()) IDI_RETURN_IF_ERROR(WriteFileAtomically((fs::path(o.out) / "report.json").string(), j.dump(2) + "\n"));
  spdlog::info("scan: {} corners of {} within {} mm (mean {:.3f}, max {:.3f} mm); pick: {} (twin: held {}, placed {})",
               t.matched_vertices, t.true_vertices, t.match_mm, t.mean_vertex_error_mm, t.max_vertex_error_mm,
               r.pick.outcome, t.held, t.placed);
  return j;
}

void AddScanCommand(CliApp& cli) {
  auto o = std::make_shared<ScanCliOptions>();
  CLI::App* cmd = cli.AddCommand(
      &cli.app, "scan",
      "scan the object on the rotary table from views around it (chapter 8), plan the Barrett grasp, pick it with "
      "robot 2 and put it down beside",
      [o] { return RunScanCli(*o); });
  cmd->add_flag("--sim", o->sim, "in the digital twin (the only mode in this version)");
  cmd->add_option("--seed", o->scan.seed, "digital twin seed (the cell: arms, rail, head)")->capture_default_str();
  cmd->add_option("--object", o->scan.object, "box, prism, bracket or cylinder")->capture_default_str();
  cmd->add_option("--scene", o->scan.scene, "which object of that kind and where on the table")->capture_default_str();
  cmd->add_option("--calibration", o->calibration_dir,
                  "folder with robot1.yaml, robot2.yaml, rail.yaml, ptu.yaml (with --sim: missing ones are calibrated "
                  "first; default OUT/calibration)");
  cmd->add_flag("!--no-pick", o->scan.pick, "scan and plan only, do not move robot 2");
  cmd->add_option("--out",
                  o->scan.out,
                  "run folder, new or empty (without --calibration it may hold the calibration folder of an earlier "
                  "run): images, overlays, model.ply, report.json")
      ->required();
  cmd->add_flag("--json", o->json, "print the report on stdout");
}

}  // namespace idi::workcell
