#include "shared/util/statistics.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace idi {
namespace {

TEST(StatisticsTest, MedianIsTheMiddleElementAndTheUpperOneForAnEvenCount) {
  EXPECT_DOUBLE_EQ(Median({5, 1, 3}), 3.0);
  EXPECT_DOUBLE_EQ(Median({4, 1, 3, 2}), 3.0);
  EXPECT_DOUBLE_EQ(Median({7}), 7.0);
  EXPECT_DOUBLE_EQ(Median({}), 0.0);
  EXPECT_TRUE(std::isnan(Median({}, NAN)));
}

TEST(StatisticsTest, NearestRankPercentile) {
  std::vector<double> v;
  for (int i = 100; i >= 1; --i) v.push_back(i);
  EXPECT_DOUBLE_EQ(NearestRankPercentile(v, 0.0), 1.0);
  EXPECT_DOUBLE_EQ(NearestRankPercentile(v, 0.5), 50.0);
  EXPECT_DOUBLE_EQ(NearestRankPercentile(v, 0.99), 99.0);
  EXPECT_DOUBLE_EQ(NearestRankPercentile(v, 0.995), 100.0);  // the rank rounds up
  EXPECT_DOUBLE_EQ(NearestRankPercentile(v, 1.0), 100.0);
  EXPECT_DOUBLE_EQ(NearestRankPercentile(v, 2.0), 100.0);  // q is clamped to [0, 1]
  EXPECT_DOUBLE_EQ(NearestRankPercentile(v, -1.0), 1.0);
  EXPECT_DOUBLE_EQ(NearestRankPercentile(v, NAN), 1.0);  // NaN is no rank: the minimum, not a cast of NaN
  EXPECT_DOUBLE_EQ(NearestRankPercentile({3, 1, 2}, 0.5), 2.0);
  EXPECT_DOUBLE_EQ(NearestRankPercentile({}, 0.5), 0.0);
  EXPECT_DOUBLE_EQ(NearestRankPercentile({}, 0.5, -1.0), -1.0);
}

// NaNs are left out (with them nth_element's order is undefined, and the median was any element), and
// a rank q n that is whole in decimals is not pushed one up by rounding (0.07 * 100 = 7.000000000000001).
TEST(StatisticsTest, NaNsAreLeftOutAndWholeRanksStayWhole) {
  const double nan = std::nan("");
  EXPECT_DOUBLE_EQ(Median({nan, 5, nan, 1, 3, nan, nan}), 3.0);
  EXPECT_DOUBLE_EQ(Median({nan, nan}, -1.0), -1.0);
  EXPECT_DOUBLE_EQ(NearestRankPercentile({nan, 4, 1, nan, 3, 2}, 1.0), 4.0);
  std::vector<double> v;
  for (int i = 1; i <= 100; ++i) v.push_back(i);
  for (const double q : {0.07, 0.14, 0.28, 0.55, 0.56}) {
    EXPECT_DOUBLE_EQ(NearestRankPercentile(v, q), std::round(q * 100)) << q;
  }
}

TEST(StatisticsTest, ChiSquareQuantileIsNearTheExactValues) {
  // Exact 0.999 quantiles: 10.83 (1 dof), 18.47 (4), 34.53 (13); Wilson-Hilferty is within 4 %.
  EXPECT_NEAR(ChiSquareQuantile(1, 3.09), 10.83, 0.04 * 10.83);
  EXPECT_NEAR(ChiSquareQuantile(4, 3.09), 18.47, 0.02 * 18.47);
  EXPECT_NEAR(ChiSquareQuantile(13, 3.09), 34.53, 0.01 * 34.53);
}

}  // namespace
}  // namespace idi
