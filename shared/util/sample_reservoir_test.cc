#include "shared/util/sample_reservoir.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace idi {
namespace {

TEST(SampleReservoirTest, ExactWhileUnderCapacity) {
  SampleReservoir r(100);
  for (int i = 100; i >= 1; --i) r.Add(i);
  EXPECT_EQ(r.count(), 100u);
  EXPECT_DOUBLE_EQ(r.sum(), 5050.0);
  EXPECT_DOUBLE_EQ(r.Percentile(0.5), 50.0);
  EXPECT_DOUBLE_EQ(r.Percentile(0.99), 99.0);
  EXPECT_DOUBLE_EQ(r.Percentile(1.0), 100.0);
  EXPECT_DOUBLE_EQ(r.Percentile(0.0), 1.0);
  EXPECT_DOUBLE_EQ(r.min(), 1.0);
  EXPECT_DOUBLE_EQ(r.max(), 100.0);
}

TEST(SampleReservoirTest, EmptyReportsZero) {
  const SampleReservoir r;
  EXPECT_EQ(r.count(), 0u);
  EXPECT_DOUBLE_EQ(r.Percentile(0.5), 0.0);
  EXPECT_DOUBLE_EQ(r.min(), 0.0);
  EXPECT_DOUBLE_EQ(r.max(), 0.0);
}

// A NaN or infinite timing (a clock that went wrong) is counted apart and changes nothing else: with it
// in the sum, the mean would be NaN; in the kept samples, the sort's order (and so every percentile)
// would be undefined.
TEST(SampleReservoirTest, NotFiniteSamplesAreCountedApart) {
  SampleReservoir r(10);
  r.Add(2.0);
  r.Add(std::nan(""));
  r.Add(std::numeric_limits<double>::infinity());
  r.Add(4.0);
  EXPECT_EQ(r.count(), 2u);
  EXPECT_EQ(r.not_finite(), 2u);
  EXPECT_DOUBLE_EQ(r.sum(), 6.0);
  EXPECT_DOUBLE_EQ(r.max(), 4.0);
  EXPECT_DOUBLE_EQ(r.Percentile(1.0), 4.0);
  EXPECT_EQ(r.kept().size(), 2u);
}

// A long run keeps only `capacity` samples, and they stay a uniform sample of the whole run: a
// reservoir that kept only the first or the last samples would put the median of a rising ramp at
// its start or its end.
TEST(SampleReservoirTest, BoundedAndUniformOverALongRun) {
  SampleReservoir r(1000);
  const int n = 200000;
  for (int i = 0; i < n; ++i) r.Add(i);
  EXPECT_EQ(r.kept().size(), 1000u);
  EXPECT_EQ(r.count(), static_cast<uint64_t>(n));
  EXPECT_DOUBLE_EQ(r.sum(), 0.5 * n * (n - 1.0));
  EXPECT_DOUBLE_EQ(r.max(), n - 1.0);
  // The sample median of 1000 uniform draws has a standard deviation of about n / 63.
  EXPECT_NEAR(r.Percentile(0.5), 0.5 * n, 0.06 * n);
  EXPECT_NEAR(r.Percentile(0.9), 0.9 * n, 0.04 * n);
  int late = 0;
  for (const double v : r.kept()) late += v >= 0.5 * n;
  EXPECT_NEAR(late, 500, 60);
}

TEST(SampleReservoirTest, SameSamplesSameResult) {
  SampleReservoir a(50), b(50);
  for (int i = 0; i < 5000; ++i) {
    a.Add(i % 97);
    b.Add(i % 97);
  }
  EXPECT_EQ(a.kept(), b.kept());
}

}  // namespace
}  // namespace idi
