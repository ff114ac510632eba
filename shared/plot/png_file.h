// An image written as a PNG file for people to look at (overlays, renders, figures): encoded, then
// replacing the file atomically (shared/util/atomic_file.h), so a reader never sees half a file.
#pragma once

#include <opencv2/core.hpp>
#include <string>

#include "shared/util/status.h"

namespace idi::plot {

// 8-bit gray or BGR(A) (or 16-bit) as cv::imencode takes them. InvalidArgument naming `path` for an
// empty image, IoError naming it when the encoding or the write fails.
Status WritePngFile(const std::string& path, const cv::Mat& image);

}  // namespace idi::plot
