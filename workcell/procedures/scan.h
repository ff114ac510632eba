// Scan and pick (chapter 8 on the cell, §8.12.3): arm 1 carries the Biclops head to stations around the
// rotary table, both pan-tilt cameras fixate the table and take images; every view's projection matrix
// comes from the calibrated chain — robot 1's calibrated kinematics at its encoder readings, its rail
// position, the calibrated pan-tilt model at the PTU readings and the calibrated intrinsics (§8.3,
// eqs. 3.10-3.14). The views are reconstructed (EMPL lines, IDI points, bundle correspondence,
// triangulation, bundle adjustment: procedures/structure.h); the object's points give a top grasp for
// the Barrett hand (§8.11, shared/grasp), carried into robot 2's base frame through the rail calibration
// (eq. 3.4); robot 2 approaches, closes the hand, lifts, puts the object down at the place position and
// opens.
//
// Only hal devices and the calibration are used: the procedure runs the same on the twin and the real
// cell. Whether the hand holds something is judged from the finger encoders (stalled fingers).
#pragma once

#include <array>
#include <functional>
#include <string>
#include <vector>

#include "shared/calib/ptu/ptu_calibration.h"
#include "shared/calib/rail_calibration.h"
#include "shared/grasp/grasp_planner.h"
#include "shared/hal/arm.h"
#include "shared/hal/camera.h"
#include "shared/hal/pan_tilt.h"
#include "shared/kinematics/barrett_hand.h"
#include "workcell/procedures/structure.h"

namespace idi::workcell {

struct ScanDevices {
  hal::ArmDevice* arm1 = nullptr;  // carries the Biclops head
  hal::RailDevice* rail1 = nullptr;
  hal::ArmDevice* arm2 = nullptr;  // carries the Barrett hand
  hal::RailDevice* rail2 = nullptr;
  std::array<hal::PanTiltDevice*, 2> ptu{};         // left, right
  std::array<hal::CameraDevice*, 2> camera{};       // left, right
  hal::GripperDevice* hand = nullptr;
};

// The calibration in use: robot models (chapter 4), psi (chapter 5), the pan-tilt cameras (chapter 6),
// and the hand's mounting (design drawing: palm centre along the flange's z).
struct ScanCalibration {
  calib::ArmModel robot1, robot2;
  std::array<double, kRobotToRobotParamCount> psi = calib::NominalPsi();
  std::array<calib::PtuCameraModel, 2> cameras = {calib::PtuCameraModel::Nominal(BiclopsSide::kLeft),
                                                  calib::PtuCameraModel::Nominal(BiclopsSide::kRight)};
  Rigid3d flange_from_palm = Translation(0.0, 0.0, 120.0);
  BarrettHandParams hand;
};

struct ScanOptions {
  // The cell's setup (operator's knowledge): where the table top's centre is in R1, its radius.
  Vec3d table_centre_world = Vec3d(2825, -500, -400);
  double table_radius_mm = 300;
  // Views: stations at these azimuths (deg; 0 looks along +x, from robot 1's side), at this distance
  // from the table centre and elevation; both cameras fixate the point `aim_height_mm` above the table.
  // Four stations spread over 190 deg: the far sides of the object are seen too (a prism's second
  // slope, a bracket's inner faces), which a grasp needs. In the twin (scan_study --oracle, 2 x 120
  // scenes) picks succeed in 92 % of scenes with these, against 71 % with -35, 0, 35.
  std::vector<double> azimuths_deg = {-95, -31.7, 31.7, 95};
  // When no grasp fits the model from those views (a face the grasp needs was not seen, or seen at too
  // low a contrast), a second round of stations at these azimuths, and the model rebuilt from all views.
  // Empty: no second round.
  std::vector<double> extra_azimuths_deg = {-63.3, 0, 63.3};
  // A station the arm cannot reach is moved this much towards azimuth 0, up to station_retries times.
  double station_step_deg = 10;
  int station_retries = 3;
  double view_distance_mm = 1000;
  double elevation_deg = 45;
  double aim_height_mm = 40;
  double rail1_max_mm = 2500;
  double rail2_max_mm = 2500;
  std::vector<double> rail2_candidates_mm = {2400, 2100, 1800, 2500, 1500};
  // Where objects stand: a cylinder of this radius about the table centre, this tall; the images'
  // features outside its projection are ignored (floor tiles, the table's rim, clutter), and the model
  // points inside it (down to `table_tolerance_mm` below the table top) are the object's.
  double object_region_radius_mm = 220;
  double object_region_height_mm = 200;
  // A point of the region joined by edges to no other point is kept only within this of the bounding
  // box (extended down to the table) of the largest group of points joined by edges.
  double object_link_mm = 40;
  double table_tolerance_mm = 5;
  // The adjustment estimates each station's rail stop (mount_prior_mm: the rail's repeatability, 0.1 mm).
  StructureOptions structure = [] {
    StructureOptions so;
    so.bundle_adjustment.mount_prior_mm = 0.1;
    return so;
  }();
  // Model points within structure.support_snap_mm of the table top (an object's bottom corners) are held
  // on it in the adjustment, the table's height estimated within table_height_prior_mm of the setup's
  // value; the corners where a dark face meets the dark table are the least precise in the images.
  bool points_on_table = true;
  double table_height_prior_mm = 0.5;
  double table_flatness_mm = 0.05;
  GraspOptions grasp;
  int grasp_alternatives = 8;  // grasps planned, best first; robot 2 takes the best it can reach
  bool pick = true;
  Vec3d place_offset_world = Vec3d(0, 150, 0);  // where to put it down, from where it stood
  hal::MoveOptions move;
  std::string out_dir;                  // images, overlays, model.ply, scan_before_pick.json (empty: nothing written)
  std::function<bool()> cancelled;      // checked between steps
  std::function<void(double, const std::string&)> progress;
  Status Check() const;
};

struct ScanView {
  StructureView view;
  Joints arm1_q{};
  double rail1_mm = 0;
  double pan_rad = 0, tilt_rad = 0;
  int station = 0;
  double azimuth_deg = 0;  // where the station was taken (moved inwards when the set one was out of reach)
};

struct PickReport {
  bool attempted = false;
  bool grasped = false;  // at least two fingers stalled on something after closing
  bool lifted = false;   // still stalled after the lift
  bool placed = false;   // opened at the place position and retreated
  double rail2_mm = 0;
  int grasp_rank = 0;  // which of the planned grasps robot 2 took (0: the best; more when it was out of reach)
  std::array<double, 3> finger_rad{};
  std::string outcome;
};

struct ScanReport {
  std::vector<ScanView> views;
  StructureResult structure;
  std::vector<int> object_points;  // indices into structure.model.points
  // An object without corners, fitted as a standing cylinder from its silhouettes (object_points empty).
  bool cylinder = false;
  Vec2d cylinder_axis_xy = Vec2d::Zero();
  double cylinder_radius_mm = 0, cylinder_top_z = 0;
  // The best grasp, world frame (R1). A scan without a pick (ScanOptions::pick false) still returns the
  // model when no grasp fits it: then grasp_found is false and no_grasp_reason says why.
  bool grasp_found = false;
  std::string no_grasp_reason;
  GraspPlan grasp;
  Rigid3d base2_from_grasp;        // robot 2's base frame at its rail position
  PickReport pick;
  bool second_round = false;  // the extra stations were taken (no grasp fitted the first model)
  double acquisition_s = 0, reconstruction_s = 0, pick_s = 0;
};

// The scan, and the pick when options.pick (with a pick, no grasp fitting the model is an error; without,
// a report with grasp_found false). Errors name the step; on cancel or a device error both arms
// are told to stop.
Result<ScanReport> ScanAndPick(ScanDevices& devices, const ScanCalibration& calibration, const ScanOptions& options);

// The model points (indices) of the object region that belong to the object: a point joined by edges
// to no other point of the region and farther than options.object_link_mm from the box of the largest
// group of joined points (extended down to the table) is a stray match, not the object, and is left out.
std::vector<int> DropStrayPoints(const StructureModel& model, const std::vector<int>& object_points,
                                 const ScanOptions& options);

// World (R1) from camera for robot 1 at `q`, rail position `rail_mm`, PTU readings.
Rigid3d ChainWorldFromCamera(const ScanCalibration& calibration, int camera, const Joints& q, double rail_mm,
                             double pan_rad, double tilt_rad);

// Pan and tilt that put `target_world` on the camera's principal point (Gauss-Newton on the calibrated
// model). NotFound when it is out of the unit's range or behind the camera.
Result<std::array<double, 2>> FixatePtu(const ScanCalibration& calibration, int camera, const Joints& q, double rail_mm,
                                        const Vec3d& target_world, const hal::PanTiltLimits& limits);

// {points: [{id, xyz_mm, views, reproj_rms_px, object}], edges, grasp: {...}, pick: {...}}
nlohmann::json ScanReportJson(const ScanReport& report);

}  // namespace idi::workcell
