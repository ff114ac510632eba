// `idi-workcell scan` (issue 7): scan an object on the rotary table from views around it, reconstruct it
// (chapter 8), plan the Barrett grasp and pick and place it with the other arm. With --sim the cell is
// the digital twin of --seed; the calibration comes from files (the calibration folder: robot1.yaml,
// robot2.yaml, rail.yaml, ptu.yaml), and in the twin whatever is missing is calibrated first with the
// same procedures as `idi-workcell calibrate ... --sim` (it takes a minute or two).
#pragma once

#include <nlohmann/json.hpp>
#include <string>

#include "shared/runtime/cli.h"
#include "workcell/procedures/scan.h"

namespace idi::workcell {

struct CalibrationFiles {
  std::string robot1, robot2, rail, ptu;
};
// The calibration for a scan from its four files.
Result<ScanCalibration> LoadScanCalibration(const CalibrationFiles& files);
// The files in `dir` (robot1.yaml, robot2.yaml, rail.yaml, ptu.yaml); those missing are made in the twin
// of `seed` (procedures of `calibrate robot|rtu|ptu --sim`).
Result<CalibrationFiles> EnsureSimCalibration(const std::string& dir, unsigned seed);

struct SimScanOptions {
  unsigned seed = 1;
  std::string object = "box";  // box | prism | bracket | cylinder
  unsigned scene = 0;
  bool pick = true;
  std::string out;             // run folder: views, overlays, model.ply, report.json
  std::function<bool()> cancelled;
  std::function<void(double, const std::string&)> progress;
};
// One scan (and pick) in the twin with the given calibration; the report holds the procedure's results
// and, under "truth", the twin's ground-truth judgement (vertex errors, did the grasp hold).
Result<nlohmann::json> RunSimScan(const SimScanOptions& options, const ScanCalibration& calibration);

void AddScanCommand(CliApp& cli);

}  // namespace idi::workcell
