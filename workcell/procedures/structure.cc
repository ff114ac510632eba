#include "workcell/procedures/structure.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <thread>
#include <utility>

#include "shared/reconstruction/features_adapter.h"
#include "shared/reconstruction/triangulation.h"

namespace idi::workcell {
namespace {

double MsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

// Undistorted pixel -> the raw (distorted) pixel the camera would record.
Vec2d Redistort(const CameraModel& c, const Vec2d& undistorted) {
  const Vec3d p((undistorted.x() - c.cx()) / c.fx(), (undistorted.y() - c.cy()) / c.fy(), 1.0);
  return ProjectToPixel(c.params.data(), p);
}

bool InsideRoi(const cv::Mat& roi, const Vec2d& px) {
  const int x = static_cast<int>(std::lround(px.x())), y = static_cast<int>(std::lround(px.y()));
  return x >= 0 && y >= 0 && x < roi.cols && y < roi.rows && roi.at<uint8_t>(y, x) != 0;
}

// Keeps the IDI points inside the region and the lines that reach into it (a point of the segment, its
// ends and 9 stations between, inside), with the indices renumbered.
AdaptedFeatures KeepInsideRoi(const AdaptedFeatures& in, const cv::Mat& roi, const CameraModel& camera) {
  AdaptedFeatures out;
  std::vector<int> line_map(in.features.lines.size(), -1), point_map(in.features.points.size(), -1);
  for (std::size_t l = 0; l < in.features.lines.size(); ++l) {
    const ViewLine& vl = in.features.lines[l];
    bool inside = false;
    for (int k = 0; k <= 10 && !inside; ++k) {
      inside = InsideRoi(roi, Redistort(camera, vl.end1 + (vl.end2 - vl.end1) * (k / 10.0)));
    }
    if (!inside) continue;
    line_map[l] = static_cast<int>(out.features.lines.size());
    out.features.lines.push_back(vl);
    out.line_sigma_px.push_back(in.line_sigma_px[l]);
  }
  for (std::size_t i = 0; i < in.features.points.size(); ++i) {
    const ViewPoint& vp = in.features.points[i];
    if (!InsideRoi(roi, Redistort(camera, vp.xy))) continue;
    ViewPoint kept = vp;
    kept.lines.clear();
    for (int l : vp.lines) {
      if (line_map[static_cast<std::size_t>(l)] >= 0) kept.lines.push_back(line_map[static_cast<std::size_t>(l)]);
    }
    point_map[i] = static_cast<int>(out.features.points.size());
    out.features.points.push_back(std::move(kept));
  }
  for (ViewLine& vl : out.features.lines) {
    std::vector<int> pts;
    for (int i : vl.points) {
      if (point_map[static_cast<std::size_t>(i)] >= 0) pts.push_back(point_map[static_cast<std::size_t>(i)]);
    }
    vl.points = std::move(pts);
  }
  return out;
}

}  // namespace

Result<StructureResult> ReconstructStructure(const std::vector<StructureView>& views, const StructureOptions& options) {
  const auto t_start = std::chrono::steady_clock::now();
  if (views.size() < 2) {
    return InvalidArgument("reconstruction needs at least two views, got " + std::to_string(views.size()));
  }
  IDI_RETURN_IF_ERROR(options.model.Check());
  for (std::size_t v = 0; v < views.size(); ++v) {
    const StructureView& sv = views[v];
    const std::string who = "view " + std::to_string(v) + (sv.name.empty() ? "" : " (" + sv.name + ")");
    if (sv.image.empty()) return InvalidArgument(who + ": empty image");
    if (sv.image.cols != sv.camera.width || sv.image.rows != sv.camera.height) {
      return InvalidArgument(who + ": image is " + std::to_string(sv.image.cols) + "x" + std::to_string(sv.image.rows) +
                             " but the camera is " + std::to_string(sv.camera.width) + "x" +
                             std::to_string(sv.camera.height));
    }
    if (!sv.cam_from_world.rotation.allFinite() || !sv.cam_from_world.translation.allFinite()) {
      return InvalidArgument(who + ": pose is not finite");
    }
    if (!sv.roi.empty() && (sv.roi.type() != CV_8UC1 || sv.roi.size() != sv.image.size())) {
      return InvalidArgument(who + ": the region of interest must be an 8-bit mask of the image's size");
    }
    const double det = sv.cam_from_world.rotation.determinant();
    if (std::abs(det - 1.0) > 1e-6 ||
        (sv.cam_from_world.rotation * sv.cam_from_world.rotation.transpose() - Mat3d::Identity()).norm() > 1e-6) {
      return InvalidArgument(who + ": cam_from_world's rotation is not a rotation (inconsistent projection matrix)");
    }
  }
  if (!(options.adjusted_outlier_z >= 0 && std::isfinite(options.adjusted_outlier_z)) ||
      !(options.adjusted_sigma_floor_px >= 0 && std::isfinite(options.adjusted_sigma_floor_px))) {
    return InvalidArgument("reconstruction: adjusted_outlier_z and adjusted_sigma_floor_px must be finite and >= 0");
  }
  if (options.support && !(options.support_snap_mm >= 0 && std::isfinite(options.support_snap_mm))) {
    return InvalidArgument("reconstruction: support_snap_mm must be finite and >= 0");
  }
  StructureResult out;
  std::vector<AdaptedFeatures> adapted;
  auto t0 = std::chrono::steady_clock::now();
  {
    // The views' features are independent: one worker per core (the vision front end is pure).
    std::vector<std::optional<Result<FeatureResult>>> found(views.size());
    std::atomic<std::size_t> next{0};
    auto work = [&] {
      for (std::size_t v = next++; v < views.size(); v = next++) {
        cv::Mat gray = views[v].image;
        if (gray.channels() == 3) cv::cvtColor(views[v].image, gray, cv::COLOR_BGR2GRAY);
        found[v] = DetectFeatures(gray, options.features, std::optional<CameraModel>(views[v].camera));
      }
    };
    const std::size_t workers =
        std::min<std::size_t>(views.size(), std::max(1u, std::min(8u, std::thread::hardware_concurrency())));
    std::vector<std::thread> pool;
    for (std::size_t w = 1; w < workers; ++w) pool.emplace_back(work);
    work();
    for (std::thread& t : pool) t.join();
    for (std::size_t v = 0; v < views.size(); ++v) {
      if (!found[v]->ok()) {
        return found[v]->status().WithContext("view " + std::to_string(v) + " (" + views[v].name + ")");
      }
      const FeatureResult& f = **found[v];
      adapted.push_back(views[v].roi.empty() ? FromFeatureResult(f) : KeepInsideRoi(FromFeatureResult(f), views[v].roi, views[v].camera));
      out.features.push_back(f);
    }
  }
  out.features_ms = MsSince(t0);
  t0 = std::chrono::steady_clock::now();
  std::vector<CorrespondenceView> cviews;
  for (std::size_t v = 0; v < views.size(); ++v) {
    cviews.push_back({&adapted[v].features, &views[v].camera, views[v].cam_from_world});
  }
  IDI_ASSIGN_OR_RETURN(out.correspondences, MatchViews(cviews, options.correspondence));
  out.model = BuildModel(out.correspondences, cviews, options.model);
  out.correspondence_ms = MsSince(t0);
  if (options.adjust && !out.model.points.empty()) {
    t0 = std::chrono::steady_clock::now();
    std::vector<Vec3d> xyz;
    for (const ModelPoint& p : out.model.points) xyz.push_back(p.xyz);
    std::vector<optim::BaView> ba_views;
    // One intrinsics group per physical camera (views with identical intrinsics): the left and right
    // cameras of a stereo head must not share one set of parameters.
    std::vector<std::vector<double>> groups;
    for (const StructureView& sv : views) {
      const std::vector<double> k(sv.camera.params.begin(), sv.camera.params.end());
      auto it = std::find(groups.begin(), groups.end(), k);
      if (it == groups.end()) it = groups.insert(groups.end(), k);
      ba_views.push_back(
          {sv.camera, sv.cam_from_world, static_cast<int>(it - groups.begin()), sv.mount, sv.mount_axis});
    }
    // The observations of the model as it stands: its points' IDI points, and its edges' EMPL lines.
    std::vector<optim::BaPointObservation> obs;
    std::vector<optim::BaLineObservation> line_obs;
    auto collect = [&] {
      obs.clear();
      line_obs.clear();
      for (std::size_t i = 0; i < out.model.points.size(); ++i) {
        for (const Observation& o : out.model.points[i].observations) {
          const ViewPoint& vp =
              adapted[static_cast<std::size_t>(o.view)].features.points[static_cast<std::size_t>(o.index)];
          obs.push_back({static_cast<int>(i),
                         o.view,
                         Redistort(views[static_cast<std::size_t>(o.view)].camera, vp.xy),
                         std::max(vp.sigma_px, 0.02)});
        }
      }
      // Each model edge lies on an EMPL line in the views that see both its ends on one line.
      for (const auto& [a, b] : out.model.edges) {
        for (const Observation& oa : out.model.points[static_cast<std::size_t>(a)].observations) {
          for (const Observation& ob : out.model.points[static_cast<std::size_t>(b)].observations) {
            if (oa.view != ob.view) continue;
            const ViewFeatures& f = adapted[static_cast<std::size_t>(oa.view)].features;
            for (const int la : f.points[static_cast<std::size_t>(oa.index)].lines) {
              for (const int lb : f.points[static_cast<std::size_t>(ob.index)].lines) {
                if (la != lb) continue;
                const double sigma = std::max(
                    adapted[static_cast<std::size_t>(oa.view)].line_sigma_px[static_cast<std::size_t>(la)], 0.01);
                line_obs.push_back({a, oa.view, f.lines[static_cast<std::size_t>(la)].line, sigma});
                line_obs.push_back({b, oa.view, f.lines[static_cast<std::size_t>(la)].line, sigma});
              }
            }
          }
        }
      }
    };
    collect();
    std::vector<optim::BaPlane> planes;
    if (options.support) {
      optim::BaPlane plane = *options.support;
      plane.points.clear();
      for (std::size_t i = 0; i < xyz.size(); ++i) {
        if (std::abs(plane.normal.dot(xyz[i]) - plane.offset) <= options.support_snap_mm) {
          plane.points.push_back(static_cast<int>(i));
        }
      }
      out.on_support = plane.points;
      if (!plane.points.empty()) planes.push_back(std::move(plane));
    }
    const std::vector<Vec3d> xyz_before = xyz;
    const std::vector<optim::BaView> views_before = ba_views;
    IDI_ASSIGN_OR_RETURN(out.adjustment,
                         optim::BundleAdjust(&xyz, &ba_views, obs, line_obs, options.bundle_adjustment, planes));
    // With the views adjusted (the rail's stops estimated), an observation that disagrees with the rest of
    // its point by their own sigmas shows: a point of four or more views whose observations fail the
    // chi-square test (sigmas widened by adjusted_sigma_floor_px) loses the one without which the rest
    // agree best, and the adjustment runs again from the start. With three views, any two of them agree,
    // so which one is wrong cannot be told (leaving one out made a bracket corner 1 mm worse).
    if (options.adjusted_outlier_z > 0) {
      int dropped = 0;
      for (std::size_t i = 0; i < out.model.points.size(); ++i) {
        std::vector<Observation>& po = out.model.points[i].observations;
        if (po.size() < 4) continue;
        std::vector<PointObservation> rays;
        for (const Observation& o : po) {
          const auto v = static_cast<std::size_t>(o.view);
          const ViewPoint& vp = adapted[v].features.points[static_cast<std::size_t>(o.index)];
          rays.push_back({&views[v].camera,
                          ba_views[v].cam_from_world,
                          Redistort(views[v].camera, vp.xy),
                          std::hypot(std::max(vp.sigma_px, 0.02), options.adjusted_sigma_floor_px)});
        }
        const auto all = TriangulatePoint(rays);
        if (!all || ChiSquareConsistent(*all, rays.size(), options.adjusted_outlier_z)) continue;
        const std::optional<LeftOut> left = LeaveOneOut(rays);
        if (!left) continue;
        po.erase(po.begin() + static_cast<std::ptrdiff_t>(left->index));
        ++dropped;
      }
      if (dropped > 0) {
        out.adjusted_observations_dropped = dropped;
        xyz = xyz_before;
        ba_views = views_before;
        collect();
        IDI_ASSIGN_OR_RETURN(out.adjustment,
                             optim::BundleAdjust(&xyz, &ba_views, obs, line_obs, options.bundle_adjustment, planes));
      }
    }
    for (std::size_t i = 0; i < xyz.size(); ++i) {
      out.model.points[i].xyz = xyz[i];
      out.model.points[i].reprojection_rms_px = out.adjustment.point_rms_px[i];
    }
    out.adjusted_cam_from_world.clear();
    for (const optim::BaView& bv : ba_views) out.adjusted_cam_from_world.push_back(bv.cam_from_world);
    out.adjustment_ms = MsSince(t0);
  }
  if (out.adjusted_cam_from_world.empty()) {
    for (const StructureView& sv : views) out.adjusted_cam_from_world.push_back(sv.cam_from_world);
  }
  // Handed over once nothing refers to them any more (cviews and the adjustment's observations do).
  for (AdaptedFeatures& a : adapted) out.matched_features.push_back(std::move(a.features));
  out.total_ms = MsSince(t_start);
  return out;
}

cv::Mat DrawModelOverlay(const StructureView& view, const StructureModel& model, const FeatureResult* features) {
  cv::Mat canvas;
  if (view.image.channels() == 1) {
    cv::cvtColor(view.image, canvas, cv::COLOR_GRAY2BGR);
  } else {
    canvas = view.image.clone();
  }
  auto to_cv = [](const Vec2d& p) { return cv::Point2d(p.x(), p.y()); };
  if (features != nullptr) {
    for (const EmplLine& l : features->lines) {
      cv::line(canvas, to_cv(l.p1), to_cv(l.p2), cv::Scalar(160, 160, 0), 1, cv::LINE_AA);
    }
  }
  std::vector<std::optional<Vec2d>> px;
  for (const ModelPoint& p : model.points) px.push_back(Project(view.camera, view.cam_from_world * p.xyz));
  for (const auto& [a, b] : model.edges) {
    if (px[static_cast<std::size_t>(a)] && px[static_cast<std::size_t>(b)]) {
      cv::line(canvas, to_cv(*px[static_cast<std::size_t>(a)]), to_cv(*px[static_cast<std::size_t>(b)]),
               cv::Scalar(0, 255, 0), 1, cv::LINE_AA);
    }
  }
  for (std::size_t i = 0; i < px.size(); ++i) {
    if (!px[i]) continue;
    cv::circle(canvas, to_cv(*px[i]), 3, cv::Scalar(0, 0, 255), 1, cv::LINE_AA);
    cv::putText(canvas, std::to_string(model.points[i].id), to_cv(*px[i] + Vec2d(4, -4)), cv::FONT_HERSHEY_SIMPLEX, 0.35,
                cv::Scalar(0, 0, 255), 1, cv::LINE_AA);
  }
  return canvas;
}

nlohmann::json StructureModelJson(const StructureModel& model) {
  nlohmann::json out;
  out["points"] = nlohmann::json::array();
  for (const ModelPoint& p : model.points) {
    nlohmann::json vs = nlohmann::json::array();
    for (const Observation& ob : p.observations) vs.push_back(ob.view);
    out["points"].push_back(
        {{"id", p.id}, {"xyz_mm", {p.xyz.x(), p.xyz.y(), p.xyz.z()}}, {"views", vs}, {"reproj_rms_px", p.reprojection_rms_px}});
  }
  out["edges"] = nlohmann::json::array();
  for (const auto& [a, b] : model.edges) out["edges"].push_back({a, b});
  return out;
}

}  // namespace idi::workcell
