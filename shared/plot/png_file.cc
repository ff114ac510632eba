#include "shared/plot/png_file.h"

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

}  // namespace idi::plot
