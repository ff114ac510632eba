#include "rmp/app/hardware_run.h"

#include <spdlog/spdlog.h>

#include <chrono>

#include "rmp/app/camera_frames.h"
#include "shared/runtime/systemd_notify.h"

#if IDI_RMP_HARDWARE
#include "shared/drivers/socketcan/socketcan_bus.h"
#include "shared/drivers/v4l2/v4l2_camera.h"
#endif
#if IDI_RMP_LIBCAMERA
#include "shared/drivers/libcamera/libcamera_camera.h"
#endif

namespace idi::rmp {

#if IDI_RMP_HARDWARE
namespace {

// The camera device a config entry names (its backend was checked by RmpConfig::Check).
Result<std::unique_ptr<hal::CameraDevice>> MakeCamera(const CameraDeviceConfig& c) {
  if (c.backend == "libcamera") {
#if IDI_RMP_LIBCAMERA
    drivers::LibcameraCameraOptions lo;
    lo.camera = c.device;
    lo.name = c.name;
    lo.frame_rate_hz = c.frame_rate_hz;
    return std::unique_ptr<hal::CameraDevice>(std::make_unique<drivers::LibcameraCamera>(lo));
#else
    return FailedPrecondition("camera " + c.name + ": this idi-rmp was built without libcamera");
#endif
  }
  drivers::V4l2CameraOptions vo;
  vo.device = c.device;
  vo.name = c.name;
  vo.frame_rate_hz = c.frame_rate_hz;
  return std::unique_ptr<hal::CameraDevice>(std::make_unique<drivers::V4l2Camera>(vo));
}

}  // namespace

Result<RunReport> RunHardware(const HardwareRunOptions& o) {
  const RmpConfig& config = o.config;
  hal::MonotonicClock clock;
  drivers::SocketCanOptions can_options;
  can_options.interface = config.can_interface;
  IDI_ASSIGN_OR_RETURN(std::unique_ptr<drivers::SocketCanBus> bus, drivers::SocketCanBus::Open(can_options, &clock));
  std::vector<CameraFrames::Camera> cams;
  for (const CameraDeviceConfig& c : config.cameras) {
    IDI_ASSIGN_OR_RETURN(std::unique_ptr<hal::CameraDevice> cam, MakeCamera(c));
    hal::CameraSettings s;
    s.width = c.width;
    s.height = c.height;
    s.gray = true;
    IDI_RETURN_IF_ERROR(cam->Start(s).WithContext("camera " + c.name));
    cams.push_back({std::move(cam), s});
  }
  CameraFrames frames(std::move(cams));
  IDI_ASSIGN_OR_RETURN(std::unique_ptr<TrackPerception> perception, TrackPerception::Create(config.rig, config.perception));
  // The log before the driver: the driver's destructor logs its last zero command, also on an early return.
  std::unique_ptr<replay::DriveLogWriter> log;
  if (!o.record_dir.empty()) {
    RecordingHeader header;
    header.created_unix_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch()).count();
    header.created_clock_ns = clock.NowNs();  // the events' clock (CLOCK_MONOTONIC, from boot)
    header.cameras["left"] = config.rig.left.intrinsics;
    header.cameras["right"] = config.rig.right.intrinsics;
    header.meta = {{"source", "hardware"}, {"config_yaml", o.config_text}, {"cruise_speed_mps", config.planner.cruise_speed_mps}};
    IDI_ASSIGN_OR_RETURN(log, replay::DriveLogWriter::Create(o.record_dir, header));
  }
  IDI_ASSIGN_OR_RETURN(std::unique_ptr<RmpDriver> driver, RmpDriver::Create(bus.get(), &clock, config.driver));
  drivers::SocketCanBus* raw_bus = bus.get();
  driver->SetBusRecovery([raw_bus] { return raw_bus->Restart(); });
  driver->SetEventSink([](int64_t, const std::string& e) { spdlog::info("rmp driver: {}", e); });
  ControlLoop loop(config.control, &clock, driver.get(), &frames, perception.get(), config.planner, config.track, log.get());
  IDI_RETURN_IF_ERROR(loop.Start());
  NotifyReady();
  NotifyStatus("driving");
  RunReport report;
  Status failure;
  const int64_t started_ns = clock.NowNs();
  while (true) {
    if (o.stop != nullptr && o.stop->load()) {
      loop.RequestStop("signal");
      report.end = "stopped";
      break;
    }
    if (config.control.max_run_s > 0 &&
        static_cast<double>(clock.NowNs() - started_ns) * 1e-9 > config.control.max_run_s) {
      loop.RequestStop("control.max_run_s reached");
      report.end = "max_run_s";
      break;
    }
    auto rec = loop.Step();
    if (!rec.ok()) {
      failure = rec.status();
      report.end = "error: " + failure.message();
      break;
    }
    if (loop.finished()) {
      report.end = "finished";
      break;
    }
  }
  NotifyStopping();
  const Status shutdown = loop.Shutdown();  // zero, whatever happened
  if (!shutdown.ok()) spdlog::error("driver shutdown: {}", shutdown.ToString());
  if (log) IDI_RETURN_IF_ERROR(log->Finish({{"source", "hardware"}, {"config_yaml", o.config_text}}));
  const ControlLoopStats& st = loop.stats();
  report.completed = loop.finished();
  report.frames = st.perceptions;
  report.perception_ms_median = st.perception_ms.Percentile(0.5);
  report.perception_ms_p99 = st.perception_ms.Percentile(0.99);
  report.frame_to_command_ms_median = st.frame_to_command_ms.Percentile(0.5);
  report.frame_to_command_ms_p99 = st.frame_to_command_ms.Percentile(0.99);
  report.commands = driver->health().counters.frames_sent;
  report.commands_nonzero = driver->health().counters.motion_frames;
  if (const uint64_t lost = driver->health().counters.log_errors; lost > 0) {
    spdlog::error("the drive log's can.log is missing {} CAN frames that could not be written (disk full?)", lost);
  }
  report.distance_m = driver->odometry().pose().distance_m;
  report.decisions = st.decisions;
  if (!failure.ok()) return failure;
  return report;
}

#else

Result<RunReport> RunHardware(const HardwareRunOptions&) {
  return FailedPrecondition("this idi-rmp was built without the SocketCAN and V4L2 backends (targets/<t>/target.cmake)");
}

#endif

}  // namespace idi::rmp
