#include "rmp/app/replay_run.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <optional>

#include "rmp/segway/rmp_codec.h"
#include "shared/replay/can_log_bus.h"

namespace idi::rmp {
namespace {

// The log's frames, delivered to the loop when the log says they were.
class LogFrames final : public FrameSource {
 public:
  explicit LogFrames(const replay::DriveLog* log) : log_(log) {
    for (std::size_t i = 0; i < log->frames.size(); ++i) {
      if (log->frames[i].delivered_ns >= 0) order_.push_back(i);
    }
    std::stable_sort(order_.begin(), order_.end(), [&](std::size_t a, std::size_t b) {
      return log->frames[a].delivered_ns < log->frames[b].delivered_ns;
    });
  }
  Result<std::vector<hal::Image>> Collect(int64_t now_ns) override {
    std::vector<hal::Image> out;
    while (next_ < order_.size() && log_->frames[order_[next_]].delivered_ns <= now_ns) {
      IDI_ASSIGN_OR_RETURN(hal::Image img, replay::LoadDriveFrame(*log_, log_->frames[order_[next_]]));
      out.push_back(std::move(img));
      ++next_;
    }
    return out;
  }

 private:
  const replay::DriveLog* log_;
  std::vector<std::size_t> order_;
  std::size_t next_ = 0;
};

}  // namespace

Result<ReplayResult> RunReplay(const ReplayOptions& o) {
  IDI_ASSIGN_OR_RETURN(const replay::DriveLog log, replay::ReadDriveLog(o.dir));
  return RunReplay(o, log);
}

Result<ReplayResult> RunReplay(const ReplayOptions& o, const replay::DriveLog& log) {
  const nlohmann::json& meta = log.recording.header.meta;
  const std::string header_path = o.dir + "/recording.json";
  if (log.ticks.empty()) return InvalidArgument(o.dir + ": the drive log has no control ticks");
  if (log.can.empty()) return InvalidArgument(o.dir + ": the drive log's can.log is empty");
  // A recording cut by a power loss replays up to the tear.
  if (log.recording.truncated) {
    spdlog::warn(
        "{}/events.jsonl:{}: the last line is torn (no newline, or NUL bytes only: the recorder stopped "
        "mid-line?); skipped",
        o.dir,
        log.recording.truncated_line);
  }
  if (!log.can_torn_last_line.empty()) {
    spdlog::warn("{}/{}:{}: the last line has no newline (the recorder stopped mid-line?); dropped: '{}'",
                 o.dir,
                 replay::kDriveLogCanFile,
                 log.can_torn_line,
                 log.can_torn_last_line);
  }
  // The pipeline as it was configured when the log was recorded.
  RmpConfig config = DefaultRmpConfig();
  if (!meta.is_null() && !meta.is_object()) return InvalidArgument(header_path + ": meta must be an object");
  // A number of the recording's metadata, when it is there.
  auto meta_number = [&](const char* key) -> Result<std::optional<double>> {
    if (!meta.is_object() || !meta.contains(key)) return std::optional<double>();
    if (!meta[key].is_number()) return InvalidArgument(header_path + ": meta." + key + " must be a number");
    return std::optional<double>(meta[key].get<double>());
  };
  if (meta.is_object() && meta.contains("config_yaml")) {
    if (!meta["config_yaml"].is_string()) return InvalidArgument(header_path + ": meta.config_yaml must be a string");
    const std::string config_yaml = meta["config_yaml"].get<std::string>();
    if (!config_yaml.empty()) {
      IDI_ASSIGN_OR_RETURN(config, ParseRmpConfig(config_yaml, header_path + " (config_yaml)"));
    }
  }
  IDI_ASSIGN_OR_RETURN(const std::optional<double> cruise, meta_number("cruise_speed_mps"));
  IDI_ASSIGN_OR_RETURN(const std::optional<double> tape_width, meta_number("tape_width_m"));
  // A value the options refuse is the recording's: its file and key start the message.
  if (cruise) {
    config.planner.cruise_speed_mps = *cruise;
    config.planner.max_speed_mps = std::max(config.planner.max_speed_mps, config.planner.cruise_speed_mps);
    IDI_RETURN_IF_ERROR(
        config.planner.Check().WithContext(fmt::format("{}: meta.cruise_speed_mps {}", header_path, *cruise)));
  }
  if (tape_width) {
    config.perception.tape.SetTapeWidth(*tape_width);
    IDI_RETURN_IF_ERROR(
        config.perception.Check().WithContext(fmt::format("{}: meta.tape_width_m {}", header_path, *tape_width)));
  }
  IDI_RETURN_IF_ERROR(config.planner.Check().WithContext(header_path));
  IDI_RETURN_IF_ERROR(config.perception.Check().WithContext(header_path));
  IDI_ASSIGN_OR_RETURN(std::unique_ptr<TrackPerception> perception,
                       TrackPerception::Create(config.rig, config.perception));

  // The clock starts where the log does (its first frame or its first tick, whichever is earlier: on the
  // vehicle the schedule's clock reading comes before the first frame's stamp, in microseconds); the
  // driver's own frames are compared, not delivered.
  int64_t start_ns = log.can.front().frame.timestamp_ns;
  if (!log.ticks.empty()) start_ns = std::min(start_ns, log.ticks.front().t_ns);
  hal::SimClock clock(start_ns);
  replay::CanLogReplayOptions ro;
  ro.own_ids = {kRmpIdCommand, kRmpIdShutdown};
  replay::CanLogReplayBus bus(log.can, &clock, ro);
  // Before the driver: its destructor's last zero command goes to this log, also on an early return.
  std::unique_ptr<replay::CandumpWriter> can_out;
  if (!o.can_log.empty()) {
    replay::CandumpWriterOptions co;
    co.mark_direction = true;
    IDI_ASSIGN_OR_RETURN(can_out, replay::CandumpWriter::Open(o.can_log, co));
  }
  IDI_ASSIGN_OR_RETURN(std::unique_ptr<RmpDriver> driver, RmpDriver::Create(&bus, &clock, config.driver));
  if (can_out) driver->SetFrameLog(can_out.get());
  LogFrames frames(&log);
  ControlLoop loop(
      config.control, &clock, driver.get(), &frames, perception.get(), config.planner, config.track, nullptr);
  IDI_RETURN_IF_ERROR(loop.Start());

  ReplayResult result;
  double sum_sq = 0.0, max_lat = 0.0;
  int lat_n = 0;
  uint64_t pairs_with_track = 0;
  bool moving = false;
  bool stopped = false;
  // The driver's frames sent before a stop: the stop's own zero commands are not the recording's.
  std::size_t sent_before_stop = 0;
  for (const replay::DriveTickRecord& want : log.ticks) {
    if (o.stop != nullptr && o.stop->load()) {
      sent_before_stop = bus.sent().size();
      loop.RequestStop("signal");
      stopped = true;
      break;
    }
    // The recorded run's schedule: its start and every move after a late tick.
    const std::string where = fmt::format("{}/events.jsonl:{}", o.dir, want.line);
    if (driver->next_send_ns() != want.t_ns) {
      // ReadDriveLog refused ticks out of order: a tick before now is the replay's fault.
      const Status st = driver->ResyncSchedule(want.t_ns);
      if (!st.ok()) return Internal(where + ": the replay cannot tick at the log's time: " + st.message());
      ++result.ticks_resynced;
    }
    IDI_ASSIGN_OR_RETURN(const TickRecord got, loop.Step());
    if (got.t_ns != want.t_ns) {
      return Internal(where + ": replay tick at " + std::to_string(got.t_ns) + " ns, the log's at " +
                      std::to_string(want.t_ns) + " ns (the driver's schedule differs from the recording)");
    }
    ++result.ticks_compared;
    const double dv = std::abs(got.speed_mps - want.speed_mps), dw = std::abs(got.yaw_rate_rps - want.yaw_rate_rps);
    result.max_speed_difference_mps = std::max(result.max_speed_difference_mps, dv);
    result.max_yaw_rate_difference_rps = std::max(result.max_yaw_rate_difference_rps, dw);
    if (dv < 1e-6 && dw < 1e-6 && want.decision == DecisionName(got.decision)) {
      ++result.ticks_matching;
    } else if (result.first_tick_difference_line == 0) {
      result.first_tick_difference_s = static_cast<double>(want.t_ns - log.ticks.front().t_ns) * 1e-9;
      result.first_tick_difference_line = want.line;
    }
    if (got.perceived && loop.last_perception() != nullptr && !loop.last_perception()->observation.pieces.empty())
      ++pairs_with_track;
    if (got.speed_mps != 0.0 || got.yaw_rate_rps != 0.0) moving = true;
    if (o.on_tick) o.on_tick(got);
    if (moving && !loop.finished() && loop.track().initialised()) {
      const double e = std::abs(loop.track().vehicle_offset_m());
      sum_sq += e * e;
      max_lat = std::max(max_lat, e);
      ++lat_n;
    }
  }
  // The recorded run's own shutdown frames follow; replay them too. A log cut at a torn line (a power
  // loss) has none: its can.log goes on with the frames of the ticks after the tear, so the replay's own
  // shutdown is not compared.
  const bool cut = log.recording.truncated && !stopped;
  const std::size_t sent_before_shutdown = bus.sent().size();
  const Status shutdown = loop.Shutdown();
  if (!shutdown.ok()) spdlog::warn("replay: driver shutdown: {}", shutdown.ToString());

  // The driver's frames against the log's, in order (after a stop or at a tear, those before it).
  const std::vector<hal::CanFrame>& sent = bus.sent();
  const std::vector<hal::CanFrame>& logged = bus.logged_transmitted();
  const std::size_t n = std::min(stopped ? sent_before_stop : cut ? sent_before_shutdown : sent.size(), logged.size());
  for (std::size_t i = 0; i < n; ++i) {
    ++result.can_frames_compared;
    if (sent[i].id == logged[i].id && sent[i].dlc == logged[i].dlc && sent[i].data == logged[i].data &&
        std::llabs(bus.ClockTimeForLog(logged[i].timestamp_ns) - sent[i].timestamp_ns) <= 1000) {
      ++result.can_frames_matching;
    }
  }
  RunReport& r = result.report;
  const ControlLoopStats& st = loop.stats();
  r.frames = st.perceptions;
  r.perception_ms_median = st.perception_ms.Percentile(0.5);
  r.perception_ms_p99 = st.perception_ms.Percentile(0.99);
  r.frame_to_command_ms_median = st.frame_to_command_ms.Percentile(0.5);
  r.frame_to_command_ms_p99 = st.frame_to_command_ms.Percentile(0.99);
  r.frozen_frames = st.frozen_frames;
  r.dropped_frames = st.dropped_frames;
  r.unpaired_frames = st.unpaired_frames;
  r.pairs_without_pose = st.pairs_without_pose;
  r.pairs_from_the_future = st.pairs_from_the_future;
  r.perception_errors = st.perception_errors;
  r.decisions = st.decisions;
  r.commands = driver->health().counters.frames_sent;
  r.commands_nonzero = driver->health().counters.motion_frames;
  r.completed = loop.finished();
  r.end = stopped ? "stopped" : loop.finished() ? "finished" : "log-ended";
  r.distance_m = driver->odometry().pose().distance_m;
  const int64_t t_begin = st.running_since_ns >= 0 ? st.running_since_ns : start_ns;
  const int64_t t_end = st.finished_ns >= 0 ? st.finished_ns : stopped ? clock.NowNs() : log.ticks.back().t_ns;
  r.time_s = static_cast<double>(t_end - t_begin) * 1e-9;
  r.lateral_error_rms_m = lat_n > 0 ? std::sqrt(sum_sq / lat_n) : 0.0;
  r.lateral_error_max_m = max_lat;
  r.track_visible_fraction =
      st.perceptions > 0 ? static_cast<double>(pairs_with_track) / static_cast<double>(st.perceptions) : 0.0;
  r.cruise_speed_mps = config.planner.cruise_speed_mps;
  r.extra["lateral_error_reference"] = "the perceived track (no ground truth in a log)";
  r.extra["track_visible_reference"] = "stereo pairs in which the track was perceived";
  r.extra["ticks_compared"] = result.ticks_compared;
  r.extra["ticks_matching"] = result.ticks_matching;
  r.extra["ticks_resynced"] = result.ticks_resynced;
  r.extra["can_frames_compared"] = result.can_frames_compared;
  r.extra["can_frames_matching"] = result.can_frames_matching;
  r.extra["can_frames_logged"] = logged.size();
  r.extra["can_frames_sent"] = sent.size();
  r.extra["max_speed_difference_mps"] = result.max_speed_difference_mps;
  r.extra["max_yaw_rate_difference_rps"] = result.max_yaw_rate_difference_rps;
  if (stopped) r.extra["comparison"] = "up to the stop (the ticks and CAN frames before it)";
  if (cut) {
    r.extra["comparison"] = fmt::format("up to the torn line {} of events.jsonl (the ticks and CAN frames before it)",
                                        log.recording.truncated_line);
  }
  r.extra["commands_reproduced"] = result.commands_reproduced();
  if (result.first_tick_difference_line > 0) {
    r.extra["first_tick_difference_s"] = result.first_tick_difference_s;
    r.extra["first_tick_difference_line"] = result.first_tick_difference_line;
  }
  if (can_out) {
    IDI_RETURN_IF_ERROR(can_out->Close());
    r.extra["can_log"] = o.can_log;
  }
  return result;
}

std::string ReplayComparisonSummary(const ReplayResult& r) {
  const uint64_t ticks_differing = r.ticks_compared - r.ticks_matching;
  const uint64_t frames_differing = r.can_frames_compared - r.can_frames_matching;
  if (r.commands_reproduced()) {
    return fmt::format("commands reproduced: yes ({} ticks and {} CAN frames compared, all as recorded)",
                       r.ticks_compared,
                       r.can_frames_compared);
  }
  std::string why;
  if (ticks_differing > 0) {
    why = fmt::format("{} of {} ticks differ, first at t={:.3f} s, events.jsonl line {}",
                      ticks_differing,
                      r.ticks_compared,
                      r.first_tick_difference_s,
                      r.first_tick_difference_line);
  }
  if (frames_differing > 0) {
    why +=
        fmt::format("{}{} of {} CAN frames differ", why.empty() ? "" : "; ", frames_differing, r.can_frames_compared);
  }
  return "commands reproduced: no (" + why + ")";
}

}  // namespace idi::rmp
