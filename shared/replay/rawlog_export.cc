#include "shared/replay/rawlog_export.h"

#include <mrpt/obs/CObservationImage.h>
#include <mrpt/obs/CRawlog.h>
#include <mrpt/system/datetime.h>
#include <unistd.h>

#include <filesystem>
#include <string>

namespace idi {

Status ExportRawlog(const std::vector<RawlogFrame>& frames, const std::string& path) {
  mrpt::obs::CRawlog log;
  for (std::size_t k = 0; k < frames.size(); ++k) {
    const RawlogFrame& f = frames[k];
    if (f.image.empty() || (f.image.type() != CV_8UC1 && f.image.type() != CV_8UC3)) {
      return InvalidArgument(path + ": frame " + std::to_string(k) + " is empty or not an 8-bit gray/BGR image");
    }
    auto obs = mrpt::obs::CObservationImage::Create();
    obs->sensorLabel = f.sensor_label;
    obs->timestamp = mrpt::Clock::fromDouble(static_cast<double>(f.timestamp_unix_ns) * 1e-9);
    // Shares the frame's pixels (the frames outlive the log): a long drive is not held twice in memory.
    obs->image = mrpt::img::CImage(f.image, mrpt::img::SHALLOW_COPY);
    if (f.camera) {
      const CameraModel& c = *f.camera;
      obs->cameraParams.ncols = static_cast<uint32_t>(c.width);
      obs->cameraParams.nrows = static_cast<uint32_t>(c.height);
      obs->cameraParams.fx(c.fx());
      obs->cameraParams.fy(c.fy());
      obs->cameraParams.cx(c.cx());
      obs->cameraParams.cy(c.cy());
      obs->cameraParams.k1(c.params[kK1]);
      obs->cameraParams.k2(c.params[kK2]);
      obs->cameraParams.p1(c.params[kP1]);
      obs->cameraParams.p2(c.params[kP2]);
      obs->cameraParams.k3(c.params[kK3]);
    }
    log.insert(obs);
  }
  // Written beside the target and renamed over it: a failed or interrupted export leaves an earlier
  // file at `path` as it was.
  const std::string tmp = path + ".tmp-" + std::to_string(::getpid());
  bool ok = false;
  std::string why;
  try {
    ok = log.saveToRawLogFile(tmp);
  } catch (const std::exception& e) {
    why = std::string(": ") + e.what();
  }
  std::error_code ec;
  if (ok) {
    std::filesystem::rename(tmp, path, ec);
    if (ec) why = ": cannot replace it with " + tmp + ": " + ec.message();
  }
  if (!ok || ec) {
    std::error_code ignored;
    std::filesystem::remove(tmp, ignored);
    return IoError(path + ": cannot write the rawlog" + why);
  }
  return Status::Ok();
}

Result<std::vector<RawlogFrame>> ReadRawlogImages(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) return NotFound(path + ": no such file");
  mrpt::obs::CRawlog log;
  try {
    if (!log.loadFromRawLogFile(path)) return ParseError(path + ": not a readable rawlog");
  } catch (const std::exception& e) {
    return ParseError(path + ": not a readable rawlog: " + e.what());
  }
  std::vector<RawlogFrame> out;
  for (std::size_t k = 0; k < log.size(); ++k) {
    if (log.getType(k) != mrpt::obs::CRawlog::etObservation) continue;
    const auto img = std::dynamic_pointer_cast<mrpt::obs::CObservationImage>(log.getAsObservation(k));
    if (!img) continue;
    RawlogFrame f;
    f.sensor_label = img->sensorLabel;
    f.timestamp_unix_ns = static_cast<int64_t>(mrpt::Clock::toDouble(img->timestamp) * 1e9);
    f.image = img->image.asCvMat<cv::Mat>(mrpt::img::DEEP_COPY);
    out.push_back(std::move(f));
  }
  return out;
}

}  // namespace idi
