#include "shared/calib/ptu/ptu_simulation.h"

#include <cmath>

namespace idi::calib {

Status PtuTruthOptions::Check() const {
  const double v[] = {length_sigma_mm, angle_sigma_deg, tilt_zero_sigma_deg, focal_sigma_fraction, principal_sigma_px};
  for (double x : v) {
    if (!(x >= 0) || !std::isfinite(x)) return InvalidArgument("PtuTruthOptions: sigmas must be finite and >= 0");
  }
  if (!std::isfinite(k1) || !std::isfinite(k2)) return InvalidArgument("PtuTruthOptions: k1, k2 not finite");
  return Status::Ok();
}

PtuCameraModel SamplePtuTruth(BiclopsSide side, const PtuTruthOptions& o, std::mt19937_64& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  PtuCameraModel m = PtuCameraModel::Nominal(side);
  for (int k = 0; k < kPtuParamCount; ++k) {
    const std::size_t i = static_cast<std::size_t>(k);
    const bool angle = m.ptu.spec(i).unit == Unit::kDegree;
    const double sigma = k == kPtuTheta1 ? DegToRad(o.tilt_zero_sigma_deg)
                         : angle         ? DegToRad(o.angle_sigma_deg)
                                         : o.length_sigma_mm;
    m.ptu.set_value(i, m.ptu.value(i) + sigma * n(rng));
  }
  m.intrinsics.set_value(kFx, m.intrinsics.value(kFx) * (1 + o.focal_sigma_fraction * n(rng)));
  m.intrinsics.set_value(kFy, m.intrinsics.value(kFy) * (1 + o.focal_sigma_fraction * n(rng)));
  m.intrinsics.set_value(kCx, m.intrinsics.value(kCx) + o.principal_sigma_px * n(rng));
  m.intrinsics.set_value(kCy, m.intrinsics.value(kCy) + o.principal_sigma_px * n(rng));
  m.intrinsics.set_value(kK1, o.k1);
  m.intrinsics.set_value(kK2, o.k2);
  return m;
}

std::optional<Vec2d> SimulateSpotPixel(const PtuCameraModel& truth, const TcfPose& true_tcf, double pan_rad,
                                       double tilt_rad, const Vec3d& point_mm, double sigma_px, std::mt19937_64& rng) {
  const auto px = truth.Project(true_tcf, pan_rad, tilt_rad, point_mm);
  if (!px) return std::nullopt;
  std::normal_distribution<double> n(0.0, sigma_px > 0 ? sigma_px : 1.0);
  const Vec2d noisy = sigma_px > 0 ? Vec2d(px->x() + n(rng), px->y() + n(rng)) : *px;
  if (!truth.Camera().InImage(noisy)) return std::nullopt;
  return noisy;
}

Result<PtuSyntheticData> SimulatePtuDataset(const PtuSyntheticOptions& options) {
  IDI_RETURN_IF_ERROR(options.truth.Check());
  std::mt19937_64 rng(options.seed);
  PtuSyntheticData d;
  d.truth = {SamplePtuTruth(BiclopsSide::kLeft, options.truth, rng), SamplePtuTruth(BiclopsSide::kRight, options.truth, rng)};
  d.point_mm = options.point_mm;
  const std::array<PtuCameraModel, 2> nominal = {PtuCameraModel::Nominal(BiclopsSide::kLeft),
                                                 PtuCameraModel::Nominal(BiclopsSide::kRight)};
  PtuPlanOptions plan_options = options.plan;
  plan_options.seed = options.seed;
  IDI_ASSIGN_OR_RETURN(d.plan, PlanPtuAcquisition(Rx130Nominal(), Rx130JointLimits(), nominal,
                                                  options.point_mm + options.point_guess_error_mm, plan_options));
  auto observe = [&](const std::vector<PtuPlannedPose>& poses, std::vector<PtuObservation>* out) {
    for (const PtuPlannedPose& p : poses) {
      for (std::size_t cam = 0; cam < 2; ++cam) {
        const auto px = SimulateSpotPixel(d.truth[cam], p.tcf, p.pan_rad[cam], p.tilt_rad[cam], d.point_mm,
                                          options.noise_px, rng);
        if (!px) continue;
        PtuObservation o;
        o.camera = d.truth[cam].side;
        o.tcf = p.tcf;
        o.pan_rad = p.pan_rad[cam];
        o.tilt_rad = p.tilt_rad[cam];
        o.pixel_px = *px;
        out->push_back(o);
      }
    }
  };
  observe(d.plan.calibration, &d.calibration);
  observe(d.plan.validation, &d.validation);
  return d;
}

}  // namespace idi::calib
