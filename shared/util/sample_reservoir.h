// Timing statistics of a service that runs for hours: count, sum and extremes over every sample, and
// percentiles from a fixed-size uniform sample of them (reservoir sampling, Vitter's algorithm R).
// Memory stays bounded whatever the run's length; while no more than `capacity` samples have been
// added, the percentiles are exact. The reservoir's choices come from a fixed-seed generator, so a
// simulated run reports the same numbers every time.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "shared/util/statistics.h"

namespace idi {

class SampleReservoir {
 public:
  explicit SampleReservoir(std::size_t capacity = 16384) : capacity_(std::max<std::size_t>(capacity, 1)) {}

  // A sample that is not a number is counted apart (not_finite()) and left out of everything else, so
  // one bad timing cannot poison the sum or the percentiles.
  void Add(double v) {
    if (!std::isfinite(v)) {
      ++not_finite_;
      return;
    }
    ++count_;
    sum_ += v;
    min_ = std::min(min_, v);
    max_ = std::max(max_, v);
    if (kept_.size() < capacity_) {
      kept_.push_back(v);
      return;
    }
    // Keep the new sample with probability capacity / count, in place of a uniformly chosen one.
    const uint64_t slot = Next() % count_;
    if (slot < capacity_) kept_[static_cast<std::size_t>(slot)] = v;
  }

  uint64_t count() const { return count_; }
  uint64_t not_finite() const { return not_finite_; }
  double sum() const { return sum_; }
  double min() const { return count_ ? min_ : 0.0; }
  double max() const { return count_ ? max_ : 0.0; }
  std::size_t capacity() const { return capacity_; }
  // The samples kept: all of them while count() <= capacity(), in the order added.
  const std::vector<double>& kept() const { return kept_; }

  // Nearest-rank percentile (q in [0, 1]) of the kept samples; 0 when there are none.
  double Percentile(double q) const { return NearestRankPercentile(kept_, q); }

 private:
  // splitmix64: a fixed sequence, independent of any other generator in the program.
  uint64_t Next() {
    uint64_t z = (state_ += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }

  std::size_t capacity_;
  std::vector<double> kept_;
  uint64_t count_ = 0, not_finite_ = 0, state_ = 0x5EED;
  double sum_ = 0.0;
  double min_ = std::numeric_limits<double>::infinity(), max_ = -std::numeric_limits<double>::infinity();
};

}  // namespace idi
