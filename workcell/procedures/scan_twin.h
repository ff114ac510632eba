// The scan-and-pick cell of the digital twin (shared/sim/cell): the twin of `seed` — the same arms, rail
// and Biclops head as the calibration twins of that seed (`calibrate robot|rtu|ptu --sim --seed N`), so
// their calibrations apply here — with the simulated PTUs and Barrett hand of workcell/devices attached,
// one object on the rotary table and clutter on the floor around it.
//
// Ground truth (the object's corners, whether the hand really held and lifted it, where the object ended
// up) is for tests, studies and reports: Evaluate() scores a ScanReport against it.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "shared/sim/cell/cell_twin.h"
#include "workcell/devices/barrett/barrett_sim.h"
#include "workcell/devices/ptu/ptu_sim.h"
#include "workcell/procedures/scan.h"

namespace idi::workcell {

struct ScanTwinOptions {
  unsigned seed = 1;            // the cell (arms, rail, head)
  sim::ObjectKind kind = sim::ObjectKind::kBox;
  unsigned scene = 0;           // which object of that kind, and its place on the table
  double max_offset_mm = 60;    // the object's distance from the table centre
  int clutter_objects = 6;
  bool keep_truth = false;
  double rail_repeatability_mm = -1;  // >= 0: replaces the cell's (0.1 mm std; 0 for a rail that lands exactly)
  Status Check() const;
};

// How a scan did against the truth.
struct ScanTruth {
  int true_vertices = 0;        // corners of the object (none for a cylinder)
  int matched_vertices = 0;     // with a model point within `match_mm`
  double mean_vertex_error_mm = 0, max_vertex_error_mm = 0;
  // Per true corner: its error (-1 when not matched) and its height above the table top.
  std::vector<double> vertex_error_mm, vertex_height_mm;
  std::vector<int> vertex_views;  // per true corner: the views that observe its model point (0 when not matched)
  int object_points = 0;        // model points the scan put on the object
  int spurious_points = 0;      // of those, farther than `match_mm` from every true corner (non-cylinders)
  // The model's edges between object points: those joining the matches of two corners the object's
  // wireframe joins, and the rest (an edge through the solid or to a spurious point: it can fake a wall
  // in the grasp planner's cross-sections).
  int true_edges = 0, false_edges = 0;
  std::vector<std::string> false_edge_list;  // "model points a-b (corners i-j)", for the study's log
  bool held = false;            // the hand's grasp held (the twin's contact physics)
  bool lifted = false;          // the object rose with the hand
  bool placed = false;          // it ended up on the table at the place position (within 20 mm)
  int collisions = 0;
  std::string grasp_reason;
  double match_mm = 5.0;
  // A cylinder (fitted from its silhouettes): errors of its axis, radius and top height.
  double cylinder_axis_error_mm = -1, cylinder_radius_error_mm = -1, cylinder_top_error_mm = -1;
};

// The correspondence against the truth over every pair of views (issue 7: precision >= 99 %, recall >= 95 %,
// median epipolar error of the matched points <= 0.1 px). Every IDI point the correspondence saw is
// labelled with the visible true 3D corners whose images lie within 1.5 px of it (usually one; two where
// corners meet in one point of the image), or with none (a T-junction, a texture corner, a stray point);
// a pair's match is true when both points carry the same corner.
inline constexpr double kBackgroundMarginMm = 20.0;

struct CorrespondenceTruth {
  long true_matches = 0, false_matches = 0;
  // Pairs of points at no true corner whose track's 3D point lies away from the target (more than
  // kBackgroundMarginMm outside its box): background inside the object region, counted in neither.
  long background_matches = 0;
  long corners_matched = 0;  // per pair: distinct true corners among the true matches
  long found_in_both = 0;    // per pair: true corners found as an IDI point (inside the object region) in both views
  long visible_in_both = 0;  // per pair: true corners visible inside the object region in both views
  std::vector<double> epipolar_px;  // every matched pair's epipolar error (calibrated projections)
  // The same errors split by whether the pair's views share a station (both cameras of one head pose:
  // no arm, rail or table motion between them) or not.
  std::vector<double> epipolar_same_station_px, epipolar_across_stations_px;
  // Every matched pair's epipolar error with the views as the bundle adjustment left them (each station's
  // rail stop estimated).
  std::vector<double> epipolar_adjusted_px;
  // Every IDI point labelled with exactly one corner: its distance to that corner's image and its own
  // sigma_px (the front end's accuracy on the scan's images; the points of every view, matched or not).
  std::vector<double> point_error_px, point_sigma_px;
  // With EvaluateCorrespondence's `list_over_px` > 0: one line per labelled IDI point farther than that
  // from its corner, saying which view and corner, the junction, the point's own sigma, and for each of
  // its lines how far the true corner lies off it and its angle to the nearest true edge.
  std::vector<std::string> far_points;
  bool scored = false;       // false without kept truth (ScanTwinOptions::keep_truth) or views that do not line up
  double precision() const { return Ratio(true_matches, true_matches + false_matches); }
  double recall() const { return Ratio(corners_matched, found_in_both); }
  double recall_of_visible() const { return Ratio(corners_matched, visible_in_both); }
  // Pools another scan's counts and epipolar errors into these (over several scenes).
  void Add(const CorrespondenceTruth& other);
  static double Ratio(long a, long b) { return b > 0 ? static_cast<double>(a) / static_cast<double>(b) : 0.0; }
};

class ScanTwin {
 public:
  explicit ScanTwin(const ScanTwinOptions& options);
  ~ScanTwin();
  ScanTwin(const ScanTwin&) = delete;
  ScanTwin& operator=(const ScanTwin&) = delete;

  ScanDevices Devices();
  // The cell's setup as the operator knows it (the table's place and size).
  ScanOptions SetupOptions() const;
  sim::CellTwin& cell() { return *cell_; }
  const sim::CellObject& target_at_start() const { return target_; }

  // Ground truth: the calibration a perfect calibration would give (tests that score the scan alone), and
  // the scan's result against the truth.
  ScanCalibration TrueCalibration() const;
  ScanTruth Evaluate(const ScanReport& report, const ScanOptions& options) const;
  // Needs ScanTwinOptions::keep_truth: the scan takes one frame per camera per station, in the order of
  // report.views, and the twin kept each frame's truth.
  CorrespondenceTruth EvaluateCorrespondence(const ScanReport& report, double list_over_px = 0) const;

 private:
  ScanTwinOptions options_;
  std::array<calib::PtuCameraModel, 2> head_;
  std::unique_ptr<sim::CellTwin> cell_;
  std::array<std::unique_ptr<SimPanTilt>, 2> ptu_;
  std::unique_ptr<SimGripper> hand_;
  sim::CellObject target_;
  bool lifted_ = false;
};

}  // namespace idi::workcell
