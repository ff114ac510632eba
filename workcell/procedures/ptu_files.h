// Files of the pan-tilt camera calibration (DESIGN.md §6): the observation CSV, the result YAML, the
// JSON report and the residual histograms (like Figs. 6.3-6.4).
//
// Result YAML (through shared/runtime/param_file.h, written atomically):
//   model: biclops-ptu
//   left:  {image_width_px, image_height_px, tx_mm: {value, std}, ..., d2_mm, fx_px, ..., k3}
//   right: {...}
//   point_x_mm: {value, std}   point_y_mm, point_z_mm   (robot base frame)
//   statistics: {...}
// Parameters held fixed (gauge, p1/p2/k3, k1/k2 without --distortion) carry no std.
#pragma once

#include <nlohmann/json_fwd.hpp>
#include <string>
#include <vector>

#include "shared/calib/ptu/ptu_calibration.h"

namespace idi::workcell {

// The `model` of the result file (LoadPtuCalibration refuses a file of another model).
inline constexpr const char* kPtuCalibrationModel = "biclops-ptu";

Result<std::vector<calib::PtuObservation>> ReadPtuObservations(const std::string& path);
Status WritePtuObservations(const std::string& path, const std::vector<calib::PtuObservation>& observations);

// `validation` may be null.
Status WritePtuCalibration(const std::string& path, const calib::PtuCalibrationResult& result,
                           const calib::PtuValidation* validation);
// The camera models of a result file (those present), e.g. as start values. A file whose `model` is not
// kPtuCalibrationModel is refused, naming the file and the line.
Result<std::vector<calib::PtuCameraModel>> LoadPtuCalibration(const std::string& path);

// {"point_mm": [x, y, z], "point_std_mm", "residual_rms_px", "validation_rms_px", "cameras": [...],
//  "gauge", "held_fixed", "correlated", "condition_number", "params": {"left": {...}, ...}, ...}
nlohmann::json PtuReportJson(const calib::PtuCalibrationResult& result, const calib::PtuValidation* validation);

// One PNG per camera in `dir`: histogram of the projection errors (pixel distance) of the calibration
// images, and of the held-out images when given.
Status SavePtuResidualHistograms(const std::string& dir, const calib::PtuCalibrationResult& result,
                                 const calib::PtuValidation* validation);

}  // namespace idi::workcell
