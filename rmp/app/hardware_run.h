// `idi-rmp run` on the vehicle: the RMP on SocketCAN, two cameras (V4L2, or libcamera when built with
// it; hardware.cameras[].backend), the monotonic clock.
#pragma once

#include <atomic>
#include <string>

#include "rmp/app/rmp_config.h"
#include "rmp/app/sim_run.h"

namespace idi::rmp {

struct HardwareRunOptions {
  RmpConfig config;
  std::string config_text;
  std::string record_dir;               // drive log; empty: none
  std::atomic<bool>* stop = nullptr;    // a signal: zero, shut down, return
};

// Runs until the track's end is reached, a signal arrives or a device fails; always ends with the
// driver's zero commands. FailedPrecondition when this build has no SocketCAN or V4L2 backend.
Result<RunReport> RunHardware(const HardwareRunOptions& options);

}  // namespace idi::rmp
