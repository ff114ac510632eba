// CAN error frames (CanFrame::error): the error class bits in `id` and the details in `data` follow
// the Linux SocketCAN layout (linux/can/error.h), so SocketCAN, the virtual bus and log replay all
// report bus faults the same way. Values are repeated here so this header builds anywhere; the
// SocketCAN driver asserts at compile time that they equal the kernel's.
#pragma once

#include <cstdint>
#include <string>

#include "shared/hal/can_bus.h"

namespace idi::hal {

// Error classes (CanFrame::id of an error frame).
inline constexpr uint32_t kCanErrTxTimeout = 0x001;  // TX timeout (netdevice driver)
inline constexpr uint32_t kCanErrLostArb = 0x002;    // lost arbitration, bit in data[0]
inline constexpr uint32_t kCanErrCrtl = 0x004;       // controller problems, data[1]
inline constexpr uint32_t kCanErrProt = 0x008;       // protocol violations, data[2..3]
inline constexpr uint32_t kCanErrTrx = 0x010;        // transceiver status, data[4]
inline constexpr uint32_t kCanErrAck = 0x020;        // no ACK on transmission
inline constexpr uint32_t kCanErrBusOff = 0x040;     // bus off
inline constexpr uint32_t kCanErrBusError = 0x080;   // bus error
inline constexpr uint32_t kCanErrRestarted = 0x100;  // controller restarted
inline constexpr uint32_t kCanErrCnt = 0x200;        // TX/RX error counters in data[6]/data[7]
inline constexpr uint32_t kCanErrClassMask = 0x3FF;

// Controller status bits (data[1] when kCanErrCrtl is set).
inline constexpr uint8_t kCanErrCrtlRxOverflow = 0x01;
inline constexpr uint8_t kCanErrCrtlTxOverflow = 0x02;
inline constexpr uint8_t kCanErrCrtlRxWarning = 0x04;
inline constexpr uint8_t kCanErrCrtlTxWarning = 0x08;
inline constexpr uint8_t kCanErrCrtlRxPassive = 0x10;
inline constexpr uint8_t kCanErrCrtlTxPassive = 0x20;
inline constexpr uint8_t kCanErrCrtlActive = 0x40;  // recovered to error-active

// The controller's fault-confinement state as the error frames report it.
enum class CanControllerState { kErrorActive, kErrorWarning, kErrorPassive, kBusOff };

inline const char* CanControllerStateName(CanControllerState state) {
  switch (state) {
    case CanControllerState::kErrorActive: return "error-active";
    case CanControllerState::kErrorWarning: return "error-warning";
    case CanControllerState::kErrorPassive: return "error-passive";
    case CanControllerState::kBusOff: return "bus-off";
  }
  return "?";
}

// One error frame, decoded.
struct CanErrorInfo {
  uint32_t classes = 0;  // the kCanErr* bits that were set
  bool tx_timeout = false, lost_arbitration = false, no_ack = false, bus_error = false;
  bool bus_off = false, restarted = false;
  bool rx_overflow = false, tx_overflow = false;
  // The state this frame moves the controller to, when it says so (bus-off, warning, passive,
  // back to active or restarted); unset when the frame does not change the state.
  bool has_state = false;
  CanControllerState state = CanControllerState::kErrorActive;
  bool has_counters = false;
  uint8_t tx_error_count = 0, rx_error_count = 0;
  uint8_t protocol_type = 0, protocol_location = 0;  // data[2], data[3] when kCanErrProt
  uint8_t transceiver = 0;                           // data[4] when kCanErrTrx
};

inline CanErrorInfo DecodeCanError(const CanFrame& frame) {
  CanErrorInfo info;
  const uint32_t c = frame.id & kCanErrClassMask;
  info.classes = c;
  info.tx_timeout = (c & kCanErrTxTimeout) != 0;
  info.lost_arbitration = (c & kCanErrLostArb) != 0;
  info.no_ack = (c & kCanErrAck) != 0;
  info.bus_error = (c & kCanErrBusError) != 0;
  info.bus_off = (c & kCanErrBusOff) != 0;
  info.restarted = (c & kCanErrRestarted) != 0;
  if (c & kCanErrCrtl) {
    const uint8_t d1 = frame.data[1];
    info.rx_overflow = (d1 & kCanErrCrtlRxOverflow) != 0;
    info.tx_overflow = (d1 & kCanErrCrtlTxOverflow) != 0;
    if (d1 & (kCanErrCrtlRxPassive | kCanErrCrtlTxPassive)) {
      info.has_state = true;
      info.state = CanControllerState::kErrorPassive;
    } else if (d1 & (kCanErrCrtlRxWarning | kCanErrCrtlTxWarning)) {
      info.has_state = true;
      info.state = CanControllerState::kErrorWarning;
    } else if (d1 & kCanErrCrtlActive) {
      info.has_state = true;
      info.state = CanControllerState::kErrorActive;
    }
  }
  if (c & kCanErrProt) {
    info.protocol_type = frame.data[2];
    info.protocol_location = frame.data[3];
  }
  if (c & kCanErrTrx) info.transceiver = frame.data[4];
  if (c & kCanErrCnt) {
    info.has_counters = true;
    info.tx_error_count = frame.data[6];
    info.rx_error_count = frame.data[7];
  }
  // Bus-off wins over everything; a restart brings the controller back to error-active.
  if (info.restarted) {
    info.has_state = true;
    info.state = CanControllerState::kErrorActive;
  }
  if (info.bus_off) {
    info.has_state = true;
    info.state = CanControllerState::kBusOff;
  }
  return info;
}

// An error frame as the kernel would deliver it (the virtual bus and tests use this).
inline CanFrame MakeCanErrorFrame(int64_t timestamp_ns, uint32_t classes, uint8_t controller_bits = 0) {
  CanFrame f;
  f.timestamp_ns = timestamp_ns;
  f.error = true;
  f.id = classes & kCanErrClassMask;
  f.dlc = 8;
  f.data[1] = controller_bits;
  return f;
}

// "bus-off", "controller restarted", "controller error-passive, tx 130 rx 0", ... for logs.
inline std::string DescribeCanError(const CanErrorInfo& info) {
  std::string s;
  auto add = [&s](const std::string& part) {
    if (!s.empty()) s += ", ";
    s += part;
  };
  if (info.bus_off) add("bus-off");
  if (info.restarted) add("controller restarted");
  if (info.has_state && !info.bus_off && !info.restarted) {
    add(std::string("controller ") + CanControllerStateName(info.state));
  }
  if (info.tx_timeout) add("tx timeout");
  if (info.lost_arbitration) add("lost arbitration");
  if (info.no_ack) add("no ack");
  if (info.bus_error) add("bus error");
  if (info.rx_overflow) add("rx overflow");
  if (info.tx_overflow) add("tx overflow");
  if (info.classes & kCanErrProt) add("protocol violation");
  if (info.classes & kCanErrTrx) add("transceiver");
  if (info.has_counters) {
    add("tx errors " + std::to_string(info.tx_error_count) + " rx errors " + std::to_string(info.rx_error_count));
  }
  if (s.empty()) s = "error frame (no class bits)";
  return s;
}

}  // namespace idi::hal
