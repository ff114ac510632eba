// Conversion between hal::CanFrame and Linux SocketCAN's struct can_frame (linux/can.h), kept apart
// from the socket so it is tested without a CAN-capable kernel.
//
// Linux packs the frame kind into can_id: CAN_EFF_FLAG (29-bit id), CAN_RTR_FLAG (remote request),
// CAN_ERR_FLAG (error frame: the id bits are error classes, linux/can/error.h, which hal/can_error.h
// mirrors). hal::CanFrame keeps them as separate flags.
#pragma once

#include <linux/can.h>

#include <cstdint>

#include "shared/hal/can_bus.h"
#include "shared/util/status.h"

namespace idi::drivers {

// InvalidArgument for a frame no controller can send: DLC above 8, an id beyond 11 (29) bits, or
// an error frame (error frames are only ever received).
Result<can_frame> ToSocketCanFrame(const hal::CanFrame& frame);

// Any frame the kernel delivers converts; `timestamp_ns` is the receive time.
hal::CanFrame FromSocketCanFrame(const can_frame& frame, int64_t timestamp_ns);

// A receive filter (CAN_RAW_FILTER): passes when (received id & mask) == (id & mask). With
// `extended` the filter matches 29-bit ids only, otherwise 11-bit ids only.
struct SocketCanFilter {
  uint32_t id = 0;
  uint32_t mask = 0;
  bool extended = false;
  bool invert = false;  // CAN_INV_FILTER: pass what does not match
};
can_filter ToKernelFilter(const SocketCanFilter& filter);

}  // namespace idi::drivers
