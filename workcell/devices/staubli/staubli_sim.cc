#include "workcell/devices/staubli/staubli_sim.h"

#include <algorithm>
#include <cmath>

#include "shared/util/units.h"
#include "workcell/devices/staubli/staubli_joints.h"

namespace idi::workcell {

Status SimStaubliOptions::Check() const {
  if (!(joint_speed_deg_per_s > 0) || !(rail_speed_mm_per_s > 0) || !(rail_resolution_mm > 0) ||
      !(rail_min_mm < rail_max_mm)) {
    return InvalidArgument(name + ": speeds and rail resolution must be positive, rail_min_mm < rail_max_mm");
  }
  if (!Rx130JointLimits().Contains(initial_q_rad)) return InvalidArgument(name + ": initial joints outside the limits");
  return Status::Ok();
}

SimStaubli::SimStaubli(SimStaubliOptions options, hal::Clock* clock) : options_(std::move(options)), clock_(clock) {
  IDI_CHECK(clock_ != nullptr, "SimStaubli needs a clock");
  const Status ok = options_.Check();
  IDI_CHECK(ok.ok(), ok.ToString());
  q_rad_ = Quantised(options_.initial_q_rad);
}

Joints SimStaubli::Quantised(const Joints& q) const {
  ControllerJointsDeg deg = ModelRadToControllerDeg(q);
  for (std::size_t i = 0; i < deg.size(); ++i) {
    deg[i] = std::round(deg[i] * kRx130CountsPerDeg[i]) / kRx130CountsPerDeg[i];
  }
  return ControllerDegToModelRad(deg);
}

Status SimStaubli::MoveJoints(const Joints& q_rad, const hal::MoveOptions& options) {
  if (!(options.speed_fraction > 0 && options.speed_fraction <= 1)) {
    return InvalidArgument(options_.name + ": speed_fraction must be in (0, 1]");
  }
  for (const double q : q_rad) {
    if (!std::isfinite(q)) return InvalidArgument(options_.name + ": joints must be finite");
  }
  const int bad = Rx130JointLimits().FirstViolation(q_rad);
  if (bad >= 0) {
    return OutOfRange(options_.name + ": joint " + std::to_string(bad + 1) + " = " +
                      FormatNumber(RadToDeg(q_rad[static_cast<std::size_t>(bad)])) + " deg outside its limits");
  }
  double largest_deg = 0;
  for (std::size_t i = 0; i < q_rad.size(); ++i) largest_deg = std::max(largest_deg, RadToDeg(std::abs(q_rad[i] - q_rad_[i])));
  const double duration_s = largest_deg / (options_.joint_speed_deg_per_s * options.speed_fraction);
  const double allowed_s = std::chrono::duration<double>(options.timeout).count();
  double fraction = 1;
  Status result = Status::Ok();
  if (fault_) {
    fraction = 0.5;
    result = Status(fault_->code(), fault_->message() + "; stop sent");
    fault_.reset();
  } else if (duration_s > allowed_s) {
    fraction = allowed_s / duration_s;
    result = Timeout(options_.name + ": move not finished within " + std::to_string(options.timeout.count()) +
                     " ms; stop sent");
  }
  clock_->SleepForNs(hal::SecToNs(duration_s * fraction));
  Joints reached{};
  for (std::size_t i = 0; i < reached.size(); ++i) reached[i] = q_rad_[i] + (q_rad[i] - q_rad_[i]) * fraction;
  q_rad_ = Quantised(reached);
  if (!result.ok()) ++stops_;
  return result;
}

Result<hal::JointState> SimStaubli::ReadJoints() {
  if (fault_) return *std::exchange(fault_, std::nullopt);
  hal::JointState state;
  state.timestamp_ns = clock_->NowNs();
  state.q_rad = q_rad_;
  return state;
}

Status SimStaubli::Stop() {
  ++stops_;
  return Status::Ok();
}

Status SimStaubli::MoveTo(double position_mm, const hal::MoveOptions& options) {
  if (!options_.has_rail) return FailedPrecondition(options_.name + ": no rail on this controller");
  if (!(options.speed_fraction > 0 && options.speed_fraction <= 1)) {
    return InvalidArgument(options_.name + ": speed_fraction must be in (0, 1]");
  }
  if (!std::isfinite(position_mm) || position_mm < options_.rail_min_mm || position_mm > options_.rail_max_mm) {
    return OutOfRange(options_.name + ": rail position " + FormatNumber(position_mm) + " mm outside [" +
                      FormatNumber(options_.rail_min_mm) + ", " + FormatNumber(options_.rail_max_mm) + "]");
  }
  const double duration_s = std::abs(position_mm - rail_mm_) / (options_.rail_speed_mm_per_s * options.speed_fraction);
  const double allowed_s = std::chrono::duration<double>(options.timeout).count();
  double fraction = 1;
  Status result = Status::Ok();
  if (fault_) {
    fraction = 0.5;
    result = Status(fault_->code(), fault_->message() + "; stop sent");
    fault_.reset();
  } else if (duration_s > allowed_s) {
    fraction = allowed_s / duration_s;
    result = Timeout(options_.name + ": rail move not finished in time; stop sent");
  }
  clock_->SleepForNs(hal::SecToNs(duration_s * fraction));
  const double reached = rail_mm_ + (position_mm - rail_mm_) * fraction;
  rail_mm_ = std::round(reached / options_.rail_resolution_mm) * options_.rail_resolution_mm;
  if (!result.ok()) ++stops_;
  return result;
}

Result<hal::RailState> SimStaubli::Read() {
  if (!options_.has_rail) return FailedPrecondition(options_.name + ": no rail on this controller");
  if (fault_) return *std::exchange(fault_, std::nullopt);
  hal::RailState state;
  state.timestamp_ns = clock_->NowNs();
  state.position_mm = rail_mm_;
  return state;
}

}  // namespace idi::workcell
