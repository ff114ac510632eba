// `idi-workcell calibrate ptu` (DESIGN.md §6): pan-tilt camera calibration from one unknown laser spot
// (chapter 6), from observation files or, with --sim, the whole procedure in the digital twin.
// Registered under the `calibrate` parent that `calibrate robot|rtu` use (created here if absent).
#pragma once

#include <functional>
#include <string>

#include "shared/runtime/cli.h"

namespace idi::workcell {

struct CalibratePtuOptions {
  std::string observations;  // CSV in; with --sim: where to save the acquired images' data
  std::string out;           // result YAML
  std::string validate;      // held-out CSV in; with --sim: where to save them
  std::string report;        // JSON report
  std::string plots;         // folder for the residual histograms
  std::string start;         // a previous result YAML as start values (default: as designed)
  bool json = false;         // print the report on stdout
  bool distortion = false;   // also estimate k1, k2
  double robust_scale_px = 1.0;
  // --sim
  bool sim = false;
  unsigned seed = 1;
  bool image = false;        // render the images and find the spot in them (default: geometric spots)
  double noise_px = 0.2;     // geometric spot noise per axis
  std::string lens_k1_k2;    // the twin lens' distortion "k1,k2"
  int poses = 60;
  int validation_poses = 60;
  std::function<bool()> cancelled;  // --sim: polled between poses (the service's stop)
};

Status RunCalibratePtu(const CalibratePtuOptions& options);
void AddCalibratePtuCommand(CliApp& cli);

}  // namespace idi::workcell
