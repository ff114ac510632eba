#include "workcell/devices/staubli/val3_emulator.h"

#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cmath>
#include <cstring>

#include "workcell/devices/staubli/val3_protocol.h"

namespace idi::workcell {

Result<std::unique_ptr<Val3Emulator>> Val3Emulator::Start(const Val3EmulatorOptions& options) {
  std::unique_ptr<Val3Emulator> emulator(new Val3Emulator(options));
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
  if (fd < 0) return IoError(std::string("val3 emulator: socket: ") + std::strerror(errno));
  emulator->listen_fd_ = fd;
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  addr.sin_port = 0;  // any free port
  if (::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)) != 0 || ::listen(fd, 4) != 0) {
    return IoError(std::string("val3 emulator: bind/listen on loopback: ") + std::strerror(errno));
  }
  socklen_t len = sizeof(addr);
  ::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len);
  emulator->port_ = ntohs(addr.sin_port);
  emulator->thread_ = std::thread([e = emulator.get()] { e->Run(); });
  return emulator;
}

Val3Emulator::Val3Emulator(const Val3EmulatorOptions& options) : options_(options) {}

Val3Emulator::~Val3Emulator() {
  stop_ = true;
  if (thread_.joinable()) thread_.join();
  if (client_fd_ >= 0) ::close(client_fd_);
  if (listen_fd_ >= 0) ::close(listen_fd_);
}

void Val3Emulator::ReplaceNextReplyWithGarbage(std::string bytes) {
  std::lock_guard lock(mu_);
  garbage_next_ = std::move(bytes);
}
void Val3Emulator::SetSilent(bool silent) {
  std::lock_guard lock(mu_);
  silent_ = silent;
}
void Val3Emulator::DropConnectionOnRequest(int n) {
  std::lock_guard lock(mu_);
  drop_countdown_ = n;
}
void Val3Emulator::FailNextRequest(int code, std::string text) {
  std::lock_guard lock(mu_);
  fail_code_ = code;
  fail_text_ = std::move(text);
}
void Val3Emulator::SetPowered(bool powered) {
  std::lock_guard lock(mu_);
  powered_ = powered;
}
void Val3Emulator::StopNextMoveHalfway() {
  std::lock_guard lock(mu_);
  halfway_next_ = true;
}
ControllerJointsDeg Val3Emulator::joints_deg() const {
  std::lock_guard lock(mu_);
  return joints_;
}
double Val3Emulator::rail_mm() const {
  std::lock_guard lock(mu_);
  return rail_;
}
bool Val3Emulator::moving() const {
  std::lock_guard lock(mu_);
  return MovingLocked();
}
int Val3Emulator::stop_requests() const {
  std::lock_guard lock(mu_);
  return stop_requests_;
}
int Val3Emulator::watchdog_stops() const {
  std::lock_guard lock(mu_);
  return watchdog_stops_;
}
int Val3Emulator::disconnect_stops() const {
  std::lock_guard lock(mu_);
  return disconnect_stops_;
}
int Val3Emulator::connections() const {
  std::lock_guard lock(mu_);
  return connections_;
}
std::vector<std::string> Val3Emulator::verbs() const {
  std::lock_guard lock(mu_);
  return verbs_;
}

bool Val3Emulator::MovingLocked() const { return joints_ != target_ || rail_ != rail_target_; }

void Val3Emulator::StopMotion() {
  target_ = joints_;
  rail_target_ = rail_;
}

void Val3Emulator::CloseClient(bool count_stop) {
  if (client_fd_ >= 0) ::close(client_fd_);
  client_fd_ = -1;
  inbox_.clear();
  // The server stops everything when its client goes away (sioGet reports the broken connection).
  if (count_stop && MovingLocked()) ++disconnect_stops_;
  StopMotion();
}

void Val3Emulator::SendReply(const std::string& bytes) {
  std::size_t done = 0;
  while (client_fd_ >= 0 && done < bytes.size()) {
    const ssize_t n = ::send(client_fd_, bytes.data() + done, bytes.size() - done, MSG_NOSIGNAL);
    if (n <= 0) {
      if (n < 0 && (errno == EAGAIN || errno == EINTR)) continue;
      CloseClient(true);
      return;
    }
    done += static_cast<std::size_t>(n);
  }
}

void Val3Emulator::Run() {
  auto last = std::chrono::steady_clock::now();
  while (!stop_) {
    pollfd fds[2] = {{listen_fd_, POLLIN, 0}, {client_fd_, POLLIN, 0}};
    ::poll(fds, client_fd_ >= 0 ? 2 : 1, 2);
    std::lock_guard lock(mu_);
    if ((fds[0].revents & POLLIN) != 0) {
      const int fd = ::accept4(listen_fd_, nullptr, nullptr, SOCK_NONBLOCK | SOCK_CLOEXEC);
      if (fd >= 0) {
        CloseClient(true);  // one client at a time: a new connection replaces the old one
        client_fd_ = fd;
        ++connections_;
        last_request_ = std::chrono::steady_clock::now();
      }
    }
    if (client_fd_ >= 0 && (fds[1].revents & (POLLIN | POLLHUP | POLLERR)) != 0) {
      char chunk[512];
      const ssize_t n = ::recv(client_fd_, chunk, sizeof(chunk), 0);
      if (n == 0 || (n < 0 && errno != EAGAIN && errno != EINTR)) {
        CloseClient(true);
      } else if (n > 0) {
        inbox_.append(chunk, static_cast<std::size_t>(n));
        std::size_t end;
        while (client_fd_ >= 0 && (end = inbox_.find('\n')) != std::string::npos) {
          std::string line = inbox_.substr(0, end);
          inbox_.erase(0, end + 1);
          if (!line.empty() && line.back() == '\r') line.pop_back();
          Handle(line);
        }
        if (inbox_.size() > 4 * kVal3MaxLineBytes) inbox_.clear();
      }
    }
    const auto now = std::chrono::steady_clock::now();
    Step(std::chrono::duration<double>(now - last).count());
    last = now;
    if (MovingLocked() && now - last_request_ > options_.watchdog) {
      ++watchdog_stops_;
      StopMotion();
    }
  }
}

void Val3Emulator::Handle(const std::string& line) {
  last_request_ = std::chrono::steady_clock::now();
  auto request = ParseVal3Request(line);
  verbs_.push_back(request.ok() ? Val3VerbName(request->verb) : "?");
  if (drop_countdown_ > 0 && --drop_countdown_ == 0) {
    CloseClient(true);
    return;
  }
  if (silent_) return;
  Val3Reply reply;
  const auto fail = [&](Val3Error code, std::string text) {
    reply.ok = false;
    reply.error_code = static_cast<int>(code);
    reply.error_text = std::move(text);
    last_error_ = reply.error_code;
  };
  if (!request.ok()) {
    // Recover the id when there is one, so the client can match the error to its request.
    uint32_t id = 0;
    std::sscanf(line.c_str(), "%u", &id);
    reply.id = id <= kVal3MaxId ? id : 0;
    fail(request.status().code() == StatusCode::kOutOfRange ? Val3Error::kBadArguments : Val3Error::kMalformed,
         request.status().message());
  } else if (fail_code_ != 0) {
    reply.id = request->id;
    fail(static_cast<Val3Error>(std::exchange(fail_code_, 0)), fail_text_);
  } else {
    reply.id = request->id;
    const std::vector<double>& a = request->args;
    const bool settled = joints_ == target_, rail_settled = rail_ == rail_target_;
    switch (request->verb) {
      case Val3Verb::kHello:
        reply.fields = {std::string(kVal3ServerName), std::to_string(kVal3ProtocolVersion),
                        options_.has_rail ? "1" : "0"};
        break;
      case Val3Verb::kPing:
        reply.fields = {FormatVal3Number(
            std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count())};
        break;
      case Val3Verb::kStatus:
        reply.fields = {powered_ ? "1" : "0", "0", settled ? "1" : "0", rail_settled ? "1" : "0",
                        std::to_string(last_error_)};
        break;
      case Val3Verb::kJoints:
        for (const double j : joints_) reply.fields.push_back(FormatVal3Number(j));
        reply.fields.push_back(settled ? "1" : "0");
        break;
      case Val3Verb::kMoveJ: {
        if (!(a[0] > 0 && a[0] <= 100)) {
          fail(Val3Error::kOutOfRange, "speed must be in (0, 100] %");
          break;
        }
        if (!powered_) {
          fail(Val3Error::kNotPossible, "arm power is off");
          break;
        }
        const ControllerJointsDeg lo = Rx130ControllerMinDeg(), hi = Rx130ControllerMaxDeg();
        ControllerJointsDeg goal{};
        bool in_range = true;
        for (std::size_t i = 0; i < goal.size(); ++i) {
          goal[i] = a[i + 1];
          if (goal[i] < lo[i] || goal[i] > hi[i]) {
            fail(Val3Error::kOutOfRange, "joint " + std::to_string(i + 1) + " out of range");
            in_range = false;
            break;
          }
        }
        if (!in_range) break;
        if (std::exchange(halfway_next_, false)) {
          for (std::size_t i = 0; i < goal.size(); ++i) goal[i] = joints_[i] + (goal[i] - joints_[i]) / 2;
        }
        target_ = goal;
        speed_pct_ = a[0];
        break;
      }
      case Val3Verb::kStop:
        ++stop_requests_;
        StopMotion();
        break;
      case Val3Verb::kRail:
        if (!options_.has_rail) {
          fail(Val3Error::kNoRail, "no rail on this controller");
          break;
        }
        reply.fields = {FormatVal3Number(rail_), rail_settled ? "1" : "0"};
        break;
      case Val3Verb::kRailMove:
        if (!options_.has_rail) {
          fail(Val3Error::kNoRail, "no rail on this controller");
        } else if (!(a[0] > 0 && a[0] <= 100) || a[1] < options_.rail_min_mm || a[1] > options_.rail_max_mm) {
          fail(Val3Error::kOutOfRange, "rail speed or position out of range");
        } else if (!powered_) {
          fail(Val3Error::kNotPossible, "arm power is off");
        } else {
          rail_target_ = a[1];
          rail_speed_pct_ = a[0];
        }
        break;
    }
  }
  if (!garbage_next_.empty()) {
    SendReply(std::exchange(garbage_next_, std::string()));
    return;
  }
  SendReply(EncodeVal3Reply(reply));
}

void Val3Emulator::Step(double dt_s) {
  const double step = options_.joint_speed_deg_per_s * speed_pct_ / 100.0 * dt_s;
  for (std::size_t i = 0; i < joints_.size(); ++i) {
    const double diff = target_[i] - joints_[i];
    joints_[i] = std::abs(diff) <= step ? target_[i] : joints_[i] + std::copysign(step, diff);
  }
  const double rail_step = options_.rail_speed_mm_per_s * rail_speed_pct_ / 100.0 * dt_s;
  const double rail_diff = rail_target_ - rail_;
  rail_ = std::abs(rail_diff) <= rail_step ? rail_target_ : rail_ + std::copysign(rail_step, rail_diff);
}

}  // namespace idi::workcell
