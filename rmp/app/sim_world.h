// The closed loop's digital twin: the vehicle (shared/sim/vehicle) behind the simulated RMP on the
// virtual CAN bus (rmp/segway), two cameras rendering the taped track (shared/sim/render) from the
// vehicle's true pose at every exposure, scheduled faults, and the ground truth for the report
// (lateral error against the true centre line, whether the coming track was in view).
//
// Everything runs on one SimClock; the driver under test talks to the bus through its own endpoint,
// so the control loop cannot tell the twin from the vehicle.
#pragma once

#include <cstdint>
#include <memory>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "rmp/app/control_loop.h"
#include "rmp/app/track_spec.h"
#include "rmp/perception/track_perception.h"
#include "rmp/segway/sim_rmp.h"
#include "shared/hal/clock.h"
#include "shared/sim/can/virtual_can_bus.h"
#include "shared/sim/render/render.h"

namespace idi::rmp {

struct SimFaults {
  // Times are seconds on the twin's clock (the run starts at 0).
  std::string frozen_camera;  // "left" or "right": from frozen_from_s to frozen_to_s it repeats its last image
  double frozen_from_s = -1, frozen_to_s = -1;
  double drop_probability = 0.0;  // each frame of each camera is lost with this probability
  std::string dead_camera;        // delivers nothing from dead_from_s to dead_to_s
  double dead_from_s = -1, dead_to_s = -1;
  double rmp_silent_from_s = -1, rmp_silent_to_s = -1;  // the RMP stops sending status (still obeys)
  // The RMP sends every status frame but the wheel integrators (0x403): the odometry stops while the
  // status stays fresh.
  double integrators_missing_from_s = -1, integrators_missing_to_s = -1;
  double bus_off_at_s = -1, bus_off_duration_s = 0.5;   // our CAN controller goes bus-off
  double battery_drop_at_s = -1, battery_drop_v = 0.0;  // the powerbase battery sags
  std::vector<std::pair<double, double>> covered_m;     // stretches of tape covered by a mat
  // A glitch of the cameras' clock: both frames of the first capture at or after stamp_glitch_at_s are
  // stamped stamp_glitch_s later than their exposure (the frames after it are stamped right again).
  double stamp_glitch_at_s = -1, stamp_glitch_s = 0.0;

  Status Check() const;
};

struct SimOptions {
  double camera_rate_hz = 15.0;
  double camera_latency_s = 0.03;  // exposure to delivery (readout, transfer)
  uint64_t seed = 1;
  // Odometry realism (the twin's wheel scale errors and slip).
  double left_wheel_scale_error = 0.002;
  double right_wheel_scale_error = -0.001;
  double slip_noise_m_per_sqrt_m = 0.0005;
  // The cameras as mounted differ from their calibration (what perception is given) by this.
  double calibration_pitch_error_deg = 0.1;
  double calibration_height_error_m = 0.003;
  bool balance_mode = false;  // the RMP balances (the platform pitches with acceleration)
  sim::RenderOptions render;
  TrackSceneOptions scene;
  SimFaults faults;

  Status Check() const;
};

// The truth of one run (metres, seconds).
struct SimTruth {
  double distance_m = 0.0;
  double lateral_rms_m = 0.0, lateral_max_m = 0.0;
  double end_distance_m = 0.0;   // from the track's last point where the vehicle ended
  double visible_fraction = 0.0;
  int frames_following = 0;
  double max_speed_mps = 0.0;
  // Along the run, for the plot: distance along the track and the lateral error there.
  std::vector<double> s_m, lateral_m;
  std::vector<Vec2d> path_xy;
  std::vector<double> path_error_m;  // per path_xy point; -1 before following started or after the end
};

class TwinCameras;

class SimWorld {
 public:
  // `calibrated_rig` is what perception uses; the twin's cameras are that rig with the calibration
  // error of the options applied.
  static Result<std::unique_ptr<SimWorld>> Create(const TrackSpec& track, const SimOptions& options,
                                                  const StereoRig& calibrated_rig, const SimRmpOptions& rmp);
  ~SimWorld();

  hal::SimClock* clock() { return &clock_; }
  sim::VirtualCanBus* bus() { return bus_.get(); }
  sim::VirtualCanEndpoint* endpoint() { return endpoint_; }  // the driver's node
  SimRmp& rmp() { return *rmp_; }
  FrameSource* frames();
  const TrackSpec& track() const { return track_; }

  // Truth bookkeeping after each control tick: `following` marks ticks between the first move and
  // the end of the run (the lateral error and visibility count only then).
  void AfterTick(const TickRecord& tick, bool following);
  SimTruth Truth() const;
  // The world pose of the vehicle (truth) now.
  Pose2 TruthPose() const;
  // Wall-clock seconds spent rendering the cameras' images so far (both cameras, the time they took
  // together): where a faster-than-real-time run spends its time.
  double render_wall_s() const { return render_wall_s_; }

 private:
  SimWorld(const TrackSpec& track, const SimOptions& options);
  double ProgressAt(const Vec2d& p, double* lateral) const;

  TrackSpec track_;
  SimOptions options_;
  hal::SimClock clock_;
  std::unique_ptr<sim::VirtualCanBus> bus_;
  std::unique_ptr<SimRmp> rmp_;
  sim::VirtualCanEndpoint* endpoint_ = nullptr;
  std::unique_ptr<TwinCameras> cameras_;
  std::unique_ptr<sim::SimProcess> faults_;
  std::vector<double> vertex_s_;  // arc length of every track vertex
  // Truth accumulators.
  mutable double progress_s_ = 0.0;
  double sum_sq_ = 0.0, max_lat_ = 0.0;
  int samples_ = 0;
  bool following_ = false;
  bool was_following_ = false;
  SimTruth truth_;
  double render_wall_s_ = 0.0;
  friend class TwinCameras;
};

}  // namespace idi::rmp
