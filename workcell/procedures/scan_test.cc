// Scan and pick on the cell twin: the views come from the calibration's chain, the model's corners land
// on the object's, the hand lifts it and puts it down at the place position; bad set-ups and an operator's
// cancel end the procedure with a clear status and the arms stopped.
#include "workcell/procedures/scan.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

#include "shared/util/units.h"
#include "workcell/procedures/scan_twin.h"

namespace idi::workcell {
namespace {

ScanTwinOptions Twin(sim::ObjectKind kind, unsigned scene) {
  ScanTwinOptions o;
  o.seed = 3;
  o.kind = kind;
  o.scene = scene;
  o.clutter_objects = 4;
  return o;
}

// With a perfect calibration the scan is limited by the images alone: the box's corners within a fraction
// of a millimetre, and the pick succeeds in the twin's contact physics.
TEST(ScanTest, BoxIsReconstructedPickedAndPlaced) {
  ScanTwin twin(Twin(sim::ObjectKind::kBox, 0));
  ScanDevices d = twin.Devices();
  ScanOptions o = twin.SetupOptions();
  if (const char* dir = std::getenv("IDI_SCAN_TEST_OUT")) o.out_dir = dir;  // to look at the views
  auto r = ScanAndPick(d, twin.TrueCalibration(), o);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  ASSERT_EQ(r->views.size(), 2 * o.azimuths_deg.size());
  for (const ScanView& v : r->views) {
    EXPECT_EQ(v.azimuth_deg, o.azimuths_deg[static_cast<std::size_t>(v.station)]) << "every default station is reachable";
  }
  const ScanTruth t = twin.Evaluate(*r, o);
  EXPECT_GE(t.matched_vertices, 6) << "a box seen from above shows its top four and two or more bottom corners";
  EXPECT_LT(t.mean_vertex_error_mm, 0.3);
  EXPECT_LT(t.max_vertex_error_mm, 1.0);
  EXPECT_EQ(t.spurious_points, 0);
  EXPECT_TRUE(r->pick.grasped && r->pick.lifted && r->pick.placed) << r->pick.outcome;
  EXPECT_TRUE(t.held) << t.grasp_reason;
  EXPECT_TRUE(t.placed);
  EXPECT_EQ(t.collisions, 0);
  // The bottom corners found are held on the table top, whose height the adjustment estimates; the twin's
  // table is where the setup says, and the object stands on it.
  int bottom_found = 0;
  for (std::size_t k = 0; k < t.vertex_error_mm.size(); ++k)
    bottom_found += t.vertex_height_mm[k] < 1.0 && t.vertex_error_mm[k] >= 0;
  EXPECT_GE(static_cast<int>(r->structure.on_support.size()), bottom_found);
  ASSERT_EQ(r->structure.adjustment.plane_offset.size(), 1u);
  EXPECT_NEAR(r->structure.adjustment.plane_offset[0], o.table_centre_world.z(), 0.1);
  for (const int i : r->structure.on_support) {
    EXPECT_NEAR(
        r->structure.model.points[static_cast<std::size_t>(i)].xyz.z(), r->structure.adjustment.plane_offset[0], 0.2);
  }
  EXPECT_TRUE(ScanReportJson(*r).contains("table_top_z_mm"));
  // Without the table the same scan leaves them free, and the adjustment has no plane.
  ScanTwin again(Twin(sim::ObjectKind::kBox, 0));
  ScanDevices d2 = again.Devices();
  o.points_on_table = false;
  o.out_dir.clear();
  auto unheld = ScanAndPick(d2, again.TrueCalibration(), o);
  ASSERT_TRUE(unheld.ok()) << unheld.status().ToString();
  EXPECT_TRUE(unheld->structure.on_support.empty());
  EXPECT_TRUE(unheld->structure.adjustment.plane_offset.empty());
}

// The correspondence against the twin's truth over every view pair (issue 7: precision >= 99 %, recall
// >= 95 %, over all four kinds of object: scan_study). Brackets are the hard case: legs and inner faces
// give corners that line up along epipolar lines, and a wrong point chained into a track (0.9-1.4 px off
// its triangulation) must be dropped by the track check: with the old 1.5 px check these three scenes
// give 95.3 % (17 false), with 0.8 px 98.9 % (4 false: one view's point is the image of a visible corner
// and lies 0.4 px from the hidden corner of the track, which no image measurement can tell apart).
TEST(ScanTest, CorrespondenceOfBracketScenesIsPrecise) {
  CorrespondenceTruth pooled;
  for (unsigned scene = 0; scene < 3; ++scene) {
    ScanTwinOptions to;
    to.seed = 1;
    to.kind = sim::ObjectKind::kLBracket;
    to.scene = scene;
    to.keep_truth = true;
    ScanTwin twin(to);
    ScanDevices d = twin.Devices();
    ScanOptions o = twin.SetupOptions();
    // The four stations' views alone, whether or not a grasp fits their model (that depends on the noise's
    // draw: with the sensor seeded otherwise, a trial, scenes 1 and 2 fitted none and took the second round).
    o.pick = false;
    o.extra_azimuths_deg.clear();
    auto r = ScanAndPick(d, twin.TrueCalibration(), o);
    ASSERT_TRUE(r.ok()) << r.status().ToString();
    ASSERT_EQ(r->views.size(), 2 * o.azimuths_deg.size());
    const CorrespondenceTruth c = twin.EvaluateCorrespondence(*r);
    ASSERT_TRUE(c.scored) << "scene " << scene << ": frames and views do not line up";
    pooled.Add(c);
  }
  ASSERT_GT(pooled.true_matches, 200) << "three bracket scans of 8 views match hundreds of corner pairs";
  EXPECT_GE(pooled.precision(), 0.98) << pooled.true_matches << " true, " << pooled.false_matches << " false";
  // Recall of brackets, the hard case: 93.2 % over scan_study --oracle --seed 77 --object bracket --scenes
  // 45; these three scenes gave 97.1 % with the sensor's generator as it is and 95.8, 95 or more, 94.1 and
  // 93.1 % with it seeded four other ways (trials). Issue 7's 95 % is over all four kinds (scan_study).
  EXPECT_GE(pooled.recall(), 0.92) << pooled.corners_matched << " of " << pooled.found_in_both;
  std::vector<double>& epipolar = pooled.epipolar_px;
  std::nth_element(epipolar.begin(), epipolar.begin() + static_cast<long>(epipolar.size() / 2), epipolar.end());
  EXPECT_LT(epipolar[epipolar.size() / 2], 0.15) << "median epipolar error of the matched points, px";
  // Between the two cameras of one station nothing moved (no rail, arm or table motion), so there the
  // epipolar error is the front end's and the correspondence's alone; across stations the rail's
  // repeatability (0.1 mm, about 0.12 px at 1 m) adds to it. Over the scan study's scenes: 0.04 px within
  // a station, 0.14 px across.
  std::vector<double>& within = pooled.epipolar_same_station_px;
  ASSERT_GT(within.size(), 50u);
  ASSERT_EQ(within.size() + pooled.epipolar_across_stations_px.size(), pooled.epipolar_px.size());
  std::nth_element(within.begin(), within.begin() + static_cast<long>(within.size() / 2), within.end());
  std::printf("epipolar error within a station: %zu pairs, median %.4f px\n", within.size(), within[within.size() / 2]);
  EXPECT_LT(within[within.size() / 2], 0.07) << "median epipolar error of the points matched within a station, px";
  // The bundle adjustment estimates each station's rail stop; with the views as it leaves them the
  // stations agree nearly as well as the two cameras of one station do (0.046 px over the scan study's
  // 120 scenes, against 0.12-0.13 px across stations before the adjustment). These three bracket scenes
  // alone give 0.070-0.072 px, by the image noise's draw and the front end's options: the limit leaves
  // that spread room and still fails if the rail stops are not estimated.
  std::vector<double>& adjusted = pooled.epipolar_adjusted_px;
  ASSERT_EQ(adjusted.size(), pooled.epipolar_px.size());
  std::nth_element(adjusted.begin(), adjusted.begin() + static_cast<long>(adjusted.size() / 2), adjusted.end());
  std::printf("epipolar error with the adjusted views: median %.4f px\n", adjusted[adjusted.size() / 2]);
  EXPECT_LT(adjusted[adjusted.size() / 2], 0.08) << "median epipolar error with each station's rail stop estimated, px";
  // Each labelled IDI point against its true corner's image: the front end's accuracy on these images
  // (0.05 px median over the scan study's scenes).
  ASSERT_EQ(pooled.point_error_px.size(), pooled.point_sigma_px.size());
  ASSERT_GT(pooled.point_error_px.size(), 50u);
  std::vector<double> point_error = pooled.point_error_px;
  std::nth_element(
      point_error.begin(), point_error.begin() + static_cast<long>(point_error.size() / 2), point_error.end());
  std::printf("IDI points against the truth: %zu, median error %.4f px\n",
              point_error.size(),
              point_error[point_error.size() / 2]);
  EXPECT_LT(point_error[point_error.size() / 2], 0.1) << "median error of the labelled IDI points, px";
}

// Scenes where robot 2 reaches none of the poses of the best grasp from any rail position (in seed 1's
// prism 26 its IK is 171 mm off) depend on the image noise's draw, through the model the grasps are
// planned on: over scan_study --oracle --object prism --scenes 45, seed 1's prism 26, seed 3's 0 and 16,
// seed 77's 7 and 44 (with the sensor seeded otherwise, a trial: seed 3's 0, 16, 33, seed 77's 7, 30, 44).
// The test takes the first candidate where robot 2 took a lower-ranked grasp, and fails when none does.
// There it must pick the prism; with only the best grasp the scan fails.
TEST(ScanTest, RobotTwoTakesTheBestGraspItCanReach) {
  bool tested = false;
  for (const auto& [seed, scene] : {std::pair<unsigned, unsigned>{1, 26}, {3, 0}, {77, 7}, {3, 16}, {77, 44}}) {
    ScanTwinOptions to;
    to.seed = seed;
    to.kind = sim::ObjectKind::kTriangularPrism;
    to.scene = scene;
    ScanTwin twin(to);
    ScanDevices d = twin.Devices();
    ScanOptions o = twin.SetupOptions();
    auto r = ScanAndPick(d, twin.TrueCalibration(), o);
    ASSERT_TRUE(r.ok()) << "seed " << seed << ", prism " << scene << ": " << r.status().ToString();
    if (r->pick.grasp_rank == 0) continue;
    tested = true;
    SCOPED_TRACE("seed " + std::to_string(seed) + ", prism " + std::to_string(scene));
    const ScanTruth t = twin.Evaluate(*r, o);
    EXPECT_TRUE(t.held && t.placed) << t.grasp_reason << "; " << r->pick.outcome;
    o.grasp_alternatives = 1;
    ScanTwin again(to);
    ScanDevices d2 = again.Devices();
    EXPECT_FALSE(ScanAndPick(d2, again.TrueCalibration(), o).ok())
        << "with the best grasp alone robot 2 cannot pick it";
    break;
  }
  EXPECT_TRUE(tested)
      << "robot 2 reached the best grasp in every candidate scene: the test no longer covers the fallback";
}

// Scenes where the four stations' model lacks a face the grasp needs (the planner finds no grasp on it; on the true
// bracket it finds 8) depend on the image noise's draw and on the front end: with the sensor's generator as it is,
// seed 77's brackets 5, 9 and 33 before the IDI points' gap test (IdiOptions::max_gap_px), 5 alone with it (its faint
// corners complete 9's and 33's models from the first round); with it seeded otherwise (trials), 21, 32 and 33, or 21
// and 29 (there 33 took the second round and still fitted no grasp). The test takes the first of these candidates that
// needs the second round, and fails when none does. There the scan must take the second round of stations, rebuild the
// model from all 14 views and pick the bracket. Without the second round the pick fails; a scan without a pick still
// returns the model, with no grasp.
TEST(ScanTest, SecondRoundOfStationsWhenNoGraspFitsTheModel) {
  ScanTwinOptions to;
  to.seed = 77;
  to.kind = sim::ObjectKind::kLBracket;
  to.keep_truth = true;
  bool tested = false;
  for (const unsigned scene : {9u, 33u, 5u, 21u, 32u}) {
    to.scene = scene;
    ScanTwin twin(to);
    ScanDevices d = twin.Devices();
    ScanOptions o = twin.SetupOptions();
    auto r = ScanAndPick(d, twin.TrueCalibration(), o);
    if (!r.ok()) {
      // The second round does not always give the faces a grasp needs (with the sensor reseeded, a
      // trial: bracket 33); the scan then fails naming it, and the next candidate is tried.
      EXPECT_EQ(r.status().code(), StatusCode::kNotFound) << r.status().ToString();
      EXPECT_NE(r.status().message().find("second round"), std::string::npos) << r.status().ToString();
      continue;
    }
    if (!r->second_round) continue;
    tested = true;
    SCOPED_TRACE("scene " + std::to_string(scene));
    EXPECT_TRUE(r->grasp_found);
    EXPECT_EQ(r->views.size(), 2 * (o.azimuths_deg.size() + o.extra_azimuths_deg.size()));
    const ScanTruth t = twin.Evaluate(*r, o);
    EXPECT_TRUE(t.held && t.placed) << t.grasp_reason << "; " << r->pick.outcome;
    // The worst corner as in most bracket scans: over scan_study --oracle --seed 77 --object bracket
    // --scenes 45, the scenes' worst corners have median 0.25 mm and 90th percentile 0.85 mm; scenes 5, 9
    // and 33 (second round) 0.20-0.23 mm, and scene 33 0.80 mm under another noise draw (a trial).
    EXPECT_LT(t.max_vertex_error_mm, 1.0);
    // The extra views match the object's corners about as well as the first round's: the pairs at no true
    // corner are mostly background past the table. The precision counts view pairs, so one wrong track seen in
    // n views weighs n (n - 1) / 2 false pairs: per scene it moves in steps. Measured on the second round's 14
    // views: scene 9 100 % (426 pairs) without the gap test; scene 5 97.99 % (6 false of 299) without it,
    // 96.52 % (11 of 316) with it. Over 45 bracket scenes (scan_study --oracle --seed 77 --object bracket
    // --scenes 45) 99.74 % without and 99.59 % with it.
    const CorrespondenceTruth m = twin.EvaluateCorrespondence(*r);
    ASSERT_TRUE(m.scored);
    EXPECT_GE(m.precision(), 0.95) << m.false_matches << " false of " << m.true_matches + m.false_matches;
    o.extra_azimuths_deg.clear();
    ScanTwin again(to);
    ScanDevices d2 = again.Devices();
    const auto without = ScanAndPick(d2, again.TrueCalibration(), o);
    ASSERT_FALSE(without.ok()) << "without the second round the scan picked it too";
    EXPECT_EQ(without.status().code(), StatusCode::kNotFound) << without.status().ToString();
    // The same scan without a pick: the first round's model, reported with no grasp.
    o.pick = false;
    ScanTwin third(to);
    ScanDevices d3 = third.Devices();
    const auto model_only = ScanAndPick(d3, third.TrueCalibration(), o);
    ASSERT_TRUE(model_only.ok()) << "a scan without a pick failed because no grasp fits: "
                                 << model_only.status().ToString();
    EXPECT_FALSE(model_only->grasp_found);
    EXPECT_NE(model_only->no_grasp_reason.find("no grasp fits"), std::string::npos) << model_only->no_grasp_reason;
    EXPECT_FALSE(model_only->second_round);
    EXPECT_FALSE(model_only->pick.attempted);
    EXPECT_GE(model_only->object_points.size(), 6u) << "the first round's model is there";
    const nlohmann::json j = ScanReportJson(*model_only);
    EXPECT_TRUE(j["grasp"].is_null());
    EXPECT_EQ(j["no_grasp_reason"], model_only->no_grasp_reason);
    EXPECT_TRUE(ScanReportJson(*r)["grasp"].is_object());
    break;
  }
  EXPECT_TRUE(tested) << "no candidate scene needs the second round: the test no longer covers it";
}

// Observations that the adjustment followed can leave a corner 0.4-0.7 mm off; with the views adjusted,
// that corner's observations fail the chi-square test and those that disagree are dropped. Which scenes
// show it depends on the image noise's draw: over scan_study --oracle --seed 77 --object box --scenes 45
// (and --no-adjusted-test), boxes 4, 20 and 32 (0.44, 0.41, 0.66 mm -> 0.14, 0.07, 0.13 mm); elsewhere the
// worst corner moves by 0.03 mm at most. Over these three scenes pooled, the test must drop observations
// and cut the sum of the worst-corner errors by 15 %, and make no scene's worst corner 0.1 mm worse. With
// the sensor's generator seeded four other ways (trials), the sum fell by 63, 46, 23 and 55 % (78 % as
// it is); in two of them box 20 got worse with the test (0.51 -> 0.57, 0.47 -> 0.54 mm): the test does
// not always find the observations that disagree.
TEST(ScanTest, AnObservationThatDisagreesAfterTheAdjustmentIsDropped) {
  ScanTwinOptions to;
  to.seed = 77;
  to.kind = sim::ObjectKind::kBox;
  double sum_mm[2] = {0, 0};
  int dropped = 0;
  for (const unsigned scene : {4u, 20u, 32u}) {
    to.scene = scene;
    double max_error_mm[2] = {0, 0};
    for (const bool test : {false, true}) {
      ScanTwin twin(to);
      ScanDevices d = twin.Devices();
      ScanOptions o = twin.SetupOptions();
      o.pick = false;
      if (!test) o.structure.adjusted_outlier_z = 0;
      auto r = ScanAndPick(d, twin.TrueCalibration(), o);
      ASSERT_TRUE(r.ok()) << "scene " << scene << ": " << r.status().ToString();
      if (test) {
        dropped += r->structure.adjusted_observations_dropped;
      } else {
        EXPECT_EQ(r->structure.adjusted_observations_dropped, 0) << "scene " << scene;
      }
      max_error_mm[test ? 1 : 0] = twin.Evaluate(*r, o).max_vertex_error_mm;
      sum_mm[test ? 1 : 0] += max_error_mm[test ? 1 : 0];
    }
    std::printf(
        "box %u: worst corner %.3f mm without the test, %.3f mm with it\n", scene, max_error_mm[0], max_error_mm[1]);
    EXPECT_LT(max_error_mm[1], max_error_mm[0] + 0.1) << "scene " << scene;
  }
  EXPECT_GT(dropped, 0);
  EXPECT_LT(sum_mm[1], 0.85 * sum_mm[0]) << "the worst corners with the test against without";
}

// A cylinder has no corners: it is fitted from its silhouettes (vertical tangent planes), refined on its
// top rim (the limbs alone left the top 15-23 mm off, the axis 1-10 mm), and picked. Seed 77's scene 13
// is one where the largest consensus of limb planes was wrong (axis 69 mm off) and the rim picks the
// right one.
TEST(ScanTest, CylinderIsFittedFromItsSilhouettesAndTopRimAndPicked) {
  for (const auto& [seed, scene] : {std::pair<unsigned, unsigned>{3, 1}, {77, 13}}) {
    ScanTwinOptions to = Twin(sim::ObjectKind::kCylinder, scene);
    to.seed = seed;
    ScanTwin twin(to);
    ScanDevices d = twin.Devices();
    ScanOptions o = twin.SetupOptions();
    auto r = ScanAndPick(d, twin.TrueCalibration(), o);
    ASSERT_TRUE(r.ok()) << r.status().ToString();
    ASSERT_TRUE(r->cylinder);
    const ScanTruth t = twin.Evaluate(*r, o);
    EXPECT_LT(t.cylinder_axis_error_mm, 0.3) << "seed " << seed;
    EXPECT_LT(t.cylinder_radius_error_mm, 0.3) << "seed " << seed;
    EXPECT_LT(t.cylinder_top_error_mm, 0.3) << "seed " << seed;
    EXPECT_TRUE(t.held && t.placed) << "seed " << seed << ": " << t.grasp_reason << "; " << r->pick.outcome;
  }
}

// A scan without a pick returns the model even when no grasp fits it, a cylinder too (before, a
// cylinder the planner refused, here one wider than a hand that opens to 30 mm, ended the scan with the
// planner's NotFound and no model).
TEST(ScanTest, AScanOnlyCylinderThatNoGraspFitsIsReported) {
  ScanTwin twin(Twin(sim::ObjectKind::kCylinder, 1));
  ScanDevices d = twin.Devices();
  ScanOptions o = twin.SetupOptions();
  o.pick = false;
  o.grasp.hand.max_aperture_mm = 30;
  auto r = ScanAndPick(d, twin.TrueCalibration(), o);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_TRUE(r->cylinder);
  EXPECT_FALSE(r->grasp_found);
  EXPECT_FALSE(r->second_round) << "more views do not change a fitted cylinder";
  EXPECT_NE(r->no_grasp_reason.find("no grasp fits"), std::string::npos) << r->no_grasp_reason;
}

// A pick that fails (here no rail position lets robot 2 reach the place position, 5 m up) returns only
// its status; the model and the grasps planned were written before the arm moved, so the scan is not
// lost with the pick.
TEST(ScanTest, AFailedPickKeepsTheScanOnDisk) {
  ScanTwin twin(Twin(sim::ObjectKind::kBox, 2));
  ScanDevices d = twin.Devices();
  ScanOptions o = twin.SetupOptions();
  o.place_offset_world = Vec3d(0, 0, 5000);
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("idi_scan_failed_pick_" + std::to_string(::getpid()));
  o.out_dir = dir.string();
  const auto r = ScanAndPick(d, twin.TrueCalibration(), o);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("no rail position of robot 2 reaches"), std::string::npos)
      << r.status().ToString();
  std::ifstream in(dir / "scan_before_pick.json");
  ASSERT_TRUE(in.good()) << "no scan_before_pick.json in " << dir;
  const nlohmann::json j = nlohmann::json::parse(in);
  EXPECT_FALSE(j.at("grasp").is_null());
  EXPECT_GE(j.at("points").size(), 8u);
  std::filesystem::remove_all(dir);
}

// The projection matrices follow the encoders: a view's camera is where the chain puts it for the true
// model (the twin renders from the same chain), up to the rail's repeatability (0.1 mm sigma along it).
TEST(ScanTest, ChainMatchesTheTwinsCamera) {
  ScanTwin twin(Twin(sim::ObjectKind::kTriangularPrism, 1));
  ScanDevices d = twin.Devices();
  ScanOptions o = twin.SetupOptions();
  o.pick = false;
  o.azimuths_deg = {0};
  auto r = ScanAndPick(d, twin.TrueCalibration(), o);
  // One station gives two views; reconstruction may still find the prism.
  ASSERT_TRUE(r.ok() || r.status().code() == StatusCode::kNotFound) << r.status().ToString();
  auto world_from_cam = twin.cell().TrueWorldFromCamera(BiclopsSide::kRight);
  ASSERT_TRUE(world_from_cam.ok());
  const auto js = d.arm1->ReadJoints();
  const auto rs = d.rail1->Read();
  const auto ps = d.ptu[1]->Read();
  ASSERT_TRUE(js.ok() && rs.ok() && ps.ok());
  const Rigid3d chain = ChainWorldFromCamera(twin.TrueCalibration(), 1, js->q_rad, rs->position_mm, ps->pan_rad, ps->tilt_rad);
  EXPECT_LT((chain.translation - world_from_cam->translation).norm(), 0.5);
  EXPECT_LT((chain.rotation - world_from_cam->rotation).norm(), 1e-9);
  // Fixating put the table's aim point near the image centre (within the PTU's step of ~0.9 mrad).
  const Vec3d aim = o.table_centre_world + Vec3d(0, 0, o.aim_height_mm);
  const auto px = Project(twin.TrueCalibration().cameras[1].Camera(), chain.Inverse() * aim);
  ASSERT_TRUE(px.has_value());
  EXPECT_LT((*px - Vec2d(320, 240)).norm(), 15.0);
}

TEST(ScanTest, BadSetUpsAreRejected) {
  ScanTwin twin(Twin(sim::ObjectKind::kBox, 2));
  ScanDevices d = twin.Devices();
  ScanOptions o = twin.SetupOptions();
  ScanDevices missing = d;
  missing.camera[1] = nullptr;
  auto r = ScanAndPick(missing, twin.TrueCalibration(), o);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(r.status().message().find("cameras"), std::string::npos) << r.status().ToString();
  o.table_centre_world.x() = std::nan("");
  EXPECT_EQ(ScanAndPick(d, twin.TrueCalibration(), o).status().code(), StatusCode::kInvalidArgument);
  o = twin.SetupOptions();
  o.azimuths_deg.clear();
  EXPECT_EQ(ScanAndPick(d, twin.TrueCalibration(), o).status().code(), StatusCode::kInvalidArgument);
  o = twin.SetupOptions();
  o.extra_azimuths_deg = {0, std::nan("")};
  r = ScanAndPick(d, twin.TrueCalibration(), o);
  EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(r.status().message().find("second round"), std::string::npos) << r.status().ToString();
  o = twin.SetupOptions();
  o.table_flatness_mm = 0;
  r = ScanAndPick(d, twin.TrueCalibration(), o);
  EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
  EXPECT_NE(r.status().message().find("flatness"), std::string::npos) << r.status().ToString();
  o = twin.SetupOptions();
  o.structure.support_snap_mm = -1;
  o.structure.support = optim::BaPlane{};
  EXPECT_EQ(ScanAndPick(d, twin.TrueCalibration(), o).status().code(), StatusCode::kInvalidArgument);
  for (const auto& [z, floor] : {std::pair<double, double>{-1, 0.05}, {3.09, std::nan("")}}) {
    o = twin.SetupOptions();
    o.structure.adjusted_outlier_z = z;
    o.structure.adjusted_sigma_floor_px = floor;
    r = ScanAndPick(d, twin.TrueCalibration(), o);
    EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument);
    EXPECT_NE(r.status().message().find("adjusted_outlier_z"), std::string::npos) << r.status().ToString();
  }
  // Values that compared true to their bounds but hung the rim search (an infinite region) or made a
  // clamp's range empty (a negative rail travel), or let any rail position through (NaN).
  for (int k = 0; k < 4; ++k) {
    o = twin.SetupOptions();
    if (k == 0) o.object_region_height_mm = INFINITY;
    if (k == 1) o.rail1_max_mm = -1;
    if (k == 2) o.rail2_max_mm = std::nan("");
    if (k == 3) o.table_tolerance_mm = INFINITY;
    EXPECT_EQ(ScanAndPick(d, twin.TrueCalibration(), o).status().code(), StatusCode::kInvalidArgument) << k;
  }
  // A table 5 m away: no head pose reaches a view of it; the error names the station.
  o = twin.SetupOptions();
  o.table_centre_world += Vec3d(0, -5000, 0);
  r = ScanAndPick(d, twin.TrueCalibration(), o);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("station 1"), std::string::npos) << r.status().ToString();
}

// An empty table: the scan finds no object and says so (nothing is picked).
TEST(ScanTest, EmptyTableIsReportedNotPicked) {
  ScanTwin twin(Twin(sim::ObjectKind::kBox, 3));
  twin.cell().ClearObjects();
  ScanDevices d = twin.Devices();
  auto r = ScanAndPick(d, twin.TrueCalibration(), twin.SetupOptions());
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kNotFound);
  EXPECT_NE(r.status().message().find("no object"), std::string::npos) << r.status().ToString();
}

TEST(ScanTest, CancelStopsBeforeTheNextStep) {
  ScanTwin twin(Twin(sim::ObjectKind::kBox, 4));
  ScanDevices d = twin.Devices();
  ScanOptions o = twin.SetupOptions();
  int steps = 0;
  o.progress = [&](double, const std::string&) { ++steps; };
  o.cancelled = [&] { return steps >= 2; };  // after the first station
  auto r = ScanAndPick(d, twin.TrueCalibration(), o);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.status().code(), StatusCode::kCancelled);
  EXPECT_TRUE(twin.cell().objects()[0].world_from_object.translation.isApprox(
      twin.target_at_start().world_from_object.translation));
}

// A station out of the arm's reach is moved towards azimuth 0 until it can be reached, and the view
// records where it was taken; without retries the same station fails and the error names it.
TEST(ScanTest, UnreachableStationIsMovedInwards) {
  ScanTwin twin(Twin(sim::ObjectKind::kBox, 0));
  ScanDevices d = twin.Devices();
  ScanOptions o = twin.SetupOptions();
  o.pick = false;
  // In this cell robot 1 cannot put the head at azimuths 120 and 135 deg (1 m from the table), but can
  // at 105 deg.
  o.azimuths_deg = {135, 0};
  o.station_step_deg = 15;
  o.station_retries = 3;
  auto r = ScanAndPick(d, twin.TrueCalibration(), o);
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  ASSERT_EQ(r->views.size(), 4u);
  EXPECT_NEAR(r->views[0].azimuth_deg, 105.0, 1e-9);
  EXPECT_NEAR(r->views[1].azimuth_deg, 105.0, 1e-9);
  EXPECT_EQ(r->views[2].azimuth_deg, 0.0);
  ScanTwin again(Twin(sim::ObjectKind::kBox, 0));
  ScanDevices d2 = again.Devices();
  o.station_retries = 0;
  r = ScanAndPick(d2, again.TrueCalibration(), o);
  ASSERT_FALSE(r.ok());
  EXPECT_NE(r.status().message().find("station 1"), std::string::npos) << r.status().ToString();
}

// A wrong match alone in the object region is left out of the object; a corner without edges close to
// the object, and points joined by an edge, stay.
TEST(ScanTest, StrayPointsAreDroppedJoinedPointsKept) {
  ScanOptions o;
  const Vec3d t = o.table_centre_world;
  StructureModel m;
  auto add = [&](const Vec3d& rel) {
    ModelPoint p;
    p.id = static_cast<int>(m.points.size());
    p.xyz = t + rel;
    m.points.push_back(p);
    return p.id;
  };
  // A box's top face, 100 x 60 mm, 70 mm high, its four edges.
  for (const auto& [x, y] : std::vector<std::pair<double, double>>{{-50, -30}, {50, -30}, {50, 30}, {-50, 30}}) add(Vec3d(x, y, 70));
  m.edges = {{0, 1}, {1, 2}, {2, 3}, {0, 3}};
  const int bottom = add(Vec3d(50, -30, 0));        // a bottom corner, its vertical edge not reconstructed
  const int near = add(Vec3d(80, 0, 35));           // 30 mm off the top face's box: within object_link_mm
  const int stray = add(Vec3d(-160, 120, 2));       // the table rim's corner, matched wrongly
  const int pair_a = add(Vec3d(150, -120, 0)), pair_b = add(Vec3d(150, -60, 0));  // two joined points
  m.edges.emplace_back(pair_a, pair_b);
  const int outside = add(Vec3d(0, 0, 500));        // joined to a point outside the region: counts as alone
  const int far_end = add(Vec3d(400, 400, 0));
  m.edges.emplace_back(outside, far_end);
  std::vector<int> region = {0, 1, 2, 3, bottom, near, stray, pair_a, pair_b, outside};
  const std::vector<int> kept = DropStrayPoints(m, region, o);
  EXPECT_EQ(kept, (std::vector<int>{0, 1, 2, 3, bottom, near, pair_a, pair_b}));
  // Too few points to tell the object from a stray: nothing is dropped.
  EXPECT_EQ(DropStrayPoints(m, {0, stray}, o), (std::vector<int>{0, stray}));
  o.object_link_mm = 10;  // the near corner is now too far
  const std::vector<int> tight = DropStrayPoints(m, region, o);
  EXPECT_EQ(std::count(tight.begin(), tight.end(), near), 0);
  EXPECT_EQ(std::count(tight.begin(), tight.end(), bottom), 1);
}

}  // namespace
}  // namespace idi::workcell
