// The recording format: what a run saw and did, replayable on a desktop. One folder per run:
//
//   <run>/recording.json   {"format": "idi-recording", "version": 1, "kind": "...", "created_unix_ns": ...,
//                           "created_clock_ns": ... (the run's clock then; see UnixTimeOf),
//                           "cameras": {"left": {"width", "height", "params": [fx, fy, cx, cy, k1, k2, p1, p2, k3]}},
//                           "meta": {...}}
//   <run>/events.jsonl     one JSON object per line, in the order written (an image, written when it is
//                          delivered, may follow events of later t_ns); every event has "t_ns" (the
//                          run's clock, sample time) and "type":
//                            image   {"camera", "seq", "file": "images/000042_left.png"}
//                            joints  {"arm", "q_deg": [6]}           encoder readings, model convention
//                            rail    {"arm", "position_mm"}
//                            pan_tilt {"head", "pan_deg", "tilt_deg"}
//                            tcf     {"arm", "pose": [x_mm, y_mm, z_mm, alpha_deg, beta_deg, gamma_deg]}
//                            spot    {"camera", "u_px", "v_px"} / {"wall", "x_mm", "y_mm"}
//                            command {...}  status {...}  note {"text"}   (free-form fields)
//   <run>/images/          lossless PNG, 8-bit gray or BGR
//   <run>/can.log          (vehicle) every CAN frame in candump -l format
//
// The writer appends and flushes each event, so a run killed half way leaves a readable prefix.
// Files are never rewritten; recording.json is written atomically when the run starts and once more
// with the final meta when it ends.
#pragma once

#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "shared/camera/pinhole.h"
#include "shared/util/status.h"

namespace idi {

inline constexpr int kRecordingVersion = 1;

struct RecordingHeader {
  std::string kind;  // "scan", "calibrate-robot", "calibrate-rail", "calibrate-ptu", "pick", "rmp-drive", ...
  int64_t created_unix_ns = 0;
  // The run's clock (the clock of the events' t_ns: CLOCK_MONOTONIC on hardware, the twin's clock in a
  // simulation) when created_unix_ns was taken; 0 in recordings written before it was stored.
  int64_t created_clock_ns = 0;
  std::map<std::string, CameraModel> cameras;
  nlohmann::json meta = nlohmann::json::object();
};

// The wall-clock (Unix) time of an event's t_ns: the events' clock is not the wall clock (on the vehicle
// it counts from boot), so t_ns is taken relative to the clock's reading at creation. ReadRecording
// refuses an event whose time does not fit in int64 (the sum would overflow).
inline int64_t UnixTimeOf(const RecordingHeader& header, int64_t t_ns) {
  return header.created_unix_ns + (t_ns - header.created_clock_ns);
}

class RecordingWriter {
 public:
  // Creates the folder (must not exist or be empty) and writes recording.json.
  static Result<RecordingWriter> Create(const std::string& dir, const RecordingHeader& header);
  RecordingWriter(RecordingWriter&&) = default;
  RecordingWriter& operator=(RecordingWriter&&) = default;

  // Appends an event (must hold "type"; "t_ns" is added). Flushed immediately.
  Status Add(int64_t t_ns, nlohmann::json event);
  // Writes the image as PNG and appends its image event.
  Status AddImage(int64_t t_ns, const std::string& camera, uint64_t seq, const cv::Mat& image);
  // Rewrites recording.json with the final meta (atomically).
  Status Finish(const nlohmann::json& final_meta);

  const std::string& dir() const { return dir_; }
  std::size_t events() const { return events_; }

 private:
  RecordingWriter() = default;
  std::string dir_;
  RecordingHeader header_;
  std::unique_ptr<std::ofstream> out_;
  std::size_t events_ = 0;
};

struct Recording {
  std::string dir;
  RecordingHeader header;
  std::vector<nlohmann::json> events;  // in file order
  std::vector<int> lines;              // events[i]'s line in events.jsonl (1-based), for messages
  bool truncated = false;              // the last line was torn (a run killed while writing, a power loss)
  int truncated_line = 0;              // that line's number (skipped)
};

// Reads a recording. ParseError naming the file and line for malformed content (fields of the wrong
// type; a meta that is not an object; a t_ns whose UnixTimeOf overflows; an image event whose seq is
// not an integer >= 0, whose file is absolute or leaves the folder (..), or that records a frame (camera,
// seq) or a file seen before); a torn last line (no newline, or NUL bytes only) is skipped and reported in truncated
// and truncated_line, for the caller to warn about.
Result<Recording> ReadRecording(const std::string& dir);
// The path of an image event's file (inside the recording's folder).
Result<std::string> RecordedImagePath(const Recording& recording, const nlohmann::json& image_event);
// Loads an image event's PNG; InvalidArgument naming the file when it cannot be read.
Result<cv::Mat> LoadRecordedImage(const Recording& recording, const nlohmann::json& image_event);

}  // namespace idi
