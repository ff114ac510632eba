#include "shared/util/param_set.h"

#include <limits>

#include "shared/util/check.h"
#include "shared/util/units.h"

namespace idi {

std::string_view UnitSuffix(Unit unit) {
  switch (unit) {
    case Unit::kMillimetre: return "mm";
    case Unit::kMetre: return "m";
    case Unit::kDegree: return "deg";
    case Unit::kPixel: return "px";
    case Unit::kUnitless: return "";
  }
  return "";
}

double FromFileUnits(Unit unit, double file_value) {
  return unit == Unit::kDegree ? DegToRad(file_value) : file_value;
}

double ToFileUnits(Unit unit, double code_value) {
  return unit == Unit::kDegree ? RadToDeg(code_value) : code_value;
}

std::string ParamSpec::Key() const {
  const std::string_view suffix = UnitSuffix(unit);
  return suffix.empty() ? name : name + "_" + std::string(suffix);
}

ParamSet::ParamSet(std::vector<ParamSpec> specs)
    : specs_(std::move(specs)), stddevs_(specs_.size(), std::numeric_limits<double>::quiet_NaN()) {
  values_.reserve(specs_.size());
  for (const ParamSpec& s : specs_) {
    values_.push_back(FromFileUnits(s.unit, s.nominal_file));
  }
}

std::optional<std::size_t> ParamSet::Find(std::string_view name) const {
  for (std::size_t i = 0; i < specs_.size(); ++i) {
    if (specs_[i].name == name) {
      return i;
    }
  }
  return std::nullopt;
}

double ParamSet::Get(std::string_view name) const {
  const auto i = Find(name);
  IDI_CHECK(i.has_value(), "no parameter named " + std::string(name));
  return values_[*i];
}

void ParamSet::Set(std::string_view name, double code_value) {
  const auto i = Find(name);
  IDI_CHECK(i.has_value(), "no parameter named " + std::string(name));
  values_[*i] = code_value;
}

void ParamSet::Append(const ParamSet& other) {
  for (std::size_t i = 0; i < other.size(); ++i) {
    IDI_CHECK(!Find(other.spec(i).name).has_value(), "duplicate parameter " + other.spec(i).name);
    specs_.push_back(other.specs_[i]);
    values_.push_back(other.values_[i]);
    stddevs_.push_back(other.stddevs_[i]);
  }
}

ParamSet ParamSet::Slice(std::size_t first, std::size_t count) const {
  IDI_CHECK(first + count <= size(), "slice out of range");
  ParamSet out;
  out.specs_.assign(specs_.begin() + static_cast<long>(first), specs_.begin() + static_cast<long>(first + count));
  out.values_.assign(values_.begin() + static_cast<long>(first), values_.begin() + static_cast<long>(first + count));
  out.stddevs_.assign(stddevs_.begin() + static_cast<long>(first),
                      stddevs_.begin() + static_cast<long>(first + count));
  return out;
}

}  // namespace idi
