#include "workcell/devices/ptu/ptu_emulator.h"

#include <poll.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>

namespace idi::workcell {
namespace {

using EmuClock = std::chrono::steady_clock;

std::string PtuEmuFormat(const char* format, double value) {
  char buf[96];
  std::snprintf(buf, sizeof(buf), format, value);
  return buf;
}

}  // namespace

Result<std::unique_ptr<PtuEmulator>> PtuEmulator::Start(const PtuEmulatorOptions& options) {
  IDI_ASSIGN_OR_RETURN(drivers::PtyPair pty, drivers::PtyPair::Open());
  std::unique_ptr<PtuEmulator> emulator(new PtuEmulator(options, std::move(pty)));
  emulator->thread_ = std::thread([e = emulator.get()] { e->Run(); });
  return emulator;
}

PtuEmulator::PtuEmulator(const PtuEmulatorOptions& options, drivers::PtyPair pty)
    : options_(options), pty_(std::move(pty)) {}

PtuEmulator::~PtuEmulator() {
  stop_ = true;
  if (thread_.joinable()) thread_.join();
}

void PtuEmulator::SetSilent(bool silent) {
  std::lock_guard lock(mu_);
  silent_ = silent;
}
void PtuEmulator::InjectGarbageBeforeNextReply(std::string bytes) {
  std::lock_guard lock(mu_);
  garbage_ = std::move(bytes);
}
void PtuEmulator::FailNextCommand(std::string message) {
  std::lock_guard lock(mu_);
  fail_next_ = true;
  fail_message_ = std::move(message);
}
void PtuEmulator::DelayNextReply(std::chrono::milliseconds delay) {
  std::lock_guard lock(mu_);
  delay_ = delay;
}
void PtuEmulator::LimitHitDuringNextMove(PtuAxis axis) {
  std::lock_guard lock(mu_);
  limit_hit_axis_ = axis;
  limit_hit_armed_ = false;
}
void PtuEmulator::PowerCycle() {
  std::lock_guard lock(mu_);
  pan_ = tilt_ = 0;
  pan_target_ = tilt_target_ = 0;
  echo_ = true;
  terse_ = false;
  await_pending_ = false;
  token_.clear();
  EmitChatter();
}
int32_t PtuEmulator::pan_position() const {
  std::lock_guard lock(mu_);
  return static_cast<int32_t>(std::lround(pan_));
}
int32_t PtuEmulator::tilt_position() const {
  std::lock_guard lock(mu_);
  return static_cast<int32_t>(std::lround(tilt_));
}
int PtuEmulator::halts() const {
  std::lock_guard lock(mu_);
  return halts_;
}
std::vector<std::string> PtuEmulator::commands() const {
  std::lock_guard lock(mu_);
  return commands_;
}

void PtuEmulator::Run() {
  auto last = EmuClock::now();
  while (!stop_) {
    pollfd pfd{pty_.master_fd(), POLLIN, 0};
    const int ready = ::poll(&pfd, 1, 2);
    if (ready > 0 && (pfd.revents & POLLIN) != 0) {
      char chunk[256];
      const ssize_t n = ::read(pty_.master_fd(), chunk, sizeof(chunk));
      if (n > 0) HandleBytes(chunk, static_cast<std::size_t>(n));
    }
    const auto now = EmuClock::now();
    std::lock_guard lock(mu_);
    Step(std::chrono::duration<double>(now - last).count());
    last = now;
    Flush();
  }
}

void PtuEmulator::Queue(std::string bytes) { out_.push_back({EmuClock::now(), std::move(bytes)}); }

void PtuEmulator::Reply(const std::string& reply_line) {
  std::string bytes = std::exchange(garbage_, std::string()) + reply_line + "\r\n";
  out_.push_back({EmuClock::now() + std::exchange(delay_, std::chrono::milliseconds(0)), std::move(bytes)});
}

void PtuEmulator::Flush() {
  // In order: a late reply holds back the ones after it, as on a real serial line.
  const auto now = EmuClock::now();
  std::size_t sent = 0;
  for (; sent < out_.size() && out_[sent].due <= now; ++sent) {
    const std::string& bytes = out_[sent].bytes;
    std::size_t done = 0;
    while (done < bytes.size()) {
      const ssize_t n = ::write(pty_.master_fd(), bytes.data() + done, bytes.size() - done);
      if (n <= 0) break;
      done += static_cast<std::size_t>(n);
    }
  }
  out_.erase(out_.begin(), out_.begin() + static_cast<std::ptrdiff_t>(sent));
}

void PtuEmulator::EmitChatter() {
  // Garbage from the UART waking up, the banner, and a mode announcement a little later (the one
  // that broke naive parsers, ros-drivers/flir_ptu issue 22).
  Queue(std::string("\xff\xfe\x00\x13", 4) +
        "Pan-Tilt Controller v2.14.0, (C)2010 Directed Perception, Inc., All Rights Reserved\r\n"
        "Initializing...\r\n");
  out_.push_back({EmuClock::now() + std::chrono::milliseconds(40), "independent (default) speed control mode\r\n"});
}

void PtuEmulator::HandleBytes(const char* data, std::size_t n) {
  std::lock_guard lock(mu_);
  if (!seen_input_) {
    seen_input_ = true;
    if (options_.chatter_on_first_input) EmitChatter();
  }
  if (silent_) return;
  for (std::size_t i = 0; i < n; ++i) {
    const char c = data[i];
    if (echo_) Queue(std::string(1, c));
    if (c == ' ' || c == '\r' || c == '\n') {
      if (!token_.empty()) HandleCommand(std::exchange(token_, std::string()));
      continue;
    }
    token_ += static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
    if (token_.size() > 40) {
      token_.clear();
      Reply("! Illegal command");
    }
  }
}

void PtuEmulator::HandleCommand(const std::string& command) {
  commands_.push_back(command);
  if (fail_next_) {
    fail_next_ = false;
    Reply("! " + fail_message_);
    return;
  }
  std::size_t split = 0;
  while (split < command.size() && std::isalpha(static_cast<unsigned char>(command[split]))) ++split;
  const std::string code = command.substr(0, split);
  const std::string arg = command.substr(split);
  long long value = 0;
  if (!arg.empty()) {
    char* end = nullptr;
    value = std::strtoll(arg.c_str(), &end, 10);
    if (end != arg.c_str() + arg.size()) {
      Reply("! Illegal argument");
      return;
    }
  }
  const auto ack = [this] { Reply("*"); };
  const auto value_reply = [this](const std::string& terse, const std::string& verbose) {
    Reply("* " + (terse_ ? terse : verbose));
  };
  if (code == "FT" || code == "FV") {
    terse_ = code == "FT";
    ack();
  } else if (code == "EE" || code == "ED") {
    echo_ = code == "EE";
    ack();
  } else if (code == "CI" || code == "I" || code == "LE" || code == "LD") {
    if (code == "LE" || code == "LD") limits_enabled_ = code == "LE";
    ack();
  } else if ((code == "PR" || code == "TR") && arg.empty()) {
    const bool pan = code[0] == 'P';
    const double r = pan ? options_.pan_arcsec : options_.tilt_arcsec;
    value_reply(PtuEmuFormat("%.4f", r),
                PtuEmuFormat("%.4f", r) + " seconds arc per " + (pan ? "Pan" : "Tilt") + " position");
  } else if ((code == "PN" || code == "PX" || code == "TN" || code == "TX") && arg.empty()) {
    const bool pan = code[0] == 'P', min = code[1] == 'N';
    const int32_t v = pan ? (min ? options_.pan_min : options_.pan_max) : (min ? options_.tilt_min : options_.tilt_max);
    value_reply(std::to_string(v), std::string(min ? "Minimum " : "Maximum ") + (pan ? "Pan" : "Tilt") +
                                       " position is " + std::to_string(v));
  } else if (code == "PP" || code == "TP") {
    const bool pan = code[0] == 'P';
    const char* axis_name = pan ? "Pan" : "Tilt";
    if (arg.empty()) {
      const long v = std::lround(pan ? pan_ : tilt_);
      value_reply(std::to_string(v), std::string("Current ") + axis_name + " position is " + std::to_string(v));
      return;
    }
    const int32_t lo = pan ? options_.pan_min : options_.tilt_min, hi = pan ? options_.pan_max : options_.tilt_max;
    if (limits_enabled_ && value > hi) {
      Reply(std::string("! Maximum allowable ") + axis_name + " position is " + std::to_string(hi));
      return;
    }
    if (limits_enabled_ && value < lo) {
      Reply(std::string("! Minimum allowable ") + axis_name + " position is " + std::to_string(lo));
      return;
    }
    (pan ? pan_target_ : tilt_target_) = static_cast<int32_t>(value);
    if (limit_hit_axis_ && *limit_hit_axis_ == (pan ? PtuAxis::kPan : PtuAxis::kTilt)) {
      const double from = pan ? pan_ : tilt_;
      limit_stop_at_ = static_cast<int32_t>(std::lround(from + (static_cast<double>(value) - from) / 2));
      limit_hit_armed_ = true;
    }
    ack();
  } else if (code == "A" && arg.empty()) {
    if (std::lround(pan_) != pan_target_ || std::lround(tilt_) != tilt_target_) {
      await_pending_ = true;
    } else {
      ack();
    }
  } else if (code == "H" || code == "HP" || code == "HT") {
    if (code != "HT") pan_target_ = static_cast<int32_t>(std::lround(pan_ = std::round(pan_)));
    if (code != "HP") tilt_target_ = static_cast<int32_t>(std::lround(tilt_ = std::round(tilt_)));
    ++halts_;
    ack();
  } else if (code == "PS" || code == "TS") {
    if (arg.empty()) {
      value_reply(PtuEmuFormat("%.0f", options_.speed_pos_per_s), PtuEmuFormat("%.0f", options_.speed_pos_per_s));
    } else {
      ack();
    }
  } else if (code == "V") {
    Reply("* Pan-Tilt Controller v2.14.0, (C)2010 Directed Perception, Inc., All Rights Reserved");
  } else {
    Reply("! Illegal command");
  }
}

void PtuEmulator::Step(double dt_s) {
  const double step = options_.speed_pos_per_s * dt_s;
  for (const PtuAxis axis : {PtuAxis::kPan, PtuAxis::kTilt}) {
    double& pos = axis == PtuAxis::kPan ? pan_ : tilt_;
    int32_t& target = axis == PtuAxis::kPan ? pan_target_ : tilt_target_;
    const double before = pos;
    const double diff = target - pos;
    pos = std::abs(diff) <= step ? static_cast<double>(target) : pos + std::copysign(step, diff);
    if (limit_hit_armed_ && limit_hit_axis_ && *limit_hit_axis_ == axis &&
        (before - limit_stop_at_) * (pos - limit_stop_at_) <= 0 && before != pos) {
      pos = limit_stop_at_;
      target = limit_stop_at_;
      limit_hit_armed_ = false;
      limit_hit_axis_.reset();
      Queue(std::string("!") + PtuAxisLetter(axis) + "\r\n");
    }
  }
  if (await_pending_ && std::lround(pan_) == pan_target_ && std::lround(tilt_) == tilt_target_ &&
      pan_ == std::round(pan_) && tilt_ == std::round(tilt_)) {
    await_pending_ = false;
    Reply("*");
  }
}

}  // namespace idi::workcell
