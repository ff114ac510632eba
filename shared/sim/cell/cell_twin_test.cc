// The complete workcell twin: the head's cameras see the table from the true chain and follow the PTUs,
// the laser spot lands where the beam meets the scene, and the hand picks and places an object.
#include "shared/sim/cell/cell_twin.h"

#include <gtest/gtest.h>

#include <limits>

#include "shared/kinematics/aiming.h"
#include "shared/util/units.h"

namespace idi::sim {
namespace {

// Minimal stand-ins for the PTU and the hand's controller (the real simulated devices live in
// workcell/devices, which shared/ tests cannot use).
class TestPanTilt final : public hal::PanTiltDevice {
 public:
  std::string name() const override { return "test-ptu"; }
  Result<hal::PanTiltLimits> Limits() override { return hal::PanTiltLimits{-3, 3, -1, 1, 1e-4, 1e-4}; }
  Status MoveTo(double pan, double tilt, std::chrono::milliseconds) override {
    pan_ = pan;
    tilt_ = tilt;
    return Status::Ok();
  }
  Result<hal::PanTiltState> Read() override { return hal::PanTiltState{0, pan_, tilt_}; }
  Status Halt() override { return Status::Ok(); }

 private:
  double pan_ = 0, tilt_ = 0;
};

class TestHand final : public hal::GripperDevice {
 public:
  Status Initialize() override {
    init_ = true;
    return Status::Ok();
  }
  Status Open() override {
    fingers_ = {0, 0, 0};
    return Status::Ok();
  }
  Status Close() override {
    for (std::size_t f = 0; f < 3; ++f) fingers_[f] = stall_[f] ? *stall_[f] : DegToRad(140.0);
    return Status::Ok();
  }
  Status SetSpread(double s) override {
    spread_ = s;
    return Status::Ok();
  }
  Result<hal::GripperState> Read() override { return hal::GripperState{0, spread_, fingers_, init_}; }
  Status Stop() override { return Status::Ok(); }
  void SetStall(const std::array<std::optional<double>, 3>& s) { stall_ = s; }

 private:
  bool init_ = false;
  double spread_ = 0;
  std::array<double, 3> fingers_{};
  std::array<std::optional<double>, 3> stall_{};
};

struct Rig {
  explicit Rig(CellTwinOptions o = Options()) : twin(o) {
    twin.AttachPanTilt(BiclopsSide::kLeft, &ptu[0]);
    twin.AttachPanTilt(BiclopsSide::kRight, &ptu[1]);
    twin.AttachHand(&hand, [this](const auto& s) { hand.SetStall(s); });
  }
  static CellTwinOptions Options() {
    CellTwinOptions o;
    o.keep_truth = true;
    o.clutter_objects = 2;
    return o;
  }
  std::array<TestPanTilt, 2> ptu;
  TestHand hand;
  CellTwin twin;
};

CellObject TestBox(const Vec3d& table_top) {
  CellObject o;
  o.name = "box";
  o.shape.kind = ObjectKind::kBox;
  o.shape.size_x = 110;
  o.shape.size_y = 80;
  o.shape.size_z = 70;
  o.shape.face_albedos = {0.5, 0.75, 0.9, 0.55, 0.65, 0.8};
  o.world_from_object = Translation(table_top) * RotZ(0.3);
  return o;
}

// Moves arm 1 so that the TCF (the flange) is `above_mm` over the table centre looking at it from the
// -x side: flange z axis down-ish so the cameras (which look along the TCF's x+y diagonal) see the table.
Status AimHeadAtTable(CellTwin& twin, const Vec3d& table_top) {
  // Cameras look along TCF (1, 1, 0)/sqrt2 with image-down along TCF +z. Point that axis at the table from
  // 900 mm away, 40 deg down.
  const double el = DegToRad(40.0);
  const Vec3d view_dir(std::cos(el), 0, -std::sin(el));  // towards +x and down
  const Vec3d cam_pos = table_top - 900 * view_dir;
  Mat3d r;
  const Vec3d axis_tcf = Vec3d(1, 1, 0).normalized(), down_tcf = Vec3d::UnitZ();
  const Vec3d down = Vec3d(0, 0, -1) - Vec3d(0, 0, -1).dot(view_dir) * view_dir;
  Mat3d a, b;
  a << axis_tcf, down_tcf, axis_tcf.cross(down_tcf);
  b << view_dir, down.normalized(), view_dir.cross(down.normalized());
  r = b * a.transpose();
  Rigid3d world_from_tcf;
  world_from_tcf.rotation = r;
  world_from_tcf.translation = cam_pos - r * Vec3d(40, 40, 275);
  IDI_RETURN_IF_ERROR(twin.rail(0).MoveTo(1900, {}));
  const Rigid3d base_from_tcf = twin.workcell().WorldFromBase(0).Inverse() * world_from_tcf;
  Joints start = JointsFromDeg({0, -40, 110, 0, 20, 0});
  start[0] = std::atan2(base_from_tcf.translation.y(), base_from_tcf.translation.x());
  IDI_ASSIGN_OR_RETURN(const IkSummary ik,
                       SolveFlangePose(twin.workcell().true_robot(0), start, base_from_tcf, Rx130JointLimits()));
  return twin.arm(0).MoveJoints(ik.q, {});
}

// Options and camera settings must be finite: an infinite exposure gave black frames, an infinite frame
// period sent the clock to the end of time, an infinite collision tolerance turned collisions off.
TEST(CellTwinTest, InfiniteOptionsAndSettingsAreRefused) {
  EXPECT_TRUE(CellTwinOptions{}.Check().ok());
  const double inf = std::numeric_limits<double>::infinity();
  for (int k = 0; k < 4; ++k) {
    CellTwinOptions o;
    (k == 0   ? o.nominal_exposure_us
     : k == 1 ? o.frame_period_s
     : k == 2 ? o.collision_tolerance_mm
              : o.laser_spot_peak) = inf;
    EXPECT_FALSE(o.Check().ok()) << k;
  }
  Rig rig;
  hal::CameraSettings s;
  s.width = rig.twin.options().head[0].camera.width;
  s.height = rig.twin.options().head[0].camera.height;
  s.exposure_us = inf;
  EXPECT_EQ(rig.twin.camera(BiclopsSide::kLeft).Start(s).code(), StatusCode::kInvalidArgument);
  s.exposure_us = 0;
  s.gain_db = inf;
  EXPECT_EQ(rig.twin.camera(BiclopsSide::kLeft).Start(s).code(), StatusCode::kInvalidArgument);
  s.gain_db = 0;
  EXPECT_TRUE(rig.twin.camera(BiclopsSide::kLeft).Start(s).ok());
}

TEST(CellTwinTest, CamerasSeeTheObjectThroughTheTrueChainAndFollowThePtu) {
  Rig rig;
  const Vec3d top = rig.twin.options().table.top_centre_world;
  rig.twin.AddObject(TestBox(top));
  ASSERT_TRUE(AimHeadAtTable(rig.twin, top).ok());
  hal::CameraDevice& cam = rig.twin.camera(BiclopsSide::kLeft);
  ASSERT_FALSE(cam.Grab(std::chrono::milliseconds(100)).ok()) << "Grab before Start must fail";
  ASSERT_TRUE(cam.Start({}).ok());
  auto image = cam.Grab(std::chrono::milliseconds(100));
  ASSERT_TRUE(image.ok()) << image.status().ToString();
  EXPECT_EQ(image->pixels.cols, 640);
  EXPECT_EQ(image->pixels.type(), CV_8UC1);
  const GroundTruth* truth = rig.twin.LastTruth(BiclopsSide::kLeft);
  ASSERT_NE(truth, nullptr);
  // The box's corners are junctions in the image where the true chain projects them.
  auto world_from_cam = rig.twin.TrueWorldFromCamera(BiclopsSide::kLeft);
  ASSERT_TRUE(world_from_cam.ok());
  const CameraModel& k = rig.twin.options().head[0].camera;
  int box_corners = 0;
  for (const TruthJunction& j : truth->junctions) {
    if (j.object != "box" || !j.is_vertex) continue;
    const auto px = Project(k, world_from_cam->Inverse() * j.point_world);
    ASSERT_TRUE(px.has_value());
    EXPECT_NEAR((*px - j.xy_px).norm(), 0.0, 1e-6);
    ++box_corners;
  }
  EXPECT_GE(box_corners, 6) << "a box seen from above shows at least 6 corners";
  // Panning moves the image: a corner moves by about f * dpan pixels.
  std::vector<Vec2d> before;
  for (const TruthJunction& j : truth->junctions) {
    if (j.object == "box" && j.is_vertex) before.push_back(j.xy_px);
  }
  ASSERT_TRUE(rig.ptu[0].MoveTo(0.01, 0, std::chrono::milliseconds(100)).ok());
  ASSERT_TRUE(cam.Grab(std::chrono::milliseconds(100)).ok());
  std::vector<Vec2d> after;
  for (const TruthJunction& j : rig.twin.LastTruth(BiclopsSide::kLeft)->junctions) {
    if (j.object == "box" && j.is_vertex) after.push_back(j.xy_px);
  }
  ASSERT_EQ(after.size(), before.size());
  const double moved = (after[0] - before[0]).norm();
  EXPECT_NEAR(moved, 0.01 * k.fx(), 3.0);
  // The clock runs a frame per image; frames carry sequence numbers.
  auto next = cam.Grab(std::chrono::milliseconds(100));
  ASSERT_TRUE(next.ok());
  EXPECT_EQ(next->sequence, 3u);
  EXPECT_GT(next->timestamp_ns, image->timestamp_ns);
  // A short exposure darkens the frame.
  ASSERT_TRUE(cam.SetExposure(500).ok());
  auto dark = cam.Grab(std::chrono::milliseconds(100));
  ASSERT_TRUE(dark.ok());
  EXPECT_LT(cv::mean(dark->pixels)[0], 0.2 * cv::mean(next->pixels)[0]);
  EXPECT_FALSE(cam.SetExposure(-1).ok());
}

TEST(CellTwinTest, WithoutAPtuTheCameraSaysSo) {
  CellTwin twin(Rig::Options());
  ASSERT_TRUE(twin.camera(BiclopsSide::kRight).Start({}).ok());
  const auto image = twin.camera(BiclopsSide::kRight).Grab(std::chrono::milliseconds(100));
  ASSERT_FALSE(image.ok());
  EXPECT_NE(image.status().message().find("pan-tilt"), std::string::npos) << image.status().ToString();
  EXPECT_EQ(twin.gripper().Close().code(), StatusCode::kFailedPrecondition);
}

TEST(CellTwinTest, LaserSpotAppearsWhereTheBeamMeetsTheTable) {
  CellTwinOptions o = Rig::Options();
  o.arm2_tool = Arm2Tool::kLaser;
  Rig rig(o);
  const Vec3d top = rig.twin.options().table.top_centre_world;
  ASSERT_TRUE(AimHeadAtTable(rig.twin, top).ok());
  // Arm 2 aims its laser at the table centre with its true model.
  WorkcellTwin& w = rig.twin.workcell();
  ASSERT_TRUE(rig.twin.rail(1).MoveTo(2200, {}).ok());
  const Vec3d target_base = w.WorldFromBase(1).Inverse() * (top + Vec3d(30, -20, 0));
  auto ik = AimLaserAt(w.true_robot(1), w.true_laser(1), JointsFromDeg({0, -40, 100, 0, 60, 0}), target_base,
                       Rx130JointLimits());
  ASSERT_TRUE(ik.ok()) << ik.status().ToString();
  ASSERT_TRUE(rig.twin.arm(1).MoveJoints(ik->q, {}).ok());
  ASSERT_TRUE(rig.twin.laser().SetOn(true).ok());
  ASSERT_TRUE(rig.twin.camera(BiclopsSide::kRight).Start({}).ok());
  ASSERT_TRUE(rig.twin.camera(BiclopsSide::kRight).Grab(std::chrono::milliseconds(100)).ok());
  const GroundTruth* t = rig.twin.LastTruth(BiclopsSide::kRight);
  ASSERT_NE(t, nullptr);
  ASSERT_EQ(t->spots.size(), 1u);
  EXPECT_TRUE(t->spots[0].visible);
  EXPECT_NEAR((t->spots[0].center_world - (top + Vec3d(30, -20, 0))).norm(), 0.0, 0.5);
}

// Hand pointing down over (x, y) of the world with its x axis along world x, palm at height z.
Status MoveHand(CellTwin& twin, const Vec3d& palm_world) {
  Rigid3d world_from_palm;
  world_from_palm.rotation << 1, 0, 0, 0, -1, 0, 0, 0, -1;
  world_from_palm.translation = palm_world;
  const Rigid3d base_from_flange = twin.workcell().WorldFromBase(1).Inverse() * world_from_palm *
                                   twin.options().hand.flange_from_palm.Inverse();
  IDI_ASSIGN_OR_RETURN(const hal::JointState js, twin.arm(1).ReadJoints());
  auto ik = SolveFlangePose(twin.workcell().true_robot(1), js.q_rad, base_from_flange, Rx130JointLimits());
  if (!ik.ok()) {
    ik = SolveFlangePose(twin.workcell().true_robot(1), JointsFromDeg({180, -40, 120, 0, 10, 0}), base_from_flange,
                         Rx130JointLimits());
  }
  if (!ik.ok()) return ik.status();
  return twin.arm(1).MoveJoints(ik->q, {});
}

TEST(CellTwinTest, HandPicksLiftsAndPlacesABox) {
  Rig rig;
  const Vec3d top = rig.twin.options().table.top_centre_world;
  CellObject box = TestBox(top);
  box.world_from_object = Translation(top);  // axis-aligned: the two-on-one grasp closes across x
  rig.twin.AddObject(box);
  ASSERT_TRUE(rig.twin.rail(1).MoveTo(2400, {}).ok());
  ASSERT_TRUE(rig.twin.gripper().Initialize().ok());
  const double contact_z = top.z() + 45;  // 25 mm below the box's top
  double reading = 0, depth = 0;
  ASSERT_TRUE(BarrettTipOnFace(rig.twin.options().hand.fingers, 2, 0, 55.0, &reading, &depth));
  ASSERT_TRUE(MoveHand(rig.twin, top + Vec3d(0, 0, 300)).ok());
  ASSERT_TRUE(MoveHand(rig.twin, Vec3d(top.x(), top.y(), contact_z + depth)).ok());
  EXPECT_EQ(rig.twin.collisions(), 0) << (rig.twin.events().empty() ? "" : rig.twin.events().back().what);
  ASSERT_TRUE(rig.twin.gripper().Close().ok());
  ASSERT_TRUE(rig.twin.held_object().has_value()) << rig.twin.last_grasp().reason;
  const auto st = rig.twin.gripper().Read();
  ASSERT_TRUE(st.ok());
  EXPECT_LT(st->finger_rad[2], DegToRad(100.0)) << "the thumb stalled on the box";
  // Lift: the box goes up with the hand.
  ASSERT_TRUE(MoveHand(rig.twin, Vec3d(top.x(), top.y(), contact_z + depth + 150)).ok());
  EXPECT_NEAR(rig.twin.objects()[0].world_from_object.translation.z(), top.z() + 150, 1.0);
  // Place it 100 mm along y and let go: it rests on the table there.
  ASSERT_TRUE(MoveHand(rig.twin, Vec3d(top.x(), top.y() + 100, contact_z + depth + 2)).ok());
  ASSERT_TRUE(rig.twin.gripper().Open().ok());
  EXPECT_FALSE(rig.twin.held_object().has_value());
  const Vec3d placed = rig.twin.objects()[0].world_from_object.translation;
  EXPECT_NEAR(placed.z(), top.z(), 1e-3) << "released, the box rests on the table (to a micrometre)";
  EXPECT_NEAR((placed.head<2>() - (top.head<2>() + Vec2d(0, 100))).norm(), 0.0, 1.0);
  EXPECT_EQ(rig.twin.collisions(), 0);
}

// A squeeze across a steep prism (its faces 45 deg from the closing direction, the friction cone 26.6
// deg) does not hold: the object is pushed out and the fingers that pressed on it close on, so the
// hand's encoders show the miss (a finger left at its contact would read as a grasp).
TEST(CellTwinTest, GraspThatSlipsLetsTheFingersCloseOn) {
  Rig rig;
  const Vec3d top = rig.twin.options().table.top_centre_world;
  CellObject prism;
  prism.name = "prism";
  prism.shape.kind = ObjectKind::kTriangularPrism;
  prism.shape.size_x = 120;
  prism.shape.size_y = 80;
  prism.shape.size_z = 60;
  prism.shape.apex_x = 0;
  prism.world_from_object = Translation(top);
  rig.twin.AddObject(prism);
  ASSERT_TRUE(rig.twin.rail(1).MoveTo(2400, {}).ok());
  ASSERT_TRUE(rig.twin.gripper().Initialize().ok());
  ASSERT_TRUE(MoveHand(rig.twin, top + Vec3d(0, 0, 300)).ok());
  ASSERT_TRUE(MoveHand(rig.twin, top + Vec3d(0, 0, 150)).ok());
  ASSERT_TRUE(rig.twin.gripper().Close().ok());
  EXPECT_FALSE(rig.twin.held_object().has_value()) << rig.twin.last_grasp().reason;
  const std::vector<FingerContact>& contacts = rig.twin.last_grasp().contacts;
  ASSERT_FALSE(contacts.empty()) << "the fingers met the prism";
  const auto st = rig.twin.gripper().Read();
  ASSERT_TRUE(st.ok());
  for (const FingerContact& c : contacts) {
    if (c.obstacle < 0) continue;
    EXPECT_GT(st->finger_rad[static_cast<std::size_t>(c.finger)], c.reading_rad + DegToRad(5.0))
        << "finger " << c.finger + 1 << " closed on past the prism it slipped from";
  }
}

TEST(CellTwinTest, MissedGraspLeavesTheObjectAndDescendingIntoItIsACollision) {
  Rig rig;
  const Vec3d top = rig.twin.options().table.top_centre_world;
  CellObject box = TestBox(top);
  box.world_from_object = Translation(top);
  rig.twin.AddObject(box);
  ASSERT_TRUE(rig.twin.rail(1).MoveTo(2400, {}).ok());
  ASSERT_TRUE(rig.twin.gripper().Initialize().ok());
  // 120 mm off along y: the fingers close beside the box.
  ASSERT_TRUE(MoveHand(rig.twin, top + Vec3d(0, 140, 300)).ok());
  ASSERT_TRUE(MoveHand(rig.twin, top + Vec3d(0, 140, 155)).ok());
  ASSERT_TRUE(rig.twin.gripper().Close().ok());
  EXPECT_FALSE(rig.twin.held_object().has_value());
  ASSERT_TRUE(MoveHand(rig.twin, top + Vec3d(0, 140, 300)).ok());
  EXPECT_NEAR(rig.twin.objects()[0].world_from_object.translation.z(), top.z(), 1e-9);
  // Straight down onto the box with the palm: a collision.
  ASSERT_TRUE(rig.twin.gripper().Open().ok());
  ASSERT_TRUE(MoveHand(rig.twin, top + Vec3d(0, 0, 300)).ok());
  EXPECT_EQ(rig.twin.collisions(), 0);
  ASSERT_TRUE(MoveHand(rig.twin, top + Vec3d(0, 0, 50)).ok());
  EXPECT_GE(rig.twin.collisions(), 1);
  ASSERT_FALSE(rig.twin.disturbed().empty());
  EXPECT_EQ(rig.twin.disturbed()[0], 0);
}

}  // namespace
}  // namespace idi::sim
