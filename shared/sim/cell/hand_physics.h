// The grasp physics of the twin: the Barrett BH8 hand as built (§3.5) closing on the true geometry of
// the objects, and whether the contacts it makes hold the object when it is lifted.
//
// Hand: the finger kinematics of shared/kinematics/barrett_hand.h with the hand's true dimensions; each
// link is a capsule of the pad radius (sampled across the finger's width). Closing turns a finger until
// either link meets something: the finger stalls there (§3.5).
//
// A grasp holds when (1) every finger that stalled stalled on the same object (not the table),
// (2) at least two did, (3) each finger's push (the velocity of its contact point as it closes) lies
// inside the Coulomb friction cone of the contact normal (no slip while squeezing), and (4) the contact
// set is force closure: the origin is strictly inside the convex hull of the linearised cones' wrenches,
// so the grip can resist gravity and any other small disturbance (Nguyen; Ferrari and Canny).
#pragma once

#include <array>
#include <optional>
#include <string>
#include <vector>

#include "shared/geometry/rigid3.h"
#include "shared/kinematics/barrett_hand.h"
#include "shared/sim/cell/cell_objects.h"
#include "shared/util/status.h"

namespace idi::sim {

struct HandTruth {
  Rigid3d flange_from_palm = Translation(0.0, 0.0, 120.0);  // the palm centre 120 mm along the flange's z
  BarrettHandParams fingers;
  double finger_width_mm = 20;
  double palm_half_size_mm = 45;      // the hand's body: a box +-45 mm about the palm centre ...
  double palm_depth_mm = 120;         // ... from the palm plane back to the flange
  double friction = 0.5;              // fingertip pad on the objects (rubber on painted wood / aluminium)
  Status Check() const;
};

// Something the fingers can meet: convex parts placed in the palm frame.
struct Obstacle {
  int id = -1;  // object index (>= 0), or kTableId
  std::vector<ConvexPart> parts;
  Rigid3d palm_from_obstacle;
};
inline constexpr int kTableId = -1;

struct FingerContact {
  int finger = -1;
  int obstacle = kTableId;
  double reading_rad = 0;        // where the finger stalled
  Vec3d point = Vec3d::Zero();   // on the obstacle's surface, palm frame
  Vec3d normal = Vec3d::Zero();  // the obstacle's outward surface normal there, palm frame
  Vec3d push = Vec3d::Zero();    // unit direction the finger pushes at the contact
};

// Where finger `finger` stalls when closed from `start_rad`: the first reading at which its link (a
// swept capsule, sampled across its width) meets an obstacle. nullopt when it closes fully, and for a
// finger index beyond 0..2, a NaN spread or a start that is not an angle within a turn.
std::optional<FingerContact> SweepFinger(const HandTruth& hand, int finger, double spread_rad, double start_rad,
                                         const std::vector<Obstacle>& obstacles);

// Force closure of frictional point contacts (linearised cones of 8 edges), wrenches about `reference`
// with torques divided by `length_scale_mm`. `inward` are the directions into the object.
bool ForceClosure(const std::vector<Vec3d>& points, const std::vector<Vec3d>& inward, double friction,
                  const Vec3d& reference, double length_scale_mm);

struct GraspJudgement {
  bool holds = false;
  int object = -1;              // the object the fingers are on (when they agree)
  std::vector<FingerContact> contacts;
  double worst_cone_margin_deg = 0;  // friction cone half-angle minus the largest push-normal angle
  std::string reason;           // why it holds or not
};
// Judges the stalled fingers (the contacts from SweepFinger; fingers that closed fully have none).
GraspJudgement JudgeGrasp(const HandTruth& hand, const std::vector<FingerContact>& contacts, const Vec3d& centre_of_mass);

// The hand's body (palm box and the three finger links at their readings) against the obstacles: the
// first one it penetrates by more than `tolerance_mm`, naming the part ("palm", "finger 2").
struct HandCollision {
  int obstacle = kTableId;
  std::string part;
};
std::optional<HandCollision> FindHandCollision(const HandTruth& hand, double spread_rad,
                                               const std::array<double, 3>& readings_rad,
                                               const std::vector<Obstacle>& obstacles, double tolerance_mm = 1.0);

}  // namespace idi::sim
