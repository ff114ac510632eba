// A PTU-D46 behind a pseudo-terminal, for driver tests and bench runs without the unit. It speaks the
// protocol of ../shared/reference/device-protocols.md §2 as the manual describes it: verbose feedback
// and echo on at power-up, '*' / '* <value>' / '! <message>' replies, limit enforcement with
// "! Maximum allowable Pan position is 3090", 'A' answered when motion completes, asynchronous
// "!P" / "!T" when an axis hits a limit. Faults are injected on demand: power-up chatter with
// garbage bytes, noise before a reply, an error reply, a late reply, a unit that stops answering, a
// limit hit during a move, a power cycle.
//
// Positions move at a constant speed in real time (a background thread), so keep speeds high in tests.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "shared/drivers/serial/pty.h"
#include "shared/util/status.h"
#include "workcell/devices/ptu/ptu_codec.h"

namespace idi::workcell {

struct PtuEmulatorOptions {
  double pan_arcsec = 185.1428;  // PTU-46-17.5 (PTUMAN p=15)
  double tilt_arcsec = 185.1428;
  int32_t pan_min = -3090, pan_max = 3090;  // PTUMAN p=16 example
  int32_t tilt_min = -907, tilt_max = 604;
  double speed_pos_per_s = 20000;
  // On the first byte from the host the unit "powers up": garbage bytes and banner lines.
  bool chatter_on_first_input = true;
};

class PtuEmulator {
 public:
  static Result<std::unique_ptr<PtuEmulator>> Start(const PtuEmulatorOptions& options = {});
  ~PtuEmulator();
  PtuEmulator(const PtuEmulator&) = delete;
  PtuEmulator& operator=(const PtuEmulator&) = delete;

  // The path a driver opens, like /dev/ttyUSB0.
  const std::string& port_path() const { return pty_.slave_path(); }

  // Faults (thread-safe).
  void SetSilent(bool silent);                           // reads and ignores everything
  void InjectGarbageBeforeNextReply(std::string bytes);  // noise on the line, then the reply
  void FailNextCommand(std::string message);             // the next command gets "! <message>"
  void DelayNextReply(std::chrono::milliseconds delay);  // the next reply comes late
  void LimitHitDuringNextMove(PtuAxis axis);             // the axis stops half-way with "!P"/"!T"
  void PowerCycle();  // chatter, positions 0, verbose feedback and echo on again

  // Inspection (thread-safe).
  int32_t pan_position() const;
  int32_t tilt_position() const;
  int halts() const;
  std::vector<std::string> commands() const;  // commands received, upper case, in order

 private:
  explicit PtuEmulator(const PtuEmulatorOptions& options, drivers::PtyPair pty);
  void Run();
  void HandleBytes(const char* data, std::size_t n);
  void HandleCommand(const std::string& command);
  void Step(double dt_s);
  void Queue(std::string bytes);
  void Reply(const std::string& reply_line);  // adds CR LF, applies pending faults
  void Flush();
  void EmitChatter();

  PtuEmulatorOptions options_;
  drivers::PtyPair pty_;
  std::thread thread_;
  std::atomic<bool> stop_{false};

  mutable std::mutex mu_;
  bool silent_ = false;
  bool echo_ = true;
  bool terse_ = false;
  bool limits_enabled_ = true;
  bool seen_input_ = false;
  double pan_ = 0, tilt_ = 0;  // positions (continuous while moving)
  int32_t pan_target_ = 0, tilt_target_ = 0;
  bool await_pending_ = false;
  std::optional<PtuAxis> limit_hit_axis_;
  bool limit_hit_armed_ = false;
  int32_t limit_stop_at_ = 0;
  std::string garbage_;
  std::string fail_message_;
  bool fail_next_ = false;
  std::chrono::milliseconds delay_{0};
  std::string token_;
  int halts_ = 0;
  std::vector<std::string> commands_;
  struct Pending {
    std::chrono::steady_clock::time_point due;
    std::string bytes;
  };
  std::vector<Pending> out_;
};

}  // namespace idi::workcell
