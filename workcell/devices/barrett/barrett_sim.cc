#include "workcell/devices/barrett/barrett_sim.h"

#include <algorithm>
#include <cmath>

namespace idi::workcell {

Status SimGripperOptions::Check() const {
  if (!(finger_closed_rad > 0) || !(spread_max_rad > 0) || !(finger_speed_rad_per_s > 0) ||
      !(spread_speed_rad_per_s > 0) || !(init_duration_s >= 0) || !(finger_counts_per_rad > 0) ||
      !(spread_counts_per_rad > 0)) {
    return InvalidArgument(name + ": ranges, speeds and encoder factors must be positive");
  }
  return Status::Ok();
}

SimGripper::SimGripper(SimGripperOptions options, hal::Clock* clock) : options_(std::move(options)), clock_(clock) {
  IDI_CHECK(clock_ != nullptr, "SimGripper needs a clock");
  const Status ok = options_.Check();
  IDI_CHECK(ok.ok(), ok.ToString());
}

double SimGripper::Quantise(double rad, double counts_per_rad) const {
  return std::round(rad * counts_per_rad) / counts_per_rad;
}

Status SimGripper::Initialize() {
  if (fault_) {
    ++stops_;
    return *std::exchange(fault_, std::nullopt);
  }
  clock_->SleepForNs(hal::SecToNs(options_.init_duration_s));
  finger_rad_ = {0, 0, 0};
  spread_rad_ = 0;
  initialized_ = true;
  return Status::Ok();
}

Status SimGripper::MoveFingers(const std::array<double, 3>& goal) {
  if (!initialized_) return FailedPrecondition(options_.name + ": move before Initialize (HI)");
  double longest = 0;
  std::array<double, 3> end = goal;
  for (std::size_t i = 0; i < 3; ++i) {
    // Closing onto an object stops the inner link at the contact.
    if (contact_rad_[i] && goal[i] > finger_rad_[i] && *contact_rad_[i] >= finger_rad_[i] &&
        *contact_rad_[i] < goal[i]) {
      end[i] = *contact_rad_[i];
    }
    longest = std::max(longest, std::abs(end[i] - finger_rad_[i]));
  }
  if (fault_) {
    clock_->SleepForNs(hal::SecToNs(longest / options_.finger_speed_rad_per_s / 2));
    for (std::size_t i = 0; i < 3; ++i) {
      finger_rad_[i] = Quantise((finger_rad_[i] + end[i]) / 2, options_.finger_counts_per_rad);
    }
    ++stops_;
    const Status s = *std::exchange(fault_, std::nullopt);
    return Status(s.code(), s.message() + "; stop sent");
  }
  clock_->SleepForNs(hal::SecToNs(longest / options_.finger_speed_rad_per_s));
  for (std::size_t i = 0; i < 3; ++i) finger_rad_[i] = Quantise(end[i], options_.finger_counts_per_rad);
  return Status::Ok();
}

Status SimGripper::Open() { return MoveFingers({0, 0, 0}); }

Status SimGripper::Close() {
  const double c = options_.finger_closed_rad;
  return MoveFingers({c, c, c});
}

Status SimGripper::SetSpread(double spread_rad) {
  if (!std::isfinite(spread_rad) || spread_rad < 0 || spread_rad > options_.spread_max_rad) {
    return OutOfRange(options_.name + ": spread " + FormatNumber(spread_rad) + " rad outside [0, " +
                      FormatNumber(options_.spread_max_rad) + "]");
  }
  if (!initialized_) return FailedPrecondition(options_.name + ": spread before Initialize (HI)");
  if (fault_) {
    ++stops_;
    return *std::exchange(fault_, std::nullopt);
  }
  clock_->SleepForNs(hal::SecToNs(std::abs(spread_rad - spread_rad_) / options_.spread_speed_rad_per_s));
  spread_rad_ = Quantise(spread_rad, options_.spread_counts_per_rad);
  return Status::Ok();
}

Result<hal::GripperState> SimGripper::Read() {
  if (fault_) return *std::exchange(fault_, std::nullopt);
  hal::GripperState state;
  state.timestamp_ns = clock_->NowNs();
  state.spread_rad = spread_rad_;
  state.finger_rad = finger_rad_;
  state.initialized = initialized_;
  return state;
}

Status SimGripper::Stop() {
  ++stops_;
  return Status::Ok();
}

}  // namespace idi::workcell
