// Barrett BH8 finger kinematics: the spread geometry, the open and closing shapes, the fingertip on a face.
#include "shared/kinematics/barrett_hand.h"

#include <gtest/gtest.h>

#include <cmath>

#include "shared/util/units.h"

namespace idi {
namespace {

TEST(BarrettHandTest, SpreadPlacesTheFingers) {
  const BarrettHandParams hand;
  // Spread 0: fingers 1 and 2 side by side at y = +-25 mm, closing towards the thumb.
  EXPECT_NEAR(BarrettFingerAt(hand, 0, 0).knuckle.y(), 25.0, 1e-9);
  EXPECT_NEAR(BarrettFingerAt(hand, 1, 0).knuckle.y(), -25.0, 1e-9);
  EXPECT_NEAR(BarrettFingerAt(hand, 0, 0).closing.x(), -1.0, 1e-12);
  EXPECT_NEAR(BarrettFingerAt(hand, 2, 0).closing.x(), 1.0, 1e-12);
  // Spread 60 deg: the three closing lines pass through the palm centre, 120 deg apart.
  for (int f = 0; f < 3; ++f) {
    const BarrettFingerFrame g = BarrettFingerAt(hand, f, DegToRad(60.0));
    EXPECT_NEAR(g.knuckle.head<2>().normalized().dot(-g.closing.head<2>()), 1.0, 1e-12) << "finger " << f + 1;
    EXPECT_NEAR(g.hinge.cross(Vec3d::UnitZ()).dot(g.closing), 1.0, 1e-12) << "closing = hinge x z";
  }
}

TEST(BarrettHandTest, OpenFingertipsHangStraightDownAtTheWidestOpening) {
  const BarrettHandParams hand;
  const auto p = BarrettFingerPoints(hand, 2, 0, 0.0);
  EXPECT_NEAR(p[2].x(), p[1].x(), 1e-9) << "distal link vertical";
  const double reach = hand.knuckle_radius_mm + hand.proximal_mm * std::sin(DegToRad(hand.open_angle_deg));
  EXPECT_NEAR(-p[2].x(), reach, 1e-9);
  EXPECT_NEAR((p[1] - p[0]).norm(), hand.proximal_mm, 1e-9);
  EXPECT_NEAR((p[2] - p[1]).norm(), hand.distal_mm, 1e-9);
  // Closing moves the fingertip inward.
  const auto q = BarrettFingerPoints(hand, 2, 0, DegToRad(30.0));
  EXPECT_GT(q[2].x(), p[2].x());
}

TEST(BarrettHandTest, FingertipReachesAFace) {
  const BarrettHandParams hand;
  double reading = 0, depth = 0;
  ASSERT_TRUE(BarrettTipOnFace(hand, 2, 0, 40.0, &reading, &depth));
  const auto p = BarrettFingerPoints(hand, 2, 0, reading);
  EXPECT_NEAR(-p[2].x() - hand.pad_radius_mm, 40.0, 1e-6);
  EXPECT_NEAR(depth, p[2].z(), 1e-12);
  EXPECT_GT(depth, 80.0);
  EXPECT_LT(depth, hand.proximal_mm + hand.distal_mm);
  // Beyond the widest opening, or on the far side of the palm centre, the fingertip cannot get there.
  EXPECT_FALSE(BarrettTipOnFace(hand, 2, 0, 100.0, &reading, &depth));
  EXPECT_FALSE(BarrettTipOnFace(hand, 2, 0, -200.0, &reading, &depth));
  // Parameters that are not a hand: an infinite finger range searched for ever, a finger index beyond
  // the thumb was taken for finger 2.
  BarrettHandParams endless;
  endless.closed_deg = INFINITY;
  EXPECT_FALSE(BarrettTipOnFace(endless, 2, 0, 1e6, &reading, &depth));
  EXPECT_FALSE(BarrettTipOnFace(hand, 3, 0, 40.0, &reading, &depth));
  EXPECT_FALSE(BarrettTipOnFace(hand, 2, std::nan(""), 40.0, &reading, &depth));
}

}  // namespace
}  // namespace idi
