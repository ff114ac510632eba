// A CAN bus: SocketCAN (CAN_RAW) on the vehicle, the simulation's virtual bus, or log replay.
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <optional>
#include <string>

#include "shared/util/status.h"

namespace idi::hal {

struct CanFrame {
  int64_t timestamp_ns = 0;  // receive time (or send time for transmitted frames)
  uint32_t id = 0;           // 11-bit standard or 29-bit extended identifier
  bool extended = false;
  bool rtr = false;
  bool error = false;        // an error frame (id holds the error class bits)
  uint8_t dlc = 0;
  std::array<uint8_t, 8> data{};
};

struct CanBusCounters {
  uint64_t sent = 0, received = 0, error_frames = 0, dropped = 0, bus_off = 0;
};

class CanBus {
 public:
  virtual ~CanBus() = default;
  virtual std::string name() const = 0;
  virtual Status Send(const CanFrame& frame) = 0;
  // The next frame, or nullopt on timeout. DeviceError when the interface failed.
  virtual Result<std::optional<CanFrame>> Receive(std::chrono::milliseconds timeout) = 0;
  virtual CanBusCounters counters() const = 0;
};

}  // namespace idi::hal
