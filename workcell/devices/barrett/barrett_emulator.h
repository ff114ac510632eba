// A BH8-262 hand behind a pseudo-terminal, for driver tests: supervisory mode as described in
// ../shared/reference/device-protocols.md §3 and Barrett's BH8-262 supervisory notes - input echoed,
// one command per CR-ended line, output and any "ERR <code>" then the prompt "=> ", commands run one
// at a time (input that arrives during a motion waits), Control-C (0x03) aborts the command in progress
// (every motor stops, "ERR 16384", the prompt; BH8-Series User's Manual D3000, termination case 4). HI, O, C, M <pos>,
// T, FGET/FSET, PGET/PSET, RESET with the motor prefixes 1-3, G, S. Fingers closing on an object stall there (the inner
// link stops; §3.5). The error codes it prints are this emulator's own (1 unknown command, 2 bad argument, 3 not
// initialised); the driver reports any code it is given.
//
// Faults: power-up banner, noise before a reply, an error reply, a hand that stops answering, a
// power cycle (uninitialised afterwards).
#pragma once

#include <array>
#include <atomic>
#include <chrono>
#include <deque>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "shared/drivers/serial/pty.h"
#include "shared/util/status.h"

namespace idi::workcell {

struct BarrettEmulatorOptions {
  long finger_max_counts = 17800;
  long spread_max_counts = 3150;
  double speed_counts_per_s = 400'000;  // fast, for tests
  std::chrono::milliseconds hi_duration{30};
  bool banner_on_first_input = true;
};

class BarrettEmulator {
 public:
  static Result<std::unique_ptr<BarrettEmulator>> Start(const BarrettEmulatorOptions& options = {});
  ~BarrettEmulator();
  BarrettEmulator(const BarrettEmulator&) = delete;
  BarrettEmulator& operator=(const BarrettEmulator&) = delete;

  const std::string& port_path() const { return pty_.slave_path(); }

  void SetSilent(bool silent);
  void InjectGarbageBeforeNextReply(std::string bytes);
  void FailNextCommand(int code);
  void PowerCycle();
  // Finger `finger` (0..2) meets an object at `counts` while closing (-1: no object).
  void SetObject(int finger, long counts);

  std::array<long, 4> positions() const;  // F1, F2, F3, spread (counts)
  bool initialized() const;
  int stops() const;
  int aborts() const;  // commands ended by Control-C
  std::vector<std::string> commands() const;

 private:
  BarrettEmulator(const BarrettEmulatorOptions& options, drivers::PtyPair pty);
  void Run();
  void HandleBytes(const char* data, std::size_t n);
  void Execute(const std::string& line);
  void Step(double dt_s);
  void Send(const std::string& bytes);
  void Finish(const std::string& output);  // output lines, then the prompt
  bool Moving() const;

  BarrettEmulatorOptions options_;
  drivers::PtyPair pty_;
  std::thread thread_;
  std::atomic<bool> stop_{false};

  mutable std::mutex mu_;
  bool silent_ = false;
  bool seen_input_ = false;
  bool initialized_ = false;
  bool busy_ = false;          // a motion command awaits its prompt
  bool initialising_ = false;  // that command is HI
  int aborts_ = 0;
  std::chrono::steady_clock::time_point busy_until_{};
  std::array<double, 4> position_{};
  std::array<long, 4> target_{};
  std::array<long, 3> object_{-1, -1, -1};
  std::string garbage_;
  int fail_code_ = 0;
  std::string line_;
  std::deque<std::string> pending_lines_;
  int stops_ = 0;
  std::vector<std::string> commands_;
};

}  // namespace idi::workcell
