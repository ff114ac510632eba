#include "shared/drivers/socketcan/socketcan_frame.h"

#include <linux/can/error.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <string>

#include "shared/hal/can_error.h"

namespace idi::drivers {

// hal/can_error.h repeats the kernel's values; they must agree.
static_assert(hal::kCanErrTxTimeout == CAN_ERR_TX_TIMEOUT);
static_assert(hal::kCanErrLostArb == CAN_ERR_LOSTARB);
static_assert(hal::kCanErrCrtl == CAN_ERR_CRTL);
static_assert(hal::kCanErrProt == CAN_ERR_PROT);
static_assert(hal::kCanErrTrx == CAN_ERR_TRX);
static_assert(hal::kCanErrAck == CAN_ERR_ACK);
static_assert(hal::kCanErrBusOff == CAN_ERR_BUSOFF);
static_assert(hal::kCanErrBusError == CAN_ERR_BUSERROR);
static_assert(hal::kCanErrRestarted == CAN_ERR_RESTARTED);
static_assert(hal::kCanErrCnt == CAN_ERR_CNT);
static_assert(hal::kCanErrCrtlRxOverflow == CAN_ERR_CRTL_RX_OVERFLOW);
static_assert(hal::kCanErrCrtlTxOverflow == CAN_ERR_CRTL_TX_OVERFLOW);
static_assert(hal::kCanErrCrtlRxWarning == CAN_ERR_CRTL_RX_WARNING);
static_assert(hal::kCanErrCrtlTxWarning == CAN_ERR_CRTL_TX_WARNING);
static_assert(hal::kCanErrCrtlRxPassive == CAN_ERR_CRTL_RX_PASSIVE);
static_assert(hal::kCanErrCrtlTxPassive == CAN_ERR_CRTL_TX_PASSIVE);
static_assert(hal::kCanErrCrtlActive == CAN_ERR_CRTL_ACTIVE);

namespace {

std::string SocketCanHexId(uint32_t id) {
  char buf[16];
  std::snprintf(buf, sizeof(buf), "0x%X", id);
  return buf;
}

}  // namespace

Result<can_frame> ToSocketCanFrame(const hal::CanFrame& frame) {
  if (frame.error) return InvalidArgument("SocketCAN: error frames cannot be sent");
  if (frame.dlc > CAN_MAX_DLEN) {
    return InvalidArgument("SocketCAN: frame " + SocketCanHexId(frame.id) + " has DLC " + std::to_string(frame.dlc) +
                           " (classic CAN allows 0..8)");
  }
  const uint32_t max_id = frame.extended ? CAN_EFF_MASK : CAN_SFF_MASK;
  if (frame.id > max_id) {
    return InvalidArgument("SocketCAN: id " + SocketCanHexId(frame.id) + " does not fit a " +
                           (frame.extended ? "29-bit" : "11-bit") + " identifier");
  }
  can_frame out;
  std::memset(&out, 0, sizeof(out));
  out.can_id = frame.id;
  if (frame.extended) out.can_id |= CAN_EFF_FLAG;
  if (frame.rtr) out.can_id |= CAN_RTR_FLAG;
  out.len = frame.dlc;
  if (!frame.rtr) std::memcpy(out.data, frame.data.data(), frame.dlc);
  return out;
}

hal::CanFrame FromSocketCanFrame(const can_frame& frame, int64_t timestamp_ns) {
  hal::CanFrame out;
  out.timestamp_ns = timestamp_ns;
  out.error = (frame.can_id & CAN_ERR_FLAG) != 0;
  out.extended = !out.error && (frame.can_id & CAN_EFF_FLAG) != 0;
  out.rtr = !out.error && (frame.can_id & CAN_RTR_FLAG) != 0;
  if (out.error) {
    out.id = frame.can_id & CAN_ERR_MASK;
  } else {
    out.id = frame.can_id & (out.extended ? CAN_EFF_MASK : CAN_SFF_MASK);
  }
  out.dlc = std::min<uint8_t>(frame.len, CAN_MAX_DLEN);
  if (!out.rtr) std::memcpy(out.data.data(), frame.data, out.dlc);
  return out;
}

can_filter ToKernelFilter(const SocketCanFilter& filter) {
  can_filter f;
  if (filter.extended) {
    f.can_id = (filter.id & CAN_EFF_MASK) | CAN_EFF_FLAG;
    f.can_mask = (filter.mask & CAN_EFF_MASK) | CAN_EFF_FLAG | CAN_RTR_FLAG;
  } else {
    f.can_id = filter.id & CAN_SFF_MASK;
    // Matching on the EFF flag too keeps 29-bit frames out of an 11-bit filter.
    f.can_mask = (filter.mask & CAN_SFF_MASK) | CAN_EFF_FLAG | CAN_RTR_FLAG;
  }
  if (filter.invert) f.can_id |= CAN_INV_FILTER;
  return f;
}

}  // namespace idi::drivers
