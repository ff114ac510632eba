// ViCKi robot calibration (chapter 4): the 18 RX-130 and 4 laser parameters, the fixed point (3) and
// the direction of the known translation (phi_l, phi_m): 27 unknowns from joint readings only.
//
// Data: readings of set 1 aim the laser at a fixed point P; readings of set 2 aim it at P after the
// base moved by D along the rail (method "translate": the point is then P - D t(phi) in the base
// frame) or at a second point at a known distance D (method "two-points": P + D t(phi)), §4.3.
// Cost: eq. 4.2, each reading's (x/z, y/z) whitened by its expected noise (shared/optim/vicki_costs.h).
//
// Start: closed form (§4.5.4's closest point): with the nominal model, the point closest to all set-1
// laser lines and the one closest to all set-2 lines give P and t; the parameters start nominal. No
// random restarts: a restart (staged, then perturbed) is made only when the solve fails its checks,
// and counted. Outliers (a mis-aimed spot) are found with a robust first solve and a robust scale,
// reported and left out. Identifiability and standard deviations come from the Jacobian at the
// solution; the standard deviations include the known distance's own uncertainty (the model's only
// scale, §4.4.3).
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "shared/geometry/rigid3.h"
#include "shared/kinematics/rtu.h"
#include "shared/kinematics/rx130.h"
#include "shared/optim/covariance.h"
#include "shared/optim/least_squares.h"
#include "shared/util/param_set.h"
#include "shared/util/status.h"

namespace idi::calib {

enum class TranslationMethod { kTranslate, kTwoPoints };
const char* MethodName(TranslationMethod m);  // "translate" / "two-points"
Result<TranslationMethod> ParseMethod(const std::string& text);

struct AimReading {
  int set = 1;   // 1 or 2
  Joints q{};    // joint readings, radians (model convention)
  int row = 0;   // where it came from (CSV line), for messages; 0 if unknown
};

struct RobotCalibrationData {
  std::vector<AimReading> readings;
  double distance_mm = 1000.0;
  TranslationMethod method = TranslationMethod::kTranslate;
};

// The expected errors of a reading (used to weight eq. 4.2 and for the bound).
struct RobotNoiseModel {
  double spot_sigma_mm = 0.05;          // spot on the observation plane, per in-plane axis
  std::optional<Vec3d> plane_normal;    // observation plane normal in the base frame; none: normal to the beam
  bool encoder_rounding = true;         // joint readings uncertain by +-1/2 count (Table 4.2)
  // Std of the known distance D (§4.4.3): D is the difference of two rail moves, each landing within
  // 0.1 mm (std) of its command: sqrt(2) x 0.1 mm.
  double distance_sigma_mm = 0.1414;
  Status Check() const;
};

struct RobotCalibrationOptions {
  ParamSet initial_robot = Rx130Nominal();
  ParamSet initial_laser = LaserNominal();
  RobotNoiseModel noise;
  int min_readings_per_unknown = 5;   // §4.3.2: at least 5 x 27 = 135 readings
  int min_readings_per_set = 10;
  double outlier_sigmas = 5.0;        // a reading is an outlier beyond this many robust sigmas ...
  double outlier_floor_mm = 0.02;     // ... and if the point misses its laser line by more than this
  int max_outlier_rounds = 4;
  double max_rms_miss_mm = 2.0;       // a solution fitting worse than this is rejected (restart)
  int max_restarts = 3;
  unsigned restart_seed = 1;
  optim::SolverOptions solver;
  optim::IdentifiabilityOptions identifiability;
  Status Check() const;
};

inline constexpr int kRobotCalibrationUnknowns = kRx130ParamCount + kLaserParamCount + 3 + kRailParamCount;  // 27
// Names and units of the 27 unknowns in solver order: the Table 4.1 robot keys, theta_x, theta_y, px,
// py, point_x..point_z (mm), phi_l, phi_m (deg).
std::vector<ParamSpec> RobotCalibrationSpecs();

struct OutlierReading {
  int index = 0;       // into RobotCalibrationData::readings
  int set = 0;
  int row = 0;
  double miss_mm = 0;  // distance of the aimed point from the laser line
  double sigmas = 0;   // in robust standard deviations
};

struct ResidualStats {
  int readings = 0;
  double rms_normalized = 0;  // eq. 4.2: sqrt(mean (distance / length)^2)
  double rms_miss_mm = 0;     // distance of the point from the laser lines
  double max_miss_mm = 0;
  double median_miss_mm = 0;
  double variance_factor = 0; // sigma0^2 of the whitened residuals (about 1 when the noise model holds)
};

struct RobotCalibrationResult {
  ParamSet params;            // the 27 unknowns (RobotCalibrationSpecs) with standard deviations
  ParamSet robot, laser, rail;  // the same values split into the kinematic models (with std)
  Vec3d point_mm = Vec3d::Zero();
  optim::SolverSummary summary;            // of the final solve
  std::vector<double> cost_per_iteration;  // every solve of the run, in order (Fig. 4.9)
  std::vector<int> solve_starts;           // where each solve begins in cost_per_iteration; the first
                                           // solve of each start uses a robust (Cauchy) loss
  std::vector<std::string> solve_labels;   // beside solve_starts: which start and which kind of solve
  std::string start;                       // how the solve was started
  int restarts = 0;                        // restarts that were needed beyond the closed-form start
  std::vector<OutlierReading> outliers;
  ResidualStats residuals;
  optim::CovarianceReport identifiability;  // covariance without the distance term
  Eigen::MatrixXd covariance;               // with the distance term (used for the std)
  Eigen::VectorXd distance_sensitivity;     // d params / d D
  std::string Summary() const;
};

Result<RobotCalibrationResult> CalibrateRobot(const RobotCalibrationData& data, const RobotCalibrationOptions& options);

// The covariance of the 27 unknowns at given parameter values for the noise model (no a posteriori
// scaling): with the true values it is the Cramer-Rao bound of the data. Readings whose point is not
// in front of the laser are skipped.
Result<Eigen::MatrixXd> RobotCovarianceAt(const RobotCalibrationData& data, const ParamSet& params,
                                          const RobotNoiseModel& noise);

// The whitened Jacobian of each reading at `params`: rows 2i, 2i+1 for reading i, 27 columns (zero
// rows for readings whose point is not in front of the laser).
Result<Eigen::MatrixXd> RobotReadingJacobians(const RobotCalibrationData& data, const ParamSet& params,
                                              const RobotNoiseModel& noise);

// The 27-vector from models (robot, laser, point, phi) and back.
ParamSet PackRobotCalibration(const ParamSet& robot, const ParamSet& laser, const Vec3d& point, const ParamSet& rail);
// Offset of the aimed point of set 2: -D (translate) or +D (two points).
double SetTwoOffset(TranslationMethod method, double distance_mm);

}  // namespace idi::calib
