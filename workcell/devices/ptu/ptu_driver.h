// The PTU-D46 driver: hal::PanTiltDevice over a serial port (../shared/reference/device-protocols.md §2).
//
// Initialisation (Connect) drains power-up chatter, ends any half-received command, then sets terse
// feedback (FT), echo off (ED), position control (CI), immediate execution (I) and limit enforcement
// (LE), and reads the resolution (PR/TR, arc-seconds per position; never assumed - units differ,
// PTU-46-17.5 vs -70, and step modes change it) and the limits (PN/PX/TN/TX).
//
// Every command is a transaction: send, then read lines until the expected reply kind. Echoes, chatter
// and noise lines are skipped and counted; an ack where a value was expected (or the reverse) is a
// reply out of step and is skipped. After a timeout, noise or a reply out of step the driver
// resynchronises before the next command: it drains until the line is quiet and checks that a PR
// query answers with the resolution read at start-up. Consecutive failures past a threshold put the
// driver in kFault; the next call reconnects and re-initialises.
//
// Safety: MoveTo checks the limits before sending anything (OutOfRange); on any failure during a move
// it sends a halt (H) when the port is usable. Asynchronous limit replies (!P, !T) during a move fail
// the move. Every Status names the device.
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <string>
#include <utility>

#include "shared/drivers/serial/serial_port.h"
#include "shared/hal/clock.h"
#include "shared/hal/pan_tilt.h"
#include "shared/util/motion_interrupt.h"
#include "workcell/devices/ptu/ptu_codec.h"

namespace idi::workcell {

struct PtuDriverOptions {
  std::string name = "ptu";
  std::string port = "/dev/ttyUSB0";
  int baud = 9600;  // the controller's default host baud rate (PTUMAN p=32)
  std::chrono::milliseconds reply_timeout{1000};
  // Power-up chatter and late replies are drained until the line is quiet this long...
  std::chrono::milliseconds quiet_period{150};
  // ... but never longer than this.
  std::chrono::milliseconds drain_limit{3000};
  int init_attempts = 3;
  // Consecutive failed transactions before the driver declares a fault and reconnects.
  int max_consecutive_failures = 3;
  Status Check() const;
};

struct PtuCounters {
  uint64_t commands = 0;
  uint64_t timeouts = 0;
  uint64_t error_replies = 0;   // "! <message>"
  uint64_t garbage_lines = 0;   // unrecognised lines, noise, chatter
  uint64_t out_of_step = 0;     // a reply of the wrong kind (late reply to an earlier command)
  uint64_t limit_hits = 0;      // asynchronous "!P" / "!T"
  uint64_t resyncs = 0;
  uint64_t reconnects = 0;
  uint64_t halts_sent = 0;
  uint64_t faults = 0;
};

enum class PtuState { kDisconnected, kReady, kFault };
const char* PtuStateName(PtuState state);

class PtuDriver final : public hal::PanTiltDevice {
 public:
  // `clock` stamps readings; it must outlive the driver.
  PtuDriver(PtuDriverOptions options, hal::Clock* clock);
  ~PtuDriver() override;

  // Opens the port and initialises the unit (see above).
  Status Connect();
  void Disconnect();

  std::string name() const override { return options_.name; }
  Result<hal::PanTiltLimits> Limits() override;
  Status MoveTo(double pan_rad, double tilt_rad, std::chrono::milliseconds timeout) override;
  Result<hal::PanTiltState> Read() override;
  Status Halt() override;

  // Raw positions (pan, tilt) as the unit reports them.
  Result<std::pair<int32_t, int32_t>> ReadPositions();

  // An operator's stop from another thread (shared/util/motion_interrupt.h): a MoveTo waiting for its
  // move to end returns Cancelled within about 50 ms and halts the unit; moves are refused, nothing
  // sent, until ClearInterrupt. Both thread-safe.
  void Interrupt() { interrupt_.Request(); }
  void ClearInterrupt() { interrupt_.Clear(); }

  PtuState state() const { return state_; }
  const PtuCounters& counters() const { return counters_; }

 private:
  enum class Expect { kAck, kValue };
  Status Initialize();
  Status InitializeOnce();
  Status EnsureReady();
  Status Resync();
  // `interruptible`: the wait for the reply is a wait for motion, which an interrupt ends (Cancelled).
  Result<PtuReply> Transact(const std::string& command,
                            Expect expect,
                            std::chrono::milliseconds timeout,
                            bool interruptible = false);
  Result<int32_t> QueryInt(PtuAxis axis, PtuQuantity quantity);
  Result<double> QueryDouble(PtuAxis axis, PtuQuantity quantity);
  // Records a failed operation: counts it, escalates to kFault past the threshold.
  Status NoteFailure(Status status);
  // Best-effort halt after a failure; appends what happened to `status`.
  Status HaltAfter(Status status);
  std::string Quote(const std::string& command) const;

  PtuDriverOptions options_;
  hal::Clock* clock_;
  std::unique_ptr<drivers::SerialPort> port_;
  PtuState state_ = PtuState::kDisconnected;
  PtuCounters counters_;
  int consecutive_failures_ = 0;
  bool needs_resync_ = false;
  bool initialized_once_ = false;
  std::string pan_resolution_text_;  // PR's value text, to recognise the resync probe's reply
  std::vector<PtuAxis> pending_limit_hits_;
  MotionInterrupt interrupt_;
  // From the unit: positions and arc-seconds per position.
  int32_t pan_min_ = 0, pan_max_ = 0, tilt_min_ = 0, tilt_max_ = 0;
  double pan_arcsec_ = 0, tilt_arcsec_ = 0;
};

}  // namespace idi::workcell
