// Named parameter sets: every model's parameters have a name, a unit and a nominal value, and are
// read from and written to files under keys that carry the unit (`alpha2_deg`, `a3_mm`, `fx_px`).
//
// Values are held in code units: angles in radians, lengths in the unit the spec names (mm in the
// workcell, m on the vehicle), pixels in pixels. Files hold angles in degrees. Specs give the nominal
// value in file units, because that is how the dissertation's tables print them.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace idi {

enum class Unit { kMillimetre, kMetre, kDegree, kPixel, kUnitless };

// The suffix a file key carries for this unit: "mm", "m", "deg", "px", or "" (no suffix).
std::string_view UnitSuffix(Unit unit);
// Code value from file value (degrees to radians; others unchanged), and back.
double FromFileUnits(Unit unit, double file_value);
double ToFileUnits(Unit unit, double code_value);

struct ParamSpec {
  std::string name;         // "alpha2", as the dissertation's tables name it
  Unit unit = Unit::kUnitless;
  double nominal_file = 0;  // nominal value in file units (degrees for angles)
  std::string description;

  // "alpha2_deg"; just the name for unitless parameters.
  std::string Key() const;
};

// A parameter vector with its specs; values are contiguous so solvers can use data() directly.
class ParamSet {
 public:
  ParamSet() = default;
  // Every value starts at its nominal; standard deviations start unknown (NaN).
  explicit ParamSet(std::vector<ParamSpec> specs);

  std::size_t size() const { return specs_.size(); }
  const std::vector<ParamSpec>& specs() const { return specs_; }
  const ParamSpec& spec(std::size_t i) const { return specs_.at(i); }

  double value(std::size_t i) const { return values_.at(i); }
  void set_value(std::size_t i, double code_value) { values_.at(i) = code_value; }
  double file_value(std::size_t i) const { return ToFileUnits(specs_.at(i).unit, values_.at(i)); }
  void set_file_value(std::size_t i, double v) { values_.at(i) = FromFileUnits(specs_.at(i).unit, v); }

  // Standard deviation in code units; NaN when unknown.
  double stddev(std::size_t i) const { return stddevs_.at(i); }
  void set_stddev(std::size_t i, double code_value) { stddevs_.at(i) = code_value; }
  double file_stddev(std::size_t i) const { return ToFileUnits(specs_.at(i).unit, stddevs_.at(i)); }

  double* data() { return values_.data(); }
  const double* data() const { return values_.data(); }
  const std::vector<double>& values() const { return values_; }

  std::optional<std::size_t> Find(std::string_view name) const;
  // Value by name; aborts if the name is not in the set (a programming error).
  double Get(std::string_view name) const;
  void Set(std::string_view name, double code_value);

  // Appends another set's specs and values (e.g. robot + laser tool).
  void Append(const ParamSet& other);
  // The sub-range [first, first+count) as its own set.
  ParamSet Slice(std::size_t first, std::size_t count) const;

 private:
  std::vector<ParamSpec> specs_;
  std::vector<double> values_;
  std::vector<double> stddevs_;
};

}  // namespace idi
