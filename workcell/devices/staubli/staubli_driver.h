// A Stäubli CS8 controller driven through the IDI-VAL3 server program (val3_protocol.h,
// targets/workcell-pc/val3/): hal::ArmDevice for the RX-130 and hal::RailDevice for its carriage on
// the robot transport unit (§3.2: each robot moves along the rail independently). One TCP
// connection per controller.
//
// Moves are checked against the model's joint limits (or the rail range) before anything is sent
// (OutOfRange), then queued on the controller and followed by polling JOINTS / RAIL until settled at
// the target. On any failure after a motion was commanded - error reply, garbage, timeout, dropped
// connection, the arm settling short of the target - the driver sends STOP (reconnecting once if the
// connection is gone) and says in the returned Status whether the stop got through. Replies carry the
// request id, so late replies are dropped; unparseable lines are counted and skipped. Consecutive
// failures past a threshold put the driver in kFault; the next call reconnects. The server also
// stops the arm by itself when the client goes quiet during a move or the connection drops.
//
// Joint values cross the wire in the controller's convention (degrees) and are converted in one
// place, staubli_joints.h.
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "shared/drivers/serial/serial_port.h"
#include "shared/hal/arm.h"
#include "shared/hal/clock.h"
#include "shared/util/motion_interrupt.h"
#include "workcell/devices/staubli/val3_protocol.h"

namespace idi::workcell {

struct StaubliDriverOptions {
  std::string name = "arm1";
  std::string host = "192.168.0.254";
  int port = 11000;
  std::chrono::milliseconds connect_timeout{2000};
  std::chrono::milliseconds reply_timeout{500};
  std::chrono::milliseconds poll_period{20};  // well inside the server's 1 s watchdog
  double joint_tolerance_deg = 0.01;
  double rail_tolerance_mm = 0.05;
  double rail_min_mm = 0, rail_max_mm = 6000;
  JointLimits limits = Rx130JointLimits();  // model convention
  int max_consecutive_failures = 3;
  Status Check() const;
};

struct StaubliCounters {
  uint64_t requests = 0;
  uint64_t timeouts = 0;
  uint64_t error_replies = 0;
  uint64_t garbage = 0;         // lines that are not replies
  uint64_t stale_replies = 0;   // replies to earlier requests
  uint64_t disconnects = 0;
  uint64_t reconnects = 0;
  uint64_t stops_sent = 0;
  uint64_t faults = 0;
};

enum class StaubliState { kDisconnected, kReady, kFault };
const char* StaubliStateName(StaubliState state);

class StaubliDriver final : public hal::ArmDevice, public hal::RailDevice {
 public:
  StaubliDriver(StaubliDriverOptions options, hal::Clock* clock);
  ~StaubliDriver() override;

  // Connects and says HELLO (checks the server and its protocol version, learns whether it has a rail).
  Status Connect();
  void Disconnect();

  // hal::ArmDevice
  std::string name() const override { return options_.name; }
  Status MoveJoints(const Joints& q_rad, const hal::MoveOptions& options) override;
  Result<hal::JointState> ReadJoints() override;
  // Stops arm and rail (the controller's resetMotion); for both interfaces.
  Status Stop() override;

  // hal::RailDevice
  Status MoveTo(double position_mm, const hal::MoveOptions& options) override;
  Result<hal::RailState> Read() override;

  // Keeps the server's watchdog fed when the caller is idle for long; also a liveness check.
  Status Heartbeat();
  Result<Val3Status> ReadStatus();

  // An operator's stop from another thread (shared/util/motion_interrupt.h): a MoveJoints or MoveTo
  // waiting for its move to end returns Cancelled at its next poll and stops the arm; moves are refused,
  // nothing sent, until ClearInterrupt. Both thread-safe.
  void Interrupt() { interrupt_.Request(); }
  void ClearInterrupt() { interrupt_.Clear(); }

  bool has_rail() const { return has_rail_; }
  StaubliState state() const { return state_; }
  const StaubliCounters& counters() const { return counters_; }

 private:
  Status EnsureConnected();
  Result<Val3Reply> Request(Val3Verb verb, const std::vector<double>& args, std::chrono::milliseconds timeout);
  Status NoteFailure(Status status);
  Status StopAfter(Status status);
  Status CheckMoveOptions(const hal::MoveOptions& options) const;

  StaubliDriverOptions options_;
  hal::Clock* clock_;
  std::unique_ptr<drivers::SerialPort> link_;  // the line framing of the serial transport, on a TCP socket
  StaubliState state_ = StaubliState::kDisconnected;
  StaubliCounters counters_;
  uint32_t next_id_ = 0;
  bool has_rail_ = false;
  bool connected_once_ = false;
  int consecutive_failures_ = 0;
  MotionInterrupt interrupt_;
};

// Connects a TCP stream socket to host:port within `timeout` (TCP_NODELAY set). Returns the descriptor.
Result<int> TcpConnect(const std::string& host, int port, std::chrono::milliseconds timeout);

}  // namespace idi::workcell
