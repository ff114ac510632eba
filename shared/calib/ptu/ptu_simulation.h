// Ground truth for the pan-tilt calibration's simulations (tests, the digital twin, the bench): a
// "built" Biclops camera whose parameters deviate from the as-designed ones the way Table 6.1's
// calibrated values deviate from the design (about a millimetre, a few tenths of a degree, the tilt
// zero by a degree or two, the principal point by tens of pixels), and the geometric observation of
// the spot (true projection plus Gaussian pixel noise) used until an image is rendered instead.
// Algorithms never see these values; they are for generating data and scoring results.
#pragma once

#include <cstdint>
#include <optional>
#include <random>

#include "shared/calib/ptu/ptu_calibration.h"
#include "shared/calib/ptu/ptu_planning.h"

namespace idi::calib {

struct PtuTruthOptions {
  double length_sigma_mm = 1.0;       // tx, ty, tz, a1, d1, a2, d2
  double angle_sigma_deg = 0.3;       // theta_x, theta_y, theta_z, alpha1, alpha2, theta2
  double tilt_zero_sigma_deg = 1.5;   // theta1 (Table 6.1: 86-88 deg against 90 designed)
  double focal_sigma_fraction = 0.01; // fx, fy
  double principal_sigma_px = 10;     // cx, cy
  double k1 = 0, k2 = 0;              // the lens' radial distortion (0: none)
  Status Check() const;
};

// A true camera model drawn around the as-designed one.
PtuCameraModel SamplePtuTruth(BiclopsSide side, const PtuTruthOptions& options, std::mt19937_64& rng);

// The spot's pixel in one image, geometrically: the true projection plus N(0, sigma_px) per axis.
// nullopt when the spot is behind the camera or off the image (a missing spot).
std::optional<Vec2d> SimulateSpotPixel(const PtuCameraModel& truth, const TcfPose& true_tcf, double pan_rad,
                                       double tilt_rad, const Vec3d& point_mm, double sigma_px, std::mt19937_64& rng);

// A whole synthetic data set without devices: true cameras drawn with SamplePtuTruth, poses planned
// with the as-designed model around a rough point (the true point plus point_guess_error_mm), and
// each planned image observed geometrically with the truth (arm poses exact). For unit tests and
// the solver benchmark; the digital twin (workcell/procedures) adds devices, encoders and images.
struct PtuSyntheticOptions {
  uint64_t seed = 1;
  double noise_px = 0.2;
  PtuTruthOptions truth;
  Vec3d point_mm = Vec3d(500, -3198, 1368);  // Table 6.1, trial I
  Vec3d point_guess_error_mm = Vec3d(30, -40, 20);
  PtuPlanOptions plan = DefaultSyntheticPlan();
  static PtuPlanOptions DefaultSyntheticPlan() {
    PtuPlanOptions p;
    p.margin_px = 80;  // the as-designed model predicts the spot within tens of pixels
    return p;
  }
};
struct PtuSyntheticData {
  std::array<PtuCameraModel, 2> truth;
  Vec3d point_mm = Vec3d::Zero();
  PtuPlan plan;
  std::vector<PtuObservation> calibration;  // spots that fell on the image
  std::vector<PtuObservation> validation;
};
Result<PtuSyntheticData> SimulatePtuDataset(const PtuSyntheticOptions& options);

}  // namespace idi::calib
