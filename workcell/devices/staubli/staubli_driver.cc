#include "workcell/devices/staubli/staubli_driver.h"

#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <thread>

#include "shared/util/units.h"
#include "workcell/devices/staubli/staubli_joints.h"

namespace idi::workcell {
namespace {

using StaubliSteadyClock = std::chrono::steady_clock;

std::string StaubliPrintable(std::string_view text) {
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

std::string StaubliFixed(double value, int decimals) {
  char buf[48];
  std::snprintf(buf, sizeof(buf), "%.*f", decimals, value);
  return buf;
}

std::chrono::milliseconds StaubliLeft(StaubliSteadyClock::time_point deadline) {
  return std::max(std::chrono::milliseconds(0),
                  std::chrono::duration_cast<std::chrono::milliseconds>(deadline - StaubliSteadyClock::now()));
}

}  // namespace

Result<int> TcpConnect(const std::string& host, int port, std::chrono::milliseconds timeout) {
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  addrinfo* found = nullptr;
  const std::string service = std::to_string(port);
  const int gai = ::getaddrinfo(host.c_str(), service.c_str(), &hints, &found);
  if (gai != 0) {
    // IoError, not NotFound: a caller must not take a controller it cannot reach for a target not found.
    return IoError("cannot resolve " + host + ": " + ::gai_strerror(gai));
  }
  std::string last_error = "no address";
  Status last = IoError("cannot connect to " + host + ":" + service);
  for (addrinfo* a = found; a != nullptr; a = a->ai_next) {
    const int fd = ::socket(a->ai_family, a->ai_socktype | SOCK_NONBLOCK | SOCK_CLOEXEC, a->ai_protocol);
    if (fd < 0) continue;
    int rc = ::connect(fd, a->ai_addr, a->ai_addrlen);
    if (rc != 0 && errno == EINPROGRESS) {
      pollfd pfd{fd, POLLOUT, 0};
      // A signal (SIGCHLD, SIGTERM) interrupts the wait: wait again for what is left of the timeout,
      // never take the connection as made.
      const auto deadline = StaubliSteadyClock::now() + timeout;
      do {
        rc = ::poll(&pfd, 1, static_cast<int>(StaubliLeft(deadline).count()));
      } while (rc < 0 && errno == EINTR);
      if (rc < 0) {
        const int err = errno;
        ::close(fd);
        last = IoError("cannot connect to " + host + ":" + service + ": " + std::strerror(err));
        continue;
      }
      if (rc == 0) {
        ::close(fd);
        last = Timeout("no connection to " + host + ":" + service + " within " + std::to_string(timeout.count()) + " ms");
        continue;
      }
      int err = 0;
      socklen_t len = sizeof(err);
      ::getsockopt(fd, SOL_SOCKET, SO_ERROR, &err, &len);
      rc = err == 0 ? 0 : -1;
      errno = err;
    }
    if (rc != 0) {
      const int err = errno;
      ::close(fd);
      last = IoError("cannot connect to " + host + ":" + service + ": " + std::strerror(err));
      continue;
    }
    const int one = 1;
    ::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof(one));  // short request/reply lines
    ::freeaddrinfo(found);
    return fd;
  }
  ::freeaddrinfo(found);
  return last;
}

Status StaubliDriverOptions::Check() const {
  if (name.empty()) return InvalidArgument("staubli options: name is empty");
  if (host.empty() || port <= 0 || port > 65535) {
    return InvalidArgument("staubli options (" + name + "): host and port 1..65535 needed");
  }
  if (connect_timeout.count() <= 0 || reply_timeout.count() <= 0 || poll_period.count() <= 0) {
    return InvalidArgument("staubli options (" + name + "): timeouts and poll period must be positive");
  }
  if (!(joint_tolerance_deg > 0) || !(rail_tolerance_mm > 0) || !(rail_min_mm < rail_max_mm)) {
    return InvalidArgument("staubli options (" + name + "): tolerances must be positive, rail_min_mm < rail_max_mm");
  }
  if (max_consecutive_failures < 1) {
    return InvalidArgument("staubli options (" + name + "): max_consecutive_failures must be >= 1");
  }
  return Status::Ok();
}

const char* StaubliStateName(StaubliState state) {
  switch (state) {
    case StaubliState::kDisconnected: return "disconnected";
    case StaubliState::kReady: return "ready";
    case StaubliState::kFault: return "fault";
  }
  return "?";
}

StaubliDriver::StaubliDriver(StaubliDriverOptions options, hal::Clock* clock)
    : options_(std::move(options)), clock_(clock) {
  IDI_CHECK(clock_ != nullptr, "StaubliDriver needs a clock");
}

StaubliDriver::~StaubliDriver() = default;

Status StaubliDriver::Connect() {
  IDI_RETURN_IF_ERROR(options_.Check());
  Disconnect();
  const std::string where = options_.host + ":" + std::to_string(options_.port);
  auto fd = TcpConnect(options_.host, options_.port, options_.connect_timeout);
  if (!fd.ok()) return fd.status().WithContext(options_.name);
  drivers::SerialOptions framing;
  framing.max_line_bytes = 4 * kVal3MaxLineBytes;
  link_ = drivers::SerialPort::FromFd(fd.value(), options_.name + " (" + where + ")", framing);
  auto hello = Request(Val3Verb::kHello, {static_cast<double>(kVal3ProtocolVersion)}, options_.reply_timeout);
  if (!hello.ok()) {
    Disconnect();
    return hello.status().WithContext("HELLO");
  }
  auto decoded = DecodeVal3Hello(hello.value());
  if (!decoded.ok()) {
    Disconnect();
    return DeviceError(options_.name + ": the server at " + where + " is not an IDI-VAL3 server: " +
                       decoded.status().message());
  }
  if (decoded->version != kVal3ProtocolVersion) {
    Disconnect();
    return FailedPrecondition(options_.name + ": the server at " + where + " speaks protocol version " +
                              std::to_string(decoded->version) + ", this client " +
                              std::to_string(kVal3ProtocolVersion) + " (install targets/workcell-pc/val3)");
  }
  has_rail_ = decoded->has_rail;
  if (connected_once_) ++counters_.reconnects;
  connected_once_ = true;
  state_ = StaubliState::kReady;
  consecutive_failures_ = 0;
  return Status::Ok();
}

void StaubliDriver::Disconnect() {
  link_.reset();
  state_ = StaubliState::kDisconnected;
}

Status StaubliDriver::EnsureConnected() {
  if (!link_ || state_ != StaubliState::kReady) return Connect();
  return Status::Ok();
}

Result<Val3Reply> StaubliDriver::Request(Val3Verb verb, const std::vector<double>& args,
                                         std::chrono::milliseconds timeout) {
  if (!link_) return FailedPrecondition(options_.name + ": not connected");
  next_id_ = next_id_ % kVal3MaxId + 1;
  const uint32_t id = next_id_;
  const std::string verb_name = Val3VerbName(verb);
  ++counters_.requests;
  const Status written = link_->Write(EncodeVal3Request({id, verb, args}), options_.reply_timeout);
  if (!written.ok()) {
    ++counters_.disconnects;
    Disconnect();
    return IoError(options_.name + ": connection lost sending " + verb_name + ": " + written.message());
  }
  const auto deadline = StaubliSteadyClock::now() + timeout;
  std::string last_garbage;
  while (true) {
    auto line = link_->ReadLine(StaubliLeft(deadline));
    if (!line.ok()) {
      const StatusCode code = line.status().code();
      if (code == StatusCode::kTimeout) {
        ++counters_.timeouts;
        return Timeout(options_.name + ": no reply to " + verb_name + " (id " + std::to_string(id) + ") within " +
                       std::to_string(timeout.count()) + " ms" +
                       (last_garbage.empty() ? std::string() : "; garbage received instead: '" + last_garbage + "'"));
      }
      if (code == StatusCode::kDeviceError) {
        ++counters_.garbage;
        last_garbage = "(over-long line)";
        continue;
      }
      ++counters_.disconnects;
      Disconnect();
      return IoError(options_.name + ": connection lost waiting for the reply to " + verb_name + ": " +
                     line.status().message());
    }
    // Stray bytes ahead of a reply (line noise, a NUL) are dropped and counted.
    std::string_view text = line.value();
    std::size_t skip = 0;
    while (skip < text.size() && (static_cast<unsigned char>(text[skip]) < 0x20 ||
                                  static_cast<unsigned char>(text[skip]) >= 0x7f)) {
      ++skip;
    }
    text.remove_prefix(skip);
    auto reply = ParseVal3Reply(text);
    if (reply.ok() && skip > 0) ++counters_.garbage;  // one count per noisy line
    if (!reply.ok()) {
      ++counters_.garbage;
      last_garbage = StaubliPrintable(line.value());
      continue;
    }
    if (reply->id != id) {
      ++counters_.stale_replies;  // a late reply to an earlier request
      continue;
    }
    if (!reply->ok) {
      ++counters_.error_replies;
      const std::string message = options_.name + ": controller refused " + verb_name + ": ERR " +
                                  std::to_string(reply->error_code) + " " + reply->error_text;
      switch (static_cast<Val3Error>(reply->error_code)) {
        case Val3Error::kOutOfRange: return OutOfRange(message);
        case Val3Error::kNotPossible:
        case Val3Error::kNoRail: return FailedPrecondition(message);
        default: return DeviceError(message);
      }
    }
    return reply;
  }
}

Status StaubliDriver::NoteFailure(Status status) {
  ++consecutive_failures_;
  if (state_ == StaubliState::kReady && consecutive_failures_ >= options_.max_consecutive_failures) {
    state_ = StaubliState::kFault;
    ++counters_.faults;
  }
  return status;
}

Status StaubliDriver::Stop() {
  if (!link_ || state_ != StaubliState::kReady) {
    // The stop matters most when things went wrong: reconnect once to deliver it.
    const Status connected = Connect();
    if (!connected.ok()) return connected.WithContext("stop");
  }
  auto reply = Request(Val3Verb::kStop, {}, options_.reply_timeout);
  if (!reply.ok()) return NoteFailure(reply.status().WithContext("stop"));
  ++counters_.stops_sent;
  return Status::Ok();
}

Status StaubliDriver::StopAfter(Status status) {
  const Status stopped = Stop();
  return Status(status.code(),
                status.message() + (stopped.ok() ? "; stop sent" : "; stop could NOT be sent: " + stopped.message()));
}

Status StaubliDriver::CheckMoveOptions(const hal::MoveOptions& options) const {
  if (!(options.speed_fraction > 0 && options.speed_fraction <= 1)) {
    return InvalidArgument(options_.name + ": speed_fraction must be in (0, 1], got " +
                           FormatNumber(options.speed_fraction));
  }
  if (options.timeout.count() <= 0) return InvalidArgument(options_.name + ": move timeout must be positive");
  return Status::Ok();
}

Status StaubliDriver::MoveJoints(const Joints& q_rad, const hal::MoveOptions& options) {
  IDI_RETURN_IF_ERROR(CheckMoveOptions(options));
  for (std::size_t i = 0; i < q_rad.size(); ++i) {
    if (!std::isfinite(q_rad[i])) {
      return InvalidArgument(options_.name + ": joint " + std::to_string(i + 1) + " is not finite; nothing sent");
    }
  }
  const int bad = options_.limits.FirstViolation(q_rad);
  if (bad >= 0) {
    const auto i = static_cast<std::size_t>(bad);
    return OutOfRange(options_.name + ": joint " + std::to_string(bad + 1) + " = " +
                      StaubliFixed(RadToDeg(q_rad[i]), 3) + " deg is outside [" +
                      StaubliFixed(RadToDeg(options_.limits.min[i]), 1) + ", " +
                      StaubliFixed(RadToDeg(options_.limits.max[i]), 1) + "] deg (model convention); nothing sent");
  }
  if (interrupt_.requested()) return Cancelled(options_.name + ": move refused: a stop is in force; nothing sent");
  IDI_RETURN_IF_ERROR(EnsureConnected());
  const ControllerJointsDeg target = ModelRadToControllerDeg(q_rad);
  std::vector<double> args = {options.speed_fraction * 100.0};
  args.insert(args.end(), target.begin(), target.end());
  auto queued = Request(Val3Verb::kMoveJ, args, options_.reply_timeout);
  if (!queued.ok()) return StopAfter(NoteFailure(queued.status()));

  const auto start = StaubliSteadyClock::now();
  const auto deadline = start + options.timeout;
  // The controller may still report "settled" for a moment after accepting the move.
  const auto grace_end = start + 10 * options_.poll_period;
  double error_deg = 0;
  while (true) {
    std::this_thread::sleep_for(options_.poll_period);
    if (interrupt_.requested()) return StopAfter(Cancelled(options_.name + ": move interrupted by a stop"));
    auto reply = Request(Val3Verb::kJoints, {}, options_.reply_timeout);
    if (!reply.ok()) return StopAfter(NoteFailure(reply.status().WithContext("during a move")));
    auto joints = DecodeVal3Joints(reply.value());
    if (!joints.ok()) {
      ++counters_.garbage;
      return StopAfter(NoteFailure(DeviceError(options_.name + ": malformed JOINTS reply during a move: " +
                                               joints.status().message())));
    }
    error_deg = 0;
    for (std::size_t i = 0; i < target.size(); ++i) error_deg = std::max(error_deg, std::abs(joints->deg[i] - target[i]));
    const auto now = StaubliSteadyClock::now();
    if (joints->settled && error_deg <= options_.joint_tolerance_deg) break;
    if (joints->settled && now > grace_end) {
      return StopAfter(NoteFailure(DeviceError(options_.name + ": the arm settled " + StaubliFixed(error_deg, 3) +
                                               " deg from the target (stopped on the controller?)")));
    }
    if (now > deadline) {
      return StopAfter(NoteFailure(Timeout(options_.name + ": move not finished within " +
                                           std::to_string(options.timeout.count()) + " ms (" +
                                           StaubliFixed(error_deg, 3) + " deg from the target)")));
    }
  }
  consecutive_failures_ = 0;
  return Status::Ok();
}

Result<hal::JointState> StaubliDriver::ReadJoints() {
  IDI_RETURN_IF_ERROR(EnsureConnected());
  const int64_t t_ns = clock_->NowNs();
  auto reply = Request(Val3Verb::kJoints, {}, options_.reply_timeout);
  if (!reply.ok()) return NoteFailure(reply.status());
  auto joints = DecodeVal3Joints(reply.value());
  if (!joints.ok()) {
    ++counters_.garbage;
    return NoteFailure(DeviceError(options_.name + ": malformed JOINTS reply: " + joints.status().message()));
  }
  consecutive_failures_ = 0;
  hal::JointState state;
  state.timestamp_ns = t_ns;
  state.q_rad = ControllerDegToModelRad(joints->deg);
  state.moving = !joints->settled;
  return state;
}

Status StaubliDriver::MoveTo(double position_mm, const hal::MoveOptions& options) {
  IDI_RETURN_IF_ERROR(CheckMoveOptions(options));
  if (!std::isfinite(position_mm) || position_mm < options_.rail_min_mm || position_mm > options_.rail_max_mm) {
    return OutOfRange(options_.name + ": rail position " + StaubliFixed(position_mm, 2) + " mm is outside [" +
                      StaubliFixed(options_.rail_min_mm, 1) + ", " + StaubliFixed(options_.rail_max_mm, 1) +
                      "] mm; nothing sent");
  }
  if (interrupt_.requested()) return Cancelled(options_.name + ": rail move refused: a stop is in force; nothing sent");
  IDI_RETURN_IF_ERROR(EnsureConnected());
  if (!has_rail_) {
    return FailedPrecondition(options_.name + ": this controller drives no rail (HELLO said has_rail 0)");
  }
  auto queued = Request(Val3Verb::kRailMove, {options.speed_fraction * 100.0, position_mm}, options_.reply_timeout);
  if (!queued.ok()) return StopAfter(NoteFailure(queued.status()));
  const auto start = StaubliSteadyClock::now();
  const auto deadline = start + options.timeout;
  const auto grace_end = start + 10 * options_.poll_period;
  while (true) {
    std::this_thread::sleep_for(options_.poll_period);
    if (interrupt_.requested()) return StopAfter(Cancelled(options_.name + ": rail move interrupted by a stop"));
    auto reply = Request(Val3Verb::kRail, {}, options_.reply_timeout);
    if (!reply.ok()) return StopAfter(NoteFailure(reply.status().WithContext("during a rail move")));
    auto rail = DecodeVal3Rail(reply.value());
    if (!rail.ok()) {
      ++counters_.garbage;
      return StopAfter(NoteFailure(DeviceError(options_.name + ": malformed RAIL reply during a move: " +
                                               rail.status().message())));
    }
    const double error_mm = std::abs(rail->mm - position_mm);
    const auto now = StaubliSteadyClock::now();
    if (rail->settled && error_mm <= options_.rail_tolerance_mm) break;
    if (rail->settled && now > grace_end) {
      return StopAfter(NoteFailure(DeviceError(options_.name + ": the rail settled " + StaubliFixed(error_mm, 2) +
                                               " mm from the target")));
    }
    if (now > deadline) {
      return StopAfter(NoteFailure(Timeout(options_.name + ": rail move not finished within " +
                                           std::to_string(options.timeout.count()) + " ms (" +
                                           StaubliFixed(error_mm, 2) + " mm from the target)")));
    }
  }
  consecutive_failures_ = 0;
  return Status::Ok();
}

Result<hal::RailState> StaubliDriver::Read() {
  IDI_RETURN_IF_ERROR(EnsureConnected());
  if (!has_rail_) return FailedPrecondition(options_.name + ": this controller drives no rail");
  const int64_t t_ns = clock_->NowNs();
  auto reply = Request(Val3Verb::kRail, {}, options_.reply_timeout);
  if (!reply.ok()) return NoteFailure(reply.status());
  auto rail = DecodeVal3Rail(reply.value());
  if (!rail.ok()) {
    ++counters_.garbage;
    return NoteFailure(DeviceError(options_.name + ": malformed RAIL reply: " + rail.status().message()));
  }
  consecutive_failures_ = 0;
  hal::RailState state;
  state.timestamp_ns = t_ns;
  state.position_mm = rail->mm;
  state.moving = !rail->settled;
  return state;
}

Status StaubliDriver::Heartbeat() {
  IDI_RETURN_IF_ERROR(EnsureConnected());
  auto reply = Request(Val3Verb::kPing, {}, options_.reply_timeout);
  if (!reply.ok()) return NoteFailure(reply.status());
  consecutive_failures_ = 0;
  return Status::Ok();
}

Result<Val3Status> StaubliDriver::ReadStatus() {
  IDI_RETURN_IF_ERROR(EnsureConnected());
  auto reply = Request(Val3Verb::kStatus, {}, options_.reply_timeout);
  if (!reply.ok()) return NoteFailure(reply.status());
  auto status = DecodeVal3Status(reply.value());
  if (!status.ok()) {
    ++counters_.garbage;
    return NoteFailure(DeviceError(options_.name + ": malformed STATUS reply: " + status.status().message()));
  }
  return status;
}

}  // namespace idi::workcell
