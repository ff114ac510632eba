// Robot arms (Stäubli RX-130 on a CS8 controller), the rail they ride on, the laser tool and the
// Barrett hand. Joint values are in the kinematic model's convention (shared/kinematics/rx130.h),
// radians; rail positions in mm. Every reading carries its sample time.
#pragma once

#include <chrono>
#include <cstdint>
#include <string>

#include "shared/kinematics/rx130.h"
#include "shared/util/status.h"

namespace idi::hal {

struct JointState {
  int64_t timestamp_ns = 0;
  Joints q_rad{};  // encoder readings converted to the model's convention
  bool moving = false;
};

struct RailState {
  int64_t timestamp_ns = 0;
  double position_mm = 0;
  bool moving = false;
};

struct MoveOptions {
  double speed_fraction = 0.2;  // of the controller's nominal joint speed, (0, 1]
  std::chrono::milliseconds timeout{60'000};
};

class ArmDevice {
 public:
  virtual ~ArmDevice() = default;
  virtual std::string name() const = 0;
  // Moves to joint readings and blocks until settled (or fails: OutOfRange for limits, Timeout,
  // DeviceError). On any failure the arm is commanded to stop.
  virtual Status MoveJoints(const Joints& q_rad, const MoveOptions& options) = 0;
  virtual Result<JointState> ReadJoints() = 0;
  // Stops motion now (safe state). Must be callable from any state, including after errors.
  virtual Status Stop() = 0;
};

class RailDevice {
 public:
  virtual ~RailDevice() = default;
  virtual Status MoveTo(double position_mm, const MoveOptions& options) = 0;
  virtual Result<RailState> Read() = 0;
  virtual Status Stop() = 0;
};

class LaserDevice {
 public:
  virtual ~LaserDevice() = default;
  virtual Status SetOn(bool on) = 0;
};

struct GripperState {
  int64_t timestamp_ns = 0;
  double spread_rad = 0;
  std::array<double, 3> finger_rad{};  // inner link angle of fingers 1..3
  bool initialized = false;
};

class GripperDevice {
 public:
  virtual ~GripperDevice() = default;
  virtual Status Initialize() = 0;
  virtual Status Open() = 0;
  // Closes all fingers until they stall on the object (or close fully).
  virtual Status Close() = 0;
  virtual Status SetSpread(double spread_rad) = 0;
  virtual Result<GripperState> Read() = 0;
  virtual Status Stop() = 0;
};

}  // namespace idi::hal
