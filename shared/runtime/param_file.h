// Reading and writing named parameter sets as YAML (the calibration and model files).
//
// File format: one key per parameter, the key carrying the unit (`alpha2_deg`), holding either a
// number or a map {value: <number>, std: <number>}:
//   alpha2_deg: {value: -89.98121, std: 0.00054}
//   a3_mm: 625.5
// Validation: every parameter must be present, no unknown key is allowed (except those the caller
// lists as extra sections), a key whose name matches a parameter but whose unit suffix does not is
// reported as a unit error, values must be finite, and a length (mm or m) at most kMaxParamLengthM in
// magnitude. Errors name the file, the line and the key.
#pragma once

#include <yaml-cpp/yaml.h>

#include <string>
#include <vector>

#include "shared/util/param_set.h"
#include "shared/util/status.h"

namespace idi {

// The largest length a parameter file may give, in metres. The workcell is a few metres across and a
// vehicle's geometry smaller still: a length beyond 100 m is a unit slip or a corrupt file, and one near
// the largest double overflows the kinematics that sum such lengths into inf and NaN poses.
inline constexpr double kMaxParamLengthM = 100.0;

struct ParamFileOptions {
  // Top-level keys that may appear besides the parameters (e.g. "model", "statistics").
  std::vector<std::string> extra_keys = {"model", "comment"};
  // When false, parameters missing from the file keep their nominal values.
  bool require_all = true;
  // The values a top-level `model` key may have (e.g. {"rx130"}); empty: any. A file without the key is
  // read (hand-written files may leave it out); one of another model is refused, naming both.
  std::vector<std::string> models;
};

// Refuses (InvalidArgument naming `where`, the line and both models) a map `node` whose top-level `model`
// is not one of `models` (empty: any); a map without the key passes (ParamFileOptions::models). For files
// whose parameters sit in sections below the top level (the pan-tilt calibration's left:, right:).
Status CheckParamFileModel(const YAML::Node& node, const std::vector<std::string>& models, const std::string& where);

// Parses `node` (a YAML map) into a ParamSet of `specs`. `where` names the source in messages.
Result<ParamSet> ParamSetFromYaml(const YAML::Node& node, const std::vector<ParamSpec>& specs,
                                  const std::string& where, const ParamFileOptions& options = {});
Result<ParamSet> LoadParamFile(const std::string& path, const std::vector<ParamSpec>& specs,
                               const ParamFileOptions& options = {});

// Emits `set` as YAML map entries (with std when known) into an emitter that is inside a map.
void EmitParamSet(YAML::Emitter& out, const ParamSet& set);
// Whether `set` can go into a parameter file that LoadParamFile reads back: every value finite, every
// length within kMaxParamLengthM, and every standard deviation known either finite or left out. FailedPrecondition
// naming the parameters otherwise, `where` (the file) starting the message: a parameter whose std is infinite is one
// the data did not determine (a calibration from too little motion, a distance given in metres for millimetres).
Status CheckParamsWritable(const ParamSet& set, const std::string& where);
// Writes `set` (plus a leading `model: <model>` line) atomically, after CheckParamsWritable.
Status SaveParamFile(const std::string& path, const ParamSet& set, const std::string& model);

}  // namespace idi
