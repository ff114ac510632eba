// idi-workcell's service configuration (`idi-workcell run --config FILE`), YAML:
//
//   backend: sim                      # sim | hardware
//   state_dir: /var/lib/idi-workcell  # runs, recordings, the calibration in use
//   control: {socket: /run/idi-workcell/control.sock, group: idi}
//   calibration: {max_age_days: 30, recalibrate_when_stale: true}
//   sim: {seed: 1, day: [box, prism, bracket], pace: 0}   # day: objects to scan and pick once calibrated;
//                                     # pace: wall seconds per simulated second (0: as fast as it goes)
//   exit_when_idle: false             # true: return when the queue has run dry (the simulated day, CI)
//   hardware:
//     arms:    [{name: arm1, host: 192.168.10.11, port: 5100}, {name: arm2, host: 192.168.10.12, port: 5100}]
//     ptus:    [{name: left, device: /dev/ttyUSB0, baud: 9600}, {name: right, device: /dev/ttyUSB1, baud: 9600}]
//     hand:    {device: /dev/ttyUSB2, baud: 9600}
//     cameras: [{name: left, backend: v4l2, device: /dev/video0}, {name: right, backend: v4l2, device: /dev/video1}]
//
// Unknown keys, wrong types and missing required fields are errors naming the file, line and key.
#pragma once

#include <string>
#include <vector>

#include "shared/util/status.h"

namespace idi::workcell {

struct ArmEndpoint {
  std::string name;
  std::string host;
  int port = 5100;
};
struct SerialEndpoint {
  std::string name;
  std::string device;
  int baud = 9600;
};
struct CameraEndpoint {
  std::string name;
  std::string backend = "v4l2";  // v4l2 | mrpt
  std::string device;
  int width = 640, height = 480;  // the frame size asked of the camera (the A602fc's 640 x 480 by default)
  double exposure_us = 0;         // 0: the camera keeps its own exposure setting
};

struct WorkcellConfig {
  std::string backend = "sim";
  std::string state_dir = "/var/lib/idi-workcell";
  std::string control_socket = "/run/idi-workcell/control.sock";
  std::string control_group;
  double calibration_max_age_days = 30;
  bool recalibrate_when_stale = true;
  unsigned sim_seed = 1;
  std::vector<std::string> sim_day;  // objects the sim cell scans and picks at start (the `day` job)
  double sim_pace = 0;               // wall seconds per simulated second; 0: as fast as it goes
  bool exit_when_idle = false;
  std::vector<ArmEndpoint> arms;
  std::vector<SerialEndpoint> ptus;
  SerialEndpoint hand;
  std::vector<CameraEndpoint> cameras;
};

Result<WorkcellConfig> ParseWorkcellConfig(const std::string& yaml_text, const std::string& where);
Result<WorkcellConfig> LoadWorkcellConfig(const std::string& path);

}  // namespace idi::workcell
