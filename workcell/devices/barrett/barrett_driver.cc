#include "workcell/devices/barrett/barrett_driver.h"

#include <cmath>
#include <cstdio>

namespace idi::workcell {
namespace {

using BarrettSteadyClock = std::chrono::steady_clock;

std::string BarrettPrintable(std::string_view text) {
  std::string out;
  for (const char c : text.substr(0, 60)) {
    const auto u = static_cast<unsigned char>(c);
    if (u >= 0x20 && u < 0x7f) {
      out += c;
    } else {
      char buf[8];
      std::snprintf(buf, sizeof(buf), "\\x%02x", u);
      out += buf;
    }
  }
  if (text.size() > 60) out += "...";
  return out;
}

}  // namespace

Status BarrettDriverOptions::Check() const {
  if (name.empty()) return InvalidArgument("barrett options: name is empty");
  if (port.empty()) return InvalidArgument("barrett options (" + name + "): port is empty");
  if (!drivers::BaudToTermiosSpeed(baud).ok()) {
    return InvalidArgument("barrett options (" + name + "): unsupported baud " + std::to_string(baud));
  }
  if (reply_timeout.count() <= 0 || motion_timeout.count() <= 0 || init_timeout.count() <= 0 ||
      quiet_period.count() <= 0 || drain_limit < quiet_period) {
    return InvalidArgument("barrett options (" + name + "): timeouts must be positive, drain_limit >= quiet_period");
  }
  if (!(finger_counts_per_rad > 0) || !(spread_counts_per_rad > 0) || !(spread_max_rad > 0)) {
    return InvalidArgument("barrett options (" + name + "): encoder factors and spread_max_rad must be positive");
  }
  if (max_consecutive_failures < 1) {
    return InvalidArgument("barrett options (" + name + "): max_consecutive_failures must be >= 1");
  }
  return Status::Ok();
}

const char* BarrettStateName(BarrettState state) {
  switch (state) {
    case BarrettState::kDisconnected: return "disconnected";
    case BarrettState::kConnected: return "connected (not initialised)";
    case BarrettState::kReady: return "ready";
    case BarrettState::kFault: return "fault";
  }
  return "?";
}

BarrettDriver::BarrettDriver(BarrettDriverOptions options, hal::Clock* clock)
    : options_(std::move(options)), clock_(clock) {
  IDI_CHECK(clock_ != nullptr, "BarrettDriver needs a clock");
}

BarrettDriver::~BarrettDriver() = default;

Status BarrettDriver::Connect() {
  IDI_RETURN_IF_ERROR(options_.Check());
  Disconnect();
  drivers::SerialOptions serial;
  serial.baud = options_.baud;
  auto port = drivers::SerialPort::Open(options_.port, serial);
  if (!port.ok()) return port.status().WithContext(options_.name);
  port_ = std::move(port).value();
  const Status synced = Resync();
  if (!synced.ok()) {
    state_ = BarrettState::kFault;
    ++counters_.faults;
    return Status(synced.code(), options_.name + ": no prompt from the hand on " + options_.port + ": " +
                                     synced.message());
  }
  if (connected_once_) ++counters_.reconnects;
  connected_once_ = true;
  state_ = initialized_ ? BarrettState::kReady : BarrettState::kConnected;
  consecutive_failures_ = 0;
  return Status::Ok();
}

void BarrettDriver::Disconnect() {
  port_.reset();
  state_ = BarrettState::kDisconnected;
}

Status BarrettDriver::Resync() {
  ++counters_.resyncs;
  // A bare CR ends any half-sent line and clears the hand's error state; then wait for silence
  // (power-up banner, late output) and ask for one more prompt.
  IDI_RETURN_IF_ERROR(port_->Write("\r", options_.reply_timeout));
  port_->DrainUntilQuiet(options_.quiet_period, options_.drain_limit);
  IDI_RETURN_IF_ERROR(port_->Write("\r", options_.reply_timeout));
  auto block = port_->ReadUntil(kBarrettPrompt, options_.reply_timeout);
  if (!block.ok()) {
    if (block.status().code() == StatusCode::kTimeout) ++counters_.timeouts;
    return block.status();
  }
  needs_resync_ = false;
  return Status::Ok();
}

Status BarrettDriver::EnsureConnected() {
  if (state_ == BarrettState::kDisconnected || state_ == BarrettState::kFault || !port_) {
    IDI_RETURN_IF_ERROR(Connect());
  }
  if (needs_resync_) {
    const Status s = Resync();
    if (!s.ok()) {
      return NoteFailure(Status(s.code(), options_.name + ": resynchronising: " + s.message()));
    }
  }
  return Status::Ok();
}

Result<BarrettReply> BarrettDriver::Transact(const std::string& text,
                                             std::chrono::milliseconds timeout,
                                             bool interruptible) {
  if (!port_) return FailedPrecondition(options_.name + ": not connected");
  ++counters_.commands;
  const Status written = port_->Write(BarrettCommandBytes(text), options_.reply_timeout);
  if (!written.ok()) return written.WithContext(options_.name + ": sending '" + text + "'");
  const auto deadline = BarrettSteadyClock::now() + timeout;
  std::string last_block;
  while (true) {
    if (interruptible && interrupt_.requested()) return Abort(text);
    const auto left = std::max(std::chrono::milliseconds(0), std::chrono::duration_cast<std::chrono::milliseconds>(
                                                                 deadline - BarrettSteadyClock::now()));
    const auto wait = interruptible ? MotionInterrupt::Slice(left) : left;
    auto block = port_->ReadUntil(kBarrettPrompt, wait);
    if (!block.ok()) {
      if (block.status().code() == StatusCode::kTimeout) {
        if (wait < left) continue;  // a slice of the wait ended, not the wait
        ++counters_.timeouts;
        needs_resync_ = true;
        return Timeout(options_.name + ": no prompt after '" + text + "' within " + std::to_string(timeout.count()) +
                       " ms" + (last_block.empty() ? std::string() : " (skipped output: '" + last_block + "')"));
      }
      if (block.status().code() == StatusCode::kDeviceError) {
        ++counters_.garbage;
        last_block = block.status().message();
        continue;
      }
      return block.status().WithContext(options_.name + ": waiting for the prompt after '" + text + "'");
    }
    BarrettReply reply = ParseBarrettReply(block.value(), text);
    if (!reply.echo_found) {
      // A prompt that is not ours: a late reply to an earlier command, or noise.
      ++counters_.out_of_step;
      last_block = BarrettPrintable(block.value());
      continue;
    }
    counters_.garbage += static_cast<uint64_t>(reply.dropped_lines);
    if (reply.error) {
      ++counters_.error_replies;
      return DeviceError(options_.name + ": '" + text + "' failed: '" + BarrettPrintable(reply.error_text) + "'");
    }
    return reply;
  }
}

Status BarrettDriver::Abort(const std::string& text) {
  // The hand runs one supervisory command at a time and takes no other (a T would wait for the end of
  // this one); Control-C ends it at once: every motor stops, "ERR 16384", then the prompt (BH8-Series
  // User's Manual D3000, termination case 4). The aborted command's output is read up to that prompt so
  // that the next command is in step; without it, the next command resynchronises first.
  // A Control-C that reaches the hand before it began the command may go unheeded: without a prompt,
  // a second one.
  std::string outcome = "; Control-C sent";
  for (int attempt = 0; attempt < 2; ++attempt) {
    const Status written = port_->Write("\x03", options_.reply_timeout);
    if (!written.ok()) {
      needs_resync_ = true;
      return Cancelled(options_.name + ": '" + text +
                       "' interrupted by a stop; Control-C could not be sent: " + written.message());
    }
    if (port_->ReadUntil(kBarrettPrompt, options_.reply_timeout).ok()) {
      return Cancelled(options_.name + ": '" + text + "' interrupted by a stop" + outcome);
    }
    outcome = "; Control-C sent twice";
  }
  needs_resync_ = true;
  return Cancelled(options_.name + ": '" + text + "' interrupted by a stop" + outcome + ", no prompt after it");
}

Status BarrettDriver::NoteFailure(Status status) {
  if (status.code() == StatusCode::kCancelled) return status;  // a stop, not a failure of the hand
  ++consecutive_failures_;
  if (status.code() == StatusCode::kTimeout || status.code() == StatusCode::kDeviceError) needs_resync_ = true;
  if (status.code() == StatusCode::kIoError || consecutive_failures_ >= options_.max_consecutive_failures) {
    if (state_ != BarrettState::kFault) ++counters_.faults;
    state_ = BarrettState::kFault;
  }
  return status;
}

Status BarrettDriver::Motion(const std::string& text, const std::string& what) {
  if (interrupt_.requested())
    return Cancelled(options_.name + ": " + what + " refused: a stop is in force; nothing sent");
  IDI_RETURN_IF_ERROR(EnsureConnected());
  if (!initialized_) {
    return FailedPrecondition(options_.name + ": " + what + " before Initialize (HI): the hand must be initialised "
                              "after power-up");
  }
  auto reply = Transact(text, options_.motion_timeout, /*interruptible=*/true);
  if (!reply.ok()) {
    const Status failed = NoteFailure(reply.status().WithContext(what));
    const Status stopped = Stop();
    return Status(failed.code(), failed.message() + (stopped.ok() ? "; stop sent" : "; stop failed: " + stopped.message()));
  }
  consecutive_failures_ = 0;
  return Status::Ok();
}

Status BarrettDriver::Initialize() {
  if (interrupt_.requested())
    return Cancelled(options_.name + ": initialise refused: a stop is in force; nothing sent");
  IDI_RETURN_IF_ERROR(EnsureConnected());
  auto reply = Transact("HI", options_.init_timeout, /*interruptible=*/true);
  if (!reply.ok()) {
    initialized_ = false;
    const Status failed = NoteFailure(reply.status().WithContext("initialise"));
    const Status stopped = Stop();
    return Status(failed.code(), failed.message() + (stopped.ok() ? "; stop sent" : "; stop failed: " + stopped.message()));
  }
  initialized_ = true;
  state_ = BarrettState::kReady;
  consecutive_failures_ = 0;
  return Status::Ok();
}

Status BarrettDriver::Open() { return Motion(BarrettCommandText(kBarrettFingers, "O"), "open"); }

Status BarrettDriver::Close() { return Motion(BarrettCommandText(kBarrettFingers, "C"), "close"); }

Status BarrettDriver::SetSpread(double spread_rad) {
  if (!std::isfinite(spread_rad) || spread_rad < 0 || spread_rad > options_.spread_max_rad) {
    return OutOfRange(options_.name + ": spread " + FormatNumber(spread_rad) + " rad is outside [0, " +
                      FormatNumber(options_.spread_max_rad) + "] rad; nothing sent");
  }
  const long counts = std::lround(spread_rad * options_.spread_counts_per_rad);
  return Motion(BarrettCommandText(kBarrettSpread, "M", std::to_string(counts)), "spread");
}

Result<long> BarrettDriver::ReadCounts(unsigned motor) {
  const std::string text = BarrettCommandText(motor, "FGET", "P");
  IDI_ASSIGN_OR_RETURN(const BarrettReply reply, Transact(text, options_.reply_timeout));
  // Lines that are not numbers are noise on the line (counted); exactly one count must remain.
  std::vector<long> counts;
  for (const std::string& line : reply.lines) {
    auto values = BarrettIntegers({line});
    if (values.ok()) {
      counts.insert(counts.end(), values->begin(), values->end());
    } else {
      ++counters_.garbage;
    }
  }
  if (counts.size() != 1) {
    ++counters_.garbage;
    needs_resync_ = true;
    std::string shown;
    for (const std::string& l : reply.lines) shown += (shown.empty() ? "" : " | ") + l;
    return DeviceError(options_.name + ": '" + text + "' answered '" + BarrettPrintable(shown) +
                       "', expected one encoder count");
  }
  return counts.front();
}

Result<hal::GripperState> BarrettDriver::Read() {
  IDI_RETURN_IF_ERROR(EnsureConnected());
  hal::GripperState state;
  state.timestamp_ns = clock_->NowNs();
  state.initialized = initialized_;
  const unsigned fingers[3] = {kBarrettF1, kBarrettF2, kBarrettF3};
  for (int i = 0; i < 3; ++i) {
    auto counts = ReadCounts(fingers[i]);
    if (!counts.ok()) return NoteFailure(counts.status());
    state.finger_rad[static_cast<std::size_t>(i)] = static_cast<double>(counts.value()) / options_.finger_counts_per_rad;
  }
  auto spread = ReadCounts(kBarrettSpread);
  if (!spread.ok()) return NoteFailure(spread.status());
  state.spread_rad = static_cast<double>(spread.value()) / options_.spread_counts_per_rad;
  consecutive_failures_ = 0;
  return state;
}

Status BarrettDriver::Stop() {
  // Stopping must work from any state: open the port without the handshake.
  const auto open_port = [this]() -> Status {
    drivers::SerialOptions serial;
    serial.baud = options_.baud;
    auto port = drivers::SerialPort::Open(options_.port, serial);
    if (!port.ok()) return port.status().WithContext(options_.name + ": stop");
    port_ = std::move(port).value();
    return Status::Ok();
  };
  if (!port_) IDI_RETURN_IF_ERROR(open_port());
  auto reply = Transact("T", options_.reply_timeout);
  if (!reply.ok() && reply.status().code() == StatusCode::kIoError) {
    // The port itself failed (the adapter dropped off the bus and came back): one fresh open for the stop.
    port_.reset();
    if (open_port().ok()) reply = Transact("T", options_.reply_timeout);
  }
  if (!reply.ok()) return NoteFailure(reply.status().WithContext("stop"));
  ++counters_.stops_sent;
  return Status::Ok();
}

}  // namespace idi::workcell
