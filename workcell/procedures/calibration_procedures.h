// Operator procedures for the ViCKi calibrations (chapters 4 and 5): acquisition with the arms, the
// rail and the wall cameras (real devices or the digital twin, through hal), with progress on long
// runs. The solves themselves are shared/calib.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "shared/calib/acquisition.h"
#include "shared/calib/rail_calibration.h"
#include "shared/calib/robot_calibration.h"
#include "shared/hal/arm.h"

namespace idi::workcell {

// One arm's devices, and the cameras that see its spot (wall index -> spot on that wall, mm).
struct ArmDevices {
  hal::ArmDevice* arm = nullptr;
  hal::RailDevice* rail = nullptr;
  hal::LaserDevice* laser = nullptr;
  std::function<Result<Vec2d>(int wall)> observe;
};

// What the operator knows about the cell: approximate wall (observation plane) poses in robot 1's rail
// frame R1 (z the wall's normal, x, y the camera's metric coordinates) and the nominal robot-to-robot
// transform.
struct CellSetup {
  std::vector<std::string> wall_names;
  std::vector<Rigid3d> world_from_wall;
  std::array<double, 4> psi = calib::NominalPsi();
};

// Polled between readings of a long acquisition; true stops it with Cancelled (the operator's stop, a
// signal). Empty: never cancelled.
using CancelCheck = std::function<bool()>;
// Cancelled("what: cancelled") when `cancelled` is set and says so, else Ok.
Status CheckCancel(const CancelCheck& cancelled, const std::string& what);

// Logs "what: done/total (percent), elapsed, remaining" at most every few seconds or 10 %.
class ProgressLog {
 public:
  explicit ProgressLog(std::string what);
  void operator()(int done, int total);

 private:
  std::string what_;
  double start_s_;
  double last_s_ = -1e9;
  int last_percent_ = -100;
};

struct RobotAcquisitionOptions {
  calib::TranslationMethod method = calib::TranslationMethod::kTranslate;
  double distance_mm = 1000.0;      // rail move (translate) or spacing of the two points on the wall
  double rail_start_mm = 0.0;
  int per_set = 270;                // 540 readings in all (20 x 27, §4.5.3)
  double pool_factor = 4.0;         // candidates planned per reading kept (for the selection)
  bool a_optimal = true;            // after the first 54 D-optimal picks, A-optimal (file units)
  int held_out = 60;                // extra readings at one other point, for §4.5.4's evaluation
  // The observation wall; -1: the upright wall whose distance from the base is nearest
  // `preferred_wall_distance_mm` (§4.4.2: about 3 m is best for a camera observing the spot).
  int wall = -1;
  double preferred_wall_distance_mm = 3000.0;
  Vec2d target_offset_mm{200.0, 300.0};  // from the wall point nearest the base, in wall coordinates
  unsigned seed = 1;
  calib::PlanOptions plan;
  calib::AimLoopOptions loop;
  double max_failure_fraction = 0.1;
  CancelCheck cancelled;
  // Not null: where an acquisition that ends with an error (a device fault, the operator's stop, too
  // many misses) leaves what it had measured, readings and held-out readings, so that they can be
  // saved (an hour of arm motion on the real cell) instead of lost.
  struct RobotAcquisition* partial = nullptr;
  Status Check() const;
};

struct RobotAcquisition {
  calib::RobotCalibrationData data;
  std::vector<Joints> held_out;        // readings aimed at one held-out point
  int wall = 0;                                  // the wall observed
  Vec3d plane_normal_in_base = Vec3d::UnitZ();  // approximate, for the noise model
  Vec3d approx_point_in_base = Vec3d::Zero();
  std::array<Vec2d, 2> targets_on_wall{};  // the points aimed at (set 1, set 2), wall coordinates
  Vec2d held_out_target_on_wall = Vec2d::Zero();
  calib::SelectionResult selection;
  double mean_loop_iterations = 0;
  int loop_failures = 0;
  std::array<double, 2> rail_readings_mm = {0, 0};
};

// §4.3.3: plans configurations aimed at the point (set 1) and at the same point after the rail move of
// D, or at a second point D away on the wall (set 2); selects them for conditioning; drives each spot
// onto its point with the closed loop of §4.3.1; records the joint readings. `arm_index` 0 or 1 (its
// base pose in R1 uses the nominal psi for robot 2).
Result<RobotAcquisition> AcquireRobotData(ArmDevices& devices, int arm_index, const CellSetup& setup,
                                          const calib::ArmModel& model, const RobotAcquisitionOptions& options);

struct RailAcquisitionOptions {
  int readings = 500;
  std::vector<int> walls = {0, 1, 2};  // candidate walls for the shared points
  int points = 6;                      // shared points chosen among the candidates
  double rail_max_mm = 1500.0;
  unsigned seed = 1;
  calib::PlanOptions plan;
  calib::AimLoopOptions loop;
  double max_failure_fraction = 0.1;
  CancelCheck cancelled;
  // Not null: where an acquisition that ends with an error leaves the readings it had taken (see
  // RobotAcquisitionOptions::partial).
  struct RailAcquisition* partial = nullptr;
  Status Check() const;
};

struct RailAcquisition {
  std::vector<calib::RailReading> readings;
  std::vector<Vec3d> points_world;       // the shared points chosen (R1, approximate)
  std::vector<int> point_walls;
  double condition_number = 0;           // predicted 4x4 information, parameters scaled
  double condition_number_one_wall = 0;  // what points on the first wall alone would give
  int loop_failures = 0;
};

// §5.3.2: chooses shared points on the walls so that all four psi are observable (greedy D-optimal
// over candidate points, predicted with the arms' models), then for each reading moves both rails to
// random positions, aims robot 2's and robot 1's spots at the point with the closed loop, and records
// both arms' joint and rail readings.
Result<RailAcquisition> AcquireRailData(ArmDevices& arm1, ArmDevices& arm2, const CellSetup& setup,
                                        const calib::ArmModel& model1, const calib::ArmModel& model2,
                                        const RailAcquisitionOptions& options);

// R1 from robot k's base at a rail position, with the models' rail directions and psi.
Rigid3d NominalWorldFromBase(int arm_index, const calib::ArmModel& model, const CellSetup& setup, double rail_mm);

}  // namespace idi::workcell
