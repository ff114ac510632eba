#include "rmp/app/sim_run.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <thread>

#include "shared/plot/plot.h"
#include "shared/plot/png_file.h"
#include "shared/util/atomic_file.h"

namespace idi::rmp {

nlohmann::json RunReport::ToJson() const {
  nlohmann::json j;
  j["completed"] = completed;
  j["distance_m"] = distance_m;
  j["time_s"] = time_s;
  j["lateral_error_rms_m"] = lateral_error_rms_m;
  j["lateral_error_max_m"] = lateral_error_max_m;
  j["track_visible_fraction"] = track_visible_fraction;
  j["frames"] = frames;
  j["perception_ms_median"] = perception_ms_median;
  j["perception_ms_p99"] = perception_ms_p99;
  j["commands"] = commands;
  j["commands_nonzero"] = commands_nonzero;
  if (end_distance_m >= 0) j["end_distance_m"] = end_distance_m;
  j["end"] = end;
  j["cruise_speed_mps"] = cruise_speed_mps;
  j["max_speed_mps"] = max_speed_mps;
  j["frame_to_command_ms_median"] = frame_to_command_ms_median;
  j["frame_to_command_ms_p99"] = frame_to_command_ms_p99;
  j["frozen_frames"] = frozen_frames;
  j["dropped_frames"] = dropped_frames;
  j["unpaired_frames"] = unpaired_frames;
  j["pairs_without_pose"] = pairs_without_pose;
  j["pairs_from_the_future"] = pairs_from_the_future;
  j["perception_errors"] = perception_errors;
  j["decisions"] = decisions;
  for (const auto& [k, v] : extra.items()) j[k] = v;
  return j;
}

namespace {

nlohmann::json RigJson(const StereoRig& rig) {
  nlohmann::json j;
  for (const RigCamera* c : {&rig.left, &rig.right}) {
    nlohmann::json cj;
    cj["params"] = c->intrinsics.params;
    cj["width"] = c->intrinsics.width;
    cj["height"] = c->intrinsics.height;
    const Eigen::Matrix<double, 3, 4> m = c->vehicle_from_camera.Matrix3x4();
    std::vector<double> v;
    for (int r = 0; r < 3; ++r) {
      for (int k = 0; k < 4; ++k) v.push_back(m(r, k));
    }
    cj["vehicle_from_camera"] = v;
    j[c == &rig.left ? "left" : "right"] = cj;
  }
  return j;
}

void FillFromLoop(const ControlLoop& loop, RunReport* r) {
  const ControlLoopStats& st = loop.stats();
  r->frames = st.perceptions;
  r->perception_ms_median = st.perception_ms.Percentile(0.5);
  r->perception_ms_p99 = st.perception_ms.Percentile(0.99);
  r->frame_to_command_ms_median = st.frame_to_command_ms.Percentile(0.5);
  r->frame_to_command_ms_p99 = st.frame_to_command_ms.Percentile(0.99);
  r->frozen_frames = st.frozen_frames;
  r->dropped_frames = st.dropped_frames;
  r->unpaired_frames = st.unpaired_frames;
  r->pairs_without_pose = st.pairs_without_pose;
  r->pairs_from_the_future = st.pairs_from_the_future;
  r->perception_errors = st.perception_errors;
  r->decisions = st.decisions;
  const RmpDriverCounters& c = loop.driver()->health().counters;
  r->commands = c.frames_sent;
  r->commands_nonzero = c.motion_frames;
}

}  // namespace

Result<SimRunResult> RunSimulation(const SimRunOptions& o) {
  RmpConfig config = o.config;
  IDI_RETURN_IF_ERROR(o.track.Check());
  if (o.track.speed_mps > 0) config.planner.cruise_speed_mps = o.track.speed_mps;
  config.planner.max_speed_mps = std::max(config.planner.max_speed_mps, config.planner.cruise_speed_mps);
  config.perception.tape.SetTapeWidth(o.track.tape_width_m);
  IDI_RETURN_IF_ERROR(config.planner.Check());
  IDI_RETURN_IF_ERROR(config.perception.Check());

  SimRmpOptions rmp_options;
  rmp_options.model = config.driver.codec.model;
  IDI_ASSIGN_OR_RETURN(std::unique_ptr<SimWorld> world, SimWorld::Create(o.track, config.sim, config.rig, rmp_options));
  IDI_ASSIGN_OR_RETURN(std::unique_ptr<TrackPerception> perception,
                       TrackPerception::Create(config.rig, config.perception));

  std::unique_ptr<replay::DriveLogWriter> log;
  if (!o.record_dir.empty()) {
    RecordingHeader header;
    header.created_unix_ns =
        std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
            .count();
    header.created_clock_ns = world->clock()->NowNs();
    header.cameras["left"] = config.rig.left.intrinsics;
    header.cameras["right"] = config.rig.right.intrinsics;
    header.meta = {{"source", "sim"},
                   {"track", o.track.source},
                   {"config_yaml", o.config_text},
                   {"cruise_speed_mps", config.planner.cruise_speed_mps},
                   {"tape_width_m", o.track.tape_width_m},
                   {"rig", RigJson(config.rig)}};
    IDI_ASSIGN_OR_RETURN(log, replay::DriveLogWriter::Create(o.record_dir, header));
  }
  std::unique_ptr<replay::CandumpWriter> can_log;
  if (!o.can_log.empty() && !log) {
    replay::CandumpWriterOptions co;
    co.mark_direction = true;
    IDI_ASSIGN_OR_RETURN(can_log, replay::CandumpWriter::Open(o.can_log, co));
  }

  IDI_ASSIGN_OR_RETURN(std::unique_ptr<RmpDriver> driver,
                       RmpDriver::Create(world->endpoint(), world->clock(), config.driver));
  sim::VirtualCanBus* bus = world->bus();
  sim::VirtualCanEndpoint* ep = world->endpoint();
  driver->SetBusRecovery([bus, ep] {
    bus->RestartEndpoint(ep);
    return Status::Ok();
  });
  driver->SetEventSink([](int64_t t, const std::string& e) {
    spdlog::info("rmp driver t={:.3f} s: {}", static_cast<double>(t) * 1e-9, e);
  });
  ControlLoop loop(config.control,
                   world->clock(),
                   driver.get(),
                   world->frames(),
                   perception.get(),
                   config.planner,
                   config.track,
                   log.get());
  if (can_log) driver->SetFrameLog(can_log.get());
  IDI_RETURN_IF_ERROR(loop.Start());

  // The limit: --max-time-s, else the config's control.max_run_s, else from the track's length.
  const double max_time_s = o.max_time_s > 0 ? o.max_time_s
                            : config.control.max_run_s > 0
                                ? config.control.max_run_s
                                : 2.5 * o.track.Length() / std::max(0.05, config.planner.cruise_speed_mps) + 30.0;
  const auto wall_start = std::chrono::steady_clock::now();
  const int64_t sim_start = world->clock()->NowNs();
  RunReport report;
  report.cruise_speed_mps = config.planner.cruise_speed_mps;
  bool moving_started = false;
  Status run_status;
  while (true) {
    if (o.stop != nullptr && o.stop->load()) {
      loop.RequestStop("signal");
      report.end = "stopped";
      break;
    }
    auto rec = loop.Step();
    if (!rec.ok()) {
      run_status = rec.status();
      report.end = "error: " + rec.status().message();
      break;
    }
    if (rec->speed_mps != 0.0 || rec->yaw_rate_rps != 0.0) moving_started = true;
    world->AfterTick(*rec, moving_started && !loop.finished());
    if (o.on_tick) o.on_tick(*rec, *world, loop);
    if (loop.finished()) {
      report.end = "finished";
      break;
    }
    if (static_cast<double>(rec->t_ns - sim_start) * 1e-9 > max_time_s) {
      report.end = "time-limit";
      break;
    }
    if (o.real_time) {
      std::this_thread::sleep_until(wall_start + std::chrono::nanoseconds(rec->t_ns - sim_start));
    }
  }
  // Never leave without commanding zero.
  const Status shutdown = loop.Shutdown();
  if (!shutdown.ok()) spdlog::warn("driver shutdown: {}", shutdown.ToString());

  SimRunResult result;
  result.truth = world->Truth();
  result.stats = loop.stats();
  result.render_wall_s = world->render_wall_s();
  FillFromLoop(loop, &report);
  const ControlLoopStats& st = loop.stats();
  const int64_t t_begin = st.running_since_ns >= 0 ? st.running_since_ns : sim_start;
  const int64_t t_end = st.finished_ns >= 0 ? st.finished_ns : world->clock()->NowNs();
  report.time_s = static_cast<double>(t_end - t_begin) * 1e-9;
  report.distance_m = result.truth.distance_m;
  report.lateral_error_rms_m = result.truth.lateral_rms_m;
  report.lateral_error_max_m = result.truth.lateral_max_m;
  report.track_visible_fraction = result.truth.visible_fraction;
  report.end_distance_m = result.truth.end_distance_m;
  report.max_speed_mps = result.truth.max_speed_mps;
  report.completed = loop.finished() && result.truth.end_distance_m <= 0.5;
  // The outputs after the run: the first failure is kept and the rest still written.
  Status& out = result.output_status;
  auto keep = [&out](const Status& written) {
    if (out.ok() && !written.ok()) out = written;
    return written.ok();
  };
  bool can_log_written = !o.can_log.empty();
  if (log) {
    const bool finished = keep(log->Finish({{"source", "sim"},
                                            {"track", o.track.source},
                                            {"config_yaml", o.config_text},
                                            {"cruise_speed_mps", config.planner.cruise_speed_mps},
                                            {"tape_width_m", o.track.tape_width_m},
                                            {"rig", RigJson(config.rig)},
                                            {"report", report.ToJson()}}));
    if (finished) report.extra["record"] = o.record_dir;
    // The recording's CAN log, copied only from a finished recording. Read and written rather than
    // copy_file: --can-log may be a device (/dev/null) or a link, written in place or at its target.
    if (!o.can_log.empty() && !finished) {
      can_log_written = false;  // the run's failure is the recording's, already kept
    } else if (!o.can_log.empty()) {
      const std::string recorded = (std::filesystem::path(o.record_dir) / replay::kDriveLogCanFile).string();
      const Result<std::string> text = ReadFile(recorded);
      const Status copied = text.ok() ? WriteFileAtomically(o.can_log, *text) : text.status();
      if (!copied.ok()) can_log_written = keep(IoError(o.can_log + ": cannot write the CAN log: " + copied.message()));
    }
  }
  if (can_log) can_log_written = keep(can_log->Close());
  if (can_log_written) report.extra["can_log"] = o.can_log;
  if (!o.png.empty()) {
    const bool written =
        keep(WriteRunPng(o.png,
                         o.track,
                         result.truth,
                         config.sim.faults.covered_m,
                         o.track.source + fmt::format(" at {:.2f} m/s: lateral error rms {:.1f} mm, max {:.1f} mm",
                                                      config.planner.cruise_speed_mps,
                                                      1000 * report.lateral_error_rms_m,
                                                      1000 * report.lateral_error_max_m)));
    if (written) report.extra["png"] = o.png;
  }
  result.report = report;
  if (!run_status.ok()) return run_status;
  return result;
}

Status WriteRunPng(const std::string& path,
                   const TrackSpec& track,
                   const SimTruth& truth,
                   const std::vector<std::pair<double, double>>& covered_m,
                   const std::string& title) {
  plot::Figure map(900, 700);
  map.SetTitle(title);
  map.SetEqualAspect(true);
  map.x_axis().label = "x (m)";
  map.y_axis().label = "y (m)";
  std::vector<std::pair<double, double>> without = track.gaps_m;
  without.insert(without.end(), covered_m.begin(), covered_m.end());
  bool first = true;
  for (const auto& stretch : TapedStretches(track.points_m, without)) {
    std::vector<double> x, y;
    for (const Vec2d& p : stretch) {
      x.push_back(p.x());
      y.push_back(p.y());
    }
    map.AddLine(x, y, first ? "tape (centre line)" : "", plot::kGray);
    first = false;
  }
  // The driven path in three error bands.
  const struct {
    double lo, hi;
    const char* label;
    plot::Color color;
  } bands[] = {{0.0, 0.02, "path, error < 2 cm", plot::kGreen},
               {0.02, 0.04, "path, 2-4 cm", plot::kOrange},
               {0.04, 1e9, "path, > 4 cm", plot::kRed}};
  const std::vector<double>& err = truth.path_error_m;
  {
    std::vector<double> x, y;
    for (std::size_t i = 0; i < truth.path_xy.size(); i += 2) {
      if (err[i] < 0) {
        x.push_back(truth.path_xy[i].x());
        y.push_back(truth.path_xy[i].y());
      }
    }
    if (!x.empty()) map.AddScatter(x, y, "path, not following", plot::kBlue, plot::Marker::kCircle);
  }
  for (const auto& b : bands) {
    std::vector<double> x, y;
    for (std::size_t i = 0; i < truth.path_xy.size(); i += 2) {
      if (err[i] >= b.lo && err[i] < b.hi) {
        x.push_back(truth.path_xy[i].x());
        y.push_back(truth.path_xy[i].y());
      }
    }
    if (!x.empty()) map.AddScatter(x, y, b.label, b.color, plot::Marker::kCircle);
  }
  map.AddScatter(
      {track.points_m.back().x()}, {track.points_m.back().y()}, "track end", plot::kPurple, plot::Marker::kCross);
  plot::Figure err_plot(900, 300);
  err_plot.SetTitle("lateral error along the track");
  err_plot.x_axis().label = "distance along the track (m)";
  err_plot.y_axis().label = "lateral error (mm)";
  std::vector<double> emm;
  for (double e : truth.lateral_m) emm.push_back(1000.0 * e);
  if (!emm.empty()) {
    err_plot.AddLine(truth.s_m, emm, "|lateral error|", plot::kBlue);
  } else {
    err_plot.AddLine({0.0, track.Length()}, {0.0, 0.0}, "no data", plot::kGray);
  }
  IDI_ASSIGN_OR_RETURN(std::vector<uint8_t> a, map.EncodePng());
  IDI_ASSIGN_OR_RETURN(std::vector<uint8_t> b, err_plot.EncodePng());
  cv::Mat ia = cv::imdecode(a, cv::IMREAD_COLOR), ib = cv::imdecode(b, cv::IMREAD_COLOR);
  if (ia.empty() || ib.empty() || ia.cols != ib.cols) return Internal("plot: cannot compose the run figure");
  cv::Mat both;
  cv::vconcat(ia, ib, both);
  return plot::WritePngFile(path, both);
}

}  // namespace idi::rmp
