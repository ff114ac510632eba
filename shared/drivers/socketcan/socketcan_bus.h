// hal::CanBus on Linux SocketCAN: a CAN_RAW socket bound to a named interface (can0, vcan0, slcan0).
//
// - Receive filters (CAN_RAW_FILTER) and the error-frame mask (CAN_RAW_ERR_FILTER): error frames are
//   delivered as hal::CanFrame with error = true (decode them with hal/can_error.h).
// - The controller state is tracked from the error frames (error-active / warning / passive /
//   bus-off); Restart() asks the kernel to restart a bus-off controller over rtnetlink
//   (IFLA_CAN_RESTART, what `ip link set can0 type can restart` does; needs CAP_NET_ADMIN). With
//   `restart-ms` configured on the interface the kernel restarts it by itself and reports
//   CAN_ERR_RESTARTED.
// - Timeouts with poll(); a full TX queue (ENOBUFS) is retried until the send timeout.
// - When the interface goes down (ENETDOWN, ENODEV), calls fail with DeviceError and the socket is
//   reopened on a later call (at most every reopen_interval).
// - Counters: sent, received, error frames, dropped (kernel drop counter SO_RXQ_OVFL), bus-off events.
//
// Timestamps are taken from the given clock when a frame is read (the monotonic clock by default),
// so they share the time line of the rest of the system. Not thread-safe: one owner.
#pragma once

#include <chrono>
#include <memory>
#include <string>
#include <vector>

#include "shared/drivers/socketcan/socketcan_frame.h"
#include "shared/hal/can_bus.h"
#include "shared/hal/can_error.h"
#include "shared/hal/clock.h"

namespace idi::drivers {

struct SocketCanOptions {
  std::string interface = "can0";
  std::vector<SocketCanFilter> filters;  // empty: every data frame
  uint32_t error_mask = hal::kCanErrClassMask;  // error classes to receive; 0: none
  bool receive_own_messages = false;            // CAN_RAW_RECV_OWN_MSGS
  bool loopback = true;                         // CAN_RAW_LOOPBACK: other local sockets see our frames
  std::chrono::milliseconds send_timeout{20};   // how long a full TX queue may block a send
  std::chrono::milliseconds reopen_interval{500};

  Status Check() const;
};

class SocketCanBus final : public hal::CanBus {
 public:
  // Opens and binds the socket. NotFound when the interface does not exist; IoError naming the
  // missing kernel support when the kernel has no SocketCAN (modules can, can-raw).
  // `clock` (not owned; nullptr = CLOCK_MONOTONIC) stamps received frames; timeouts always run on the
  // steady clock.
  static Result<std::unique_ptr<SocketCanBus>> Open(const SocketCanOptions& options, hal::Clock* clock = nullptr);
  ~SocketCanBus() override;
  SocketCanBus(const SocketCanBus&) = delete;
  SocketCanBus& operator=(const SocketCanBus&) = delete;

  std::string name() const override { return options_.interface; }
  Status Send(const hal::CanFrame& frame) override;
  Result<std::optional<hal::CanFrame>> Receive(std::chrono::milliseconds timeout) override;
  hal::CanBusCounters counters() const override { return counters_; }

  // Asks the kernel to restart the controller (bus-off recovery). FailedPrecondition without
  // CAP_NET_ADMIN, DeviceError when the interface cannot be restarted (e.g. vcan).
  Status Restart();
  // Closes and reopens the socket (after the interface was down).
  Status Reopen();

  hal::CanControllerState controller_state() const { return state_; }
  bool bus_off() const { return state_ == hal::CanControllerState::kBusOff; }
  int interface_index() const { return ifindex_; }

 private:
  SocketCanBus(const SocketCanOptions& options, hal::Clock* clock);
  Status OpenSocket();
  void CloseSocket();
  void TrackError(const hal::CanFrame& frame);
  Status InterfaceGone(const std::string& what, int err);
  Status MaybeReopen();

  SocketCanOptions options_;
  hal::Clock* clock_;
  std::unique_ptr<hal::MonotonicClock> own_clock_;
  int fd_ = -1;
  int ifindex_ = 0;
  hal::CanBusCounters counters_;
  hal::CanControllerState state_ = hal::CanControllerState::kErrorActive;
  uint32_t kernel_drops_ = 0;
  int64_t last_reopen_ns_ = 0;
};

}  // namespace idi::drivers
