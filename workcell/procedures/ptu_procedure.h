// The operator procedure of the pan-tilt camera calibration (§6.4.4): with the laser of the other arm
// on an arbitrary point, move the arm carrying Biclops and both PTUs through planned poses, take a
// short-exposure image per camera, find the spot, record the TCF pose (eq. 3.10), the PTU readings and
// the spot's pixel; then calibrate (shared/calib/ptu) and validate on held-out poses. Devices come
// through hal, so the same code runs the real cell, the digital twin and a replay.
//
// Two passes, because the spot's position is only roughly known and the as-designed model misplaces
// it by tens of pixels: a survey of poses that keep the spot near the image centre (misses expected
// and skipped) gives a preliminary calibration; with it the full plan puts the spot anywhere in the
// image, every axis over its range (§6.4.4 step 2). In that pass a missing spot is an error, as is a
// second spot in any image (§6.4.3 assumes the laser spot is the only bright light).
#pragma once

#include <array>
#include <chrono>
#include <functional>
#include <string>
#include <vector>

#include "shared/calib/ptu/ptu_calibration.h"
#include "shared/calib/ptu/ptu_planning.h"
#include "shared/features/laser_spot.h"
#include "shared/hal/arm.h"
#include "shared/hal/camera.h"
#include "shared/hal/pan_tilt.h"

namespace idi::workcell {

// Spots found in the current image of one camera (empty: none).
using PtuSpotObserver = std::function<Result<std::vector<Vec2d>>(BiclopsSide)>;

struct PtuDevices {
  hal::ArmDevice* arm = nullptr;                     // the arm carrying Biclops
  std::array<hal::PanTiltDevice*, 2> ptu{};          // left, right
  PtuSpotObserver observe;
};

// The observer for cameras: grab a frame from camera `side` (0 left, 1 right) and find the laser spot
// (shared/features/laser_spot.h). A saturated bloom shortens that camera's exposure (halved, from
// `start_exposure_us`, at most `max_halvings` times; §6.4.3) and the frame is taken again; a bloom
// that remains, or a camera without exposure control, is an error naming the camera.
PtuSpotObserver CameraSpotObserver(std::array<hal::CameraDevice*, 2> cameras, const LaserSpotOptions& options = {},
                                   std::chrono::milliseconds timeout = std::chrono::milliseconds(2000),
                                   double start_exposure_us = 1000.0, int max_halvings = 5);

// Step 1 of §6.4.4: aims the laser arm at `target_in_base` (that arm's base frame, mm) with its model,
// from its current joints, and switches the laser on.
Status AimLaserArm(hal::ArmDevice& arm, hal::LaserDevice& laser, const ParamSet& robot, const ParamSet& laser_model,
                   const Vec3d& target_in_base, const hal::MoveOptions& move = {});

struct PtuProcedureOptions {
  ParamSet robot = Rx130Nominal();  // the Biclops arm's (calibrated) model: TCF poses from joint readings
  JointLimits limits = Rx130JointLimits();
  std::array<calib::PtuCameraModel, 2> start = {calib::PtuCameraModel::Nominal(BiclopsSide::kLeft),
                                                calib::PtuCameraModel::Nominal(BiclopsSide::kRight)};
  Vec3d approx_point_mm = Vec3d::Zero();  // where the spot roughly is, in the Biclops arm's base frame
  int survey_poses = 30;
  int survey_candidates = 90;
  double survey_margin_px = 130;
  calib::PtuPlanOptions plan;             // the calibration pass (60 poses) and the held-out poses
  calib::PtuCalibrationOptions calibration;
  hal::MoveOptions move;
  std::chrono::milliseconds ptu_timeout{20'000};
  uint64_t seed = 1;
  std::function<bool()> cancelled;  // polled between poses; true stops with Cancelled
  Status Check() const;
};

struct PtuProcedureResult {
  calib::PtuPlan survey_plan;
  std::vector<calib::PtuObservation> survey;  // images where the spot was seen
  int survey_missed = 0;                      // survey images without the spot
  calib::PtuCalibrationResult preliminary;
  calib::PtuPlan plan;
  std::vector<calib::PtuObservation> calibration;
  std::vector<calib::PtuObservation> validation;
  calib::PtuCalibrationResult result;
  calib::PtuValidation validation_errors;
  std::string Summary() const;
};

Result<PtuProcedureResult> RunPtuCalibrationProcedure(PtuDevices& devices, const PtuProcedureOptions& options);

}  // namespace idi::workcell
