#include "workcell/app/features_command.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <sys/stat.h>
#include <yaml-cpp/yaml.h>

#include <filesystem>
#include <iostream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <set>

#include "shared/features/features.h"
#include "shared/features/laser_spot.h"
#include "shared/features/pixel_geometry.h"
#include "shared/plot/png_file.h"
#include "shared/runtime/param_file.h"
#include "shared/util/atomic_file.h"

namespace idi::workcell {
namespace {

struct FeaturesCliOptions {
  std::vector<std::string> images;
  bool json = false;
  std::string overlay_dir;
  std::string camera_file;
  bool laser_spot = false;
};

// Camera file: either `K: [9 numbers]` with optional `distortion: [k1, k2, p1, p2, k3]` (as in the
// reconstruct VIEWS.yaml), or a camera parameter file (fx_px, fy_px, cx_px, cy_px, k1, k2, p1, p2,
// k3); optional `width`, `height` (default: the image size).
Result<CameraModel> LoadCameraFile(const std::string& path, int* width, int* height) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::Exception& e) {
    return ParseError(fmt::format("{}: {}", path, e.what()));
  }
  if (!root.IsMap()) {
    return ParseError(path + ": expected a YAML map with K (and distortion) or fx_px, fy_px, cx_px, cy_px");
  }
  CameraModel cam;
  *width = 0;
  *height = 0;
  try {
    if (root["width"]) *width = root["width"].as<int>();
    if (root["height"]) *height = root["height"].as<int>();
    if (static_cast<bool>(root["width"]) != static_cast<bool>(root["height"]) ||
        (root["width"] && !(*width > 0 && *height > 0))) {
      return ParseError(path + ": width and height go together, both positive (or neither: the image's size)");
    }
    if (root["K"]) {
      // A key this branch does not read (`dist_coeffs`, `k1` beside K) would be left out without a word.
      for (const auto& kv : root) {
        const std::string key = kv.first.as<std::string>();
        if (key != "K" && key != "distortion" && key != "width" && key != "height" && key != "model" &&
            key != "comment" && key != "camera") {
          return ParseError(path + ": unknown key '" + key + "' beside K (K, distortion, width, height)");
        }
      }
      const auto k = root["K"].as<std::vector<double>>();
      if (k.size() != 9) {
        return ParseError(fmt::format("{}: K: expected 9 numbers (3x3 row-major), got {}", path, k.size()));
      }
      // Row-major [fx, 0, cx, 0, fy, cy, 0, 0, 1]: a transposed K would put the principal point at (0, 0)
      // and undistort about the wrong centre without a word.
      if (k[1] != 0 || k[3] != 0 || k[6] != 0 || k[7] != 0 || k[8] != 1 || !(k[0] > 0) || !(k[4] > 0)) {
        return ParseError(
            fmt::format("{}: K: expected [fx, 0, cx, 0, fy, cy, 0, 0, 1] with fx, fy > 0 (row-major)", path));
      }
      cam.params[kFx] = k[0];
      cam.params[kFy] = k[4];
      cam.params[kCx] = k[2];
      cam.params[kCy] = k[5];
      if (root["distortion"]) {
        const auto d = root["distortion"].as<std::vector<double>>();
        if (d.size() != 5 && d.size() != 4) {
          return ParseError(
              fmt::format("{}: distortion: expected [k1, k2, p1, p2, k3], got {} numbers", path, d.size()));
        }
        cam.params[kK1] = d[0];
        cam.params[kK2] = d[1];
        cam.params[kP1] = d[2];
        cam.params[kP2] = d[3];
        cam.params[kK3] = d.size() == 5 ? d[4] : 0.0;
      }
    } else {
      ParamFileOptions pfo;
      pfo.extra_keys = {"model", "comment", "width", "height", "statistics", "camera"};
      pfo.require_all = false;  // the distortion may be left out (0)
      // ... but not the intrinsics: a default principal point would undistort about the wrong centre.
      for (const char* key : {"fx_px", "fy_px", "cx_px", "cy_px"}) {
        if (!root[key])
          return ParseError(fmt::format("{}: missing {} (give K: [...] or fx_px, fy_px, cx_px, cy_px)", path, key));
      }
      IDI_ASSIGN_OR_RETURN(const ParamSet set, ParamSetFromYaml(root, CameraParamSpecs(CameraModel{}), path, pfo));
      cam = CameraFromParamSet(set, 0, 0);
    }
  } catch (const YAML::Exception& e) {
    return ParseError(fmt::format("{}: {}", path, e.what()));
  }
  for (double p : cam.params) {
    if (!std::isfinite(p)) {
      return ParseError(path + ": camera parameters must be finite numbers");
    }
  }
  if (!(cam.fx() > 0 && cam.fy() > 0)) {
    return InvalidArgument(fmt::format("{}: focal lengths must be positive (fx {}, fy {})", path, cam.fx(), cam.fy()));
  }
  return cam;
}

// One JSON line; bytes of a file name that are not UTF-8 are replaced (dump() would throw).
std::string JsonLine(const nlohmann::json& j) {
  return j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

nlohmann::json Xy(const Eigen::Vector2d& v) { return {v.x(), v.y()}; }
nlohmann::json Cov(const Eigen::Matrix2d& c) { return {{c(0, 0), c(0, 1)}, {c(1, 0), c(1, 1)}}; }

// The laser spot of --laser-spot: the status, and every spot found (brightest first) in image pixels.
nlohmann::json SpotJson(const LaserSpotResult& s) {
  nlohmann::json j{
      {"status", LaserSpotStatusName(s.status)}, {"background", s.background}, {"noise_sigma", s.noise_sigma}};
  if (!s.message.empty()) j["message"] = s.message;
  j["spots"] = nlohmann::json::array();
  for (const LaserSpot& p : s.spots) {
    j["spots"].push_back({{"xy", Xy(p.xy)},
                          {"covariance", Cov(p.covariance)},
                          {"peak", p.peak},
                          {"area_px", p.area_px},
                          {"saturated_px", p.saturated_px}});
  }
  return j;
}

nlohmann::json ResultJson(const std::string& image, const FeatureResult& r) {
  nlohmann::json out;
  out["image"] = image;
  out["width"] = r.width;
  out["height"] = r.height;
  out["time_ms"] = r.timing.total_ms;
  out["noise_sigma"] = r.noise_sigma;
  out["lines"] = nlohmann::json::array();
  for (const EmplLine& l : r.lines) {
    out["lines"].push_back({{"id", l.id},
                            {"p1", Xy(l.p1)},
                            {"p2", Xy(l.p2)},
                            {"normal", Xy(l.normal)},
                            {"offset", l.offset},
                            {"length_px", l.length_px},
                            {"fit_rms_px", l.fit_rms_px},
                            {"extension1", Xy(l.extension1)},
                            {"extension2", Xy(l.extension2)},
                            {"covariance_angle_offset", Cov(l.covariance)},
                            {"contrast", l.contrast},
                            {"alternating", l.alternating},
                            {"points", l.point_ids}});
  }
  out["points"] = nlohmann::json::array();
  for (const IdiPoint& p : r.points) {
    nlohmann::json j = {{"id", p.id}, {"xy", Xy(p.xy)}, {"lines", p.line_ids}, {"covariance", Cov(p.covariance)}};
    if (p.kind == IdiPointKind::kCurveLine) {
      j["kind"] = "curve_line";
      j["curves"] = p.curve_ids;
    }
    out["points"].push_back(j);
  }
  out["curves"] = nlohmann::json::array();
  for (const Curve& c : r.curves) {
    nlohmann::json pts = nlohmann::json::array();
    for (const Eigen::Vector2d& p : c.points) {
      pts.push_back(Xy(p));
    }
    out["curves"].push_back({{"id", c.id}, {"points", pts}, {"fit_rms_px", c.fit_rms_px}, {"point_ids", c.point_ids}});
  }
  return out;
}

cv::Point2f ToCv(const PixelGeometry& geometry, const Eigen::Vector2d& fit) {
  const Vec2d p = geometry.ToPixel(fit);
  return {static_cast<float>(p.x()), static_cast<float>(p.y())};
}

// Polyline of a straight piece in fit coordinates, bent through the distortion when there is one.
void DrawPiece(cv::Mat& img,
               const PixelGeometry& geometry,
               const Eigen::Vector2d& a,
               const Eigen::Vector2d& b,
               const cv::Scalar& colour,
               int thickness) {
  const int steps = geometry.identity() ? 1 : std::max(1, static_cast<int>((b - a).norm() / 4));
  constexpr int kShift = 4;  // sub-pixel drawing
  for (int i = 0; i < steps; ++i) {
    const cv::Point2f p = ToCv(geometry, a + (b - a) * (static_cast<double>(i) / steps));
    const cv::Point2f q = ToCv(geometry, a + (b - a) * (static_cast<double>(i + 1) / steps));
    cv::line(img,
             cv::Point(cvRound(p.x * 16), cvRound(p.y * 16)),
             cv::Point(cvRound(q.x * 16), cvRound(q.y * 16)),
             colour,
             thickness,
             cv::LINE_AA,
             kShift);
  }
}

// The overlay file of each image: <stem>_features.png, numbered for images of one stem (a/cam.png and
// b/cam.png; UniqueOutputNames). Named before any image is read, so that they can be checked against the
// inputs and do not depend on which images fail.
std::vector<std::string> OverlayNames(const std::vector<std::string>& images) {
  return UniqueOutputNames(images, "_features.png");
}

// The overlays may not replace an image or the camera file (nor each other: their names are distinct).
Status CheckOverlaysAreNotInputs(const FeaturesCliOptions& o, const std::vector<std::string>& overlays) {
  std::vector<NamedFile> inputs = {{"--camera", o.camera_file}};
  for (const std::string& path : o.images) inputs.push_back({"image", path});
  std::vector<NamedFile> outputs;
  for (const std::string& overlay : overlays) outputs.push_back({"--overlay", overlay});
  return CheckDistinctFiles(inputs, outputs, "features");
}

Status WriteOverlay(const std::string& out,
                    const std::string& image_path,
                    const cv::Mat& image,
                    const FeatureResult& r,
                    const PixelGeometry& geometry) {
  cv::Mat grey8;
  if (image.depth() == CV_16U) {
    image.convertTo(grey8, CV_8U, 1.0 / 257.0);
  } else if (image.depth() == CV_32F) {
    image.convertTo(grey8, CV_8U);
  } else {
    grey8 = image;
  }
  cv::Mat canvas;
  cv::cvtColor(grey8, canvas, cv::COLOR_GRAY2BGR);
  for (const Curve& c : r.curves) {
    for (std::size_t i = 0; i + 1 < c.points.size(); ++i) {
      DrawPiece(canvas, geometry, c.points[i], c.points[i + 1], cv::Scalar(255, 128, 0), 1);
    }
  }
  for (const EmplLine& l : r.lines) {
    DrawPiece(canvas, geometry, l.extension1, l.p1, cv::Scalar(0, 200, 255), 1);
    DrawPiece(canvas, geometry, l.p2, l.extension2, cv::Scalar(0, 200, 255), 1);
    DrawPiece(canvas, geometry, l.p1, l.p2, cv::Scalar(0, 220, 0), 1);
  }
  for (const IdiPoint& p : r.points) {
    const cv::Point2f c = ToCv(geometry, p.xy);
    cv::circle(
        canvas, cv::Point(cvRound(c.x * 16), cvRound(c.y * 16)), 3 * 16, cv::Scalar(0, 0, 255), 1, cv::LINE_AA, 4);
  }
  IDI_RETURN_IF_ERROR(plot::WritePngFile(out, canvas).WithContext("the overlay of " + image_path));
  spdlog::info("wrote overlay {}", out);
  return Status::Ok();
}

Status RunFeatures(const FeaturesCliOptions& o) {
  std::optional<CameraModel> camera;
  int cam_w = 0, cam_h = 0;
  if (!o.camera_file.empty()) {
    IDI_ASSIGN_OR_RETURN(CameraModel c, LoadCameraFile(o.camera_file, &cam_w, &cam_h));
    camera = c;
  }
  // The overlays, named up front: one that is an image of the run (fo/a.png's overlay is
  // fo/a_features.png) would replace that image before it is read.
  std::vector<std::string> overlays;
  if (!o.overlay_dir.empty()) {
    for (const std::string& name : OverlayNames(o.images)) {
      overlays.push_back((std::filesystem::path(o.overlay_dir) / name).string());
    }
    IDI_RETURN_IF_ERROR(CheckOverlaysAreNotInputs(o, overlays));
    std::error_code ec;
    std::filesystem::create_directories(o.overlay_dir, ec);
    if (ec) {
      return IoError(fmt::format("--overlay {}: cannot create the folder: {}", o.overlay_dir, ec.message()));
    }
  }
  const FeatureOptions options;
  std::optional<FeatureDetector> detector;
  PixelGeometry geometry;
  int last_w = 0, last_h = 0;
  std::size_t failed = 0;
  Status first_error = Status::Ok();
  for (std::size_t i = 0; i < o.images.size(); ++i) {
    const std::string& path = o.images[i];
    // An image that cannot be read (missing, not an image, one OpenCV throws on) is this image's error.
    Result<cv::Mat> read = plot::ReadImageFile(path, cv::IMREAD_UNCHANGED);
    Status status = read.status();
    cv::Mat image = read.ok() ? std::move(read).value() : cv::Mat();
    const bool colour = image.channels() == 3 || image.channels() == 4;
    if (status.ok() && colour && image.depth() != CV_8U && image.depth() != CV_16U && image.depth() != CV_32F) {
      status = InvalidArgument(
          fmt::format("{}: colour image of pixel depth {} (expected 8-bit, 16-bit or float)", path, image.depth()));
    } else if (status.ok() && colour) {
      spdlog::info("{}: colour image converted to grey", path);
      cv::Mat grey;
      cv::cvtColor(image, grey, image.channels() == 3 ? cv::COLOR_BGR2GRAY : cv::COLOR_BGRA2GRAY);
      image = grey;
    }
    Result<FeatureResult> result = status.ok() ? Result<FeatureResult>(InvalidArgument("unset")) : status;
    if (status.ok()) {
      // One detector per image size (the undistortion map is per size).
      if (camera && cam_w > 0 && (cam_w != image.cols || cam_h != image.rows)) {
        // Before the detector is made: its undistortion map has the camera file's size.
        status = InvalidArgument(fmt::format("{}: the image is {} x {} px, the camera file {} is for {} x {} px",
                                             path,
                                             image.cols,
                                             image.rows,
                                             o.camera_file,
                                             cam_w,
                                             cam_h));
      } else if (!detector || image.cols != last_w || image.rows != last_h) {
        if (camera) {
          camera->width = cam_w > 0 ? cam_w : image.cols;
          camera->height = cam_h > 0 ? cam_h : image.rows;
        }
        // A detector this image cannot have (too small for it, a distortion that folds at its size) is
        // this image's error; the next image gets its own.
        Result<FeatureDetector> d = FeatureDetector::Create(options, camera);
        detector.reset();
        last_w = last_h = 0;
        if (!d.ok()) {
          status = d.status().WithContext(path);
        } else {
          detector.emplace(std::move(d).value());
          geometry = camera ? PixelGeometry(*camera) : PixelGeometry();
          last_w = image.cols;
          last_h = image.rows;
        }
      }
      if (status.ok()) {
        result = detector->Detect(image);
        if (!result.ok()) status = result.status().WithContext(path);
      }
    }
    if (!status.ok()) {
      ++failed;
      if (o.images.size() > 1) {
        spdlog::error("{}", status.message());  // the run's summary below names only the first
      }
      if (first_error.ok()) {
        first_error = status;
      }
      if (o.json) {
        std::cout << JsonLine(nlohmann::json({{"image", path}, {"error", status.message()}})) << "\n" << std::flush;
      }
      continue;
    }
    const FeatureResult& r = result.value();
    // What else failed for this image (the laser spot, the overlay) is its error, named in its JSON
    // line; the next images are still detected and reported.
    Status image_error = Status::Ok();
    std::optional<LaserSpotResult> spot;
    if (o.laser_spot) {
      Result<LaserSpotResult> found = FindLaserSpot(image);
      if (found.ok()) {
        spot = std::move(found).value();
      } else {
        image_error = found.status().WithContext(path + ": laser spot");
      }
    }
    if (!o.overlay_dir.empty()) {
      const Status written = WriteOverlay(overlays[i], path, image, r, geometry);
      if (!written.ok() && image_error.ok()) image_error = written;
    }
    if (!image_error.ok()) {
      ++failed;
      if (o.images.size() > 1) {
        spdlog::error("{}", image_error.message());  // the run's summary below names only the first
      }
      if (first_error.ok()) first_error = image_error;
    }
    if (o.json) {
      nlohmann::json j = ResultJson(path, r);
      if (spot) j["laser_spot"] = SpotJson(*spot);
      if (!image_error.ok()) j["error"] = image_error.message();
      std::cout << JsonLine(j) << "\n" << std::flush;
    } else {
      std::cout << fmt::format("{}: {} x {} px, {} lines, {} IDI points, {} curves, {:.2f} ms (noise {:.2f})\n",
                               path,
                               r.width,
                               r.height,
                               r.lines.size(),
                               r.points.size(),
                               r.curves.size(),
                               r.timing.total_ms,
                               r.noise_sigma);
      if (spot) {
        std::cout << fmt::format("  laser spot: {}", LaserSpotStatusName(spot->status));
        if (!spot->spots.empty()) {
          std::cout << fmt::format(" at ({:.3f}, {:.3f}) px, peak {:.0f} above {:.0f}, {} px",
                                   spot->spots[0].xy.x(),
                                   spot->spots[0].xy.y(),
                                   spot->spots[0].peak,
                                   spot->background,
                                   spot->spots[0].area_px);
        }
        if (!spot->message.empty()) std::cout << " (" << spot->message << ")";
        std::cout << "\n";
      }
    }
  }
  if (failed > 0 && o.images.size() > 1) {
    return Status(
        first_error.code(),
        fmt::format(
            "{} of {} images could not be processed (first: {})", failed, o.images.size(), first_error.message()));
  }
  return first_error;
}

}  // namespace

void AddFeaturesCommand(CliApp& cli) {
  auto o = std::make_shared<FeaturesCliOptions>();
  CLI::App* cmd = cli.AddCommand(
      &cli.app,
      "features",
      "EMPL lines and IDI points of grey images (chapter 7); one JSON object per image per line with --json",
      [o] { return RunFeatures(*o); });
  cmd->add_option("images", o->images, "image files (PNG, PGM, ...; 8- or 16-bit grey; colour is converted)")
      ->required();
  cmd->add_flag("--json",
                o->json,
                "print {image, width, height, time_ms, lines: [{id, p1, p2, normal, offset, length_px, fit_rms_px, "
                "...}], points: [{id, xy, lines, ...}], curves} per image");
  cmd->add_option(
      "--overlay", o->overlay_dir, "folder for <image>_features.png with lines, extensions and points drawn");
  cmd->add_option("--camera",
                  o->camera_file,
                  "intrinsics YAML (K: [9], distortion: [k1, k2, p1, p2, k3], optional width/height; or fx_px, "
                  "fy_px, cx_px, cy_px, k1.. keys): lines are fitted in undistorted pixel coordinates")
      ->check(CLI::ExistingFile);
  cmd->add_flag("--laser-spot",
                o->laser_spot,
                "also find the laser spot (a short-exposure image, §6.4.3): laser_spot: {status: found | no_spot | "
                "several_spots | saturated, spots: [{xy, covariance, peak, area_px, saturated_px}]}, in image pixels "
                "(not undistorted)");
}

}  // namespace idi::workcell
