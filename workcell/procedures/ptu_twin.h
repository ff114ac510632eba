// The digital twin of the pan-tilt camera calibration (chapter 6): the workcell twin's two arms on
// the rail (shared/sim/workcell; robot 1 carries Biclops, robot 2 the laser), two simulated PTU-D46
// (workcell/devices/ptu), and the Biclops cameras as built (calib::SamplePtuTruth).
//
// The spot is where robot 2's true laser line meets the true wall. A camera sees it either
//  - geometrically: the true projection (eqs. 3.10-3.14, 6.2) plus Gaussian pixel noise, or
//  - in an image: the renderer (shared/sim/render) draws the walls and the spot into a short-exposure
//    8-bit frame with optics and sensor noise, and the procedure finds the spot in it with the feature
//    detector, exactly as with a real camera (hal::CameraDevice).
// Robot 1's model for the TCF poses is its truth: the arm counts as calibrated (`calibrate robot`
// reaches ~1e-4 mm), so the PTU calibration is scored on its own. Ground truth is for tests and
// reports only.
#pragma once

#include <array>
#include <memory>
#include <random>

#include "shared/calib/ptu/ptu_simulation.h"
#include "shared/sim/render/render.h"
#include "shared/sim/workcell/workcell_twin.h"
#include "workcell/devices/ptu/ptu_sim.h"
#include "workcell/procedures/ptu_procedure.h"

namespace idi::workcell {

enum class PtuSpotMode { kGeometric, kImage };

struct PtuTwinOptions {
  unsigned seed = 1;
  sim::WorkcellTwinOptions cell = DefaultCell();
  calib::PtuTruthOptions truth;
  PtuSpotMode mode = PtuSpotMode::kGeometric;
  double spot_noise_px = 0.2;  // geometric mode: per axis
  // Where robot 2 aims (§6.4.4 step 1): on this wall, at robot 1's x (along the rail) and height z.
  int wall = 1;                // the "right" wall, on robot 1's -y side like Table 6.1's points
  Vec2d target_x_z_mm = Vec2d(600, 1300);
  // Image mode: the spot on the wall, and a short exposure that leaves the wall dark.
  double spot_sigma_mm = 2.0;
  double spot_peak = 60.0;     // relative radiance at the spot's centre
  double exposure_dn = 20.0;
  sim::RenderOptions render = DefaultRender();
  LaserSpotOptions detector;
  // Faults, for tests: the n-th image taken (0-based, both cameras counted) also shows a reflection of
  // the spot, or has none.
  int second_spot_image = -1;
  int missing_spot_image = -1;

  static sim::WorkcellTwinOptions DefaultCell() {
    sim::WorkcellTwinOptions c;
    c.wall_distance_min_mm = 2300;  // Table 6.1's points are 2.1-3.2 m from the arm's base
    c.wall_distance_max_mm = 3200;
    return c;
  }
  static sim::RenderOptions DefaultRender() {
    sim::RenderOptions r;
    r.psf_sigma_px = 0.8;
    return r;
  }
  Status Check() const;
};

// The Biclops cameras as built in the twin of `seed` (left, right): the same cameras for every twin of
// that seed (the pan-tilt calibration's and the scan cell's), like one physical head.
std::array<calib::PtuCameraModel, 2> SampleHeadTruth(unsigned seed, const calib::PtuTruthOptions& options);

class PtuTwin {
 public:
  explicit PtuTwin(const PtuTwinOptions& options);
  ~PtuTwin();
  PtuTwin(const PtuTwin&) = delete;
  PtuTwin& operator=(const PtuTwin&) = delete;

  // Step 1 of §6.4.4: robot 2 aims its laser at the target with its as-designed model and the nominal
  // cell setup, so the spot lands near, not on, the target: an arbitrary, unknown point.
  Status AimLaser();
  PtuDevices Devices();

  // What the procedure may use: robot 1's calibrated model, and where the spot roughly is (the aimed
  // target, carried into robot 1's base frame with the nominal setup).
  const ParamSet& arm_model() const { return cell_.true_robot(0); }
  Vec3d approx_point_in_base() const { return approx_point_; }

  // Ground truth.
  const calib::PtuCameraModel& true_camera(BiclopsSide side) const;
  std::optional<Vec3d> true_point_in_base() const;
  sim::WorkcellTwin& cell() { return cell_; }
  int images_taken() const { return images_; }

 private:
  class Camera;
  // The TCF pose of robot 1 now (true joints, true model) and the PTUs' true angles.
  TcfPose TrueTcf() const;
  std::array<double, 2> TrueAngles(BiclopsSide side);
  Result<std::vector<Vec2d>> ObserveGeometric(BiclopsSide side);
  Result<cv::Mat> Render(BiclopsSide side, double exposure_scale);  // scale: exposure / nominal

  PtuTwinOptions options_;
  sim::WorkcellTwin cell_;
  std::array<std::unique_ptr<SimPanTilt>, 2> ptu_;
  std::array<std::unique_ptr<Camera>, 2> cameras_;
  std::array<calib::PtuCameraModel, 2> truth_;
  std::mt19937_64 noise_rng_;
  Vec3d approx_point_ = Vec3d::Zero();
  int images_ = 0;
};

}  // namespace idi::workcell
