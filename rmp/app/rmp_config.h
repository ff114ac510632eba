// idi-rmp's configuration file (`idi-rmp run --config /etc/idi/rmp.yaml`; `sim` and `replay` take one
// too). Every section is optional; unknown keys are errors naming the file, line and key. Keys carry
// their unit. The full list:
//
//   backend: sim | replay | hardware
//   state_dir: /var/lib/idi-rmp       drive logs go to <state_dir>/logs/<time>[-N] when record: true
//   record: false
//   rig:      {left: {fx_px, fy_px, cx_px, cy_px, k1, k2, p1, p2, k3, x_m, y_m, z_m, yaw_deg, pitch_down_deg},
//              right: {...}, width_px, height_px}          the fixed cameras' calibration
//   tape:     {width_m, brighter}
//   perception: {max_range_m, parallel_views (the two images on two threads, default true; same result)}
//   planner:  {cruise_speed_mps, max_speed_mps, max_accel_mps2, max_decel_mps2, max_yaw_rate_rps,
//              max_yaw_accel_rps2, max_lateral_accel_mps2, corner_cut_m, max_corner_cut_m,
//              command_latency_s, response_time_constant_s, keep_track_in_view}
//   control:  {rate_hz, max_perception_age_s, max_odometry_age_s, status_timeout_s, track_lost_s, finish_hold_s,
//              max_run_s}
//   rmp:      {model, velocity_scale, accel_scale, turn_scale, min_base_battery_v, balance}
//   hardware: {can: {interface}, cameras: [{name, backend: v4l2 | libcamera, device, width, height, frame_rate_hz}]}
//             device: v4l2: a capture node (/dev/video0, better /dev/v4l/by-id/...); libcamera: a camera
//             id as `cam --list` prints it, or its index 0, 1, ... in libcamera's list. libcamera is
//             optional at build time: a build without it refuses `backend: libcamera` at load.
//   sim:      {track, real_time, camera_rate_hz, camera_latency_s, seed, calibration_pitch_error_deg,
//              calibration_height_error_m, left_wheel_scale_error, right_wheel_scale_error,
//              slip_noise_m_per_sqrt_m, faults: {frozen_camera, frozen_from_s, frozen_to_s,
//              drop_probability, dead_camera, dead_from_s, dead_to_s, rmp_silent_from_s, rmp_silent_to_s,
//              integrators_missing_from_s, integrators_missing_to_s, bus_off_at_s, bus_off_duration_s,
//              battery_drop_at_s, battery_drop_v, stamp_glitch_at_s, stamp_glitch_s,
//              covered_m: [[from, to], ...]}}
//   replay:   {dir}
#pragma once

#include <string>
#include <vector>

#include "rmp/app/control_loop.h"
#include "rmp/app/sim_world.h"
#include "rmp/perception/track_perception.h"
#include "rmp/planning/planner.h"
#include "rmp/segway/rmp_driver.h"
#include "rmp/track/track_model.h"
#include "shared/util/status.h"

namespace idi::rmp {

enum class Backend { kSim, kReplay, kHardware };
const char* BackendName(Backend b);

struct CameraDeviceConfig {
  std::string name;              // "left" / "right"
  std::string backend = "v4l2";  // "v4l2" or "libcamera" (when built with it: LibcameraBuilt())
  std::string device;            // v4l2: /dev/video0, /dev/v4l/by-id/...; libcamera: a camera id or index
  int width = 640, height = 480;
  double frame_rate_hz = 0.0;  // 0: the device's default
};

struct RmpConfig {
  std::string source = "(defaults)";
  Backend backend = Backend::kSim;
  std::string state_dir;
  bool record = false;
  StereoRig rig;
  PerceptionOptions perception;
  PlannerOptions planner;
  TrackModelOptions track;
  ControlLoopOptions control;
  RmpDriverOptions driver;
  bool balance = false;
  // hardware
  std::string can_interface = "can0";
  std::vector<CameraDeviceConfig> cameras;
  // sim
  std::string sim_track;
  bool sim_real_time = false;
  SimOptions sim;
  // replay
  std::string replay_dir;

  Status Check() const;
};

// Whether this idi-rmp was built with the libcamera camera backend (pkg-config found libcamera).
bool LibcameraBuilt();

// The fixed stereo cameras of the default vehicle: 640x480, 90 deg wide lenses, 1.2 m above the
// ground over the wheel axle, 0.3 m apart, looking 55 deg down - they see from just behind the axle
// to about 4 m ahead, so the coming track stays in view through sharp corners.
StereoRig DefaultStereoRig();
// Defaults for everything (sim backend, the default rig).
RmpConfig DefaultRmpConfig();

Result<RmpConfig> ParseRmpConfig(const std::string& yaml_text, const std::string& source);
Result<RmpConfig> LoadRmpConfig(const std::string& path);

}  // namespace idi::rmp
