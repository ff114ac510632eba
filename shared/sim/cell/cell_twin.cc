#include "shared/sim/cell/cell_twin.h"

#include <algorithm>
#include <cmath>

#include "shared/sim/render/shapes.h"
#include "shared/util/units.h"

namespace idi::sim {

// A Biclops camera: renders the scene from the head's true pose at the PTU's position.
class CellTwin::Camera final : public hal::CameraDevice {
 public:
  Camera(CellTwin* twin, BiclopsSide side) : twin_(twin), side_(side) {}
  std::string name() const override { return std::string("sim-biclops-") + BiclopsSideName(side_); }
  Status Start(const hal::CameraSettings& settings) override {
    const CameraModel& c = twin_->options_.head[Index()].camera;
    if (settings.width != c.width || settings.height != c.height) {
      return InvalidArgument(name() + ": the camera delivers " + std::to_string(c.width) + "x" +
                             std::to_string(c.height) + " frames, not " + std::to_string(settings.width) + "x" +
                             std::to_string(settings.height));
    }
    if (!(settings.exposure_us >= 0 && std::isfinite(settings.exposure_us)) ||
        !(settings.gain_db >= 0 && settings.gain_db <= 60)) {
      return InvalidArgument(name() + ": exposure must be a finite time >= 0, gain in [0, 60] dB");
    }
    gray_ = settings.gray;
    exposure_us_ = settings.exposure_us > 0 ? settings.exposure_us : twin_->options_.nominal_exposure_us;
    gain_ = std::pow(10.0, settings.gain_db / 20.0);
    started_ = true;
    return Status::Ok();
  }
  Status Stop() override {
    started_ = false;
    return Status::Ok();
  }
  Result<hal::Image> Grab(std::chrono::milliseconds /*timeout*/) override {
    if (!started_) return FailedPrecondition(name() + ": Grab before Start");
    IDI_ASSIGN_OR_RETURN(const Rigid3d world_from_cam, twin_->TrueWorldFromCamera(side_));
    Scene scene = twin_->CurrentScene();
    const CellTwinOptions& o = twin_->options_;
    if (o.arm2_tool == Arm2Tool::kLaser && twin_->workcell_->laser_on(1)) {
      const WorkcellTwin& w = *twin_->workcell_;
      const Joints q = w.true_joints(1);
      const Line3d beam = LaserLineInBase(w.true_robot(1).data(), w.true_laser(1).data(), q.data());
      const Rigid3d world_from_base = w.WorldFromBase(1);
      const auto hit = CastRay(scene, world_from_base * beam.origin, world_from_base.RotateVector(beam.direction));
      if (hit) scene.laser_spots.push_back({hit->point, o.laser_spot_sigma_mm, o.laser_spot_peak});
    }
    RenderOptions r = o.render;
    r.exposure_dn *= gain_ * exposure_us_ / o.nominal_exposure_us;
    r.color = !gray_;
    r.seed = o.seed * 1000003ULL + twin_->frames_++;
    GroundTruth truth;
    const CameraModel& camera = o.head[Index()].camera;
    IDI_ASSIGN_OR_RETURN(cv::Mat pixels, RenderScene(scene, camera, world_from_cam.Inverse(), r,
                                                     o.keep_truth ? &truth : nullptr));
    if (o.keep_truth) twin_->truth_[Index()].push_back(std::move(truth));
    const int64_t period_ns = hal::SecToNs(o.frame_period_s);
    twin_->clock().SleepForNs(period_ns);
    hal::Image image;
    image.timestamp_ns = twin_->clock().NowNs() - period_ns / 2;
    image.sequence = ++sequence_;
    image.camera = BiclopsSideName(side_);
    image.pixels = std::move(pixels);
    return image;
  }
  Status SetExposure(double exposure_us) override {
    if (!(exposure_us > 0) || !std::isfinite(exposure_us)) {
      return InvalidArgument(name() + ": exposure must be positive, got " + FormatNumber(exposure_us) + " us");
    }
    exposure_us_ = exposure_us;
    return Status::Ok();
  }

 private:
  std::size_t Index() const { return side_ == BiclopsSide::kLeft ? 0 : 1; }
  CellTwin* twin_;
  BiclopsSide side_;
  bool started_ = false;
  bool gray_ = true;
  double exposure_us_ = 0;
  double gain_ = 1;
  uint64_t sequence_ = 0;
};

// Arm 2: the workcell twin's arm, with the hand checked against the objects along every move.
class CellTwin::HandArm final : public hal::ArmDevice {
 public:
  explicit HandArm(CellTwin* twin) : twin_(twin) {}
  std::string name() const override { return twin_->workcell_->arm(1).name(); }
  Status MoveJoints(const Joints& q_rad, const hal::MoveOptions& options) override {
    const Joints from = twin_->workcell_->true_joints(1);
    IDI_RETURN_IF_ERROR(twin_->workcell_->arm(1).MoveJoints(q_rad, options));
    twin_->CheckHandPath(from, twin_->workcell_->true_joints(1));
    return Status::Ok();
  }
  Result<hal::JointState> ReadJoints() override { return twin_->workcell_->arm(1).ReadJoints(); }
  Status Stop() override { return twin_->workcell_->arm(1).Stop(); }

 private:
  CellTwin* twin_;
};

// The hand: the attached controller moves the fingers; closing finds where each finger meets the true
// geometry, and the grasp is judged when they have stalled.
class CellTwin::Hand final : public hal::GripperDevice {
 public:
  explicit Hand(CellTwin* twin) : twin_(twin) {}
  Status Initialize() override {
    IDI_RETURN_IF_ERROR(Attached());
    return twin_->hand_controller_->Initialize();
  }
  Status Open() override {
    IDI_RETURN_IF_ERROR(Attached());
    twin_->set_stall_({std::nullopt, std::nullopt, std::nullopt});
    IDI_RETURN_IF_ERROR(twin_->hand_controller_->Open());
    if (twin_->held_) twin_->Release();
    return Status::Ok();
  }
  Status Close() override {
    IDI_RETURN_IF_ERROR(Attached());
    hal::GripperDevice& c = *twin_->hand_controller_;
    IDI_ASSIGN_OR_RETURN(const hal::GripperState before, c.Read());
    const HandTruth& hand = twin_->options_.hand;
    const Rigid3d world_from_palm = twin_->TrueWorldFromPalm();
    std::array<std::optional<FingerContact>, 3> contact;
    std::vector<Obstacle> obstacles;
    if (twin_->held_) {
      // Holding already: the fingers on the object stay there.
      for (const FingerContact& fc : twin_->last_grasp_.contacts) contact[static_cast<std::size_t>(fc.finger)] = fc;
    } else if (before.initialized) {
      obstacles = twin_->ObstaclesInPalm(world_from_palm, false);
      for (int f = 0; f < 3; ++f) {
        contact[static_cast<std::size_t>(f)] =
            SweepFinger(hand, f, before.spread_rad, before.finger_rad[static_cast<std::size_t>(f)], obstacles);
      }
    }
    std::array<std::optional<double>, 3> stall;
    for (std::size_t f = 0; f < 3; ++f) {
      if (contact[f]) stall[f] = contact[f]->reading_rad;
    }
    twin_->set_stall_(stall);
    IDI_RETURN_IF_ERROR(c.Close());
    if (twin_->held_) return Status::Ok();
    IDI_ASSIGN_OR_RETURN(const hal::GripperState after, c.Read());
    std::vector<FingerContact> touching;
    for (std::size_t f = 0; f < 3; ++f) {
      // The controller quantises to encoder counts: a stalled finger reads within a count of its contact.
      if (contact[f] && std::abs(after.finger_rad[f] - contact[f]->reading_rad) < 1e-3) touching.push_back(*contact[f]);
    }
    Vec3d com = Vec3d::Zero();
    int object = -1;
    for (const FingerContact& fc : touching) {
      if (fc.obstacle >= 0) object = fc.obstacle;
    }
    if (object >= 0) {
      const CellObject& o = twin_->objects_[static_cast<std::size_t>(object)];
      com = world_from_palm.Inverse() * (twin_->ObjectPose(object) * ObjectCentreOfMass(o.shape));
    }
    twin_->last_grasp_ = JudgeGrasp(hand, touching, com);
    if (twin_->last_grasp_.holds) {
      twin_->palm_from_held_ = world_from_palm.Inverse() * twin_->ObjectPose(twin_->last_grasp_.object);
      twin_->held_ = twin_->last_grasp_.object;
      twin_->Event("grasped " + twin_->objects_[static_cast<std::size_t>(*twin_->held_)].name + ": " +
                   twin_->last_grasp_.reason);
    } else {
      twin_->Event("grasp does not hold: " + twin_->last_grasp_.reason);
      IDI_RETURN_IF_ERROR(SlipOut(hand, before.spread_rad, touching, obstacles));
    }
    return Status::Ok();
  }
  // A grasp that does not hold squeezes the object out of the hand: the fingers that pressed on it close
  // on, past where it was, until they meet something else or close fully, so the finger encoders show
  // the miss as a real hand's would. (The object is left where it stood; where it would be pushed to is
  // not modelled.)
  Status SlipOut(const HandTruth& hand, double spread_rad, const std::vector<FingerContact>& touching,
                 const std::vector<Obstacle>& obstacles) {
    std::vector<int> slipped;
    for (const FingerContact& fc : touching) {
      if (fc.obstacle >= 0) slipped.push_back(fc.obstacle);
    }
    if (slipped.empty()) return Status::Ok();
    std::vector<Obstacle> rest;
    for (const Obstacle& o : obstacles) {
      if (std::find(slipped.begin(), slipped.end(), o.id) == slipped.end()) rest.push_back(o);
    }
    std::array<std::optional<double>, 3> stall;
    for (const FingerContact& fc : touching) {
      const auto f = static_cast<std::size_t>(fc.finger);
      if (fc.obstacle < 0) {
        stall[f] = fc.reading_rad;
        continue;
      }
      const auto on = SweepFinger(hand, fc.finger, spread_rad, fc.reading_rad, rest);
      if (on) stall[f] = on->reading_rad;
    }
    twin_->set_stall_(stall);
    return twin_->hand_controller_->Close();
  }
  Status SetSpread(double spread_rad) override {
    IDI_RETURN_IF_ERROR(Attached());
    return twin_->hand_controller_->SetSpread(spread_rad);
  }
  Result<hal::GripperState> Read() override {
    IDI_RETURN_IF_ERROR(Attached());
    return twin_->hand_controller_->Read();
  }
  Status Stop() override {
    IDI_RETURN_IF_ERROR(Attached());
    return twin_->hand_controller_->Stop();
  }

 private:
  Status Attached() const {
    if (twin_->hand_controller_ == nullptr || !twin_->set_stall_) {
      return FailedPrecondition("sim hand: no hand controller attached to the twin");
    }
    if (twin_->options_.arm2_tool != Arm2Tool::kBarrettHand) {
      return FailedPrecondition("sim hand: arm 2 carries the laser tool, not the hand");
    }
    return Status::Ok();
  }
  CellTwin* twin_;
};

HeadCameraTruth NominalHeadCamera(BiclopsSide side) {
  return HeadCameraTruth{ParamSet(PtuParamSpecs(side)), BiclopsNominalCamera(side)};
}

Status CellTwinOptions::Check() const {
  IDI_RETURN_IF_ERROR(workcell.Check());
  IDI_RETURN_IF_ERROR(hand.Check());
  IDI_RETURN_IF_ERROR(render.Check());
  for (std::size_t i = 0; i < 2; ++i) {
    if (head[i].ptu.size() != static_cast<std::size_t>(kPtuParamCount)) {
      return InvalidArgument("cell twin: head camera " + std::to_string(i) + " needs the 14 PTU parameters");
    }
    const CameraModel& c = head[i].camera;
    if (c.width < 16 || c.height < 16 || !(c.fx() > 0) || !(c.fy() > 0)) {
      return InvalidArgument("cell twin: head camera " + std::to_string(i) + " has an invalid camera model");
    }
  }
  if (!(table.radius_mm > 0) || !(table.thickness_mm > 0) || !table.top_centre_world.allFinite() ||
      !(table.top_centre_world.z() > workcell.floor_height_mm + table.thickness_mm)) {
    return InvalidArgument("cell twin: the table needs a positive size and its top above the floor");
  }
  // Finite too: an infinite exposure gave black frames, an infinite frame period sent the clock to the
  // end of time, an infinite collision tolerance turned collisions off.
  const auto positive = [](double v) { return v > 0 && std::isfinite(v); };
  if (!positive(nominal_exposure_us) || !positive(frame_period_s) || clutter_objects < 0 ||
      !positive(laser_spot_sigma_mm) || !positive(laser_spot_peak) ||
      !(collision_tolerance_mm >= 0 && std::isfinite(collision_tolerance_mm))) {
    return InvalidArgument(
        "cell twin: exposure, frame period, laser spot must be positive and finite, clutter >= 0, collision "
        "tolerance finite >= 0");
  }
  return Status::Ok();
}

CellTwin::CellTwin(const CellTwinOptions& options) : options_(options) {
  const Status ok = options_.Check();
  IDI_CHECK(ok.ok(), ok.ToString());
  WorkcellTwinOptions w = options_.workcell;
  // Both halves of the 64-bit seed (seeds 1 and 2^32 + 1 made the same arms before).
  w.seed = static_cast<unsigned>(options_.seed ^ (options_.seed >> 32));
  workcell_ = std::make_unique<WorkcellTwin>(w);
  cameras_[0] = std::make_unique<Camera>(this, BiclopsSide::kLeft);
  cameras_[1] = std::make_unique<Camera>(this, BiclopsSide::kRight);
  hand_arm_ = std::make_unique<HandArm>(this);
  hand_ = std::make_unique<Hand>(this);
  // Background clutter: boxes and cans on the floor around the table's foot.
  std::mt19937_64 rng(options_.seed * 15485863ULL + 11);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const Vec3d foot(options_.table.top_centre_world.x(), options_.table.top_centre_world.y(),
                   options_.workcell.floor_height_mm);
  for (int k = 0; k < options_.clutter_objects; ++k) {
    const ObjectKind kind = k % 3 == 2 ? ObjectKind::kCylinder : ObjectKind::kBox;
    CellObject c = SampleObject(kind, foot, 0.0, rng);
    const double scale = 1.0 + 1.5 * u(rng);  // crates and drums, larger than the objects on the table
    c.shape.size_x *= scale;
    c.shape.size_y *= scale;
    c.shape.size_z *= scale;
    c.shape.radius *= scale;
    const double r = options_.table.radius_mm + 250 + 1300 * u(rng), a = 2 * kPi * u(rng);
    c.world_from_object = Translation(Vec3d(foot + Vec3d(r * std::cos(a), r * std::sin(a), 0.0))) * RotZ(2 * kPi * u(rng));
    c.name = "clutter" + std::to_string(k);
    c.target = false;
    clutter_.push_back(c);
  }
}

CellTwin::~CellTwin() = default;

hal::ArmDevice& CellTwin::arm(int k) { return k == 1 ? *hand_arm_ : workcell_->arm(k); }
hal::CameraDevice& CellTwin::camera(BiclopsSide side) { return *cameras_[side == BiclopsSide::kLeft ? 0 : 1]; }
hal::GripperDevice& CellTwin::gripper() { return *hand_; }

void CellTwin::AttachPanTilt(BiclopsSide side, hal::PanTiltDevice* device) {
  ptu_[side == BiclopsSide::kLeft ? 0 : 1] = device;
}

void CellTwin::AttachHand(hal::GripperDevice* device, StallSetter set_stall) {
  hand_controller_ = device;
  set_stall_ = std::move(set_stall);
}

int CellTwin::AddObject(const CellObject& object) {
  objects_.push_back(object);
  return static_cast<int>(objects_.size()) - 1;
}

void CellTwin::ClearObjects() {
  objects_.clear();
  held_.reset();
  disturbed_.clear();
}

Rigid3d CellTwin::ObjectPose(int i) const {
  if (held_ && *held_ == i) return TrueWorldFromPalm() * palm_from_held_;
  return objects_.at(static_cast<std::size_t>(i)).world_from_object;
}

std::vector<CellObject> CellTwin::objects() const {
  std::vector<CellObject> out = objects_;
  for (std::size_t i = 0; i < out.size(); ++i) out[i].world_from_object = ObjectPose(static_cast<int>(i));
  return out;
}

Scene CellTwin::CurrentScene() const {
  Scene scene;
  const Vec3d table_top = options_.table.top_centre_world;
  for (const Wall& w : workcell_->walls()) {
    Material m = Gray(w.name == "floor" ? 0.42 : 0.55);
    if (w.name == "floor" && options_.tiled_floor) {
      m.texture.tile_size = 400;
      m.texture.grout_width = 8;
      m.texture.grout_albedo = Vec3d(0.18, 0.18, 0.18);
      m.texture.tile_jitter = 0.15;
      m.texture.noise_amplitude = 0.05;
      m.texture.noise_scale = 150;
      m.texture.seed = options_.seed + 5;
    } else {
      m.texture.noise_amplitude = 0.08;
      m.texture.noise_scale = 400;
      m.texture.seed = options_.seed + 7;
    }
    scene.solids.push_back(MakeRectangle(w.name, w.world_from_wall.translation, w.world_from_wall.rotation.col(0),
                                         w.world_from_wall.rotation.col(1), w.half_width_mm, w.half_height_mm, m));
  }
  // The rotary table: a disc on a pedestal.
  Cylinder disc;
  disc.name = "table";
  disc.base_center = table_top - Vec3d(0, 0, options_.table.thickness_mm);
  disc.radius = options_.table.radius_mm;
  disc.height = options_.table.thickness_mm;
  disc.top = Gray(options_.table.albedo);
  disc.side = Gray(0.6 * options_.table.albedo);
  disc.bottom = Gray(0.5 * options_.table.albedo);
  scene.cylinders.push_back(disc);
  Cylinder pedestal;
  pedestal.name = "table-pedestal";
  pedestal.base_center = Vec3d(table_top.x(), table_top.y(), options_.workcell.floor_height_mm);
  pedestal.radius = 60;
  pedestal.height = disc.base_center.z() - options_.workcell.floor_height_mm;
  pedestal.side = pedestal.top = pedestal.bottom = Gray(0.3);
  scene.cylinders.push_back(pedestal);
  for (const CellObject& c : clutter_) AddObjectToScene(c, &scene);
  for (std::size_t i = 0; i < objects_.size(); ++i) {
    CellObject o = objects_[i];
    o.world_from_object = ObjectPose(static_cast<int>(i));
    AddObjectToScene(o, &scene);
  }
  scene.lighting.directional = {{Vec3d(0.3, -0.5, 1.0), 0.6}};
  return scene;
}

Rigid3d CellTwin::TrueWorldFromTcf() const {
  const Joints q = workcell_->true_joints(0);
  return workcell_->WorldFromBase(0) * Rx130BaseFromFlange(workcell_->true_robot(0).data(), q.data()) *
         options_.flange_from_tcf;
}

Result<Rigid3d> CellTwin::TrueWorldFromCamera(BiclopsSide side) {
  const std::size_t i = side == BiclopsSide::kLeft ? 0 : 1;
  if (ptu_[i] == nullptr) {
    return FailedPrecondition(std::string("sim Biclops: no pan-tilt unit attached for the ") + BiclopsSideName(side) +
                              " camera");
  }
  auto state = ptu_[i]->Read();
  if (!state.ok()) return state.status().WithContext(std::string("sim Biclops ") + BiclopsSideName(side));
  return TrueWorldFromTcf() * TcfFromCamera(options_.head[i].ptu.data(), state->pan_rad, state->tilt_rad);
}

Rigid3d CellTwin::WorldFromPalmAt(const Joints& q) const {
  return workcell_->WorldFromBase(1) * Rx130BaseFromFlange(workcell_->true_robot(1).data(), q.data()) *
         options_.hand.flange_from_palm;
}

Rigid3d CellTwin::TrueWorldFromPalm() const { return WorldFromPalmAt(workcell_->true_joints(1)); }

const GroundTruth* CellTwin::LastTruth(BiclopsSide side) const {
  const auto& t = truth_[side == BiclopsSide::kLeft ? 0 : 1];
  return t.empty() ? nullptr : &t.back();
}

const std::vector<GroundTruth>& CellTwin::Truths(BiclopsSide side) const {
  return truth_[side == BiclopsSide::kLeft ? 0 : 1];
}

void CellTwin::Event(const std::string& what) { events_.push_back({workcell_->clock().NowNs(), what}); }

std::vector<Obstacle> CellTwin::ObstaclesInPalm(const Rigid3d& world_from_palm, bool include_held) const {
  const Rigid3d palm_from_world = world_from_palm.Inverse();
  std::vector<Obstacle> out;
  for (std::size_t i = 0; i < objects_.size(); ++i) {
    if (!include_held && held_ && *held_ == static_cast<int>(i)) continue;
    out.push_back({static_cast<int>(i), ObjectParts(objects_[i].shape), palm_from_world * ObjectPose(static_cast<int>(i))});
  }
  ObjectShape disc;
  disc.kind = ObjectKind::kCylinder;
  disc.radius = options_.table.radius_mm;
  disc.size_z = options_.table.thickness_mm;
  out.push_back({kTableId, ObjectParts(disc),
                 palm_from_world * Translation(Vec3d(options_.table.top_centre_world - Vec3d(0, 0, disc.size_z)))});
  return out;
}

void CellTwin::CheckHandPath(const Joints& from, const Joints& to) {
  if (options_.arm2_tool != Arm2Tool::kBarrettHand) return;
  double spread = 0;
  std::array<double, 3> fingers{};
  if (hand_controller_ != nullptr) {
    const auto st = hand_controller_->Read();
    if (st.ok()) {
      spread = st->spread_rad;
      fingers = st->finger_rad;
    }
  }
  double largest = 0;
  for (std::size_t i = 0; i < from.size(); ++i) largest = std::max(largest, std::abs(to[i] - from[i]));
  // 0.5 deg steps of the joint that moves most, for any move (a cap of 120 steps made a 180 deg swing
  // 1.5 deg steps, 40 mm at the hand: objects could slip between them).
  const int steps = std::isfinite(largest)
                        ? std::clamp(static_cast<int>(std::min(std::ceil(largest / DegToRad(0.5)), 1440.0)), 1, 1440)
                        : 1;
  std::vector<int> hit;
  for (int s = 1; s <= steps; ++s) {
    Joints q;
    for (std::size_t i = 0; i < q.size(); ++i) q[i] = from[i] + (to[i] - from[i]) * s / steps;
    const Rigid3d world_from_palm = WorldFromPalmAt(q);
    const std::vector<Obstacle> obstacles = ObstaclesInPalm(world_from_palm, false);
    const auto c = FindHandCollision(options_.hand, spread, fingers, obstacles, options_.collision_tolerance_mm);
    if (c && std::find(hit.begin(), hit.end(), c->obstacle) == hit.end()) {
      hit.push_back(c->obstacle);
      ++collisions_;
      const std::string what = c->obstacle == kTableId ? std::string("the table")
                                                       : objects_[static_cast<std::size_t>(c->obstacle)].name;
      Event("collision: the hand's " + c->part + " ran into " + what);
      if (c->obstacle >= 0) disturbed_.push_back(c->obstacle);
    }
    if (held_) {
      // The held object against the table and the other objects.
      const Rigid3d world_from_held = world_from_palm * palm_from_held_;
      const std::vector<ConvexPart> parts = ObjectParts(objects_[static_cast<std::size_t>(*held_)].shape);
      for (const Obstacle& o : obstacles) {
        if (std::find(hit.begin(), hit.end(), o.id - 1000) != hit.end()) continue;
        const Rigid3d obstacle_from_held = o.palm_from_obstacle.Inverse() * world_from_palm.Inverse() * world_from_held;
        bool inside = false;
        for (const ConvexPart& hp : parts) {
          for (const Vec3d& v : hp.vertices) {
            for (const ConvexPart& op : o.parts) {
              inside = inside || op.MaxSeparation(obstacle_from_held * v) < -options_.collision_tolerance_mm;
            }
          }
        }
        if (inside) {
          hit.push_back(o.id - 1000);
          ++collisions_;
          Event("collision: the held " + objects_[static_cast<std::size_t>(*held_)].name + " ran into " +
                (o.id == kTableId ? std::string("the table") : objects_[static_cast<std::size_t>(o.id)].name));
          if (o.id >= 0) disturbed_.push_back(o.id);
        }
      }
    }
  }
}

void CellTwin::Release() {
  const int i = *held_;
  Rigid3d pose = ObjectPose(i);
  held_.reset();
  // It drops onto what is below it: the table where any of its footprint is over the table, else the floor.
  const Vec3d table = options_.table.top_centre_world;
  double lowest = 1e300;
  bool over_table = false;
  for (const ConvexPart& p : ObjectParts(objects_[static_cast<std::size_t>(i)].shape)) {
    for (const Vec3d& v : p.vertices) {
      const Vec3d w = pose * v;
      lowest = std::min(lowest, w.z());
      over_table = over_table || (w.head<2>() - table.head<2>()).norm() <= options_.table.radius_mm;
    }
  }
  const double support = over_table ? table.z() : options_.workcell.floor_height_mm;
  if (lowest < support - options_.collision_tolerance_mm) {
    ++collisions_;
    Event("collision: " + objects_[static_cast<std::size_t>(i)].name + " released " + FormatNumber(support - lowest) +
          " mm inside the " + (over_table ? "table" : "floor"));
  }
  pose.translation.z() += support - lowest;
  objects_[static_cast<std::size_t>(i)].world_from_object = pose;
  Event("released " + objects_[static_cast<std::size_t>(i)].name + ", dropped " +
        FormatNumber(std::max(0.0, lowest - support)) + " mm onto the " + (over_table ? "table" : "floor"));
}

}  // namespace idi::sim
