// Small inline helpers for the per-pixel loops of the features module.
#pragma once

#include <cmath>

namespace idi {

// Nearest integer (halves away from zero) without a libm call: the scans round millions of times.
inline int RoundToInt(double v) { return static_cast<int>(v >= 0 ? v + 0.5 : v - 0.5); }

// atan2 by an odd minimax polynomial on [0, 1] (max error about 1e-5 rad) and octant folding.
inline double FastAtan2(double y, double x) {
  const double ax = std::fabs(x), ay = std::fabs(y);
  const double mx = ax > ay ? ax : ay, mn = ax > ay ? ay : ax;
  if (mx == 0) {
    return 0;
  }
  const double a = mn / mx, s = a * a;
  double r = ((((-0.0117212 * s + 0.05265332) * s - 0.11643287) * s + 0.19354346) * s - 0.33262347) * s * a +
             0.99997726 * a;
  if (ay > ax) r = 1.57079632679489662 - r;
  if (x < 0) r = 3.14159265358979324 - r;
  return y < 0 ? -r : r;
}

}  // namespace idi
