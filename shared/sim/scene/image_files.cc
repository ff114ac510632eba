#include "shared/sim/scene/image_files.h"

#include <filesystem>
#include <vector>

#include "shared/plot/png_file.h"
#include "shared/util/atomic_file.h"

namespace idi::sim {

std::string WrittenImage::Summary() const {
  return png_path + " (" + std::to_string(width) + "x" + std::to_string(height) + (color ? " colour" : " gray") +
         ") + " + json_path + " (" + std::to_string(lines) + " lines, " + std::to_string(junctions) + " junctions, " +
         std::to_string(visible_spots) + " visible spots)";
}

Result<WrittenImage> WriteImageWithTruth(const cv::Mat& image, const GroundTruth& truth, const std::string& dir,
                                         const std::string& stem) {
  if (image.empty() || (image.type() != CV_8UC1 && image.type() != CV_8UC3)) {
    return InvalidArgument("image " + stem + ": expected an 8-bit gray or colour image");
  }
  if (image.cols != truth.width || image.rows != truth.height) {
    return InvalidArgument("image " + stem + ": " + std::to_string(image.cols) + "x" + std::to_string(image.rows) +
                           " does not match its ground truth (" + std::to_string(truth.width) + "x" +
                           std::to_string(truth.height) + ")");
  }
  WrittenImage w;
  w.png_path = (std::filesystem::path(dir) / (stem + ".png")).string();
  w.json_path = (std::filesystem::path(dir) / (stem + ".json")).string();
  IDI_RETURN_IF_ERROR(plot::WritePngFile(w.png_path, image));
  if (Status st = WriteFileAtomically(w.json_path, GroundTruthToJson(truth) + "\n"); !st.ok()) {
    // An image without its truth is not written: a failure leaves neither (the PNG was written whole above,
    // so it is this call's own file that is removed).
    std::error_code ec;
    std::filesystem::remove(w.png_path, ec);
    return st;
  }
  w.width = image.cols;
  w.height = image.rows;
  w.color = image.channels() == 3;
  w.lines = truth.lines.size();
  w.junctions = truth.junctions.size();
  for (const TruthSpot& s : truth.spots) w.visible_spots += s.visible ? 1 : 0;
  return w;
}

}  // namespace idi::sim
