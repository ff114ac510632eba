// Example images of the twin for people to look at: a rendered frame as PNG with its ground truth as
// JSON beside it (GroundTruthToJson's layout, shared/sim/render/truth_json.cc). Used by
// `idi-workcell sim render` and `idi-rmp sim render`.
#pragma once

#include <opencv2/core.hpp>

#include <string>

#include "shared/sim/render/render.h"
#include "shared/util/status.h"

namespace idi::sim {

struct WrittenImage {
  std::string png_path, json_path;
  int width = 0, height = 0;
  bool color = false;
  std::size_t lines = 0, junctions = 0, visible_spots = 0;
  std::string Summary() const;  // one line: paths, size, what the truth holds
};

// Writes `<dir>/<stem>.png` and `<dir>/<stem>.json` atomically (the folder must exist). The image
// must be CV_8UC1 or CV_8UC3 and match the truth's size.
Result<WrittenImage> WriteImageWithTruth(const cv::Mat& image, const GroundTruth& truth, const std::string& dir,
                                         const std::string& stem);

}  // namespace idi::sim
