// The vehicle's drive log: the recording format (recording.h, kind "rmp-drive") with the event
// vocabulary idi-rmp writes while it drives and reads back in `idi-rmp replay DIR`:
//
//   recording.json  header: the camera models ("left", "right") and meta: {"source": "sim" or
//                   "hardware", "config_yaml", "cruise_speed_mps", and from the twin "track",
//                   "tape_width_m", "rig"; at the end also "report"} (what replay needs to rebuild the
//                   pipeline)
//   events.jsonl    image     {"camera", "seq", "file"}                 t_ns = exposure time
//                   delivered {"camera", "seq"}                          t_ns = when the loop received it
//                   tick      {"left_seq", "right_seq", "speed_mps", "yaw_rate_rps", "decision", "state"}
//                             t_ns = the control tick; *_seq the stereo pair perceived at this tick
//                             (-1: none), the command given to the RMP driver, why
//   images/         lossless PNG (8-bit grey)
//   can.log         every CAN frame sent and received, candump -l format with direction marks (R/T)
//
// A replay feeds the images at their delivery times and the CAN frames at their receive times to the
// same pipeline, runs the same ticks and compares its commands with the tick events.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "shared/hal/camera.h"
#include "shared/replay/candump_log.h"
#include "shared/replay/recording.h"
#include "shared/util/status.h"

namespace idi::replay {

inline constexpr const char* kDriveLogKind = "rmp-drive";
inline constexpr const char* kDriveLogCanFile = "can.log";

struct DriveFrameRecord {
  std::string camera;
  uint64_t seq = 0;
  int64_t exposure_ns = 0;
  int64_t delivered_ns = -1;  // -1: never delivered (dropped)
  std::size_t event = 0;      // index of its image event (to load it)
};

struct DriveTickRecord {
  int64_t t_ns = 0;
  int64_t left_seq = -1, right_seq = -1;
  double speed_mps = 0.0, yaw_rate_rps = 0.0;
  std::string decision;  // "drive", or why zero was commanded
  std::string state;     // the planner's state
  int line = 0;          // its line in events.jsonl (read logs only; for messages)
};

class DriveLogWriter {
 public:
  // Creates the folder (must not exist or be empty), the header and can.log.
  static Result<std::unique_ptr<DriveLogWriter>> Create(const std::string& dir, const RecordingHeader& header);
  ~DriveLogWriter();

  Status AddFrame(const hal::Image& image);                                    // image event + PNG
  Status AddDelivered(int64_t t_ns, const std::string& camera, uint64_t seq);  // delivered event
  Status AddTick(const DriveTickRecord& tick);
  // The CAN log for the driver (RmpDriver::SetFrameLog).
  CandumpWriter* can_log() { return can_.get(); }
  Status Finish(const nlohmann::json& final_meta);
  const std::string& dir() const { return recording_.dir(); }

 private:
  DriveLogWriter(RecordingWriter recording, std::unique_ptr<CandumpWriter> can)
      : recording_(std::move(recording)), can_(std::move(can)) {}
  RecordingWriter recording_;
  std::unique_ptr<CandumpWriter> can_;
};

struct DriveLog {
  Recording recording;
  std::vector<DriveFrameRecord> frames;  // in the order their image events were written
  std::vector<DriveTickRecord> ticks;
  std::vector<CandumpRecord> can;
  std::string can_torn_last_line;  // can.log's last line, dropped: it has no newline (see ParseCandumpText)
  int can_torn_line = 0;           // its line number (0: none)
};

// Reads a drive log. ParseError naming the file (and line) for malformed content, a recording of
// another kind, ticks out of time order (each must come after the one before) and a can.log whose time
// goes backwards; NotFound when the folder or a file is missing. A torn last line of events.jsonl or
// can.log (a power cut) is skipped and reported (recording.truncated_line, can_torn_last_line).
Result<DriveLog> ReadDriveLog(const std::string& dir);
// Loads one frame's image (8-bit grey) with its exposure time and sequence number.
Result<hal::Image> LoadDriveFrame(const DriveLog& log, const DriveFrameRecord& frame);

}  // namespace idi::replay
