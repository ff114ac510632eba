#include "shared/plot/png_file.h"

#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <new>
#include <opencv2/imgcodecs.hpp>
#include <string_view>
#include <vector>

#include "shared/util/atomic_file.h"

namespace idi::plot {

Status WritePngFile(const std::string& path, const cv::Mat& image) {
  if (image.empty()) return InvalidArgument(path + ": no image to write (empty)");
  std::vector<uchar> png;
  try {
    if (!cv::imencode(".png", image, png)) return IoError(path + ": PNG encoding failed");
  } catch (const cv::Exception& e) {
    return IoError(path + ": PNG encoding failed: " + e.what());
  }
  return WriteFileAtomically(path, std::string_view(reinterpret_cast<const char*>(png.data()), png.size()));
}

Result<cv::Mat> ReadImageFile(const std::string& path, int flags) {
  cv::Mat image;
  try {
    image = cv::imread(path, flags);
  } catch (const cv::Exception& e) {
    return InvalidArgument(path + ": cannot read the image: OpenCV refused it (" + e.err +
                           "; a corrupt header or an image too large)");
  } catch (const std::bad_alloc&) {
    return Internal(path + ": cannot read the image: not enough memory for its pixels");  // a failed run, not bad input
  }
  if (image.empty()) {
    std::error_code ec;
    if (!std::filesystem::exists(path, ec)) return NotFound(path + ": cannot read the image: no such file");
    if (::access(path.c_str(), R_OK) != 0) return IoError(path + ": cannot read the image: " + std::strerror(errno));
    return InvalidArgument(path + ": cannot read the image (not an image format OpenCV reads, or corrupt)");
  }
  return image;
}

}  // namespace idi::plot
