// The complete digital twin of the workcell (chapter 3, §8.12.3): the calibration cell of
// shared/sim/workcell (two RX-130 arms on the rail, walls, floor) plus
//  - the Biclops head on arm 1 (§3.4): two cameras, each on a pan-tilt unit, with true PTU parameters
//    (eqs. 3.11-3.14, deviating from the design like Table 6.1) and true intrinsics (optional lens
//    distortion). The cameras implement hal::CameraDevice by rendering the scene (shared/sim/render)
//    from the head's true pose: arm 1's true kinematics at its encoder readings, its true rail position,
//    and the PTUs' positions;
//  - the rotary table with an object on it (box, triangular prism, L-bracket, cylinder: cell_objects.h)
//    and background clutter on a tiled floor;
//  - the Barrett hand on arm 2 (or the laser tool, for the pan-tilt calibration of chapter 6: its spot
//    is rendered where the true beam meets the scene) with the grasp physics of hand_physics.h: the
//    fingers close on the true object geometry, the object is lifted when the contacts hold it, moves
//    with the hand, and is put down where the hand opens. Arm 2's moves are checked for collisions of
//    the hand (and a held object) with the objects and the table.
//
// The PTUs and the hand's motor controller are the simulated devices of workcell/devices, attached
// here (shared/ cannot include workcell/): the cameras read the PTUs' positions through hal, and the
// hand tells its controller where each finger stalls. World frame: robot 1's rail frame R1 (as
// WorkcellTwin), z up, mm. Ground truth (poses, GroundTruth of each frame, grasp judgements, collision
// events) is for tests and reports; procedures see only the hal devices.
#pragma once

#include <array>
#include <functional>
#include <memory>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "shared/camera/pinhole.h"
#include "shared/hal/arm.h"
#include "shared/hal/camera.h"
#include "shared/hal/pan_tilt.h"
#include "shared/kinematics/biclops.h"
#include "shared/sim/cell/cell_objects.h"
#include "shared/sim/cell/hand_physics.h"
#include "shared/sim/render/render.h"
#include "shared/sim/workcell/workcell_twin.h"

namespace idi::sim {

// One Biclops camera as built: its PTU parameters (PtuParamSpecs, code units) and its intrinsics.
struct HeadCameraTruth {
  ParamSet ptu;
  CameraModel camera;
};
HeadCameraTruth NominalHeadCamera(BiclopsSide side);

enum class Arm2Tool { kBarrettHand, kLaser };

struct RotaryTable {
  Vec3d top_centre_world = Vec3d(2825, -500, -400);
  double radius_mm = 300;
  double thickness_mm = 40;
  double albedo = 0.22;
};

struct CellTwinOptions {
  WorkcellTwinOptions workcell = DefaultWorkcell();
  std::array<HeadCameraTruth, 2> head = {NominalHeadCamera(BiclopsSide::kLeft),
                                         NominalHeadCamera(BiclopsSide::kRight)};
  Rigid3d flange_from_tcf;  // Biclops' tool base on arm 1: the TCF of eq. 3.10 (identity: the flange)
  Arm2Tool arm2_tool = Arm2Tool::kBarrettHand;
  HandTruth hand;
  RotaryTable table;
  RenderOptions render = DefaultRender();
  double nominal_exposure_us = 10000;  // the exposure at which render.exposure_dn holds
  double frame_period_s = 1.0 / 30;
  bool keep_truth = false;             // keep every frame's GroundTruth (tests, studies)
  int clutter_objects = 6;             // boxes and cans on the floor around the table
  bool tiled_floor = true;
  double laser_spot_sigma_mm = 2.0;
  double laser_spot_peak = 60.0;
  double collision_tolerance_mm = 1.0;
  uint64_t seed = 1;

  static WorkcellTwinOptions DefaultWorkcell() {
    WorkcellTwinOptions w;
    w.rail_length_mm = 2500;  // each arm's travel; the table stands between the two rails' ends
    return w;
  }
  static RenderOptions DefaultRender() { return RenderOptions{}; }
  Status Check() const;
};

// What happened to the hand and the objects (ground truth for reports).
struct CellEvent {
  int64_t time_ns = 0;
  std::string what;
};

class CellTwin {
 public:
  explicit CellTwin(const CellTwinOptions& options);
  ~CellTwin();
  CellTwin(const CellTwin&) = delete;
  CellTwin& operator=(const CellTwin&) = delete;

  WorkcellTwin& workcell() { return *workcell_; }
  const WorkcellTwin& workcell() const { return *workcell_; }
  hal::SimClock& clock() { return workcell_->clock(); }

  // Devices. arm(1) checks the hand against the objects along every move.
  hal::ArmDevice& arm(int k);
  hal::RailDevice& rail(int k) { return workcell_->rail(k); }
  hal::LaserDevice& laser() { return workcell_->laser(1); }  // arm 2's laser (Arm2Tool::kLaser)
  hal::CameraDevice& camera(BiclopsSide side);
  hal::GripperDevice& gripper();

  // The PTUs carrying the cameras and the hand's motor controller (must outlive the twin).
  // `set_stall` tells the controller where each finger will stall when it next closes (nullopt: free).
  using StallSetter = std::function<void(const std::array<std::optional<double>, 3>&)>;
  void AttachPanTilt(BiclopsSide side, hal::PanTiltDevice* device);
  void AttachHand(hal::GripperDevice* device, StallSetter set_stall);

  // The scene.
  int AddObject(const CellObject& object);
  void ClearObjects();
  // Objects with their current poses (a held object moves with the hand).
  std::vector<CellObject> objects() const;
  const std::vector<CellObject>& clutter() const { return clutter_; }
  Scene CurrentScene() const;

  // Ground truth.
  const CellTwinOptions& options() const { return options_; }
  Result<Rigid3d> TrueWorldFromCamera(BiclopsSide side);
  Rigid3d TrueWorldFromTcf() const;
  Rigid3d TrueWorldFromPalm() const;
  const GroundTruth* LastTruth(BiclopsSide side) const;
  // Every frame's truth in the order the camera took them (empty unless options().keep_truth).
  const std::vector<GroundTruth>& Truths(BiclopsSide side) const;
  std::optional<int> held_object() const { return held_; }
  const GraspJudgement& last_grasp() const { return last_grasp_; }
  const std::vector<CellEvent>& events() const { return events_; }
  int collisions() const { return collisions_; }
  // Objects the hand (or a held object) ran into.
  const std::vector<int>& disturbed() const { return disturbed_; }

 private:
  class Camera;
  class HandArm;
  class Hand;
  friend class Camera;
  friend class HandArm;
  friend class Hand;

  void Event(const std::string& what);
  Rigid3d ObjectPose(int i) const;
  // The objects (except the held one) and the table, in the palm frame at `world_from_palm`.
  std::vector<Obstacle> ObstaclesInPalm(const Rigid3d& world_from_palm, bool include_held) const;
  Rigid3d WorldFromPalmAt(const Joints& q) const;
  void CheckHandPath(const Joints& from, const Joints& to);
  void Release();

  CellTwinOptions options_;
  std::unique_ptr<WorkcellTwin> workcell_;
  std::array<std::unique_ptr<Camera>, 2> cameras_;
  std::unique_ptr<HandArm> hand_arm_;
  std::unique_ptr<Hand> hand_;
  std::array<hal::PanTiltDevice*, 2> ptu_{};
  hal::GripperDevice* hand_controller_ = nullptr;
  StallSetter set_stall_;
  std::vector<CellObject> objects_;
  std::vector<CellObject> clutter_;
  std::optional<int> held_;
  Rigid3d palm_from_held_;
  GraspJudgement last_grasp_;
  std::vector<CellEvent> events_;
  int collisions_ = 0;
  std::vector<int> disturbed_;
  std::array<std::vector<GroundTruth>, 2> truth_;  // every frame, when keep_truth
  uint64_t frames_ = 0;
};

}  // namespace idi::sim
