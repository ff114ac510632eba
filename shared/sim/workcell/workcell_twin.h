// The digital twin of the calibration cell: two RX-130 arms with laser tools on a rail (RTU), walls,
// and cameras that see the laser spots on the walls.
//
// Truth differs from nominal the way real robots do (Tables 4.3, 4.5, 4.6: tenths of a degree and of
// a millimetre, a laser tool misaligned by up to a degree), drawn from a seed. A commanded joint is
// realised at the nearest encoder count (Table 4.2) and read back as that count; a rail move lands
// within its repeatability of the commanded position and reads back the commanded position; the
// spot is where the true laser line meets a wall, seen by that wall's camera with noise. Calibration
// code sees only the hal devices, spot observations and the operator's approximate setup (Setup()).
//
// World frame = robot 1's rail frame R1 (x along the rail, eq. 3.3); robot 2's rail frame is placed by
// psi (eq. 3.5). Wall frames: z is the wall's normal (towards the robots), x and y are the camera's
// metric coordinates on the wall (mm).
#pragma once

#include <array>
#include <memory>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "shared/geometry/rigid3.h"
#include "shared/hal/arm.h"
#include "shared/hal/clock.h"
#include "shared/kinematics/rtu.h"
#include "shared/kinematics/rx130.h"
#include "shared/util/param_set.h"
#include "shared/util/status.h"

namespace idi::sim {

struct Wall {
  std::string name;
  Rigid3d world_from_wall;
  double half_width_mm = 5000;   // extent along the wall's x
  double half_height_mm = 3000;  // extent along the wall's y
};

enum class SpotNoise { kGaussian, kUniform };

struct WorkcellTwinOptions {
  unsigned seed = 1;
  // Truth: std of the deviations from nominal (Table 4.1) of every arm.
  double joint_offset_sigma_deg = 0.05;  // theta2..theta5
  double twist_sigma_deg = 0.03;         // alphas, beta3
  double length_sigma_mm = 0.5;          // a2, d2, a4, a5, d5, a6
  double arm_length_sigma_mm = 1.0;      // a3, d4
  double laser_angle_sigma_deg = 0.3;    // theta_x, theta_y
  double laser_offset_sigma_mm = 1.0;    // px, py
  double rail_angle_sigma_deg = 0.3;     // phi_l, phi_m
  std::array<double, 4> psi_sigma = {5.0, 3.0, 3.0, 0.02};  // mm, mm, mm, deg about NominalPsi
  // Room: a wall on each side of the rail at a distance drawn from [min, max], and the floor.
  double wall_distance_min_mm = 3000;
  double wall_distance_max_mm = 7000;
  double floor_height_mm = -1200;  // below the rail frame's origin
  // Sensors.
  double spot_sigma_mm = 0.05;           // camera noise per axis (kUniform: half width)
  SpotNoise spot_noise = SpotNoise::kGaussian;
  bool quantize_joints = true;           // Table 4.2 encoders
  double rail_repeatability_mm = 0.1;    // std of where a rail move lands
  double rail_length_mm = 2000;          // each arm's travel
  // What the operator's setup knows about the walls (errors of the approximate wall poses).
  double setup_wall_position_error_mm = 20;
  double setup_wall_angle_error_deg = 1.0;
  Status Check() const;
};

// What the operator knows before calibrating: nominal models, approximate wall poses.
struct WorkcellSetup {
  std::vector<Wall> walls;                   // approximate poses in the (nominal) world frame
  std::array<double, 4> psi = {5650, 0, 0, 0};  // nominal robot-to-robot transform
};

class WorkcellTwin {
 public:
  explicit WorkcellTwin(const WorkcellTwinOptions& options);
  ~WorkcellTwin();
  WorkcellTwin(const WorkcellTwin&) = delete;
  WorkcellTwin& operator=(const WorkcellTwin&) = delete;

  // Devices (arm 0 = robot 1, arm 1 = robot 2).
  hal::ArmDevice& arm(int k);
  hal::RailDevice& rail(int k);
  hal::LaserDevice& laser(int k);
  hal::SimClock& clock() { return clock_; }

  // The camera on `wall` reports arm k's spot in wall coordinates (mm) with noise. NotFound if the
  // laser is off, or its beam does not hit that wall within the wall's extent.
  Result<Vec2d> ObserveSpot(int arm, int wall);
  WorkcellSetup Setup() const;

  // Ground truth, for tests and reports only.
  const ParamSet& true_robot(int k) const;
  const ParamSet& true_laser(int k) const;
  const ParamSet& true_rail(int k) const;  // phi_l, phi_m
  const std::array<double, 4>& true_psi() const { return psi_; }
  const std::vector<Wall>& walls() const { return walls_; }
  // World (R1) from arm k's base at its true current rail position.
  Rigid3d WorldFromBase(int k) const;
  Joints true_joints(int k) const;
  double true_rail_position(int k) const;
  bool laser_on(int k) const;
  // The noise-free spot of arm k on `wall` (wall coordinates), if it hits.
  std::optional<Vec2d> TrueSpot(int arm, int wall) const;
  const WorkcellTwinOptions& options() const { return options_; }

 private:
  struct ArmState;
  friend class SimArm;
  friend class SimRail;
  friend class SimLaser;
  WorkcellTwinOptions options_;
  hal::SimClock clock_;
  std::mt19937_64 truth_rng_, spot_rng_, rail_rng_;
  std::array<std::unique_ptr<ArmState>, 2> arms_;
  std::array<double, 4> psi_{};
  std::vector<Wall> walls_;
  std::vector<Wall> setup_walls_;
};

}  // namespace idi::sim
