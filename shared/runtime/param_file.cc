#include "shared/runtime/param_file.h"

#include <cmath>
#include <map>
#include <optional>
#include <set>
#include <sstream>

#include "shared/runtime/yaml_error.h"
#include "shared/util/atomic_file.h"

namespace idi {
namespace {

std::string At(const std::string& where, const YAML::Node& node) {
  const YAML::Mark mark = node.Mark();
  if (mark.line >= 0) {
    return where + ":" + std::to_string(mark.line + 1);
  }
  return where;
}

// The parameter name of a key with a unit suffix: "a3_deg" -> "a3"; keys without a known suffix
// are returned whole.
std::string StripUnitSuffix(const std::string& key) {
  for (const char* suffix : {"_mm", "_m", "_deg", "_px", "_rad"}) {
    const std::string s(suffix);
    if (key.size() > s.size() && key.compare(key.size() - s.size(), s.size(), s) == 0) {
      return key.substr(0, key.size() - s.size());
    }
  }
  return key;
}

Result<double> ReadNumber(const YAML::Node& node, const std::string& where, const std::string& key,
                          const char* field) {
  if (!node.IsScalar()) {
    return ParseError(At(where, node) + ": key '" + key + "': " + field + " must be a number");
  }
  double v = 0;
  try {
    v = node.as<double>();
  } catch (const YAML::Exception&) {
    return ParseError(At(where, node) + ": key '" + key + "': " + field + " '" + node.Scalar() +
                      "' is not a number");
  }
  if (!std::isfinite(v)) {
    return InvalidArgument(At(where, node) + ": key '" + key + "': " + field + " is not a finite number ('" +
                           node.Scalar() + "')");
  }
  return v;
}

// The largest magnitude a length parameter may have in a file, in its unit (kMaxParamLengthM); none for
// a parameter that is not a length. The loader (CheckLength) and the writer (CheckParamsWritable) share it.
std::optional<double> MaxLength(const ParamSpec& spec) {
  if (spec.unit == Unit::kMillimetre) return kMaxParamLengthM * 1000.0;
  if (spec.unit == Unit::kMetre) return kMaxParamLengthM;
  return std::nullopt;
}

// A length beyond kMaxParamLengthM (in the spec's unit) is refused, naming the key and the bound.
Status CheckLength(const ParamSpec& spec, double file_value, const YAML::Node& node, const std::string& where) {
  const std::optional<double> max = MaxLength(spec);
  if (!max || std::abs(file_value) <= *max) return Status::Ok();
  std::ostringstream s;
  s << At(where, node) << ": key '" << spec.Key() << "': " << file_value << " " << UnitSuffix(spec.unit)
    << " is out of range (a length is at most " << *max << " " << UnitSuffix(spec.unit);
  if (spec.unit == Unit::kMillimetre) s << ", " << kMaxParamLengthM << " m,";
  s << " in magnitude)";
  return OutOfRange(s.str());
}

}  // namespace

Status CheckParamFileModel(const YAML::Node& node, const std::vector<std::string>& models, const std::string& where) {
  const YAML::Node model = node["model"];
  if (models.empty() || !model) return Status::Ok();
  const std::string name = model.IsScalar() ? model.Scalar() : std::string();
  for (const std::string& m : models) {
    if (name == m) return Status::Ok();
  }
  std::string expected;
  for (std::size_t i = 0; i < models.size(); ++i) {
    expected += (i == 0 ? "" : i + 1 == models.size() ? " or " : ", ") + models[i];
  }
  return InvalidArgument(At(where, model) + ": model '" + name +
                         "' is not the one expected here (expected model: " + expected + ")");
}

Result<ParamSet> ParamSetFromYaml(const YAML::Node& node,
                                  const std::vector<ParamSpec>& specs,
                                  const std::string& where,
                                  const ParamFileOptions& options) try {
  if (!node.IsMap()) {
    return ParseError(where + ": expected a map of parameters (key: value)");
  }
  IDI_RETURN_IF_ERROR(CheckParamFileModel(node, options.models, where));
  ParamSet set(specs);
  std::map<std::string, std::size_t> by_key, by_name;
  for (std::size_t i = 0; i < specs.size(); ++i) {
    by_key[specs[i].Key()] = i;
    by_name[specs[i].name] = i;
  }
  const std::set<std::string> extras(options.extra_keys.begin(), options.extra_keys.end());
  std::vector<bool> seen(specs.size(), false);
  for (const auto& kv : node) {
    const std::string key = kv.first.as<std::string>();
    const auto it = by_key.find(key);
    if (it == by_key.end()) {
      if (extras.count(key) != 0) {
        continue;
      }
      const auto named = by_name.find(StripUnitSuffix(key));
      const auto named_whole = by_name.find(key);
      if (named != by_name.end() || named_whole != by_name.end()) {
        const ParamSpec& s = specs[named != by_name.end() ? named->second : named_whole->second];
        const std::string_view unit = UnitSuffix(s.unit);
        return InvalidArgument(At(where, kv.first) + ": key '" + key + "': wrong unit, " + s.name + " is " +
                               (unit.empty() ? std::string("unitless") : "in " + std::string(unit)) +
                               " (expected key '" + s.Key() + "')");
      }
      return InvalidArgument(At(where, kv.first) + ": unknown key '" + key + "'");
    }
    const std::size_t i = it->second;
    if (seen[i]) {
      return InvalidArgument(At(where, kv.first) + ": key '" + key + "' given twice");
    }
    seen[i] = true;
    const YAML::Node& v = kv.second;
    if (v.IsMap()) {
      for (const auto& field : v) {
        const std::string f = field.first.as<std::string>();
        if (f != "value" && f != "std") {
          return InvalidArgument(At(where, field.first) + ": key '" + key + "': unknown field '" + f +
                                 "' (expected value, std)");
        }
      }
      if (!v["value"]) {
        return ParseError(At(where, v) + ": key '" + key + "': missing 'value'");
      }
      IDI_ASSIGN_OR_RETURN(const double value, ReadNumber(v["value"], where, key, "value"));
      IDI_RETURN_IF_ERROR(CheckLength(specs[i], value, v["value"], where));
      set.set_file_value(i, value);
      if (v["std"]) {
        IDI_ASSIGN_OR_RETURN(const double sd, ReadNumber(v["std"], where, key, "std"));
        if (sd < 0) {
          return InvalidArgument(At(where, v["std"]) + ": key '" + key + "': std must not be negative");
        }
        set.set_stddev(i, FromFileUnits(specs[i].unit, sd));
      }
    } else {
      IDI_ASSIGN_OR_RETURN(const double value, ReadNumber(v, where, key, "value"));
      IDI_RETURN_IF_ERROR(CheckLength(specs[i], value, v, where));
      set.set_file_value(i, value);
    }
  }
  if (options.require_all) {
    for (std::size_t i = 0; i < specs.size(); ++i) {
      if (!seen[i]) {
        return InvalidArgument(where + ": missing key '" + specs[i].Key() + "' (" + specs[i].description + ")");
      }
    }
  }
  return set;
} catch (const YAML::Exception& e) {
  return YamlError(where, e);
}

Result<ParamSet> LoadParamFile(const std::string& path, const std::vector<ParamSpec>& specs,
                               const ParamFileOptions& options) {
  IDI_ASSIGN_OR_RETURN(const std::string text, ReadFile(path));
  try {
    return ParamSetFromYaml(YAML::Load(text), specs, path, options);
  } catch (const YAML::Exception& e) {
    return YamlError(path, e);
  }
}

void EmitParamSet(YAML::Emitter& out, const ParamSet& set) {
  for (std::size_t i = 0; i < set.size(); ++i) {
    out << YAML::Key << set.spec(i).Key() << YAML::Value << YAML::Flow << YAML::BeginMap;
    out << YAML::Key << "value" << YAML::Value << set.file_value(i);
    if (!std::isnan(set.stddev(i))) {
      out << YAML::Key << "std" << YAML::Value << set.file_stddev(i);
    }
    out << YAML::EndMap;
  }
}

Status CheckParamsWritable(const ParamSet& set, const std::string& where) {
  std::string values, stds, lengths;
  for (std::size_t i = 0; i < set.size(); ++i) {
    const ParamSpec& spec = set.spec(i);
    const std::string key = spec.Key();
    const std::optional<double> max_length = MaxLength(spec);
    if (!std::isfinite(set.value(i)))
      values += (values.empty() ? "" : ", ") + key;
    else if (std::isinf(set.stddev(i)))
      stds += (stds.empty() ? "" : ", ") + key;
    else if (max_length && std::abs(set.file_value(i)) > *max_length)  // the loader would refuse it (CheckLength)
      lengths += (lengths.empty() ? "" : ", ") + key;
  }
  if (values.empty() && stds.empty() && lengths.empty()) return Status::Ok();
  std::string what;
  if (!values.empty()) what = "the values of " + values + " are not finite numbers";
  if (!stds.empty()) {
    what += (what.empty() ? "" : "; ") + std::string("the data do not determine ") + stds +
            " (their standard deviation is infinite)";
  }
  if (!lengths.empty()) {
    what += (what.empty() ? "" : "; ") + ("the lengths " + lengths + " are beyond ") +
            std::to_string(static_cast<int>(kMaxParamLengthM)) + " m (a solve that diverged?)";
  }
  return FailedPrecondition(where + ": not written: " + what);
}

Status SaveParamFile(const std::string& path, const ParamSet& set, const std::string& model) {
  IDI_RETURN_IF_ERROR(CheckParamsWritable(set, path));
  YAML::Emitter out;
  out.SetDoublePrecision(12);
  out << YAML::BeginMap;
  out << YAML::Key << "model" << YAML::Value << model;
  EmitParamSet(out, set);
  out << YAML::EndMap;
  if (!out.good()) {
    return Internal(path + ": YAML emitter error: " + out.GetLastError());
  }
  return WriteFileAtomically(path, std::string(out.c_str()) + "\n");
}

}  // namespace idi
