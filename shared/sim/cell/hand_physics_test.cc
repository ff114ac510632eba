// The twin's grasp physics: fingers closing on true geometry, the friction cones and force closure.
#include "shared/sim/cell/hand_physics.h"

#include <gtest/gtest.h>

#include "shared/util/units.h"

namespace idi::sim {
namespace {

// The hand pointing down (palm z = world -z), its x along world x, the palm centre at `palm_world`.
Rigid3d PalmDown(const Vec3d& palm_world, double yaw = 0) {
  Rigid3d t;
  t.rotation << 1, 0, 0, 0, -1, 0, 0, 0, -1;
  t.rotation = RotZ(yaw).rotation * t.rotation;
  t.translation = palm_world;
  return t;
}

std::vector<Obstacle> ObjectOnTable(const ObjectShape& shape, const Rigid3d& world_from_palm,
                                    const Rigid3d& world_from_object = Rigid3d()) {
  const Rigid3d palm_from_world = world_from_palm.Inverse();
  ObjectShape disc;
  disc.kind = ObjectKind::kCylinder;
  disc.radius = 300;
  disc.size_z = 40;
  return {{0, ObjectParts(shape), palm_from_world * world_from_object},
          {kTableId, ObjectParts(disc), palm_from_world * Translation(0.0, 0.0, -40.0)}};
}

std::vector<FingerContact> CloseAll(const HandTruth& hand, double spread, const std::vector<Obstacle>& obstacles) {
  std::vector<FingerContact> out;
  for (int f = 0; f < 3; ++f) {
    if (auto c = SweepFinger(hand, f, spread, 0.0, obstacles)) out.push_back(*c);
  }
  return out;
}

ObjectShape Box(double x, double y, double z) {
  ObjectShape s;
  s.kind = ObjectKind::kBox;
  s.size_x = x;
  s.size_y = y;
  s.size_z = z;
  return s;
}

// Depth of the thumb's fingertip contact below the palm when it closes on a face `d` mm out.
double ThumbDepth(const HandTruth& hand, double d) {
  double reading = 0, depth = 0;
  EXPECT_TRUE(BarrettTipOnFace(hand.fingers, 2, 0, d, &reading, &depth));
  return depth;
}

TEST(HandPhysicsTest, TwoOnOneAcrossABoxHolds) {
  const HandTruth hand;
  const ObjectShape box = Box(100, 80, 60);
  // Contacts 25 mm below the top.
  const Rigid3d world_from_palm = PalmDown(Vec3d(0, 0, 35 + ThumbDepth(hand, 50)));
  const auto obstacles = ObjectOnTable(box, world_from_palm);
  const auto contacts = CloseAll(hand, 0, obstacles);
  ASSERT_EQ(contacts.size(), 3u);
  for (const FingerContact& c : contacts) {
    EXPECT_EQ(c.obstacle, 0);
    const Vec3d p = world_from_palm * c.point;
    EXPECT_NEAR(std::abs(p.x()), 50.0, 0.05) << "finger " << c.finger + 1 << " on an x face";
    EXPECT_NEAR(p.z(), 35.0, 3.0) << "the fingertips, not the links, touch the faces";
  }
  const GraspJudgement j = JudgeGrasp(hand, contacts, world_from_palm.Inverse() * Vec3d(0, 0, 30));
  EXPECT_TRUE(j.holds) << j.reason;
  EXPECT_GT(j.worst_cone_margin_deg, 10.0);
}

// A finger whose start is NaN never reached the end of its sweep (a loop without end): no contact.
TEST(HandPhysicsTest, ANonFiniteStartOrAFingerBeyondTheThumbHasNoContact) {
  const HandTruth hand;
  const auto obstacles = ObjectOnTable(Box(60, 60, 80), Translation(0.0, 0.0, 120.0) * RotX(kPi));
  EXPECT_FALSE(SweepFinger(hand, 2, 0.0, std::nan(""), obstacles).has_value());
  EXPECT_FALSE(SweepFinger(hand, 2, std::nan(""), 0.0, obstacles).has_value());
  EXPECT_FALSE(SweepFinger(hand, 3, 0.0, 0.0, obstacles).has_value());
  // A start so far out that a step of the sweep no longer changes it (it looped for ever).
  EXPECT_FALSE(SweepFinger(hand, 2, 0.0, -1e20, obstacles).has_value());
  EXPECT_FALSE(SweepFinger(hand, 2, 0.0, -1e6, obstacles).has_value());
}

TEST(HandPhysicsTest, OffCentreHandDoesNotHold) {
  const HandTruth hand;
  const ObjectShape box = Box(100, 80, 60);
  const Rigid3d world_from_palm = PalmDown(Vec3d(90, 0, 35 + ThumbDepth(hand, 50)));
  const auto contacts = CloseAll(hand, 0, ObjectOnTable(box, world_from_palm));
  const GraspJudgement j = JudgeGrasp(hand, contacts, world_from_palm.Inverse() * Vec3d(0, 0, 30));
  EXPECT_FALSE(j.holds) << j.reason;
}

TEST(HandPhysicsTest, TooLowAHandPutsFingersOnTheTable) {
  const HandTruth hand;
  const ObjectShape box = Box(60, 60, 30);
  // A narrow box and the palm low: the splayed fingers reach the table before the box.
  const Rigid3d world_from_palm = PalmDown(Vec3d(0, 0, 70));
  const auto contacts = CloseAll(hand, 0, ObjectOnTable(box, world_from_palm));
  ASSERT_FALSE(contacts.empty());
  const GraspJudgement j = JudgeGrasp(hand, contacts, world_from_palm.Inverse() * Vec3d(0, 0, 15));
  EXPECT_FALSE(j.holds);
  EXPECT_NE(j.reason.find("table"), std::string::npos) << j.reason;
}

TEST(HandPhysicsTest, TripodHoldsACylinder) {
  const HandTruth hand;
  ObjectShape can;
  can.kind = ObjectKind::kCylinder;
  can.radius = 40;
  can.size_z = 100;
  const Rigid3d world_from_palm = PalmDown(Vec3d(0, 0, 75 + ThumbDepth(hand, 40)), 0.3);
  const auto contacts = CloseAll(hand, DegToRad(60.0), ObjectOnTable(can, world_from_palm));
  ASSERT_EQ(contacts.size(), 3u);
  for (const FingerContact& c : contacts) {
    EXPECT_NEAR((world_from_palm * c.point).head<2>().norm(), 40.0, 0.05);
  }
  const GraspJudgement j = JudgeGrasp(hand, contacts, world_from_palm.Inverse() * Vec3d(0, 0, 50));
  EXPECT_TRUE(j.holds) << j.reason;
}

TEST(HandPhysicsTest, SteepWedgeSlipsOutOfTheFingers) {
  HandTruth hand;
  hand.friction = 0.3;  // cone 16.7 deg
  ObjectShape wedge;
  wedge.kind = ObjectKind::kTriangularPrism;
  wedge.size_x = 100;
  wedge.size_y = 120;
  wedge.size_z = 100;  // faces 63 deg from the horizontal: a horizontal push is 27 deg off their normals
  wedge.apex_x = 0;
  const Rigid3d world_from_palm = PalmDown(Vec3d(0, 0, 50 + ThumbDepth(hand, 25)));
  const auto contacts = CloseAll(hand, 0, ObjectOnTable(wedge, world_from_palm));
  ASSERT_GE(contacts.size(), 2u);
  const GraspJudgement j = JudgeGrasp(hand, contacts, world_from_palm.Inverse() * Vec3d(0, 0, 33));
  EXPECT_FALSE(j.holds);
  EXPECT_NE(j.reason.find("friction cone"), std::string::npos) << j.reason;
}

TEST(HandPhysicsTest, ForceClosureNeedsThreeNonCollinearContacts) {
  const std::vector<Vec3d> two = {Vec3d(-50, 0, 0), Vec3d(50, 0, 0)};
  const std::vector<Vec3d> two_in = {Vec3d(1, 0, 0), Vec3d(-1, 0, 0)};
  // Two point contacts cannot resist a torque about the line through them.
  EXPECT_FALSE(ForceClosure(two, two_in, 0.5, Vec3d::Zero(), 50));
  const std::vector<Vec3d> three = {Vec3d(-50, 0, 0), Vec3d(50, 25, 0), Vec3d(50, -25, 0)};
  const std::vector<Vec3d> three_in = {Vec3d(1, 0, 0), Vec3d(-1, 0, 0), Vec3d(-1, 0, 0)};
  EXPECT_TRUE(ForceClosure(three, three_in, 0.5, Vec3d::Zero(), 50));
  // Without friction nothing resists sliding along the faces.
  EXPECT_FALSE(ForceClosure(three, three_in, 1e-6, Vec3d::Zero(), 50));
  // All pushing the same way: no closure.
  const std::vector<Vec3d> same_in = {Vec3d(1, 0, 0), Vec3d(1, 0, 0), Vec3d(1, 0, 0)};
  EXPECT_FALSE(ForceClosure(three, same_in, 0.5, Vec3d::Zero(), 50));
}

TEST(HandPhysicsTest, PalmInsideTheObjectIsACollision) {
  const HandTruth hand;
  const ObjectShape box = Box(100, 80, 60);
  const auto inside = ObjectOnTable(box, PalmDown(Vec3d(0, 0, 50)));
  const auto c = FindHandCollision(hand, 0, {0, 0, 0}, inside);
  ASSERT_TRUE(c.has_value());
  EXPECT_EQ(c->obstacle, 0);
  // High above with the fingers splayed: clear of everything.
  EXPECT_FALSE(FindHandCollision(hand, 0, {0, 0, 0}, ObjectOnTable(box, PalmDown(Vec3d(0, 0, 300)))).has_value());
}

}  // namespace
}  // namespace idi::sim
