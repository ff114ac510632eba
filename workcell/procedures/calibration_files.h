// Files of the ViCKi calibrations (DESIGN.md §6): observation CSVs, result YAMLs, JSON reports.
//
// Robot observations: `set,j1_deg,j2_deg,j3_deg,j4_deg,j5_deg,j6_deg` (set 1 or 2).
// Rail observations: `r1_j1_deg..r1_j6_deg,r1_rail_mm,r2_j1_deg..r2_j6_deg,r2_rail_mm`.
// Robot result: every parameter as the tables name it with its unit, {value, std}; point_x_mm ..
// point_z_mm, phi_l_deg, phi_m_deg; `statistics` with the residuals. Rail result: psi_x_mm, psi_y_mm,
// psi_z_mm, psi_alpha_deg with std. Written atomically.
#pragma once

#include <nlohmann/json_fwd.hpp>
#include <optional>
#include <string>
#include <vector>

#include "shared/calib/rail_calibration.h"
#include "shared/calib/robot_calibration.h"

namespace idi::workcell {

// The `model` of the result files (a loader refuses a file of another model).
inline constexpr const char* kRobotCalibrationModel = "rx130-laser-vicki";
inline constexpr const char* kRailCalibrationModel = "robot-to-robot";

inline constexpr const char* kRobotCsvHeader = "set,j1_deg,j2_deg,j3_deg,j4_deg,j5_deg,j6_deg";
inline constexpr const char* kRailCsvHeader =
    "r1_j1_deg,r1_j2_deg,r1_j3_deg,r1_j4_deg,r1_j5_deg,r1_j6_deg,r1_rail_mm,"
    "r2_j1_deg,r2_j2_deg,r2_j3_deg,r2_j4_deg,r2_j5_deg,r2_j6_deg,r2_rail_mm";

// Readings with their CSV line numbers; errors name the file, the line and the column.
Result<std::vector<calib::AimReading>> ReadRobotObservations(const std::string& path);
Status WriteRobotObservations(const std::string& path, const std::vector<calib::AimReading>& readings);
Result<std::vector<calib::RailReading>> ReadRailObservations(const std::string& path);
Status WriteRailObservations(const std::string& path, const std::vector<calib::RailReading>& readings);

// `sim_seed`: the digital twin's seed when the readings came from it (written as sim_seed, so a rail
// calibration in the twin can refuse another twin's arm).
Status WriteRobotCalibration(const std::string& path,
                             const calib::RobotCalibrationResult& result,
                             const calib::RobotCalibrationData& data,
                             std::optional<unsigned> sim_seed = std::nullopt);
// The twin seed a robot calibration file records (nullopt: not made in the twin, or by an older version).
Result<std::optional<unsigned>> RobotCalibrationSimSeed(const std::string& path);
// An arm's model from a robot calibration file (robot, laser and rail direction).
Result<calib::ArmModel> LoadRobotCalibration(const std::string& path);
Status WriteRailCalibration(const std::string& path, const calib::RailCalibrationResult& result);
// psi of a rail calibration file (eq. 3.4's robot-to-robot transform).
Result<std::array<double, kRobotToRobotParamCount>> LoadRailCalibration(const std::string& path);

// {"alpha2_deg": {"value": .., "std": ..}, ...} in file units.
nlohmann::json ParamsJson(const ParamSet& set);
Status WriteJson(const std::string& path, const nlohmann::json& j);

}  // namespace idi::workcell
