// Small statistics helpers shared by the front end and the reconstruction.
#pragma once

#include <cmath>

namespace idi {

// The chi-square quantile with `dof` degrees of freedom at the probability of a standard normal's
// `z` (z = 3.09: 0.999), by the Wilson-Hilferty cube-root approximation (at z = 3.09: 11.2 against the
// exact 10.83 for one degree of freedom, 18.7 against 18.47 for four, 34.7 against 34.53 for 13).
inline double ChiSquareQuantile(double dof, double z) {
  const double c = 2.0 / (9.0 * dof);
  const double t = 1.0 - c + z * std::sqrt(c);
  return dof * t * t * t;
}

}  // namespace idi
