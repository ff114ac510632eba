// 3D structure from views (chapter 8): EMPL lines and IDI points in every image, automatic bundle
// correspondence across the views, triangulation, the model of points and edges, and bundle
// adjustment with point and line residuals. Used by `idi-workcell reconstruct` and the scan job.
#pragma once

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "shared/features/features.h"
#include "shared/optim/bundle_adjustment.h"
#include "shared/reconstruction/correspondence.h"
#include "shared/reconstruction/structure_model.h"

namespace idi::workcell {

struct StructureView {
  std::string name;
  cv::Mat image;            // 8-bit grey (colour is converted)
  CameraModel camera;       // intrinsics with distortion; width/height must match the image
  Rigid3d cam_from_world;   // from the calibrated chain (§8.3), mm
  // Optional region of interest (8-bit, the image's size; non-zero inside): IDI points outside it and
  // lines that do not reach into it are left out of the correspondence (e.g. the volume above the
  // rotary table, so the floor's tiles and the table's rim do not compete with the object's corners).
  cv::Mat roi;
  // Views taken from one placement of a mount (both cameras of the head at one rail stop): with
  // StructureOptions::bundle_adjustment.mount_prior_mm > 0 the adjustment estimates each mount's shift
  // along mount_axis (world frame, unit; the rail), which its encoder cannot see. -1: none.
  int mount = -1;
  Vec3d mount_axis = Vec3d::Zero();
};

struct StructureOptions {
  FeatureOptions features;
  CorrespondenceOptions correspondence;
  ModelOptions model;
  optim::BundleAdjustmentOptions bundle_adjustment;
  bool adjust = true;
  // The plane the objects stand on (world frame; its `points` are ignored): the model points that
  // triangulate within support_snap_mm of it are held on it in the adjustment, its offset estimated.
  std::optional<optim::BaPlane> support;
  double support_snap_mm = 2.0;
  // After the adjustment: a point's observations (four or more) must agree by their sigmas, widened by
  // adjusted_sigma_floor_px, at a chi-square test of adjusted_outlier_z standard deviations; else the
  // one without which the rest agree best is dropped and the adjustment runs again. 0: no test.
  double adjusted_outlier_z = 3.09;
  double adjusted_sigma_floor_px = 0.05;
};

struct StructureResult {
  StructureModel model;                    // after bundle adjustment
  std::vector<FeatureResult> features;     // per view (undistorted pixel coordinates)
  // What the correspondence saw in each view (the IDI points inside the view's roi and the lines reaching
  // into it, renumbered): the observations' indices in `correspondences` and `model` refer to these.
  std::vector<ViewFeatures> matched_features;
  Correspondences correspondences;
  optim::BundleAdjustmentSummary adjustment;
  std::vector<int> on_support;  // model points held on the support plane in the adjustment
  int adjusted_observations_dropped = 0;  // by the test after the adjustment (StructureOptions::adjusted_outlier_z)
  // Each view's cam_from_world after the adjustment (its mount's shift included; as given without one).
  std::vector<Rigid3d> adjusted_cam_from_world;
  double features_ms = 0, correspondence_ms = 0, adjustment_ms = 0, total_ms = 0;
};

// InvalidArgument for fewer than two views, an empty image, a camera that does not match its image,
// or a non-finite pose; views without features simply contribute nothing.
Result<StructureResult> ReconstructStructure(const std::vector<StructureView>& views, const StructureOptions& options);

// {points: [{id, xyz_mm, views, reproj_rms_px}], edges: [[a, b], ...]}
nlohmann::json StructureModelJson(const StructureModel& model);

// The model drawn back into a view (like Fig. 8.16): edges as lines, points as labelled circles.
cv::Mat DrawModelOverlay(const StructureView& view, const StructureModel& model, const FeatureResult* features);

}  // namespace idi::workcell
