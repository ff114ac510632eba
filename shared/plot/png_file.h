// An image written as a PNG file for people to look at (overlays, renders, figures): encoded, then
// replacing the file atomically (shared/util/atomic_file.h), so a reader never sees half a file. And
// image files read (any format cv::imread knows) with every failure an error naming the file.
#pragma once

#include <opencv2/core.hpp>
#include <string>

#include "shared/util/status.h"

namespace idi::plot {

// 8-bit gray or BGR(A) (or 16-bit) as cv::imencode takes them. InvalidArgument naming `path` for an
// empty image, IoError naming it when the encoding or the write fails.
Status WritePngFile(const std::string& path, const cv::Mat& image);

// cv::imread(path, flags) without its exceptions: InvalidArgument naming `path` when the file is missing
// or not an image, and when OpenCV throws on it (a header claiming more than CV_IO_MAX_IMAGE_PIXELS, a
// size whose pixels cannot be allocated), so that a bad image is that image's error, not the run's end.
Result<cv::Mat> ReadImageFile(const std::string& path, int flags);

}  // namespace idi::plot
