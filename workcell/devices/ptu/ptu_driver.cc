#include "workcell/devices/ptu/ptu_driver.h"

#include <cmath>
#include <cstdio>

namespace idi::workcell {
namespace {

using PtuSteadyClock = std::chrono::steady_clock;

// A line as it may appear in a message: non-printable bytes escaped, long lines cut.
std::string PtuPrintable(std::string_view line) {
  std::string out;
  for (const char c : line.substr(0, 60)) {
    const auto u = static_cast<unsigned char>(c);
    if (u >= 0x20 && u < 0x7f) {
      out += c;
    } else {
      char buf[8];
      std::snprintf(buf, sizeof(buf), "\\x%02x", u);
      out += buf;
    }
  }
  if (line.size() > 60) out += "...";
  return out;
}

std::string PtuFormatRad(double rad) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.5f rad", rad);
  return buf;
}

}  // namespace

Status PtuDriverOptions::Check() const {
  if (name.empty()) return InvalidArgument("ptu options: name is empty");
  if (port.empty()) return InvalidArgument("ptu options (" + name + "): port is empty");
  if (!drivers::BaudToTermiosSpeed(baud).ok()) {
    return InvalidArgument("ptu options (" + name + "): unsupported baud " + std::to_string(baud));
  }
  if (reply_timeout.count() <= 0 || quiet_period.count() <= 0 || drain_limit < quiet_period) {
    return InvalidArgument("ptu options (" + name + "): timeouts must be positive and drain_limit >= quiet_period");
  }
  if (init_attempts < 1 || max_consecutive_failures < 1) {
    return InvalidArgument("ptu options (" + name + "): init_attempts and max_consecutive_failures must be >= 1");
  }
  return Status::Ok();
}

const char* PtuStateName(PtuState state) {
  switch (state) {
    case PtuState::kDisconnected: return "disconnected";
    case PtuState::kReady: return "ready";
    case PtuState::kFault: return "fault";
  }
  return "?";
}

PtuDriver::PtuDriver(PtuDriverOptions options, hal::Clock* clock) : options_(std::move(options)), clock_(clock) {
  IDI_CHECK(clock_ != nullptr, "PtuDriver needs a clock");
}

PtuDriver::~PtuDriver() = default;

std::string PtuDriver::Quote(const std::string& command) const {
  std::string c = command;
  while (!c.empty() && c.back() == ' ') c.pop_back();
  return "'" + c + "'";
}

Status PtuDriver::Connect() {
  IDI_RETURN_IF_ERROR(options_.Check());
  Disconnect();
  drivers::SerialOptions serial;
  serial.baud = options_.baud;
  auto port = drivers::SerialPort::Open(options_.port, serial);
  if (!port.ok()) {
    return port.status().WithContext(options_.name);
  }
  port_ = std::move(port).value();
  const Status init = Initialize();
  if (!init.ok()) {
    state_ = PtuState::kFault;
    ++counters_.faults;
    return init;
  }
  if (initialized_once_) ++counters_.reconnects;
  initialized_once_ = true;
  state_ = PtuState::kReady;
  consecutive_failures_ = 0;
  needs_resync_ = false;
  return Status::Ok();
}

void PtuDriver::Disconnect() {
  port_.reset();
  state_ = PtuState::kDisconnected;
}

Status PtuDriver::Initialize() {
  Status last;
  for (int attempt = 1; attempt <= options_.init_attempts; ++attempt) {
    last = InitializeOnce();
    if (last.ok()) return last;
  }
  return Status(last.code(), options_.name + ": initialisation on " + options_.port + " failed after " +
                                 std::to_string(options_.init_attempts) + " attempts: " + last.message());
}

Status PtuDriver::InitializeOnce() {
  // End any command the unit half-received (noise, a previous program), then drop everything it
  // says while it settles: power-up banners, mode announcements, replies to that noise.
  IDI_RETURN_IF_ERROR(port_->Write(" ", options_.reply_timeout));
  const std::string chatter = port_->DrainUntilQuiet(options_.quiet_period, options_.drain_limit);
  if (!chatter.empty()) ++counters_.garbage_lines;
  for (const char* code : {"FT", "ED", "CI", "I", "LE"}) {
    auto reply = Transact(PtuCommand(code), Expect::kAck, options_.reply_timeout);
    if (!reply.ok()) return reply.status();
  }
  auto pan_res = Transact(PtuQueryCommand(PtuAxis::kPan, PtuQuantity::kResolution), Expect::kValue,
                          options_.reply_timeout);
  if (!pan_res.ok()) return pan_res.status();
  auto pan_arcsec = PtuFirstNumber(pan_res->text);
  IDI_ASSIGN_OR_RETURN(const double tilt_arcsec, QueryDouble(PtuAxis::kTilt, PtuQuantity::kResolution));
  if (!pan_arcsec.ok()) return DeviceError(options_.name + ": " + pan_arcsec.status().message());
  for (const double r : {pan_arcsec.value(), tilt_arcsec}) {
    if (!(r > 0 && r < 3600)) {
      return DeviceError(options_.name + ": implausible resolution " + FormatNumber(r) +
                         " arc-seconds per position (PR/TR)");
    }
  }
  IDI_ASSIGN_OR_RETURN(const int32_t pan_min, QueryInt(PtuAxis::kPan, PtuQuantity::kMinimum));
  IDI_ASSIGN_OR_RETURN(const int32_t pan_max, QueryInt(PtuAxis::kPan, PtuQuantity::kMaximum));
  IDI_ASSIGN_OR_RETURN(const int32_t tilt_min, QueryInt(PtuAxis::kTilt, PtuQuantity::kMinimum));
  IDI_ASSIGN_OR_RETURN(const int32_t tilt_max, QueryInt(PtuAxis::kTilt, PtuQuantity::kMaximum));
  if (!(pan_min < pan_max) || !(tilt_min < tilt_max)) {
    return DeviceError(options_.name + ": implausible limits pan [" + std::to_string(pan_min) + ", " +
                       std::to_string(pan_max) + "] tilt [" + std::to_string(tilt_min) + ", " +
                       std::to_string(tilt_max) + "] positions (PN/PX/TN/TX)");
  }
  pan_resolution_text_ = pan_res->text;
  pan_arcsec_ = pan_arcsec.value();
  tilt_arcsec_ = tilt_arcsec;
  pan_min_ = pan_min;
  pan_max_ = pan_max;
  tilt_min_ = tilt_min;
  tilt_max_ = tilt_max;
  return Status::Ok();
}

Status PtuDriver::EnsureReady() {
  if (state_ != PtuState::kReady || !port_) {
    const Status s = Connect();
    if (!s.ok()) return s;
  }
  if (needs_resync_) {
    const Status s = Resync();
    if (!s.ok()) return NoteFailure(s);
  }
  return Status::Ok();
}

Status PtuDriver::Resync() {
  ++counters_.resyncs;
  port_->DrainUntilQuiet(options_.quiet_period, options_.drain_limit);
  // A probe whose answer we know: the pan resolution read at start-up.
  auto reply = Transact(PtuQueryCommand(PtuAxis::kPan, PtuQuantity::kResolution), Expect::kValue,
                        options_.reply_timeout);
  if (!reply.ok()) {
    return reply.status().WithContext("resynchronising");
  }
  // A late value ahead of the probe's answer is skipped; the probe's answer must follow in time.
  const auto deadline = PtuSteadyClock::now() + options_.reply_timeout;
  std::string answered = reply->text;
  while (answered != pan_resolution_text_) {
    ++counters_.out_of_step;
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - PtuSteadyClock::now());
    auto line = port_->ReadLine(std::max(left, std::chrono::milliseconds(0)));
    if (!line.ok()) {
      return DeviceError(options_.name + ": resynchronising: 'PR' answered '" + PtuPrintable(answered) +
                         "', expected '" + pan_resolution_text_ + "'");
    }
    const PtuReply next = ParsePtuReply(line.value());
    if (next.kind == PtuReplyKind::kValue) answered = next.text;
  }
  needs_resync_ = false;
  return Status::Ok();
}

Result<PtuReply> PtuDriver::Transact(const std::string& command,
                                     Expect expect,
                                     std::chrono::milliseconds timeout,
                                     bool interruptible) {
  if (!port_) {
    return FailedPrecondition(options_.name + ": not connected");
  }
  ++counters_.commands;
  const Status written = port_->Write(command, options_.reply_timeout);
  if (!written.ok()) {
    return written.WithContext(options_.name + ": sending " + Quote(command));
  }
  const auto deadline = PtuSteadyClock::now() + timeout;
  std::string last_unrecognised;
  while (true) {
    if (interruptible && interrupt_.requested()) {
      needs_resync_ = true;  // the reply may still come
      return Cancelled(options_.name + ": waiting for " + Quote(command) + ": interrupted by a stop");
    }
    const auto left = std::max(std::chrono::milliseconds(0), std::chrono::duration_cast<std::chrono::milliseconds>(
                                                                 deadline - PtuSteadyClock::now()));
    const auto wait = interruptible ? MotionInterrupt::Slice(left) : left;
    auto line = port_->ReadLine(wait);
    if (!line.ok()) {
      if (line.status().code() == StatusCode::kTimeout) {
        if (wait < left) continue;  // a slice of the wait ended, not the wait
        ++counters_.timeouts;
        return Timeout(options_.name + ": no reply to " + Quote(command) + " within " +
                       std::to_string(timeout.count()) + " ms" +
                       (last_unrecognised.empty() ? std::string()
                                                  : " (last unrecognised line: '" + last_unrecognised + "')"));
      }
      if (line.status().code() == StatusCode::kDeviceError) {  // a run of bytes with no line end
        ++counters_.garbage_lines;
        last_unrecognised = line.status().message();
        continue;
      }
      return line.status().WithContext(options_.name + ": waiting for the reply to " + Quote(command));
    }
    PtuReply reply = ParsePtuReply(line.value(), command);
    for (const PtuAxis axis : reply.limit_hits) {
      ++counters_.limit_hits;
      pending_limit_hits_.push_back(axis);
    }
    switch (reply.kind) {
      case PtuReplyKind::kNone:
      case PtuReplyKind::kEcho:
        continue;
      case PtuReplyKind::kUnknown:
        ++counters_.garbage_lines;
        last_unrecognised = PtuPrintable(line.value());
        continue;
      case PtuReplyKind::kError:
        ++counters_.error_replies;
        return DeviceError(options_.name + ": " + Quote(command) + " rejected: '! " + PtuPrintable(reply.text) + "'");
      case PtuReplyKind::kAck:
      case PtuReplyKind::kValue: {
        const bool is_value = reply.kind == PtuReplyKind::kValue;
        if (is_value == (expect == Expect::kValue)) {
          return reply;
        }
        // A late reply to an earlier command: skip it, and check the alignment before the next one.
        ++counters_.out_of_step;
        needs_resync_ = true;
        continue;
      }
    }
  }
}

Result<int32_t> PtuDriver::QueryInt(PtuAxis axis, PtuQuantity quantity) {
  const std::string command = PtuQueryCommand(axis, quantity);
  IDI_ASSIGN_OR_RETURN(const PtuReply reply, Transact(command, Expect::kValue, options_.reply_timeout));
  auto value = PtuFirstInteger(reply.text);
  if (!value.ok()) {
    ++counters_.garbage_lines;
    needs_resync_ = true;
    return DeviceError(options_.name + ": reply to " + Quote(command) + " is not an integer: '" +
                       PtuPrintable(reply.text) + "'");
  }
  return value;
}

Result<double> PtuDriver::QueryDouble(PtuAxis axis, PtuQuantity quantity) {
  const std::string command = PtuQueryCommand(axis, quantity);
  IDI_ASSIGN_OR_RETURN(const PtuReply reply, Transact(command, Expect::kValue, options_.reply_timeout));
  auto value = PtuFirstNumber(reply.text);
  if (!value.ok()) {
    ++counters_.garbage_lines;
    needs_resync_ = true;
    return DeviceError(options_.name + ": reply to " + Quote(command) + " is not a number: '" +
                       PtuPrintable(reply.text) + "'");
  }
  return value;
}

Status PtuDriver::NoteFailure(Status status) {
  const StatusCode code = status.code();
  if (code == StatusCode::kCancelled) return status;  // a stop, not a failure of the unit
  ++consecutive_failures_;
  if (code == StatusCode::kTimeout || code == StatusCode::kDeviceError) {
    needs_resync_ = true;
  }
  if (code == StatusCode::kIoError ||
      (state_ == PtuState::kReady && consecutive_failures_ >= options_.max_consecutive_failures)) {
    state_ = PtuState::kFault;
    ++counters_.faults;
  }
  return status;
}

Status PtuDriver::HaltAfter(Status status) {
  const Status halted = Halt();
  return Status(status.code(), status.message() + (halted.ok() ? "; halt sent" : "; halt failed: " + halted.message()));
}

Status PtuDriver::Halt() {
  // Halting must work from any state: open the port without initialising the unit.
  const auto open_port = [this]() -> Status {
    drivers::SerialOptions serial;
    serial.baud = options_.baud;
    auto port = drivers::SerialPort::Open(options_.port, serial);
    if (!port.ok()) return port.status().WithContext(options_.name + ": halt");
    port_ = std::move(port).value();
    return Status::Ok();
  };
  if (!port_) IDI_RETURN_IF_ERROR(open_port());
  auto reply = Transact(PtuCommand("H"), Expect::kAck, options_.reply_timeout);
  if (!reply.ok() && reply.status().code() == StatusCode::kIoError) {
    // The port itself failed (a USB adapter that dropped off the bus and came back): the halt is the
    // one command worth a fresh open, once.
    port_.reset();
    if (open_port().ok()) reply = Transact(PtuCommand("H"), Expect::kAck, options_.reply_timeout);
  }
  if (!reply.ok()) {
    return NoteFailure(reply.status().WithContext("halt"));
  }
  ++counters_.halts_sent;
  return Status::Ok();
}

Result<std::pair<int32_t, int32_t>> PtuDriver::ReadPositions() {
  IDI_RETURN_IF_ERROR(EnsureReady());
  auto pan = QueryInt(PtuAxis::kPan, PtuQuantity::kPosition);
  if (!pan.ok()) return NoteFailure(pan.status());
  auto tilt = QueryInt(PtuAxis::kTilt, PtuQuantity::kPosition);
  if (!tilt.ok()) return NoteFailure(tilt.status());
  consecutive_failures_ = 0;
  return std::make_pair(pan.value(), tilt.value());
}

Result<hal::PanTiltLimits> PtuDriver::Limits() {
  IDI_RETURN_IF_ERROR(EnsureReady());
  const double pr = PtuArcSecondsToRad(pan_arcsec_), tr = PtuArcSecondsToRad(tilt_arcsec_);
  hal::PanTiltLimits limits;
  limits.pan_min_rad = pan_min_ * pr;
  limits.pan_max_rad = pan_max_ * pr;
  limits.tilt_min_rad = tilt_min_ * tr;
  limits.tilt_max_rad = tilt_max_ * tr;
  limits.pan_resolution_rad = pr;
  limits.tilt_resolution_rad = tr;
  return limits;
}

Result<hal::PanTiltState> PtuDriver::Read() {
  const int64_t t_ns = clock_->NowNs();
  IDI_ASSIGN_OR_RETURN(const auto positions, ReadPositions());
  hal::PanTiltState state;
  state.timestamp_ns = t_ns;
  state.pan_rad = positions.first * PtuArcSecondsToRad(pan_arcsec_);
  state.tilt_rad = positions.second * PtuArcSecondsToRad(tilt_arcsec_);
  return state;
}

Status PtuDriver::MoveTo(double pan_rad, double tilt_rad, std::chrono::milliseconds timeout) {
  if (!std::isfinite(pan_rad) || !std::isfinite(tilt_rad)) {
    return InvalidArgument(options_.name + ": MoveTo needs finite angles, got pan " + FormatNumber(pan_rad) +
                           ", tilt " + FormatNumber(tilt_rad));
  }
  if (timeout.count() <= 0) {
    return InvalidArgument(options_.name + ": MoveTo timeout must be positive");
  }
  if (interrupt_.requested()) return Cancelled(options_.name + ": move refused: a stop is in force; nothing sent");
  IDI_RETURN_IF_ERROR(EnsureReady());
  const double pr = PtuArcSecondsToRad(pan_arcsec_), tr = PtuArcSecondsToRad(tilt_arcsec_);
  // Nearest position; the limit check is on positions, as the unit does it.
  const double pan_pos = std::round(pan_rad / pr), tilt_pos = std::round(tilt_rad / tr);
  if (pan_pos < pan_min_ || pan_pos > pan_max_) {
    return OutOfRange(options_.name + ": pan " + PtuFormatRad(pan_rad) + " (position " +
                      std::to_string(static_cast<long long>(pan_pos)) + ") is outside [" + std::to_string(pan_min_) +
                      ", " + std::to_string(pan_max_) + "] positions = [" + PtuFormatRad(pan_min_ * pr) + ", " +
                      PtuFormatRad(pan_max_ * pr) + "]; nothing sent");
  }
  if (tilt_pos < tilt_min_ || tilt_pos > tilt_max_) {
    return OutOfRange(options_.name + ": tilt " + PtuFormatRad(tilt_rad) + " (position " +
                      std::to_string(static_cast<long long>(tilt_pos)) + ") is outside [" +
                      std::to_string(tilt_min_) + ", " + std::to_string(tilt_max_) + "] positions = [" +
                      PtuFormatRad(tilt_min_ * tr) + ", " + PtuFormatRad(tilt_max_ * tr) + "]; nothing sent");
  }
  const auto p = static_cast<int32_t>(pan_pos), t = static_cast<int32_t>(tilt_pos);
  pending_limit_hits_.clear();
  for (const std::string& command : {PtuSetPositionCommand(PtuAxis::kPan, p), PtuSetPositionCommand(PtuAxis::kTilt, t)}) {
    // A stop during the first axis' command: the second is not sent, the first is halted.
    if (interrupt_.requested()) return HaltAfter(Cancelled(options_.name + ": move interrupted by a stop"));
    auto ack = Transact(command, Expect::kAck, options_.reply_timeout);
    if (!ack.ok()) return HaltAfter(NoteFailure(ack.status()));
  }
  // Await completion: the unit answers '*' when both axes have stopped.
  auto done = Transact(PtuCommand("A"), Expect::kAck, timeout, /*interruptible=*/true);
  if (!done.ok()) {
    const Status s = done.status().code() == StatusCode::kTimeout
                         ? Timeout(options_.name + ": move to pan " + std::to_string(p) + ", tilt " + std::to_string(t) +
                                   " positions did not complete within " + std::to_string(timeout.count()) + " ms")
                         : done.status();
    return HaltAfter(NoteFailure(s));
  }
  if (!pending_limit_hits_.empty()) {
    const Status s = DeviceError(options_.name + ": asynchronous limit reply '!" +
                                 std::string(1, PtuAxisLetter(pending_limit_hits_.front())) + "' (" +
                                 PtuAxisName(pending_limit_hits_.front()) + " hit its limit) during the move to pan " +
                                 std::to_string(p) + ", tilt " + std::to_string(t) + " positions");
    pending_limit_hits_.clear();
    return HaltAfter(NoteFailure(s));
  }
  auto at = ReadPositions();
  if (!at.ok()) return HaltAfter(at.status());
  if (at->first != p || at->second != t) {
    return HaltAfter(NoteFailure(DeviceError(
        options_.name + ": after the move the unit is at pan " + std::to_string(at->first) + ", tilt " +
        std::to_string(at->second) + " positions, commanded " + std::to_string(p) + ", " + std::to_string(t))));
  }
  consecutive_failures_ = 0;
  return Status::Ok();
}

}  // namespace idi::workcell
