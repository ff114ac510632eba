// The twin's CAN bus: an in-process bus with several endpoints (each a hal::CanBus), running on a
// SimClock so a whole run is deterministic and much faster than real time.
//
// Frames occupy the bus for their transmission time at the configured bit rate (500 kbit/s, the
// Segway RMP's rate, ../shared/reference/device-protocols.md §1.1) and are delivered to every other
// endpoint when their last bit is on the wire, in send order. Simulated devices register as
// SimProcess: when a node waits in Receive() with a timeout, the bus advances the clock event by
// event and runs every process whose time has come, so a driver written for a real bus (blocking
// receive with timeouts) runs unchanged against simulated devices.
//
// Fault injection, all seeded: dropped frames (per receiver), garbage frames (random payload or a
// truncated DLC), and bus-off of an endpoint (its sends fail, it stops receiving, it gets the error
// frames a SocketCAN controller reports: bus-off, then "restarted" on recovery).
#pragma once

#include <cstdint>
#include <deque>
#include <limits>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "shared/hal/can_bus.h"
#include "shared/hal/clock.h"

namespace idi::sim {

inline constexpr int64_t kNeverNs = std::numeric_limits<int64_t>::max();

// Something that lives on simulated time (a simulated device). The bus runs it when the clock
// reaches NextWakeNs().
class SimProcess {
 public:
  virtual ~SimProcess() = default;
  // The next time this process has something to do; kNeverNs when it only reacts to frames.
  virtual int64_t NextWakeNs() const = 0;
  // Does everything due at or before `t_ns` (reads its endpoint, updates its state, sends frames).
  // Afterwards NextWakeNs() must be later than `t_ns`.
  virtual void RunUntil(int64_t t_ns) = 0;
};

struct VirtualCanBusOptions {
  double bitrate_bps = 500'000.0;
  // Frames take their transmission time (worst-case bit stuffing); off: delivered at send time.
  bool model_transmission_time = true;
  double drop_probability = 0.0;     // each frame, each receiver
  double garbage_probability = 0.0;  // each frame on the bus: random payload or a truncated DLC
  uint64_t seed = 1;
  std::size_t rx_queue_capacity = 4096;  // per endpoint (a socket's receive buffer); overflow drops

  Status Check() const;
};

// A receive filter as SocketCAN's CAN_RAW_FILTER: a frame passes when (id & mask) == (filter id & mask).
struct VirtualCanFilter {
  uint32_t id = 0;
  uint32_t mask = 0;
};

class VirtualCanBus;

class VirtualCanEndpoint final : public hal::CanBus {
 public:
  std::string name() const override { return name_; }
  Status Send(const hal::CanFrame& frame) override;
  // Returns the next frame delivered by now; with a timeout, advances the simulated clock (running
  // the bus's processes) until a frame arrives or the timeout passes.
  Result<std::optional<hal::CanFrame>> Receive(std::chrono::milliseconds timeout) override;
  hal::CanBusCounters counters() const override { return counters_; }

  // Empty: everything passes (the default, like a fresh CAN_RAW socket). Error frames always pass.
  void SetFilters(std::vector<VirtualCanFilter> filters) { filters_ = std::move(filters); }
  bool bus_off() const { return bus_off_; }
  std::size_t queued() const { return rx_.size(); }
  // When the next frame becomes readable (kNeverNs when none is on its way): a simulated device
  // wakes up then to react to it.
  int64_t next_delivery_ns() const { return rx_.empty() ? kNeverNs : rx_.front().timestamp_ns; }
  // The next frame delivered by `t_ns`, without touching the clock or running processes: what a
  // simulated device uses inside its own RunUntil().
  std::optional<hal::CanFrame> PopDelivered(int64_t t_ns);

 private:
  friend class VirtualCanBus;
  VirtualCanEndpoint(VirtualCanBus* bus, std::string name) : bus_(bus), name_(std::move(name)) {}
  bool Accepts(const hal::CanFrame& frame) const;

  VirtualCanBus* bus_;
  std::string name_;
  std::deque<hal::CanFrame> rx_;  // timestamp_ns = delivery time, non-decreasing
  std::vector<VirtualCanFilter> filters_;
  hal::CanBusCounters counters_;
  bool bus_off_ = false;
  int64_t restart_at_ns_ = kNeverNs;
  bool reported_no_ack_ = false;
};

struct VirtualCanBusStats {
  uint64_t frames_on_bus = 0;
  uint64_t garbage_injected = 0;
  uint64_t drops_injected = 0;
  int64_t busy_ns = 0;  // time the bus carried frames (load = busy_ns / elapsed)
};

class VirtualCanBus {
 public:
  explicit VirtualCanBus(hal::SimClock* clock, VirtualCanBusOptions options = {});
  VirtualCanBus(const VirtualCanBus&) = delete;
  VirtualCanBus& operator=(const VirtualCanBus&) = delete;

  // A new node on the bus; the bus owns it and it lives as long as the bus.
  VirtualCanEndpoint* AddEndpoint(const std::string& name);
  // A process the bus runs on simulated time (not owned; must outlive the bus's use).
  void AddProcess(SimProcess* process);

  // Advances the clock to `t_ns`, running processes and timers in time order on the way. Used by
  // Receive() timeouts and by simulations that step time themselves. Never moves the clock back.
  void AdvanceTo(int64_t t_ns);
  // The earliest pending process wake-up or bus timer.
  int64_t NextEventNs() const;

  // Faults. Bus-off: the endpoint's controller leaves the bus now; after `duration_ns` it restarts
  // by itself (like `ip link set canX type can restart-ms N`), or, with duration < 0, it stays off
  // until RestartEndpoint() (a manual restart, like `ip link set canX type can restart`).
  void InjectBusOff(VirtualCanEndpoint* endpoint, int64_t duration_ns = -1);
  void RestartEndpoint(VirtualCanEndpoint* endpoint);

  // Bits a frame occupies on the wire (with worst-case stuffing and the inter-frame space).
  static int FrameBits(const hal::CanFrame& frame);
  hal::SimClock* clock() const { return clock_; }
  const VirtualCanBusStats& stats() const { return stats_; }
  const VirtualCanBusOptions& options() const { return options_; }

 private:
  friend class VirtualCanEndpoint;
  Status Transmit(VirtualCanEndpoint* sender, const hal::CanFrame& frame);
  void Deliver(VirtualCanEndpoint* to, const hal::CanFrame& frame);
  void RunDue(int64_t now_ns);

  hal::SimClock* clock_;
  VirtualCanBusOptions options_;
  std::vector<std::unique_ptr<VirtualCanEndpoint>> endpoints_;
  std::vector<SimProcess*> processes_;
  std::mt19937_64 rng_;
  int64_t bus_free_ns_ = 0;
  bool running_processes_ = false;
  VirtualCanBusStats stats_;
};

}  // namespace idi::sim
