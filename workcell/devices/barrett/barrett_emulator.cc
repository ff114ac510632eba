#include "workcell/devices/barrett/barrett_emulator.h"

#include <poll.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cmath>

#include "workcell/devices/barrett/barrett_codec.h"

namespace idi::workcell {
namespace {

constexpr int kBhEmuErrUnknown = 1;
constexpr int kBhEmuErrArgument = 2;
constexpr int kBhEmuErrNotInitialized = 3;

const char kBhEmuBanner[] =
    "\r\nBarrettHand Firmware Version 4.3.3\r\nCopyright (c) Barrett Technology Inc.\r\n";

}  // namespace

Result<std::unique_ptr<BarrettEmulator>> BarrettEmulator::Start(const BarrettEmulatorOptions& options) {
  IDI_ASSIGN_OR_RETURN(drivers::PtyPair pty, drivers::PtyPair::Open());
  std::unique_ptr<BarrettEmulator> emulator(new BarrettEmulator(options, std::move(pty)));
  emulator->thread_ = std::thread([e = emulator.get()] { e->Run(); });
  return emulator;
}

BarrettEmulator::BarrettEmulator(const BarrettEmulatorOptions& options, drivers::PtyPair pty)
    : options_(options), pty_(std::move(pty)) {}

BarrettEmulator::~BarrettEmulator() {
  stop_ = true;
  if (thread_.joinable()) thread_.join();
}

void BarrettEmulator::SetSilent(bool silent) {
  std::lock_guard lock(mu_);
  silent_ = silent;
}
void BarrettEmulator::InjectGarbageBeforeNextReply(std::string bytes) {
  std::lock_guard lock(mu_);
  garbage_ = std::move(bytes);
}
void BarrettEmulator::FailNextCommand(int code) {
  std::lock_guard lock(mu_);
  fail_code_ = code;
}
void BarrettEmulator::PowerCycle() {
  std::lock_guard lock(mu_);
  initialized_ = false;
  busy_ = false;
  initialising_ = false;
  pending_lines_.clear();
  line_.clear();
  for (std::size_t i = 0; i < 4; ++i) target_[i] = std::lround(position_[i]);
  Send(std::string(kBhEmuBanner) + std::string(kBarrettPrompt));
}
void BarrettEmulator::SetObject(int finger, long counts) {
  std::lock_guard lock(mu_);
  object_.at(static_cast<std::size_t>(finger)) = counts;
}
std::array<long, 4> BarrettEmulator::positions() const {
  std::lock_guard lock(mu_);
  std::array<long, 4> out{};
  for (std::size_t i = 0; i < 4; ++i) out[i] = std::lround(position_[i]);
  return out;
}
bool BarrettEmulator::initialized() const {
  std::lock_guard lock(mu_);
  return initialized_;
}
int BarrettEmulator::aborts() const {
  std::lock_guard lock(mu_);
  return aborts_;
}

int BarrettEmulator::stops() const {
  std::lock_guard lock(mu_);
  return stops_;
}
std::vector<std::string> BarrettEmulator::commands() const {
  std::lock_guard lock(mu_);
  return commands_;
}

void BarrettEmulator::Run() {
  auto last = std::chrono::steady_clock::now();
  while (!stop_) {
    pollfd pfd{pty_.master_fd(), POLLIN, 0};
    if (::poll(&pfd, 1, 2) > 0 && (pfd.revents & POLLIN) != 0) {
      char chunk[256];
      const ssize_t n = ::read(pty_.master_fd(), chunk, sizeof(chunk));
      if (n > 0) HandleBytes(chunk, static_cast<std::size_t>(n));
    }
    const auto now = std::chrono::steady_clock::now();
    std::lock_guard lock(mu_);
    Step(std::chrono::duration<double>(now - last).count());
    last = now;
  }
}

void BarrettEmulator::Send(const std::string& bytes) {
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(pty_.master_fd(), bytes.data() + done, bytes.size() - done);
    if (n <= 0) return;
    done += static_cast<std::size_t>(n);
  }
}

void BarrettEmulator::Finish(const std::string& output) {
  Send(std::exchange(garbage_, std::string()) + output + std::string(kBarrettPrompt));
}

bool BarrettEmulator::Moving() const {
  for (std::size_t i = 0; i < 4; ++i) {
    if (position_[i] != static_cast<double>(target_[i])) return true;
  }
  return false;
}

void BarrettEmulator::HandleBytes(const char* data, std::size_t n) {
  std::lock_guard lock(mu_);
  if (!seen_input_) {
    seen_input_ = true;
    if (options_.banner_on_first_input) Send(std::string("\x00\xff", 2) + kBhEmuBanner + std::string(kBarrettPrompt));
  }
  if (silent_) return;
  for (std::size_t i = 0; i < n; ++i) {
    const char c = data[i];
    if (c == '\n') continue;
    if (c == '\x03') {
      // Control-C ends the command in progress: every motor stops where it is, status 16384, then the
      // prompt and any input that waited. Ignored when no command runs.
      if (busy_) {
        for (std::size_t m = 0; m < 4; ++m) target_[m] = std::lround(position_[m] = std::round(position_[m]));
        busy_ = false;
        if (std::exchange(initialising_, false)) initialized_ = false;  // an aborted HI leaves the hand uninitialised
        ++aborts_;
        Finish("ERR 16384\r\n");
        while (!busy_ && !pending_lines_.empty()) {
          const std::string next = pending_lines_.front();
          pending_lines_.pop_front();
          Execute(next);
        }
      }
      continue;
    }
    Send(std::string(1, c == '\r' ? '\r' : c) + (c == '\r' ? "\n" : ""));
    if (c != '\r') {
      line_ += c;
      continue;
    }
    std::string line = std::exchange(line_, std::string());
    if (busy_) {
      pending_lines_.push_back(std::move(line));  // supervisory mode: one command at a time
    } else {
      Execute(line);
    }
  }
}

void BarrettEmulator::Execute(const std::string& raw) {
  std::string line;
  for (const char c : raw) line += static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  while (!line.empty() && line.back() == ' ') line.pop_back();
  while (!line.empty() && line.front() == ' ') line.erase(line.begin());
  if (line.empty()) {
    Finish("");
    return;
  }
  commands_.push_back(line);
  if (fail_code_ != 0) {
    Finish("ERR " + std::to_string(std::exchange(fail_code_, 0)) + "\r\n");
    return;
  }
  std::size_t split = 0;
  while (split < line.size() && std::string_view("1234GS").find(line[split]) != std::string_view::npos) ++split;
  // "S" alone is not a prefix of commands that start with S; none of ours does.
  const auto motors_or = ParseBarrettMotorPrefix(line.substr(0, split));
  const unsigned motors = motors_or.ok() ? motors_or.value() : kBarrettWholeHand;
  const std::string rest = line.substr(split);
  const std::size_t space = rest.find(' ');
  const std::string command = rest.substr(0, space);
  const std::string args = space == std::string::npos ? "" : rest.substr(space + 1);
  const auto each_motor = [&](auto&& f) {
    for (std::size_t m = 0; m < 4; ++m) {
      if ((motors & (1u << m)) != 0) f(m);
    }
  };
  const auto max_of = [&](std::size_t m) { return m == 3 ? options_.spread_max_counts : options_.finger_max_counts; };

  if (command == "HI") {
    initialized_ = true;
    for (std::size_t m = 0; m < 4; ++m) position_[m] = static_cast<double>(target_[m] = 0);
    busy_ = true;
    initialising_ = true;
    busy_until_ = std::chrono::steady_clock::now() + options_.hi_duration;
    return;
  }
  if (command == "T") {
    each_motor([&](std::size_t m) { target_[m] = std::lround(position_[m] = std::round(position_[m])); });
    ++stops_;
    Finish("");
    return;
  }
  if (command == "FGET") {
    if (args == "P") {
      std::string out;
      each_motor([&](std::size_t m) { out += (out.empty() ? "" : " ") + std::to_string(std::lround(position_[m])); });
      Finish(out + "\r\n");
    } else {
      Finish("0\r\n");
    }
    return;
  }
  if (command == "FSET" || command == "PSET") {
    Finish("");
    return;
  }
  if (command == "PGET") {
    Finish(args == "TEMP" ? "312\r\n" : "0\r\n");
    return;
  }
  if (command == "RESET") {
    initialized_ = false;
    Finish(kBhEmuBanner);
    return;
  }
  if (command == "O" || command == "C" || command == "M") {
    if (!initialized_) {
      Finish("ERR " + std::to_string(kBhEmuErrNotInitialized) + "\r\n");
      return;
    }
    long goal = 0;
    if (command == "M") {
      char* end = nullptr;
      goal = std::strtol(args.c_str(), &end, 10);
      bool bad = args.empty() || end != args.c_str() + args.size();
      each_motor([&](std::size_t m) { bad = bad || goal < 0 || goal > max_of(m); });
      if (bad) {
        Finish("ERR " + std::to_string(kBhEmuErrArgument) + "\r\n");
        return;
      }
    }
    each_motor([&](std::size_t m) { target_[m] = command == "O" ? 0 : command == "C" ? max_of(m) : goal; });
    busy_ = true;
    busy_until_ = std::chrono::steady_clock::now();
    return;
  }
  Finish("ERR " + std::to_string(kBhEmuErrUnknown) + "\r\n");
}

void BarrettEmulator::Step(double dt_s) {
  const double step = options_.speed_counts_per_s * dt_s;
  for (std::size_t m = 0; m < 4; ++m) {
    const double before = position_[m];
    const double diff = static_cast<double>(target_[m]) - before;
    position_[m] = std::abs(diff) <= step ? static_cast<double>(target_[m]) : before + std::copysign(step, diff);
    // Closing onto an object: the inner link stalls at the contact (TorqueSwitch, §3.5).
    if (m < 3 && object_[m] >= 0 && diff > 0 && before <= static_cast<double>(object_[m]) &&
        position_[m] >= static_cast<double>(object_[m])) {
      position_[m] = static_cast<double>(object_[m]);
      target_[m] = object_[m];
    }
  }
  if (busy_ && !Moving() && std::chrono::steady_clock::now() >= busy_until_) {
    busy_ = false;
    initialising_ = false;
    Finish("");
    while (!busy_ && !pending_lines_.empty()) {
      const std::string next = pending_lines_.front();
      pending_lines_.pop_front();
      Execute(next);
    }
  }
}

}  // namespace idi::workcell
