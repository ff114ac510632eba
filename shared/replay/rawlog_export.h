// Export of recorded images to MRPT's rawlog format, so MRPT's RawLogViewer
// and rawlog-edit (Debian package mrpt-apps) can open what the workcell or the vehicle recorded.
// The rawlog is a plain observation stream (no actions): one CObservationImage per frame, labelled
// with its camera's name and stamped with its capture time; images are embedded.
#pragma once

#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "shared/camera/pinhole.h"
#include "shared/util/status.h"

namespace idi {

struct RawlogFrame {
  int64_t timestamp_unix_ns = 0;  // wall-clock capture time
  std::string sensor_label;       // e.g. "left", "right"
  cv::Mat image;                  // CV_8UC1 or CV_8UC3 (BGR)
  std::optional<CameraModel> camera;  // intrinsics, stored as the observation's camera parameters
};

// Writes `frames` (in order) to `path`. InvalidArgument for empty images; IoError when writing fails.
Status ExportRawlog(const std::vector<RawlogFrame>& frames, const std::string& path);

// Reads the image observations back (for tests and tools).
Result<std::vector<RawlogFrame>> ReadRawlogImages(const std::string& path);

}  // namespace idi
