#include "workcell/devices/ptu/ptu_sim.h"

#include <algorithm>
#include <cmath>

#include "workcell/devices/ptu/ptu_codec.h"

namespace idi::workcell {

Status SimPtuOptions::Check() const {
  if (!(pan_arcsec > 0) || !(tilt_arcsec > 0)) return InvalidArgument(name + ": resolutions must be positive");
  if (!(pan_min < pan_max) || !(tilt_min < tilt_max)) return InvalidArgument(name + ": limits must have min < max");
  if (!(speed_pos_per_s > 0)) return InvalidArgument(name + ": speed_pos_per_s must be positive");
  return Status::Ok();
}

SimPanTilt::SimPanTilt(SimPtuOptions options, hal::Clock* clock) : options_(std::move(options)), clock_(clock) {
  IDI_CHECK(clock_ != nullptr, "SimPanTilt needs a clock");
  const Status ok = options_.Check();
  IDI_CHECK(ok.ok(), ok.ToString());
}

std::optional<Status> SimPanTilt::TakeFault() { return std::exchange(fault_, std::nullopt); }

Result<hal::PanTiltLimits> SimPanTilt::Limits() {
  if (auto fault = TakeFault()) return *fault;
  const double pr = PtuArcSecondsToRad(options_.pan_arcsec), tr = PtuArcSecondsToRad(options_.tilt_arcsec);
  hal::PanTiltLimits limits;
  limits.pan_min_rad = options_.pan_min * pr;
  limits.pan_max_rad = options_.pan_max * pr;
  limits.tilt_min_rad = options_.tilt_min * tr;
  limits.tilt_max_rad = options_.tilt_max * tr;
  limits.pan_resolution_rad = pr;
  limits.tilt_resolution_rad = tr;
  return limits;
}

Status SimPanTilt::MoveTo(double pan_rad, double tilt_rad, std::chrono::milliseconds timeout) {
  if (!std::isfinite(pan_rad) || !std::isfinite(tilt_rad)) {
    return InvalidArgument(options_.name + ": MoveTo needs finite angles");
  }
  const double pr = PtuArcSecondsToRad(options_.pan_arcsec), tr = PtuArcSecondsToRad(options_.tilt_arcsec);
  const double p = std::round(pan_rad / pr), t = std::round(tilt_rad / tr);
  if (p < options_.pan_min || p > options_.pan_max) {
    return OutOfRange(options_.name + ": pan " + FormatNumber(pan_rad) + " rad (position " + FormatNumber(p) +
                      ") outside [" + std::to_string(options_.pan_min) + ", " + std::to_string(options_.pan_max) + "]");
  }
  if (t < options_.tilt_min || t > options_.tilt_max) {
    return OutOfRange(options_.name + ": tilt " + FormatNumber(tilt_rad) + " rad (position " + FormatNumber(t) +
                      ") outside [" + std::to_string(options_.tilt_min) + ", " + std::to_string(options_.tilt_max) +
                      "]");
  }
  const auto target_p = static_cast<int32_t>(p), target_t = static_cast<int32_t>(t);
  // Both axes move at the same speed; the move lasts as long as the longer one.
  const double distance = std::max(std::abs(target_p - pan_), std::abs(target_t - tilt_));
  const double duration_s = distance / options_.speed_pos_per_s;
  const double allowed_s = std::chrono::duration<double>(timeout).count();
  if (auto fault = TakeFault()) {
    // Fails half-way and halts there.
    clock_->SleepForNs(hal::SecToNs(duration_s / 2));
    pan_ += (target_p - pan_) / 2;
    tilt_ += (target_t - tilt_) / 2;
    ++halts_;
    return Status(fault->code(), fault->message() + "; halt sent");
  }
  if (duration_s > allowed_s) {
    const double f = allowed_s / duration_s;
    clock_->SleepForNs(hal::SecToNs(allowed_s));
    pan_ += static_cast<int32_t>(std::lround((target_p - pan_) * f));
    tilt_ += static_cast<int32_t>(std::lround((target_t - tilt_) * f));
    ++halts_;
    return Timeout(options_.name + ": move did not complete within " + std::to_string(timeout.count()) +
                   " ms; halt sent");
  }
  clock_->SleepForNs(hal::SecToNs(duration_s));
  pan_ = target_p;
  tilt_ = target_t;
  return Status::Ok();
}

Result<hal::PanTiltState> SimPanTilt::Read() {
  if (auto fault = TakeFault()) return *fault;
  hal::PanTiltState state;
  state.timestamp_ns = clock_->NowNs();
  state.pan_rad = pan_ * PtuArcSecondsToRad(options_.pan_arcsec);
  state.tilt_rad = tilt_ * PtuArcSecondsToRad(options_.tilt_arcsec);
  return state;
}

Status SimPanTilt::Halt() {
  ++halts_;
  return Status::Ok();
}

}  // namespace idi::workcell
