#include "rmp/app/rmp_commands.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <sys/stat.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <iostream>
#include <memory>
#include <set>
#include <vector>

#include "rmp/app/hardware_run.h"
#include "rmp/app/replay_run.h"
#include "rmp/app/sim_run.h"
#include "shared/runtime/stop_signals.h"
#include "shared/runtime/systemd_notify.h"
#include "shared/util/atomic_file.h"

namespace idi::rmp {
namespace {

void PrintReport(const RunReport& r, bool json) {
  if (json) {
    std::cout << r.ToJson().dump() << "\n";
    return;
  }
  std::cout << fmt::format(
      "{}: {:.2f} m in {:.1f} s, lateral error rms {:.1f} mm max {:.1f} mm, track visible {:.1f} %, {} stereo pairs "
      "(perception median {:.2f} ms, p99 {:.2f} ms), {} commands ({})\n",
      r.completed ? "completed" : "not completed",
      r.distance_m,
      r.time_s,
      1000 * r.lateral_error_rms_m,
      1000 * r.lateral_error_max_m,
      100 * r.track_visible_fraction,
      r.frames,
      r.perception_ms_median,
      r.perception_ms_p99,
      r.commands,
      r.end);
}

// The end of a replay, `replay`'s and `run`'s with the replay backend: the report, then (text output) the
// comparison line. Commands not reproduced are a failed run (exit 1): the replay ran, and its result is
// that the log is not reproduced. `what` starts the error message.
Status ReportReplay(const ReplayResult& res, const std::string& what, bool json) {
  PrintReport(res.report, json);
  const std::string comparison = ReplayComparisonSummary(res);
  if (!json) std::cout << comparison << "\n";
  if (!res.commands_reproduced()) return FailedPrecondition(what + ": " + comparison);
  return Status::Ok();
}

// A check of an output before the run: when it fails nothing ran, so the command line is at fault
// (InvalidArgument, exit 2) whatever the check's own code (an unwritable folder is an IoError).
Status BeforeTheRun(const Status& st) {
  return st.ok() || st.code() == StatusCode::kInvalidArgument ? st : InvalidArgument(st.message());
}

// Whether `path` is `folder` or a file or folder inside it (symbolic links of the existing part of each
// resolved, so that "rec/../rec/x" and a link to the folder count too).
bool InsideFolder(const std::string& path, const std::string& folder) {
  namespace fs = std::filesystem;
  auto resolved = [](const std::string& p) {
    std::error_code ec;
    fs::path r = fs::weakly_canonical(fs::absolute(p, ec), ec).lexically_normal();
    if (!r.has_filename() && r.has_parent_path()) r = r.parent_path();  // "rec/" names "rec"
    return r;
  };
  const fs::path f = resolved(folder), p = resolved(OutputTarget(path));  // a link is written through
  const auto [f_end, p_at] = std::mismatch(f.begin(), f.end(), p.begin(), p.end());
  return f_end == f.end();
}

// Refuses an output file inside a folder the command reads or writes as a whole (a drive log), and one
// that is the folder or one of its parents (writing a file there would fail after the run, or replace
// the folder that holds the log).
Status CheckOutsideFolder(const std::vector<NamedFile>& outputs, const NamedFile& folder, const std::string& command) {
  if (folder.path.empty()) return Status::Ok();
  for (const NamedFile& out : outputs) {
    if (out.path.empty()) continue;
    if (InsideFolder(out.path, folder.path)) {
      return InvalidArgument(command + ": " + out.option + " " + out.path + " is inside the drive log " +
                             folder.option + " " + folder.path +
                             ": writing it would damage the log (name a file outside it)");
    }
    if (InsideFolder(folder.path, out.path)) {
      return InvalidArgument(command + ": the drive log " + folder.option + " " + folder.path + " is inside " +
                             out.option + " " + out.path + ": it cannot be both a file and the log's folder " +
                             "(name a file outside the log)");
    }
  }
  return Status::Ok();
}

// Every regular file of a drive log folder, its subfolders' (images/) included, as inputs for
// CheckDistinctFiles (a hard link or symbolic link to one of them elsewhere is the same file). Symbolic
// links inside the log are not followed: they are not part of it.
std::vector<NamedFile> DriveLogFiles(const std::string& dir) {
  namespace fs = std::filesystem;
  std::vector<NamedFile> files;
  std::error_code ec;
  for (fs::recursive_directory_iterator it(dir, fs::directory_options::skip_permission_denied, ec), end;
       !ec && it != end;
       it.increment(ec)) {
    std::error_code type_ec;
    if (it->is_regular_file(type_ec) && !it->is_symlink(type_ec))
      files.push_back({"drive log file", it->path().string()});
  }
  return files;
}

// `replay`'s output against its input: the CAN log it writes must not be one of the log's files, nor
// one of the files the reader reads through a link (an images/ that links to another folder), nor lie
// in a folder of the log's images.
Status CheckReplayFiles(const ReplayOptions& o, const replay::DriveLog& log) {
  if (o.can_log.empty()) return Status::Ok();
  const std::vector<NamedFile> outputs = {{"--can-log", o.can_log}};
  IDI_RETURN_IF_ERROR(CheckOutsideFolder(outputs, {"DIR", o.dir}, "replay"));
  std::vector<NamedFile> inputs = DriveLogFiles(o.dir);
  const std::filesystem::path dir(o.dir);
  for (const char* file : {"recording.json", "events.jsonl", replay::kDriveLogCanFile})
    inputs.push_back({"drive log file", (dir / file).string()});
  std::set<std::string> image_folders;
  for (const replay::DriveFrameRecord& frame : log.frames) {
    IDI_ASSIGN_OR_RETURN(std::string image, RecordedImagePath(log.recording, log.recording.events[frame.event]));
    image_folders.insert(std::filesystem::path(image).parent_path().string());
    inputs.push_back({"recorded image", std::move(image)});
  }
  IDI_RETURN_IF_ERROR(CheckDistinctFiles(inputs, outputs, "replay"));
  for (const std::string& folder : image_folders) {
    IDI_RETURN_IF_ERROR(CheckOutsideFolder(outputs, {"images folder", folder}, "replay"));
  }
  return BeforeTheRun(CheckOutputFile(o.can_log, "--can-log"));
}

// The drive log folder of `run` and `sim`, made before the run (and before the service says it is ready).
// `made`: by this run, with the missing folders on its way from `top` down, which are removed again when
// the run leaves them empty (so that a failed run, or a service systemd restarts, leaves none behind).
struct RecordFolder {
  std::string path;  // empty: none
  bool made = false;
  std::filesystem::path top;  // the first folder on the way that this run made (path itself at most)
  ~RecordFolder() {
    if (!made) return;
    std::error_code ec;
    for (std::filesystem::path p = path; !p.empty(); p = p.parent_path()) {
      if (!std::filesystem::is_empty(p, ec) || ec || !std::filesystem::remove(p, ec)) return;
      if (top.empty() || p == top) return;
    }
  }
  RecordFolder() = default;
  RecordFolder(const RecordFolder&) = delete;
  RecordFolder& operator=(const RecordFolder&) = delete;
};

// --record of `command` (run, sim): a new or empty folder (CheckNewOutputFolder), made here with its
// parents. One that holds files or cannot be made is the command line's fault (exit 2), told before the
// run rather than when the recorder starts.
Status MakeRecordFolder(const std::string& command, const std::string& path, RecordFolder* folder) {
  namespace fs = std::filesystem;
  IDI_RETURN_IF_ERROR(BeforeTheRun(CheckNewOutputFolder(path, command + ": --record")));
  std::error_code ec;
  if (!fs::is_directory(path, ec)) {
    fs::path top;
    for (fs::path p = path; !p.empty() && !fs::exists(fs::symlink_status(p, ec)); p = p.parent_path()) top = p;
    const bool made = fs::create_directories(path, ec);
    if (ec || !fs::is_directory(path, ec)) {
      std::error_code link_ec;
      const std::string why = fs::is_symlink(path, link_ec)
                                  ? "it is a link to " + fs::read_symlink(path, link_ec).string() + ", not to a folder"
                              : ec ? ec.message()
                                   : std::string("something else is there");
      return InvalidArgument(command + ": --record " + path + ": cannot make the folder: " + why);
    }
    // Made by another process in between: theirs, not removed.
    folder->made = made;
    folder->top = top;
  }
  folder->path = path;
  return Status::Ok();
}

struct SimCli {
  std::string track, record, can_log, png, config, report;
  double speed_mps = 0.0, max_time_s = 0.0;
  bool speed_given = false, max_time_given = false;  // set after parsing
  bool json = false, real_time = false;
};

// The track file's own speed limit (TrackSpec::Check), for --speed-mps.
constexpr double kMaxSpeedMps = 3.0;
// A simulated day: a limit, not "never" (the loop runs until the track's end or the limit).
constexpr double kMaxSimTimeS = 86400.0;

Status CheckSimCli(const SimCli& o) {
  if (o.track.empty()) return InvalidArgument("sim: --track TRACK.yaml is required");
  if (o.speed_given && !(o.speed_mps > 0 && o.speed_mps <= kMaxSpeedMps)) {
    return InvalidArgument(fmt::format("sim: --speed-mps must be in (0, {}] m/s, got {}", kMaxSpeedMps, o.speed_mps));
  }
  if (o.max_time_given && !(o.max_time_s > 0 && o.max_time_s <= kMaxSimTimeS)) {
    return InvalidArgument(fmt::format("sim: --max-time-s must be in (0, {}] s, got {}", kMaxSimTimeS, o.max_time_s));
  }
  // Before the run, not after it: an output that would destroy an input, the recording or another
  // output, and one that cannot be written.
  const std::vector<NamedFile> outputs = {{"--report", o.report}, {"--png", o.png}, {"--can-log", o.can_log}};
  std::vector<NamedFile> all_outputs = outputs;
  all_outputs.push_back({"--record", o.record});
  IDI_RETURN_IF_ERROR(CheckOutsideFolder(outputs, {"--record", o.record}, "sim"));
  IDI_RETURN_IF_ERROR(CheckDistinctFiles({{"--track", o.track}, {"--config", o.config}}, all_outputs, "sim"));
  for (const NamedFile& out : outputs) IDI_RETURN_IF_ERROR(BeforeTheRun(CheckOutputFile(out.path, out.option)));
  return BeforeTheRun(CheckOutputFolder(o.record, "--record"));
}

Status RunSimCli(const SimCli& o) {
  IDI_RETURN_IF_ERROR(CheckSimCli(o));
  RecordFolder record_folder;
  if (!o.record.empty()) IDI_RETURN_IF_ERROR(MakeRecordFolder("sim", o.record, &record_folder));
  SimRunOptions so;
  if (!o.config.empty()) {
    IDI_ASSIGN_OR_RETURN(so.config, LoadRmpConfig(o.config));
    IDI_ASSIGN_OR_RETURN(so.config_text, ReadFile(o.config));
  }
  IDI_ASSIGN_OR_RETURN(so.track, LoadTrackFile(o.track));
  if (o.speed_given) so.track.speed_mps = o.speed_mps;
  if (so.track.speed_mps == 0) so.track.speed_mps = so.config.planner.cruise_speed_mps;
  so.record_dir = o.record;
  so.can_log = o.can_log;
  so.png = o.png;
  if (o.max_time_given) so.max_time_s = o.max_time_s;
  so.real_time = o.real_time || so.config.sim_real_time;
  const StopSignals signals;
  so.stop = signals.flag();
  IDI_ASSIGN_OR_RETURN(const SimRunResult res, RunSimulation(so));
  // The summary even when an output failed: the run itself is not lost with it.
  Status written = res.output_status;
  if (!o.report.empty()) {
    const Status st = WriteFileAtomically(o.report, res.report.ToJson().dump(2) + "\n");
    if (written.ok()) written = st;
  }
  PrintReport(res.report, o.json);
  IDI_RETURN_IF_ERROR(written);
  if (signals.requested()) return Cancelled("sim: stopped by a signal (zero commanded)");
  return Status::Ok();
}

struct RunCli {
  std::string config, record;
  bool json = false;
};

// state_dir/logs/<local time to the second>, or <time>-2, -3, ... when that is taken: made with mkdir,
// which only one process succeeds in, so that two runs started within a second never share a folder.
Status MakeLogFolder(const RunCli& o, const RmpConfig& config, RecordFolder* folder) {
  const std::string logs = (std::filesystem::path(config.state_dir) / "logs").string();
  std::error_code ec;
  std::filesystem::create_directories(logs, ec);
  if (ec) {
    return InvalidArgument(o.config + ": state_dir " + config.state_dir + ": cannot make " + logs +
                           " for record: true: " + ec.message());
  }
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  localtime_r(&now, &tm);
  char buf[64];
  std::strftime(buf, sizeof(buf), "%Y%m%d-%H%M%S", &tm);
  const std::string base = (std::filesystem::path(logs) / buf).string();
  constexpr int kMaxTries = 1000;
  for (int n = 1; n <= kMaxTries; ++n) {
    const std::string path = n == 1 ? base : fmt::format("{}-{}", base, n);
    if (::mkdir(path.c_str(), 0755) == 0) {
      folder->path = path;
      folder->made = true;
      return Status::Ok();
    }
    if (errno != EEXIST) {
      return InvalidArgument(o.config + ": state_dir " + config.state_dir + " (record: true): cannot make " + path +
                             ": " + std::strerror(errno));
    }
  }
  return InvalidArgument(fmt::format("{}: state_dir {} (record: true): {} and {} more drive logs of this second exist",
                                     o.config,
                                     config.state_dir,
                                     base,
                                     kMaxTries - 1));
}

// The drive log folder of `run`: --record, else state_dir/logs/<time> when the config says record: true.
// Checked and made before the run (and before READY=1); none when folder->path stays empty.
Status RunRecordFolder(const RunCli& o, const RmpConfig& config, RecordFolder* folder) {
  if (config.backend == Backend::kReplay) {
    // The replay drives nothing: its drive log is replay.dir. Its report is the output.
    if (!o.record.empty()) {
      return InvalidArgument(
          "run: --record is not supported with the replay backend (" + o.config +
          "): the drive log it replays is replay.dir; for the replayed CAN frames use idi-rmp replay "
          "DIR --can-log FILE");
    }
    if (config.record)
      spdlog::warn("{}: record: true is ignored by the replay backend (its drive log is replay.dir)", o.config);
    return Status::Ok();
  }
  std::vector<NamedFile> inputs = {{"--config", o.config}};
  if (config.backend == Backend::kSim) inputs.push_back({"sim.track", config.sim_track});
  if (!o.record.empty()) {
    IDI_RETURN_IF_ERROR(CheckDistinctFiles(inputs, {{"--record", o.record}}, "run"));
    IDI_RETURN_IF_ERROR(BeforeTheRun(CheckOutputFolder(o.record, "--record")));
    return MakeRecordFolder("run", o.record, folder);
  }
  if (!config.record) return Status::Ok();
  if (config.state_dir.empty()) return InvalidArgument(o.config + ": record: true needs state_dir");
  return MakeLogFolder(o, config, folder);
}

Status RunService(const RunCli& o) {
  IDI_ASSIGN_OR_RETURN(const RmpConfig config, LoadRmpConfig(o.config));
  IDI_ASSIGN_OR_RETURN(const std::string config_text, ReadFile(o.config));
  RecordFolder record_folder;
  IDI_RETURN_IF_ERROR(RunRecordFolder(o, config, &record_folder));
  const std::string& record = record_folder.path;
  const StopSignals signals;
  spdlog::info("idi-rmp run: backend {} ({})", BackendName(config.backend), o.config);
  RunReport report;
  switch (config.backend) {
    case Backend::kSim: {
      if (config.sim_track.empty()) return InvalidArgument(o.config + ": backend sim needs sim.track");
      SimRunOptions so;
      so.config = config;
      so.config_text = config_text;
      IDI_ASSIGN_OR_RETURN(so.track, LoadTrackFile(config.sim_track));
      if (so.track.speed_mps == 0) so.track.speed_mps = config.planner.cruise_speed_mps;
      so.record_dir = record;
      so.real_time = config.sim_real_time;
      so.stop = signals.flag();
      NotifyReady();
      auto res = RunSimulation(so);
      NotifyStopping();
      if (!res.ok()) return res.status();
      if (!res->output_status.ok()) {
        PrintReport(res->report, o.json);
        return res->output_status;
      }
      report = res->report;
      break;
    }
    case Backend::kReplay: {
      if (config.replay_dir.empty()) return InvalidArgument(o.config + ": backend replay needs replay.dir");
      ReplayOptions ro;
      ro.dir = config.replay_dir;
      ro.stop = signals.flag();  // the service's stop (SIGTERM from systemd): zero and end, like the sim backend
      NotifyReady();
      auto res = RunReplay(ro);
      NotifyStopping();
      if (!res.ok()) return res.status();
      // As `replay` ends: the comparison line, and exit 1 when the log's commands were not reproduced.
      return ReportReplay(*res, "run: replay.dir " + config.replay_dir + " (" + o.config + ")", o.json);
    }
    case Backend::kHardware: {
      HardwareRunOptions ho;
      ho.config = config;
      ho.config_text = config_text;
      ho.record_dir = record;
      ho.stop = signals.flag();
      IDI_ASSIGN_OR_RETURN(report, RunHardware(ho));
      break;
    }
  }
  PrintReport(report, o.json);
  return Status::Ok();
}

}  // namespace

CLI::App* AddSimRunCommand(CliApp& cli, CLI::App* sim) {
  auto o = std::make_shared<SimCli>();
  if (sim == nullptr) sim = cli.app.add_subcommand("sim", "the closed loop in the digital twin (and its tools)");
  sim->add_option("--track", o->track, "TRACK.yaml: the taped track (DESIGN.md §6)");
  sim->add_flag("--json", o->json, "print the report as JSON on stdout");
  sim->add_option("--record", o->record, "write a drive log (images, CAN, ticks) to this new or empty folder");
  sim->add_option("--can-log", o->can_log, "write the RMP's CAN traffic in candump -l format");
  sim->add_option("--png", o->png, "write the track with the driven path and the lateral error");
  sim->add_option("--report", o->report, "also write the JSON report to this file");
  sim->add_option("--config", o->config, "rmp.yaml: rig, planner, control, sim options and faults");
  sim->add_option("--speed-mps", o->speed_mps, "cruise speed (default: the track's speed_mps, else the config's)");
  sim->add_option("--max-time-s", o->max_time_s, "simulated time limit (default: from the track's length)");
  sim->add_flag("--real-time", o->real_time, "pace the twin with the wall clock");
  sim->parse_complete_callback([&cli, sim, o] {
    o->speed_given = sim->count("--speed-mps") > 0;
    o->max_time_given = sim->count("--max-time-s") > 0;
    if (sim->get_subcommands().empty()) cli.selected = [o] { return RunSimCli(*o); };
  });
  return sim;
}

void AddReplayCommand(CliApp& cli) {
  auto o = std::make_shared<ReplayOptions>();
  auto json = std::make_shared<bool>(false);
  CLI::App* cmd =
      cli.AddCommand(&cli.app,
                     "replay",
                     "re-run the pipeline on a drive log and compare the commands (exit 1 when they differ)",
                     [o, json] {
                       IDI_ASSIGN_OR_RETURN(const replay::DriveLog log, replay::ReadDriveLog(o->dir));
                       IDI_RETURN_IF_ERROR(CheckReplayFiles(*o, log));
                       const StopSignals signals;
                       ReplayOptions ro = *o;
                       ro.stop = signals.flag();
                       IDI_ASSIGN_OR_RETURN(const ReplayResult res, RunReplay(ro, log));
                       const Status reported = ReportReplay(res, "replay " + o->dir, *json);
                       if (signals.requested()) return Cancelled("replay: stopped by a signal (zero commanded)");
                       return reported;
                     });
  cmd->add_option("dir", o->dir, "the drive log folder (idi-rmp sim --record, or the vehicle's state_dir/logs)")
      ->required();
  cmd->add_flag("--json", *json, "print the report as JSON on stdout");
  cmd->add_option("--can-log", o->can_log, "write the replayed driver's CAN frames in candump -l format");
  cmd->footer(
      "After the report: \"commands reproduced: yes (...)\", or \"commands reproduced: no (N of M ticks differ, "
      "first at t=T s, events.jsonl line L; K of F CAN frames differ)\" (JSON: commands_reproduced).\n"
      "Exit 0: the recorded commands were reproduced; 1: they were not, or the replay failed; 2: a log or option "
      "it refuses (nothing replayed).");
}

void AddRunCommand(CliApp& cli) {
  auto o = std::make_shared<RunCli>();
  CLI::App* cmd =
      cli.AddCommand(&cli.app, "run", "drive: the service (hardware, replay or sim backend from the config)", [o] {
        return RunService(*o);
      });
  cmd->add_option("--config", o->config, "rmp.yaml (e.g. /etc/idi/rmp.yaml)")->required();
  cmd->add_option(
      "--record",
      o->record,
      "write a drive log to this new or empty folder (default: state_dir/logs/<time>, or <time>-2, -3, ... when "
      "taken, if record: true)");
  cmd->add_flag("--json", o->json, "print the final report as JSON on stdout");
}

}  // namespace idi::rmp
