#include "shared/util/param_set.h"

#include <gtest/gtest.h>

#include <cmath>

#include "shared/util/units.h"

namespace idi {
namespace {

ParamSet TwoParams() {
  return ParamSet({{"alpha2", Unit::kDegree, -90.0, "twist of link 2"}, {"a3", Unit::kMillimetre, 625.0, ""}});
}

TEST(ParamSetTest, KeysCarryUnitSuffix) {
  const ParamSet p = TwoParams();
  EXPECT_EQ(p.spec(0).Key(), "alpha2_deg");
  EXPECT_EQ(p.spec(1).Key(), "a3_mm");
  EXPECT_EQ(ParamSpec({"k1", Unit::kUnitless, 0.0, ""}).Key(), "k1");
  EXPECT_EQ(ParamSpec({"fx", Unit::kPixel, 800.0, ""}).Key(), "fx_px");
}

TEST(ParamSetTest, AnglesAreRadiansInCodeAndDegreesInFiles) {
  ParamSet p = TwoParams();
  EXPECT_DOUBLE_EQ(p.value(0), -kPi / 2);
  EXPECT_DOUBLE_EQ(p.file_value(0), -90.0);
  EXPECT_DOUBLE_EQ(p.value(1), 625.0);
  p.set_file_value(0, 45.0);
  EXPECT_DOUBLE_EQ(p.Get("alpha2"), kPi / 4);
  EXPECT_TRUE(std::isnan(p.stddev(0)));
}

TEST(ParamSetTest, AppendAndSlice) {
  ParamSet p = TwoParams();
  p.Append(ParamSet({{"px", Unit::kMillimetre, 0.5, ""}}));
  ASSERT_EQ(p.size(), 3u);
  EXPECT_EQ(p.Find("px"), 2u);
  const ParamSet tail = p.Slice(1, 2);
  EXPECT_EQ(tail.size(), 2u);
  EXPECT_EQ(tail.spec(0).name, "a3");
  EXPECT_DOUBLE_EQ(tail.value(1), 0.5);
  EXPECT_FALSE(p.Find("nope").has_value());
}

}  // namespace
}  // namespace idi
