// Unit conversions. Angles are radians in code; files and CLIs name their unit (`alpha2_deg`).
#pragma once

#include <numbers>

namespace idi {

inline constexpr double kPi = std::numbers::pi;
inline constexpr double kRadPerDeg = kPi / 180.0;
inline constexpr double kDegPerRad = 180.0 / kPi;

template <typename T>
constexpr T DegToRad(const T& deg) {
  return deg * T(kRadPerDeg);
}
template <typename T>
constexpr T RadToDeg(const T& rad) {
  return rad * T(kDegPerRad);
}

}  // namespace idi
