#include "workcell/procedures/ptu_procedure.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <memory>

#include "shared/kinematics/aiming.h"
#include "workcell/procedures/calibration_procedures.h"

namespace idi::workcell {
namespace {

constexpr std::array<BiclopsSide, 2> kPtuSides = {BiclopsSide::kLeft, BiclopsSide::kRight};

// Moves to one planned pose and records what both cameras see. `allow_missing`: a camera without the
// spot is skipped (survey) instead of failing.
Status AcquirePtuPose(PtuDevices& dev, const PtuProcedureOptions& o, const calib::PtuPlannedPose& pose,
                      const std::string& where, bool allow_missing, std::vector<calib::PtuObservation>* out,
                      int* missed) {
  IDI_RETURN_IF_ERROR(dev.arm->MoveJoints(pose.q, o.move).WithContext(where));
  IDI_ASSIGN_OR_RETURN(const hal::JointState js, dev.arm->ReadJoints());
  // The TCF pose from the joint readings and the arm's calibrated model (eq. 3.10).
  const TcfPose tcf = TcfPoseFromTransform(Rx130BaseFromFlange(o.robot.data(), js.q_rad.data()));
  for (std::size_t cam = 0; cam < 2; ++cam) {
    const BiclopsSide side = kPtuSides[cam];
    const std::string place = fmt::format("{}, {} camera", where, BiclopsSideName(side));
    IDI_RETURN_IF_ERROR(dev.ptu[cam]->MoveTo(pose.pan_rad[cam], pose.tilt_rad[cam], o.ptu_timeout).WithContext(place));
    IDI_ASSIGN_OR_RETURN(const hal::PanTiltState pt, dev.ptu[cam]->Read());
    auto spots = dev.observe(side);
    if (!spots.ok()) return spots.status().WithContext(place);
    if (spots->empty()) {
      if (allow_missing) {
        ++*missed;
        spdlog::debug("{}: no spot (expected near ({:.0f}, {:.0f}) px); pose skipped", place, pose.predicted_px[cam].x(),
                      pose.predicted_px[cam].y());
        continue;
      }
      return FailedPrecondition(fmt::format(
          "{}: the spot is missing (expected near ({:.1f}, {:.1f}) px); is the laser still on the point, or is the view "
          "blocked? Nothing was written",
          place, pose.predicted_px[cam].x(), pose.predicted_px[cam].y()));
    }
    if (spots->size() > 1) {
      std::vector<std::string> at;
      for (const Vec2d& s : *spots) at.push_back(fmt::format("({:.1f}, {:.1f})", s.x(), s.y()));
      return FailedPrecondition(fmt::format(
          "{}: {} spots in one image, at {} px: a reflection or a second bright source is in view, and the "
          "calibration needs exactly one spot (§6.4.3). Nothing was written",
          place, spots->size(), fmt::join(at, ", ")));
    }
    calib::PtuObservation ob;
    ob.camera = side;
    ob.tcf = tcf;
    ob.pan_rad = pt.pan_rad;
    ob.tilt_rad = pt.tilt_rad;
    ob.pixel_px = spots->front();
    out->push_back(ob);
  }
  return Status::Ok();
}

Status AcquirePtuPoses(PtuDevices& dev, const PtuProcedureOptions& o, const std::vector<calib::PtuPlannedPose>& poses,
                       const std::string& what, bool allow_missing, std::vector<calib::PtuObservation>* out,
                       int* missed) {
  ProgressLog progress(what);
  for (std::size_t i = 0; i < poses.size(); ++i) {
    IDI_RETURN_IF_ERROR(CheckCancel(o.cancelled, what));
    IDI_RETURN_IF_ERROR(AcquirePtuPose(dev, o, poses[i], fmt::format("{}: pose {} of {}", what, i + 1, poses.size()),
                                       allow_missing, out, missed));
    progress(static_cast<int>(i) + 1, static_cast<int>(poses.size()));
  }
  return Status::Ok();
}

}  // namespace

PtuSpotObserver CameraSpotObserver(std::array<hal::CameraDevice*, 2> cameras, const LaserSpotOptions& options,
                                   std::chrono::milliseconds timeout, double start_exposure_us, int max_halvings) {
  // The exposure each camera is at now (0: not set yet); shared by the copies of the observer.
  auto exposure_us = std::make_shared<std::array<double, 2>>(std::array<double, 2>{0.0, 0.0});
  return [cameras, options, timeout, start_exposure_us, max_halvings,
          exposure_us](BiclopsSide side) -> Result<std::vector<Vec2d>> {
    const std::size_t k = side == BiclopsSide::kLeft ? 0 : 1;
    hal::CameraDevice* cam = cameras[k];
    if (cam == nullptr) return InvalidArgument(std::string("no ") + BiclopsSideName(side) + " camera");
    for (int halvings = 0;; ++halvings) {
      IDI_ASSIGN_OR_RETURN(const hal::Image image, cam->Grab(timeout));
      auto found = FindLaserSpot(image.pixels, options);
      if (!found.ok()) return found.status().WithContext(cam->name() + ": frame " + std::to_string(image.sequence));
      std::vector<Vec2d> spots;
      switch (found->status) {
        case LaserSpotStatus::kNoSpot:
          return spots;
        case LaserSpotStatus::kFound:
          spots.push_back(found->spots.front().xy);
          return spots;
        case LaserSpotStatus::kSeveral:
          for (const LaserSpot& s : found->spots) spots.push_back(s.xy);
          return spots;
        case LaserSpotStatus::kSaturated:
          break;
      }
      const std::string bloom = cam->name() + ": the laser spot is a saturated bloom (" + found->message + ")";
      if (halvings >= max_halvings) {
        return DeviceError(bloom + " after " + std::to_string(halvings) + " shorter exposures (§6.4.3)");
      }
      double& e = (*exposure_us)[k];
      e = (e > 0 ? e : start_exposure_us) / 2;
      const Status set = cam->SetExposure(e);
      if (!set.ok()) return DeviceError(bloom + "; the exposure cannot be shortened: " + set.message());
      spdlog::info("{}: saturated laser spot, exposure shortened to {:.0f} us", cam->name(), e);
    }
  };
}

Status AimLaserArm(hal::ArmDevice& arm, hal::LaserDevice& laser, const ParamSet& robot, const ParamSet& laser_model,
                   const Vec3d& target_in_base, const hal::MoveOptions& move) {
  IDI_ASSIGN_OR_RETURN(const hal::JointState js, arm.ReadJoints());
  auto ik = AimLaserAt(robot, laser_model, js.q_rad, target_in_base, Rx130JointLimits());
  if (!ik.ok()) return ik.status().WithContext(arm.name() + ": aiming the laser at the calibration point");
  IDI_RETURN_IF_ERROR(arm.MoveJoints(ik->q, move).WithContext(arm.name() + ": aiming the laser"));
  return laser.SetOn(true);
}

Status PtuProcedureOptions::Check() const {
  if (robot.size() != kRx130ParamCount) return InvalidArgument("PTU procedure: the arm model has the wrong size");
  if (start[0].side != BiclopsSide::kLeft || start[1].side != BiclopsSide::kRight) {
    return InvalidArgument("PTU procedure: start models must be {left, right}");
  }
  if (!approx_point_mm.allFinite()) return InvalidArgument("PTU procedure: the approximate point is not finite");
  if (survey_poses < 10 || survey_candidates < survey_poses || !(survey_margin_px >= 0)) {
    return InvalidArgument("PTU procedure: need survey_poses >= 10 and survey_candidates >= survey_poses");
  }
  IDI_RETURN_IF_ERROR(plan.Check());
  // Each calibration pose gives each camera one observation at most: fewer poses than the solve needs
  // would fail only after the whole acquisition.
  if (plan.poses < calibration.min_observations_per_camera) {
    return InvalidArgument(
        fmt::format("PTU procedure: {} calibration poses, at least {} are needed (one observation "
                    "per camera each; §6.4.4 uses 60)",
                    plan.poses,
                    calibration.min_observations_per_camera));
  }
  return calibration.Check();
}

std::string PtuProcedureResult::Summary() const {
  std::string s = fmt::format("survey: {} spots seen, {} missed; preliminary point ({:.1f}, {:.1f}, {:.1f}) mm\n",
                              survey.size(), survey_missed, preliminary.point_mm.x(), preliminary.point_mm.y(),
                              preliminary.point_mm.z());
  s += plan.Summary() + "\n" + result.Summary();
  for (const auto& c : validation_errors.cameras) {
    s += fmt::format("\nvalidation {}: {} held-out images, RMS {:.3f} px per axis, mean {:.3f} px, max {:.3f} px",
                     BiclopsSideName(c.side), c.observations, c.rms_px, c.mean_error_px, c.max_error_px);
  }
  return s;
}

Result<PtuProcedureResult> RunPtuCalibrationProcedure(PtuDevices& dev, const PtuProcedureOptions& options) {
  IDI_RETURN_IF_ERROR(options.Check());
  if (dev.arm == nullptr || dev.ptu[0] == nullptr || dev.ptu[1] == nullptr || !dev.observe) {
    return InvalidArgument("PTU procedure: the arm, both PTUs and the spot cameras are all needed");
  }
  PtuProcedureOptions o = options;
  // The PTUs' own travel narrows the planning range.
  for (std::size_t cam = 0; cam < 2; ++cam) {
    IDI_ASSIGN_OR_RETURN(const hal::PanTiltLimits lim, dev.ptu[cam]->Limits());
    calib::PtuRange& r = o.plan.range;
    r.pan_min_rad = std::max(r.pan_min_rad, lim.pan_min_rad);
    r.pan_max_rad = std::min(r.pan_max_rad, lim.pan_max_rad);
    r.tilt_min_rad = std::max(r.tilt_min_rad, lim.tilt_min_rad);
    r.tilt_max_rad = std::min(r.tilt_max_rad, lim.tilt_max_rad);
  }
  IDI_RETURN_IF_ERROR(o.plan.range.Check().WithContext(dev.ptu[0]->name() + ", " + dev.ptu[1]->name()));
  PtuProcedureResult res;

  // Pass 1: survey around the approximate point, spot kept near the image centre.
  calib::PtuPlanOptions survey = o.plan;
  survey.poses = o.survey_poses;
  survey.validation_poses = 0;
  survey.candidates = o.survey_candidates;
  survey.margin_px = o.survey_margin_px;
  survey.seed = o.seed;
  IDI_ASSIGN_OR_RETURN(res.survey_plan, calib::PlanPtuAcquisition(o.robot, o.limits, o.start, o.approx_point_mm, survey));
  spdlog::info("PTU calibration survey: {}", res.survey_plan.Summary());
  IDI_RETURN_IF_ERROR(AcquirePtuPoses(dev, o, res.survey_plan.calibration, "PTU survey", true, &res.survey,
                                      &res.survey_missed));
  calib::PtuCalibrationOptions prelim_options = o.calibration;
  prelim_options.min_observations_per_camera = std::min(prelim_options.min_observations_per_camera, 15);
  prelim_options.source = "survey images";
  prelim_options.initial_point_mm = o.approx_point_mm;
  for (BiclopsSide side : kPtuSides) {
    const auto seen = static_cast<int>(calib::SelectCamera(res.survey, side).size());
    if (seen < prelim_options.min_observations_per_camera) {
      return FailedPrecondition(fmt::format(
          "PTU survey: the {} camera saw the spot in only {} of {} images; is the laser on, and is the approximate "
          "point ({:.0f}, {:.0f}, {:.0f}) mm right?",
          BiclopsSideName(side), seen, res.survey_plan.calibration.size(), o.approx_point_mm.x(), o.approx_point_mm.y(),
          o.approx_point_mm.z()));
    }
  }
  IDI_ASSIGN_OR_RETURN(res.preliminary,
                       calib::CalibratePtu(res.survey, {o.start[0], o.start[1]}, prelim_options));
  spdlog::info("PTU preliminary calibration from {} survey images: {}", res.survey.size(), res.preliminary.Summary());

  // Pass 2: the full plan with the preliminary model, then the held-out poses.
  const std::array<calib::PtuCameraModel, 2> prelim = {res.preliminary.Camera(BiclopsSide::kLeft)->model,
                                                       res.preliminary.Camera(BiclopsSide::kRight)->model};
  calib::PtuPlanOptions plan = o.plan;
  plan.seed = o.seed + 1;
  IDI_ASSIGN_OR_RETURN(res.plan, calib::PlanPtuAcquisition(o.robot, o.limits, prelim, res.preliminary.point_mm, plan));
  spdlog::info("PTU calibration plan: {}", res.plan.Summary());
  int missed = 0;
  IDI_RETURN_IF_ERROR(
      AcquirePtuPoses(dev, o, res.plan.calibration, "PTU calibration images", false, &res.calibration, &missed));
  IDI_RETURN_IF_ERROR(
      AcquirePtuPoses(dev, o, res.plan.validation, "PTU validation images", false, &res.validation, &missed));

  calib::PtuCalibrationOptions final_options = o.calibration;
  final_options.range = o.plan.range;
  final_options.source = "calibration images";
  IDI_ASSIGN_OR_RETURN(res.result, calib::CalibratePtu(res.calibration, {prelim[0], prelim[1]}, final_options));
  if (!res.validation.empty()) {
    IDI_ASSIGN_OR_RETURN(res.validation_errors,
                         calib::ValidatePtu(res.result, res.validation, final_options.range, "validation images"));
  }
  return res;
}

}  // namespace idi::workcell
