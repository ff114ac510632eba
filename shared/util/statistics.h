// Small statistics helpers shared by the front end and the reconstruction.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

namespace idi {

// The chi-square quantile with `dof` degrees of freedom at the probability of a standard normal's
// `z` (z = 3.09: 0.999), by the Wilson-Hilferty cube-root approximation (at z = 3.09: 11.2 against the
// exact 10.83 for one degree of freedom, 18.7 against 18.47 for four, 34.7 against 34.53 for 13).
inline double ChiSquareQuantile(double dof, double z) {
  const double c = 2.0 / (9.0 * dof);
  const double t = 1.0 - c + z * std::sqrt(c);
  return dof * t * t * t;
}

// Drops the NaNs of v (nth_element's ordering is undefined with them: the result was any element).
inline void DropNaN(std::vector<double>* v) {
  v->erase(std::remove_if(v->begin(), v->end(), [](double x) { return std::isnan(x); }), v->end());
}

// The element of rank n/2 of v in ascending order (for an even count, the upper of the two middle
// ones), NaNs left out; `if_empty` when v is empty (or all NaN).
inline double Median(std::vector<double> v, double if_empty = 0.0) {
  DropNaN(&v);
  if (v.empty()) return if_empty;
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

// Nearest-rank percentile of v, q in [0, 1]: the smallest element with at least a fraction q of v at
// or below it (q = 0 gives the minimum, q = 1 the maximum; q outside [0, 1] is clamped, NaN taken as
// 0), NaNs left out; `if_empty` when v is empty (or all NaN). The rank is rounded up from q n less a
// hair, so that q = 0.07 of 100 is rank 7 although 0.07 * 100 is 7.000000000000001 in doubles.
inline double NearestRankPercentile(std::vector<double> v, double q, double if_empty = 0.0) {
  DropNaN(&v);
  if (v.empty()) return if_empty;
  const double r = std::ceil((q > 0 ? std::min(q, 1.0) : 0.0) * static_cast<double>(v.size()) - 1e-9);
  const std::size_t rank = std::clamp<std::size_t>(static_cast<std::size_t>(r), 1, v.size());
  const auto at = v.begin() + static_cast<std::ptrdiff_t>(rank - 1);
  std::nth_element(v.begin(), at, v.end());
  return *at;
}

}  // namespace idi
