#include "workcell/app/cell_factory.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <yaml-cpp/yaml.h>

#include <atomic>
#include <ctime>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <sstream>

#include "shared/calib/ptu/ptu_calibration.h"
#include "shared/hal/camera.h"
#include "shared/hal/clock.h"
#include "shared/sim/workcell/workcell_twin.h"
#include "shared/util/atomic_file.h"
#include "shared/util/units.h"
#include "workcell/app/calibrate_command.h"
#include "workcell/app/calibrate_ptu_command.h"
#include "workcell/app/scan_command.h"
#include "workcell/devices/barrett/barrett_driver.h"
#include "workcell/devices/ptu/ptu_driver.h"
#include "workcell/devices/staubli/staubli_driver.h"
#if defined(IDI_WORKCELL_WITH_V4L2)
#include "shared/drivers/v4l2/v4l2_camera.h"
#endif
#if defined(IDI_WORKCELL_WITH_MRPT)
#include "shared/drivers/mrpt/mrpt_camera.h"
#endif

namespace idi::workcell {
namespace {

namespace fs = std::filesystem;

// The RX-130's home: the controller's zero, (0, -90, 90, 0, 0, 0) degrees in the model convention.
Joints HomeJoints() { return {0.0, -kPi / 2, kPi / 2, 0.0, 0.0, 0.0}; }

// ---- the digital twin -------------------------------------------------------------------------------

// Called from the run thread and the control socket's thread (see HardwareDeviceSet); the twin's moves
// take no wall time, so one lock around each call is enough.
class SimDeviceSet final : public DeviceSet {
 public:
  explicit SimDeviceSet(unsigned seed) {
    sim::WorkcellTwinOptions o;
    o.seed = seed;
    twin_ = std::make_unique<sim::WorkcellTwin>(o);
  }
  Status Connect() override {
    std::lock_guard<std::mutex> lock(mu_);
    for (int k = 0; k < 2; ++k) {
      IDI_RETURN_IF_ERROR(twin_->arm(k).ReadJoints().status().WithContext(twin_->arm(k).name()));
      IDI_RETURN_IF_ERROR(twin_->rail(k).Read().status());
    }
    return Status::Ok();
  }
  Status Home() override {
    std::lock_guard<std::mutex> lock(mu_);
    for (int k = 0; k < 2; ++k) {
      IDI_RETURN_IF_ERROR(twin_->laser(k).SetOn(false));
      IDI_RETURN_IF_ERROR(twin_->arm(k).MoveJoints(HomeJoints(), hal::MoveOptions{}).WithContext("homing " + twin_->arm(k).name()));
    }
    return Status::Ok();
  }
  Status StopAll() override {
    std::lock_guard<std::mutex> lock(mu_);
    Status first = Status::Ok();
    for (int k = 0; k < 2; ++k) {
      for (Status st : {twin_->arm(k).Stop(), twin_->rail(k).Stop(), twin_->laser(k).SetOn(false)}) {
        if (!st.ok() && first.ok()) first = st;
      }
    }
    return first;
  }
  nlohmann::json Health() override {
    std::lock_guard<std::mutex> lock(mu_);
    nlohmann::json h = {{"backend", "sim"}, {"simulated_time_s", hal::NsToSec(twin_->clock().NowNs())}};
    for (int k = 0; k < 2; ++k) {
      auto js = twin_->arm(k).ReadJoints();
      nlohmann::json a = {{"name", twin_->arm(k).name()}, {"ok", js.ok()}};
      if (js.ok()) {
        std::vector<double> deg;
        for (double q : js->q_rad) deg.push_back(RadToDeg(q));
        a["joints_deg"] = deg;
      } else {
        a["error"] = js.status().message();
      }
      h["arms"].push_back(a);
    }
    return h;
  }

 private:
  std::mutex mu_;
  std::unique_ptr<sim::WorkcellTwin> twin_;
};

int64_t NowUnix() { return static_cast<int64_t>(std::time(nullptr)); }

// Commits `file` as calibration item `item`, with `also` (item -> file) made by the same job, and
// returns the report with the new version. A new robot calibration drops the rail's: the rail was
// solved with the old one, and the arms and the rail in use must belong together (jobs that need the
// rail then ask for calibrate-rail first).
Result<nlohmann::json> CommitItem(JobContext& ctx,
                                  const std::string& item,
                                  const std::string& file,
                                  nlohmann::json report,
                                  const std::map<std::string, std::string>& also = {}) {
  std::map<std::string, std::string> updates;
  IDI_ASSIGN_OR_RETURN(updates[item], ReadFile(file));
  for (const auto& [other, path] : also) {
    IDI_ASSIGN_OR_RETURN(updates[other], ReadFile(path));
  }
  std::vector<std::string> drop;
  if (updates.count("rail") == 0 && (updates.count("robot1") != 0 || updates.count("robot2") != 0))
    drop.push_back("rail");
  IDI_ASSIGN_OR_RETURN(const CalibrationVersion v, ctx.calibration->Commit(updates, NowUnix(), drop));
  report["calibration_version"] = v.number;
  report["item"] = item;
  if (!also.empty()) {
    report["also_committed"] = nlohmann::json::array();
    for (const auto& [other, path] : also) report["also_committed"].push_back(other);
  }
  if (!drop.empty()) report["dropped"] = drop;
  return report;
}

Result<nlohmann::json> ReadReport(const std::string& path) {
  IDI_ASSIGN_OR_RETURN(const std::string text, ReadFile(path));
  try {
    return nlohmann::json::parse(text);
  } catch (const std::exception& e) {
    return InvalidArgument(path + ": " + e.what());
  }
}

Status CheckOnlyKeys(const nlohmann::json& args, const std::vector<std::string>& keys, const std::string& job) {
  if (!args.is_object()) return InvalidArgument(job + ": arguments must be a JSON object");
  for (auto it = args.begin(); it != args.end(); ++it) {
    if (std::find(keys.begin(), keys.end(), it.key()) == keys.end()) {
      return InvalidArgument(fmt::format("{}: unknown argument '{}'", job, it.key()));
    }
  }
  return Status::Ok();
}

Status CheckReadings(const nlohmann::json& args, const std::string& job) {
  if (!args.contains("readings")) return Status::Ok();
  const auto& r = args.at("readings");
  if (!r.is_number_integer() || r.get<int64_t>() < 20 || r.get<int64_t>() > 100000) {
    return InvalidArgument(job + ": 'readings' must be an integer in [20, 100000]");
  }
  return Status::Ok();
}

JobSpec RobotJob(int arm, unsigned seed) {
  JobSpec j;
  j.name = fmt::format("calibrate-robot{}", arm);
  j.description = fmt::format("ViCKi calibration of robot {} in the twin (chapter 4); args: readings", arm);
  j.validate = [name = j.name](const nlohmann::json& args) {
    IDI_RETURN_IF_ERROR(CheckOnlyKeys(args, {"readings"}, name));
    return CheckReadings(args, name);
  };
  j.run = [arm, seed](JobContext& ctx, const nlohmann::json& args) -> Result<nlohmann::json> {
    RobotCommandOptions o;
    o.sim = true;
    o.seed = seed;
    o.arm = arm;
    o.readings = args.value("readings", o.readings);
    o.out = (fs::path(ctx.run_dir) / fmt::format("robot{}.yaml", arm)).string();
    o.report = (fs::path(ctx.run_dir) / "calibration.json").string();
    o.observations = (fs::path(ctx.run_dir) / "observations.csv").string();
    o.validate = (fs::path(ctx.run_dir) / "held_out.csv").string();
    o.plots = ctx.run_dir;
    o.cancelled = [&ctx] { return ctx.cancelled(); };
    ctx.progress(0.05, "acquiring and solving");
    IDI_RETURN_IF_ERROR(RunCalibrateRobot(o));
    if (ctx.cancelled()) return Cancelled("cancelled by the operator; the calibration was not committed");
    IDI_ASSIGN_OR_RETURN(nlohmann::json report, ReadReport(o.report));
    return CommitItem(ctx, fmt::format("robot{}", arm), o.out, std::move(report));
  };
  return j;
}

JobSpec RailJob(unsigned seed) {
  JobSpec j;
  j.name = "calibrate-rail";
  j.description = "robot-to-robot transform on the rail in the twin (chapter 5), from the current robot calibrations; args: readings";
  j.validate = [](const nlohmann::json& args) {
    IDI_RETURN_IF_ERROR(CheckOnlyKeys(args, {"readings"}, "calibrate-rail"));
    return CheckReadings(args, "calibrate-rail");
  };
  j.run = [seed](JobContext& ctx, const nlohmann::json& args) -> Result<nlohmann::json> {
    RtuCommandOptions o;
    o.sim = true;
    o.seed = seed;
    o.readings = args.value("readings", o.readings);
    // The robots' calibrations in use; without them the rail job calibrates them first in its folder.
    auto r1 = ctx.calibration->CurrentItemPath("robot1");
    auto r2 = ctx.calibration->CurrentItemPath("robot2");
    o.robot1 = r1.ok() ? *r1 : (fs::path(ctx.run_dir) / "robot1.yaml").string();
    o.robot2 = r2.ok() ? *r2 : (fs::path(ctx.run_dir) / "robot2.yaml").string();
    o.out = (fs::path(ctx.run_dir) / "rail.yaml").string();
    o.report = (fs::path(ctx.run_dir) / "calibration.json").string();
    o.observations = (fs::path(ctx.run_dir) / "observations.csv").string();
    o.plots = ctx.run_dir;
    o.cancelled = [&ctx] { return ctx.cancelled(); };
    ctx.progress(0.05, "acquiring and solving");
    IDI_RETURN_IF_ERROR(RunCalibrateRtu(o));
    if (ctx.cancelled()) return Cancelled("cancelled by the operator; the calibration was not committed");
    IDI_ASSIGN_OR_RETURN(nlohmann::json report, ReadReport(o.report));
    report["robot1"] = o.robot1;
    report["robot2"] = o.robot2;
    // Arms this job calibrated itself (none were committed) go in with the rail solved with them.
    std::map<std::string, std::string> also;
    if (!r1.ok()) also["robot1"] = o.robot1;
    if (!r2.ok()) also["robot2"] = o.robot2;
    return CommitItem(ctx, "rail", o.out, std::move(report), also);
  };
  return j;
}

JobSpec PtuJob(unsigned seed) {
  JobSpec j;
  j.name = "calibrate-ptu";
  j.description = "both pan-tilt cameras from one unknown laser spot in the twin (chapter 6); args: image (bool), poses";
  j.validate = [](const nlohmann::json& args) {
    IDI_RETURN_IF_ERROR(CheckOnlyKeys(args, {"image", "poses"}, "calibrate-ptu"));
    if (args.contains("image") && !args.at("image").is_boolean()) {
      return InvalidArgument("calibrate-ptu: 'image' must be true or false");
    }
    if (args.contains("poses")) {
      const auto& p = args.at("poses");
      if (!p.is_number_integer() || p.get<int64_t>() < calib::kPtuMinObservationsPerCamera ||
          p.get<int64_t>() > 10000) {
        return InvalidArgument(fmt::format("calibrate-ptu: 'poses' must be an integer in [{}, 10000]",
                                           calib::kPtuMinObservationsPerCamera));
      }
    }
    return Status::Ok();
  };
  j.run = [seed](JobContext& ctx, const nlohmann::json& args) -> Result<nlohmann::json> {
    CalibratePtuOptions o;
    o.sim = true;
    o.seed = seed;
    o.image = args.value("image", true);
    o.poses = args.value("poses", o.poses);
    o.out = (fs::path(ctx.run_dir) / "ptu.yaml").string();
    o.report = (fs::path(ctx.run_dir) / "calibration.json").string();
    o.observations = (fs::path(ctx.run_dir) / "observations.csv").string();
    o.validate = (fs::path(ctx.run_dir) / "held_out.csv").string();
    o.plots = ctx.run_dir;
    o.cancelled = [&ctx] { return ctx.cancelled(); };
    ctx.progress(0.05, o.image ? "surveying and imaging the spot" : "surveying the spot");
    IDI_RETURN_IF_ERROR(RunCalibratePtu(o));
    if (ctx.cancelled()) return Cancelled("cancelled by the operator; the calibration was not committed");
    IDI_ASSIGN_OR_RETURN(nlohmann::json report, ReadReport(o.report));
    return CommitItem(ctx, "ptu", o.out, std::move(report));
  };
  return j;
}

// The calibration in use, for a scan: all four items, else FailedPrecondition naming what is missing.
Result<ScanCalibration> CurrentScanCalibration(JobContext& ctx, const std::string& job) {
  CalibrationFiles f;
  for (auto [item, path] : {std::pair{"robot1", &f.robot1}, std::pair{"robot2", &f.robot2}, std::pair{"rail", &f.rail},
                            std::pair{"ptu", &f.ptu}}) {
    auto p = ctx.calibration->CurrentItemPath(item);
    if (!p.ok()) {
      return FailedPrecondition(fmt::format("{}: the calibration in use has no '{}'; run calibrate-{} first", job, item, item));
    }
    *path = *p;
  }
  return LoadScanCalibration(f);
}

Status CheckObject(const nlohmann::json& v, const std::string& job) {
  if (!v.is_string()) return InvalidArgument(job + ": 'object' must be box, prism, bracket or cylinder");
  const std::string s = v.get<std::string>();
  if (s != "box" && s != "prism" && s != "bracket" && s != "cylinder") {
    return InvalidArgument(job + ": 'object' must be box, prism, bracket or cylinder, got '" + s + "'");
  }
  return Status::Ok();
}

JobSpec ScanJob(unsigned seed) {
  JobSpec j;
  j.name = "scan";
  j.description = "scan the object on the table, plan the grasp, pick and place it (chapter 8) in the twin; args: "
                  "object (box|prism|bracket|cylinder), scene, pick (bool)";
  j.validate = [](const nlohmann::json& args) {
    IDI_RETURN_IF_ERROR(CheckOnlyKeys(args, {"object", "scene", "pick"}, "scan"));
    if (args.contains("object")) IDI_RETURN_IF_ERROR(CheckObject(args.at("object"), "scan"));
    if (args.contains("scene") && (!args.at("scene").is_number_integer() || args.at("scene").get<int64_t>() < 0 ||
                                   args.at("scene").get<int64_t>() > int64_t{UINT32_MAX})) {
      return InvalidArgument("scan: 'scene' must be an integer in [0, 4294967295]");
    }
    if (args.contains("pick") && !args.at("pick").is_boolean()) return InvalidArgument("scan: 'pick' must be true or false");
    return Status::Ok();
  };
  j.run = [seed](JobContext& ctx, const nlohmann::json& args) -> Result<nlohmann::json> {
    IDI_ASSIGN_OR_RETURN(const ScanCalibration cal, CurrentScanCalibration(ctx, "scan"));
    SimScanOptions o;
    o.seed = seed;
    o.object = args.value("object", std::string("box"));
    o.scene = static_cast<unsigned>(args.value("scene", int64_t{0}));  // in range: validated
    o.pick = args.value("pick", true);
    o.out = ctx.run_dir;
    o.cancelled = [&ctx] { return ctx.cancelled(); };
    o.progress = ctx.progress;
    return RunSimScan(o, cal);
  };
  return j;
}

nlohmann::json YamlToJson(const YAML::Node& n) {
  if (n.IsMap()) {
    nlohmann::json out = nlohmann::json::object();
    for (const auto& kv : n) out[kv.first.as<std::string>()] = YamlToJson(kv.second);
    return out;
  }
  if (n.IsSequence()) {
    nlohmann::json out = nlohmann::json::array();
    for (const auto& e : n) out.push_back(YamlToJson(e));
    return out;
  }
  if (!n.IsScalar()) return nullptr;
  double d = 0;
  if (YAML::convert<double>::decode(n, d)) return d;
  return n.as<std::string>();
}

// The statistics block of a calibration file (its accuracy), as JSON.
nlohmann::json CalibrationStatistics(const std::string& path) {
  try {
    const YAML::Node root = YAML::LoadFile(path);
    return root["statistics"] ? YamlToJson(root["statistics"]) : nlohmann::json::object();
  } catch (const YAML::Exception& e) {
    return {{"error", path + ": " + e.what()}};
  }
}

JobSpec DayJob(unsigned seed) {
  JobSpec j;
  j.name = "day";
  j.description = "the simulated day's work once calibrated: scan and pick each object in turn; args: objects "
                  "(comma-separated, default box,prism,bracket)";
  auto parse = [](const nlohmann::json& args) -> Result<std::vector<std::string>> {
    std::vector<std::string> out;
    if (!args.contains("objects")) return std::vector<std::string>{"box", "prism", "bracket"};
    const nlohmann::json& v = args.at("objects");
    if (v.is_array()) {
      for (const auto& e : v) {
        IDI_RETURN_IF_ERROR(CheckObject(e, "day"));
        out.push_back(e.get<std::string>());
      }
    } else if (v.is_string()) {
      std::stringstream ss(v.get<std::string>());
      for (std::string item; std::getline(ss, item, ',');) {
        IDI_RETURN_IF_ERROR(CheckObject(item, "day"));
        out.push_back(item);
      }
    } else {
      return InvalidArgument("day: 'objects' must be a list or a comma-separated string");
    }
    if (out.empty() || out.size() > 50) return InvalidArgument("day: 1 to 50 objects");
    return out;
  };
  j.validate = [parse](const nlohmann::json& args) {
    IDI_RETURN_IF_ERROR(CheckOnlyKeys(args, {"objects"}, "day"));
    return parse(args).status();
  };
  j.run = [seed, parse](JobContext& ctx, const nlohmann::json& args) -> Result<nlohmann::json> {
    IDI_ASSIGN_OR_RETURN(const std::vector<std::string> objects, parse(args));
    IDI_ASSIGN_OR_RETURN(const ScanCalibration cal, CurrentScanCalibration(ctx, "day"));
    nlohmann::json report;
    IDI_ASSIGN_OR_RETURN(const auto version, ctx.calibration->Current());
    report["calibration"] = {{"version", version ? version->number : 0}};
    for (const char* item : {"robot1", "robot2", "rail", "ptu"}) {
      auto p = ctx.calibration->CurrentItemPath(item);
      if (p.ok()) report["calibration"][item] = {{"file", *p}, {"statistics", CalibrationStatistics(*p)}};
    }
    report["scans"] = nlohmann::json::array();
    int picked = 0;
    for (std::size_t i = 0; i < objects.size(); ++i) {
      if (ctx.cancelled()) return Cancelled("day: cancelled by the operator after " + std::to_string(i) + " objects");
      SimScanOptions o;
      o.seed = seed;
      o.object = objects[i];
      o.scene = static_cast<unsigned>(i);
      o.out = (fs::path(ctx.run_dir) / fmt::format("{:02d}-{}", i + 1, objects[i])).string();
      o.cancelled = [&ctx] { return ctx.cancelled(); };
      o.progress = [&ctx, i, n = objects.size(), name = objects[i]](double f, const std::string& what) {
        ctx.progress((static_cast<double>(i) + f) / static_cast<double>(n), name + ": " + what);
      };
      auto r = RunSimScan(o, cal);
      nlohmann::json row = {{"object", objects[i]}, {"folder", o.out}};
      if (!r.ok()) {
        if (r.status().code() == StatusCode::kCancelled) return r.status();
        row["error"] = r.status().ToString();
      } else {
        const auto& t = r->at("truth");
        row.update({{"corners_found", t.at("matched_vertices")}, {"corners", t.at("true_vertices")},
                    {"corner_error_mean_mm", t.at("mean_vertex_error_mm")},
                    {"corner_error_max_mm", t.at("max_vertex_error_mm")}, {"pick", r->at("pick").at("outcome")},
                    {"held", t.at("held")}, {"placed", t.at("placed")}, {"collisions", t.at("collisions")}});
        if (t.at("held").get<bool>() && t.at("placed").get<bool>()) ++picked;
      }
      spdlog::info("day: {} {}/{}: {}", objects[i], i + 1, objects.size(), row.dump());
      report["scans"].push_back(row);
    }
    report["picked"] = picked;
    report["objects"] = objects.size();
    // The job itself succeeds (its report is the day's result), so a short day must say so where the
    // operator looks: the journal, at warning level.
    if (picked < static_cast<int>(objects.size())) {
      spdlog::warn("day: picked and placed {} of {} objects; report in {}", picked, objects.size(), ctx.run_dir);
    } else {
      spdlog::info("day: picked and placed all {} objects", picked);
    }
    return report;
  };
  return j;
}

Result<Cell> MakeSimCell(const WorkcellConfig& config) {
  hal::SimClock::SetDefaultPace(config.sim_pace);  // every twin the jobs make from here on
  if (config.sim_pace > 0) spdlog::info("sim: paced at {} wall s per simulated s", config.sim_pace);
  Cell cell;
  cell.devices = std::make_unique<SimDeviceSet>(config.sim_seed);
  cell.jobs = {RobotJob(1, config.sim_seed), RobotJob(2, config.sim_seed), RailJob(config.sim_seed),
               PtuJob(config.sim_seed), ScanJob(config.sim_seed), DayJob(config.sim_seed)};
  if (!config.sim_day.empty()) cell.startup_jobs.push_back({"day", {{"objects", config.sim_day}}});
  cell.calibration_jobs = {"calibrate-robot1", "calibrate-robot2", "calibrate-rail", "calibrate-ptu"};
  cell.calibration_items = {"robot1", "robot2", "rail", "ptu"};
  cell.calibration_job_for_item = {{"robot1", "calibrate-robot1"},
                                   {"robot2", "calibrate-robot2"},
                                   {"rail", "calibrate-rail"},
                                   {"ptu", "calibrate-ptu"}};
  return cell;
}

// ---- the real cell ------------------------------------------------------------------------------------

// The service calls it from two threads: the run thread connects and homes (start-up, reset), the
// control socket's thread stops and reads health. The drivers are not thread-safe, so one thread talks
// to the devices at a time (io_), one device operation at a time: a stop during a reset interrupts the
// operation in progress when it waits for a move to end (a PTU's move home, the hand's initialisation:
// it returns within about 50 ms, its device halted), else waits for it (a command's reply: the reply
// timeout, 1 s, each; a reconnection's exchange; a camera's check frame, 3 s, or its restart, MRPT's
// up to about 15 s); then the reset's remaining steps are skipped (Cancelled) and every device is stopped.
// Health never waits: it is the snapshot taken after the last operation, marked busy while one runs.
class HardwareDeviceSet final : public DeviceSet {
 public:
  explicit HardwareDeviceSet(const WorkcellConfig& c) {
    for (const ArmEndpoint& a : c.arms) {
      StaubliDriverOptions o;
      o.name = a.name;
      o.host = a.host;
      o.port = a.port;
      arms_.push_back(std::make_unique<StaubliDriver>(o, &clock_));
    }
    for (const SerialEndpoint& p : c.ptus) {
      PtuDriverOptions o;
      o.name = "ptu-" + p.name;
      o.port = p.device;
      o.baud = p.baud;
      ptus_.push_back(std::make_unique<PtuDriver>(o, &clock_));
    }
    if (!c.hand.device.empty()) {
      BarrettDriverOptions o;
      o.name = "barrett";
      o.port = c.hand.device;
      o.baud = c.hand.baud;
      hand_ = std::make_unique<BarrettDriver>(o, &clock_);
    }
    for (const CameraEndpoint& e : c.cameras) cameras_.push_back({e, nullptr, false, 0, ""});
    std::lock_guard<std::mutex> lock(io_);
    TakeHealthSnapshot();
  }
  // Connecting is the start of a (re)start the operator asked for: it clears an earlier stop.
  Status Connect() override {
    stop_requested_ = false;
    for (auto& a : arms_) IDI_RETURN_IF_ERROR(Step("connecting", [&] { return a->Connect(); }));
    for (auto& p : ptus_) IDI_RETURN_IF_ERROR(Step("connecting", [&] { return p->Connect(); }));
    if (hand_) IDI_RETURN_IF_ERROR(Step("connecting", [&] { return hand_->Connect(); }));
    for (Camera& cam : cameras_) IDI_RETURN_IF_ERROR(Step("connecting", [&] { return StartCamera(cam); }));
    return Status::Ok();
  }
  // The arms are only read (an unattended move at power-up is not safe); the PTUs go to 0/0 and the
  // hand initialises (it drives every motor to its stops).
  Status Home() override {
    for (auto& a : arms_) {
      IDI_RETURN_IF_ERROR(Step("homing", [&] { return a->ReadJoints().status().WithContext(a->name()); }));
    }
    for (auto& p : ptus_) {
      IDI_RETURN_IF_ERROR(Step("homing", [&] { return p->MoveTo(0.0, 0.0, std::chrono::milliseconds(20'000)); }));
    }
    if (hand_) IDI_RETURN_IF_ERROR(Step("homing", [&] { return hand_->Initialize(); }));
    // The cameras do not move: each must deliver a frame.
    for (Camera& cam : cameras_) IDI_RETURN_IF_ERROR(Step("checking", [&] { return GrabOne(cam); }));
    return Status::Ok();
  }
  Status StopAll() override {
    stop_requested_ = true;  // before the lock: the operation in progress is the last one
    // A wait for a move to end in that operation ends now (Cancelled, its device halted), not when the
    // move does.
    for (auto& a : arms_) a->Interrupt();
    for (auto& p : ptus_) p->Interrupt();
    if (hand_) hand_->Interrupt();
    std::lock_guard<std::mutex> lock(io_);
    Status first = Status::Ok();
    auto keep = [&first](Status st) {
      if (!st.ok() && first.ok()) first = st;
    };
    for (auto& a : arms_) keep(a->Stop());
    for (auto& p : ptus_) keep(p->Halt());
    if (hand_) keep(hand_->Stop());
    // No operation is in progress (io_ is held) and stop_requested_ refuses the next until a Connect.
    for (auto& a : arms_) a->ClearInterrupt();
    for (auto& p : ptus_) p->ClearInterrupt();
    if (hand_) hand_->ClearInterrupt();
    // The cameras move nothing: they stay open (health goes on showing them).
    TakeHealthSnapshot();
    return first;
  }
  nlohmann::json Health() override {
    std::unique_lock<std::mutex> io(io_, std::try_to_lock);
    if (io.owns_lock()) TakeHealthSnapshot();
    std::lock_guard<std::mutex> lock(health_mu_);
    nlohmann::json h = health_;
    h["busy"] = !io.owns_lock();  // a device operation is in progress: the snapshot is from before it
    return h;
  }

 private:
  // One device operation under io_, unless a stop came first.
  template <typename Op>
  Status Step(const char* what, Op op) {
    std::lock_guard<std::mutex> lock(io_);
    if (stop_requested_) return Cancelled(std::string(what) + " the cell: stopped by the operator");
    const Status st = op();
    TakeHealthSnapshot();
    return st;
  }
  // With io_ held.
  void TakeHealthSnapshot() {
    nlohmann::json h = {{"backend", "hardware"}};
    for (auto& a : arms_) {
      h["arms"].push_back({{"name", a->name()},
                           {"state", StaubliStateName(a->state())},
                           {"timeouts", a->counters().timeouts},
                           {"faults", a->counters().faults}});
    }
    for (auto& p : ptus_) {
      h["ptus"].push_back({{"name", p->name()},
                           {"state", PtuStateName(p->state())},
                           {"timeouts", p->counters().timeouts},
                           {"faults", p->counters().faults}});
    }
    if (hand_) {
      h["hand"] = {{"name", hand_->name()},
                   {"state", BarrettStateName(hand_->state())},
                   {"timeouts", hand_->counters().timeouts},
                   {"faults", hand_->counters().faults}};
    }
    for (const Camera& cam : cameras_) {
      nlohmann::json j = {{"name", cam.endpoint.name},
                          {"backend", cam.endpoint.backend},
                          {"device", cam.endpoint.device},
                          {"state", cam.started ? "started" : "stopped"},
                          {"frames", cam.frames}};
#if defined(IDI_WORKCELL_WITH_V4L2)
      if (const auto* v4l2 = dynamic_cast<const drivers::V4l2Camera*>(cam.device.get())) {
        j["state"] = drivers::V4l2CameraStateName(v4l2->state());
        j["dropped"] = v4l2->counters().dropped;
        j["reconnects"] = v4l2->counters().reconnects;
      }
#endif
      if (!cam.last_error.empty()) j["last_error"] = cam.last_error;
      h["cameras"].push_back(j);
    }
    std::lock_guard<std::mutex> lock(health_mu_);
    health_ = std::move(h);
  }

  // A configured camera: opened at Connect (gray, at its configured size and exposure), checked with one
  // frame at Home. The jobs that use images do not run on the real cell yet (MakeHardwareCell), so nothing
  // else grabs.
  struct Camera {
    CameraEndpoint endpoint;
    std::unique_ptr<hal::CameraDevice> device;
    bool started = false;
    uint64_t frames = 0;
    std::string last_error;
  };
  static constexpr std::chrono::milliseconds kFirstFrameTimeout{3000};

  // A camera whose last start or frame failed is stopped and started again: a reset is how the operator
  // recovers it (hal::CameraDevice: Stop and Start after a DeviceError).
  Status StartCamera(Camera& cam) {
    if (cam.started && cam.last_error.empty()) return Status::Ok();
    if (cam.started) {
      if (const Status st = cam.device->Stop(); !st.ok())
        spdlog::warn("camera {}: {}", cam.endpoint.name, st.ToString());
      cam.started = false;
    }
    const std::string where =
        "camera " + cam.endpoint.name + " (" + cam.endpoint.backend + " " + cam.endpoint.device + ")";
    if (!cam.device) {
      if (cam.endpoint.backend == "v4l2") {
#if defined(IDI_WORKCELL_WITH_V4L2)
        drivers::V4l2CameraOptions o;
        o.name = cam.endpoint.name;
        o.device = cam.endpoint.device;
        cam.device = std::make_unique<drivers::V4l2Camera>(o);
#else
        cam.last_error = "this build has no V4L2 cameras";
        return FailedPrecondition(where + ": " + cam.last_error);
#endif
      } else if (cam.endpoint.backend == "mrpt") {
#if defined(IDI_WORKCELL_WITH_MRPT)
        // `device` is the IIDC camera's GUID (0x...), or 0 for the first on the bus.
        drivers::MrptCameraOptions o;
        o.name = cam.endpoint.name;
        o.grabber_type = "dc1394";
        o.settings["dc1394_camera_guid"] = cam.endpoint.device.empty() ? "0" : cam.endpoint.device;
        cam.device = std::make_unique<drivers::MrptCamera>(o, &clock_);
#else
        cam.last_error = "this build has no MRPT (FireWire cameras)";
        return FailedPrecondition(where + ": " + cam.last_error);
#endif
      } else {
        cam.last_error = "unknown camera backend";
        return InvalidArgument(where + ": " + cam.last_error);
      }
    }
    hal::CameraSettings settings;
    settings.width = cam.endpoint.width;
    settings.height = cam.endpoint.height;
    settings.exposure_us = cam.endpoint.exposure_us;
    const Status st = cam.device->Start(settings);
    if (!st.ok()) {
      cam.last_error = st.ToString();
      return st.WithContext(where);
    }
    cam.started = true;
    cam.last_error.clear();
    return Status::Ok();
  }

  Status GrabOne(Camera& cam) {
    const std::string where = "camera " + cam.endpoint.name;
    if (!cam.started) return FailedPrecondition(where + ": not started");
    const Result<hal::Image> img = cam.device->Grab(kFirstFrameTimeout);
    if (!img.ok()) {
      cam.last_error = img.status().ToString();
      return img.status().WithContext(where);
    }
    if (img->pixels.empty()) {
      cam.last_error = "empty frame";
      return DeviceError(where + ": empty frame");
    }
    ++cam.frames;
    cam.last_error.clear();
    return Status::Ok();
  }

  hal::MonotonicClock clock_;
  std::vector<std::unique_ptr<StaubliDriver>> arms_;
  std::vector<std::unique_ptr<PtuDriver>> ptus_;
  std::unique_ptr<BarrettDriver> hand_;
  std::vector<Camera> cameras_;
  std::mutex io_;
  std::atomic<bool> stop_requested_{false};
  std::mutex health_mu_;
  nlohmann::json health_;
};

Result<Cell> MakeHardwareCell(const WorkcellConfig& config) {
  if (config.arms.empty()) return InvalidArgument("backend hardware: no arms configured (hardware.arms)");
  Cell cell;
  cell.devices = std::make_unique<HardwareDeviceSet>(config);
  spdlog::warn(
      "backend hardware: devices connect, home, stop and report health (cameras: opened and checked with one "
      "frame); calibration and scan jobs on the "
      "real cell are not available in this version (use the sim backend or `idi-workcell calibrate` "
      "with recorded observation files)");
  return cell;
}

}  // namespace

Result<Cell> MakeCell(const WorkcellConfig& config) {
  if (config.backend == "sim") return MakeSimCell(config);
  if (config.backend == "hardware") return MakeHardwareCell(config);
  return InvalidArgument("unknown backend '" + config.backend + "' (sim or hardware)");
}

}  // namespace idi::workcell
