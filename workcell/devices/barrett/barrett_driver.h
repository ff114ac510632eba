// The Barrett BH8-262 hand driver: hal::GripperDevice over a serial port in supervisory mode
// (../shared/reference/device-protocols.md §3; the hand is §3.5 of the dissertation).
//
// Connect opens the port, sends a bare CR (which clears errors, as Barrett's API does), drains the
// power-up banner and waits for a prompt. Initialize sends HI (required after power-up before any
// motion). Open / Close / SetSpread are GO / GC / SM <counts>; the hand answers with the prompt once
// the motion is done, so their timeout is a motion timeout. Read queries each motor with FGET P.
//
// Each command is a transaction: send, read up to the prompt, find the echo of the command (a block
// without it is stale or noise: skipped and counted), then "ERR <code>" lines become DeviceError.
// A timeout marks the link for resynchronisation (CR, drain, prompt) before the next command; too
// many consecutive failures put the driver in kFault and the next call reconnects. A failed motion
// command is followed by a stop (T) when the port is usable. Every Status names the device.
//
// Encoder conversion: fingers are reported as inner-link angles and the spread as the spread angle,
// from counts with the options' factors. The defaults (finger 0..17800 counts over 0..140 deg, spread
// 0..3150 counts over 0..180 deg) are the commonly quoted BH8-262 ranges; check them on the hand.
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <memory>
#include <string>

#include "shared/drivers/serial/serial_port.h"
#include "shared/hal/arm.h"
#include "shared/hal/clock.h"
#include "shared/util/motion_interrupt.h"
#include "workcell/devices/barrett/barrett_codec.h"

namespace idi::workcell {

struct BarrettDriverOptions {
  std::string name = "barrett";
  std::string port = "/dev/ttyS0";
  int baud = 9600;  // BHAPI default
  std::chrono::milliseconds reply_timeout{1000};
  std::chrono::milliseconds motion_timeout{15'000};
  std::chrono::milliseconds init_timeout{30'000};  // HI drives every motor to its stops
  std::chrono::milliseconds quiet_period{150};
  std::chrono::milliseconds drain_limit{3000};
  double finger_counts_per_rad = 17800.0 / (140.0 * 3.14159265358979323846 / 180.0);
  double spread_counts_per_rad = 3150.0 / 3.14159265358979323846;
  double spread_max_rad = 3.14159265358979323846;  // 180 deg, symmetric (§3.5)
  int max_consecutive_failures = 3;
  Status Check() const;
};

struct BarrettCounters {
  uint64_t commands = 0;
  uint64_t timeouts = 0;
  uint64_t error_replies = 0;  // "ERR <code>"
  uint64_t garbage = 0;        // noise lines and unparseable output
  uint64_t out_of_step = 0;    // prompt blocks without our echo
  uint64_t resyncs = 0;
  uint64_t reconnects = 0;
  uint64_t stops_sent = 0;
  uint64_t faults = 0;
};

enum class BarrettState { kDisconnected, kConnected, kReady, kFault };
const char* BarrettStateName(BarrettState state);

class BarrettDriver final : public hal::GripperDevice {
 public:
  BarrettDriver(BarrettDriverOptions options, hal::Clock* clock);
  ~BarrettDriver() override;

  Status Connect();
  void Disconnect();
  const std::string& name() const { return options_.name; }

  Status Initialize() override;
  Status Open() override;
  Status Close() override;
  Status SetSpread(double spread_rad) override;
  Result<hal::GripperState> Read() override;
  Status Stop() override;

  // An operator's stop from another thread (shared/util/motion_interrupt.h): an Initialize, Open,
  // Close or SetSpread waiting for its motion to end aborts it (Control-C: the motors stop where they
  // are), sends the stop (T) and returns Cancelled within about 50 ms plus the hand's answer; motions
  // are refused, nothing sent, until ClearInterrupt. Both thread-safe.
  void Interrupt() { interrupt_.Request(); }
  void ClearInterrupt() { interrupt_.Clear(); }

  BarrettState state() const { return state_; }
  const BarrettCounters& counters() const { return counters_; }

 private:
  // `interruptible`: the wait for the prompt is a wait for motion, which an interrupt ends (Cancelled).
  Result<BarrettReply> Transact(const std::string& text, std::chrono::milliseconds timeout, bool interruptible = false);
  Status EnsureConnected();
  Status Resync();
  // Ends the command `text` in progress (Control-C); Cancelled, saying whether the hand confirmed it.
  Status Abort(const std::string& text);
  Status Motion(const std::string& text, const std::string& what);
  Status NoteFailure(Status status);
  Result<long> ReadCounts(unsigned motor);

  BarrettDriverOptions options_;
  hal::Clock* clock_;
  std::unique_ptr<drivers::SerialPort> port_;
  BarrettState state_ = BarrettState::kDisconnected;
  BarrettCounters counters_;
  int consecutive_failures_ = 0;
  bool needs_resync_ = false;
  bool connected_once_ = false;
  bool initialized_ = false;
  MotionInterrupt interrupt_;
};

}  // namespace idi::workcell
