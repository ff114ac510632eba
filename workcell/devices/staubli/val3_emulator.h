// An emulated IDI-VAL3 server (the program in targets/workcell-pc/val3/) on loopback TCP, for the
// arm driver's tests: the protocol of val3_protocol.h, joints moving at a speed in the controller's
// convention with the RX-130's ranges, a rail axis, the server's watchdog (stop when the client goes
// quiet during a move) and its stop on disconnect. Faults on demand: garbage instead of a reply, a
// server that stops answering, a dropped connection, an error reply, drives without power, a move
// that stops short (as when someone stops it on the pendant).
#pragma once

#include <atomic>
#include <chrono>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "shared/util/status.h"
#include "workcell/devices/staubli/staubli_joints.h"

namespace idi::workcell {

struct Val3EmulatorOptions {
  bool has_rail = true;
  double joint_speed_deg_per_s = 3000;  // at 100 %; fast, for tests
  double rail_speed_mm_per_s = 40000;
  double rail_min_mm = 0, rail_max_mm = 6000;
  std::chrono::milliseconds watchdog{1000};
};

class Val3Emulator {
 public:
  static Result<std::unique_ptr<Val3Emulator>> Start(const Val3EmulatorOptions& options = {});
  ~Val3Emulator();
  Val3Emulator(const Val3Emulator&) = delete;
  Val3Emulator& operator=(const Val3Emulator&) = delete;

  int port() const { return port_; }

  void ReplaceNextReplyWithGarbage(std::string bytes);
  void SetSilent(bool silent);  // reads requests, never answers
  // Closes the connection on the n-th request from now (1: the next one), as a network failure would.
  void DropConnectionOnRequest(int n);
  void FailNextRequest(int code, std::string text);
  void SetPowered(bool powered);
  void StopNextMoveHalfway();

  ControllerJointsDeg joints_deg() const;
  double rail_mm() const;
  bool moving() const;
  int stop_requests() const;
  int watchdog_stops() const;
  int disconnect_stops() const;
  int connections() const;
  std::vector<std::string> verbs() const;

 private:
  explicit Val3Emulator(const Val3EmulatorOptions& options);
  void Run();
  void Handle(const std::string& line);
  void SendReply(const std::string& bytes);
  void CloseClient(bool count_stop);
  void StopMotion();
  void Step(double dt_s);
  bool MovingLocked() const;

  Val3EmulatorOptions options_;
  int listen_fd_ = -1;
  int client_fd_ = -1;
  int port_ = 0;
  std::thread thread_;
  std::atomic<bool> stop_{false};

  mutable std::mutex mu_;
  std::string inbox_;
  std::chrono::steady_clock::time_point last_request_{};
  ControllerJointsDeg joints_{};
  ControllerJointsDeg target_{};
  double speed_pct_ = 100;
  double rail_ = 0, rail_target_ = 0, rail_speed_pct_ = 100;
  bool powered_ = true;
  bool silent_ = false;
  int drop_countdown_ = 0;
  bool halfway_next_ = false;
  int fail_code_ = 0;
  std::string fail_text_;
  std::string garbage_next_;
  int last_error_ = 0;
  int stop_requests_ = 0, watchdog_stops_ = 0, disconnect_stops_ = 0, connections_ = 0;
  std::vector<std::string> verbs_;
};

}  // namespace idi::workcell
