// Issue 7's acceptance study: scan and pick in the cell twin, N scenes each of a box, a triangular prism,
// an L-bracket and a cylinder (clutter on the floor), with the calibration from files (what the cell
// would use; `idi-workcell scan --sim --out DIR` leaves one in DIR/calibration) or, with --oracle, the
// twin's true parameters (the scan's own error, calibration error excluded).
//
// Per scene: views (8 by default: the scan's four stations), reconstruction, grasp, pick; scored against the
// twin's truth: corners found within 5 mm, their error, spurious object points, grasp held / object
// placed, collisions, and the time of features + correspondence + triangulation + bundle adjustment; and the
// correspondence over every view pair: precision and recall of the IDI point matches against the true
// corners, and the epipolar error of the matched points.
//
// Usage: scan_study [--calibration DIR | --oracle] [--scenes 10] [--scene 0] [--seed 1] [--stations K]
//                   [--span DEG] [--object NAME] [--elevation DEG] [--distance MM] [--flat-band]
//                   [--ramp] [--junction-refit DEG] [--refine-poses]
//                   [--no-rail-stops] [--no-track-test] [--no-table-support] [--no-second-round]
//                   [--no-adjusted-test] [--rail-repeatability MM] [--edge-spread DEG]
//                   [--list-points-over PX] [--json FILE] [--out DIR]
// --flat-band, --ramp and --junction-refit DEG turn on the front end's opt-in fits
// (empl.photometric_flat_band, empl.photometric_ramp, empl.junction_refit_angle_deg), --refine-poses the bundle
// adjustment's view poses (within their priors), to measure what they change in the scans; --no-rail-stops holds each
// station's rail stop at its reading (the adjustment estimates them by default); --no-track-test keeps the observations
// a track check by their own sigmas would drop (CorrespondenceOptions::track_outlier_z); --no-table-support leaves the
// points near the table top free (ScanOptions::points_on_table); --no-second-round takes no extra stations when no
// grasp fits the first model (ScanOptions::extra_azimuths_deg); --no-adjusted-test keeps every observation after the
// adjustment (StructureOptions::adjusted_outlier_z); --edge-spread DEG sets the angle about an edge its views must
// span (ModelOptions::min_edge_spread_deg, 2 by default; 0 takes every edge two views vote for);
// --rail-repeatability MM sets
// the twin's rail (0.1 mm std by default; 0 lands exactly where the encoder says), to tell the rail's share
// of the errors.
// --scene K starts at scene K (K, K+1, ... K+N-1), to look again at one scene of a longer study.
// --list-points-over PX lists every IDI point farther than PX from its true corner, with its view, the
// junction and how far the corner lies off each of the point's lines (which line is wrong, and by how much).
// --out DIR keeps each scene's run folder (images, regions, overlays, model) in DIR/OBJECT_SCENE.
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <numeric>
#include <string>
#include <system_error>
#include <vector>

#include "shared/util/statistics.h"
#include "workcell/app/scan_command.h"
#include "workcell/procedures/scan_twin.h"

namespace idi {
namespace {

int Main(int argc, char** argv) {
  std::string cal_dir, json_out, only, out_dir;
  bool oracle = false;
  int scenes = 10, stations = 0, first_scene = 0;  // 0: the scan's default stations
  double span_deg = 0;             // > 0: the stations spread over +-span_deg
  double elevation_deg = 0, distance_mm = 0;
  bool flat_band = false, ramp = false, refine_poses = false, rail_stops = true, track_test = true,
       table_support = true, second_round = true, adjusted_test = true;
  double junction_refit_deg = 0, rail_repeatability_mm = -1, list_over_px = 0, edge_spread_deg = -1;
  unsigned seed = 1;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) {
        fmt::print(stderr, "{} needs a value\n", a);
        std::exit(2);
      }
      return argv[++i];
    };
    // A number, or exit 2 naming the option (atof would take "abc" as 0 and run the default).
    auto number = [&]() -> double {
      const std::string v = next();
      char* end = nullptr;
      const double x = std::strtod(v.c_str(), &end);
      if (v.empty() || *end != '\0' || !std::isfinite(x)) {
        fmt::print(stderr, "scan_study: {} needs a number, got '{}'\n", a, v);
        std::exit(2);
      }
      return x;
    };
    if (a == "--calibration") cal_dir = next();
    else if (a == "--oracle") oracle = true;
    else if (a == "--scenes") scenes = static_cast<int>(number());
    else if (a == "--scene") first_scene = static_cast<int>(number());
    else if (a == "--seed") seed = static_cast<unsigned>(number());
    else if (a == "--stations") stations = static_cast<int>(number());
    else if (a == "--span") span_deg = number();
    else if (a == "--json") json_out = next();
    else if (a == "--out") out_dir = next();
    else if (a == "--object") only = next();
    else if (a == "--elevation") elevation_deg = number();
    else if (a == "--distance") distance_mm = number();
    else if (a == "--flat-band") flat_band = true;
    else if (a == "--ramp")
      ramp = true;
    else if (a == "--refine-poses") refine_poses = true;
    else if (a == "--no-rail-stops") rail_stops = false;
    else if (a == "--no-track-test") track_test = false;
    else if (a == "--no-table-support") table_support = false;
    else if (a == "--no-second-round") second_round = false;
    else if (a == "--no-adjusted-test")
      adjusted_test = false;
    else if (a == "--junction-refit") junction_refit_deg = number();
    else if (a == "--rail-repeatability") rail_repeatability_mm = number();
    else if (a == "--edge-spread") {
      edge_spread_deg = number();
      if (edge_spread_deg < 0) {
        fmt::print(stderr, "scan_study: --edge-spread needs an angle of 0 deg or more, got {}\n", edge_spread_deg);
        return 2;
      }
    } else if (a == "--list-points-over")
      list_over_px = number();
    else {
      fmt::print(
          stderr,
          "usage: scan_study [--calibration DIR | --oracle] [--scenes N] [--scene FIRST] [--seed S] "
          "[--stations K] [--span DEG] "
          "[--object box|prism|bracket|cylinder] [--elevation DEG] [--distance MM] [--flat-band] "
          "[--ramp] [--junction-refit DEG] [--refine-poses] [--no-rail-stops] [--no-track-test] [--no-table-support] "
          "[--no-second-round] [--no-adjusted-test] [--rail-repeatability MM] [--edge-spread DEG] [--list-points-over "
          "PX] "
          "[--json FILE] "
          "[--out DIR]\n");
      return 2;
    }
  }
  if (scenes < 1 || first_scene < 0 || stations < 0 || stations > 8 || !(span_deg >= 0 && span_deg <= 120) ||
      (!oracle && cal_dir.empty())) {
    fmt::print(stderr, "scan_study: give --calibration DIR or --oracle; scenes >= 1; stations 1..8; span 0..120 deg\n");
    return 2;
  }
  {
    workcell::ScanTwinOptions probe;
    probe.rail_repeatability_mm = rail_repeatability_mm;
    if (const Status st = probe.Check(); !st.ok()) {
      fmt::print(stderr, "scan_study: {}\n", st.ToString());
      return 2;
    }
  }
  spdlog::set_level(spdlog::level::warn);
  workcell::ScanCalibration cal;
  if (!oracle) {
    auto files = workcell::EnsureSimCalibration(cal_dir, seed);
    if (!files.ok()) {
      fmt::print(stderr, "{}\n", files.status().ToString());
      return 1;
    }
    auto c = workcell::LoadScanCalibration(*files);
    if (!c.ok()) {
      fmt::print(stderr, "{}\n", c.status().ToString());
      return 1;
    }
    cal = *c;
  }
  const std::vector<std::pair<const char*, sim::ObjectKind>> kinds = {{"box", sim::ObjectKind::kBox},
                                                                      {"prism", sim::ObjectKind::kTriangularPrism},
                                                                      {"bracket", sim::ObjectKind::kLBracket},
                                                                      {"cylinder", sim::ObjectKind::kCylinder}};
  nlohmann::json all = nlohmann::json::array();
  int total = 0, picked = 0, failed_scans = 0, second_rounds = 0, failed_second_rounds = 0;
  int true_edges_all = 0, false_edges_all = 0;
  std::vector<double> errors_all, ms_all;
  workcell::CorrespondenceTruth match_all;  // pooled over every scene
  double max_err_all = 0;
  fmt::print("{:9} {:>6} {:>8} {:>9} {:>9} {:>9} {:>7} {:>7} {:>9} {:>7} {:>7} {:>7} {:>8}\n", "object", "scenes", "corners",
             "mean mm", "max mm", "spurious", "held", "placed", "ms (med)", "prec %", "rec %", "vis %", "epi px");
  for (const auto& [name, kind] : kinds) {
    if (!only.empty() && only != name) continue;
    int found = 0, possible = 0, spurious = 0, objpts = 0, held = 0, placed = 0;
    std::vector<double> on_table, above_table;  // corner errors: bottom corners (on the table) and the rest
    std::vector<double> six_views, fewer_views;  // the same by how many views observe the corner's model point
    double sum = 0, worst = 0;
    int matched = 0;
    workcell::CorrespondenceTruth match;  // pooled over this object's scenes
    std::vector<double> ms;
    for (int s = first_scene; s < first_scene + scenes; ++s) {
      workcell::ScanTwinOptions to;
      to.seed = seed;
      to.kind = kind;
      to.scene = static_cast<unsigned>(s);
      to.keep_truth = true;  // every frame's truth, for the correspondence score
      to.rail_repeatability_mm = rail_repeatability_mm;
      workcell::ScanTwin twin(to);
      if (oracle) cal = twin.TrueCalibration();
      workcell::ScanDevices d = twin.Devices();
      workcell::ScanOptions o = twin.SetupOptions();
      if (elevation_deg > 0) o.elevation_deg = elevation_deg;
      if (distance_mm > 0) o.view_distance_mm = distance_mm;
      o.structure.features.empl.photometric_flat_band = flat_band;
      o.structure.features.empl.photometric_ramp = ramp;
      o.structure.features.empl.junction_refit_angle_deg = junction_refit_deg;
      o.structure.bundle_adjustment.refine_poses = refine_poses;
      if (!rail_stops) o.structure.bundle_adjustment.mount_prior_mm = 0;
      if (!track_test) o.structure.correspondence.track_outlier_z = 0;
      o.points_on_table = table_support;
      if (!adjusted_test) o.structure.adjusted_outlier_z = 0;
      if (edge_spread_deg >= 0) o.structure.model.min_edge_spread_deg = edge_spread_deg;
      if (!second_round) o.extra_azimuths_deg.clear();
      if (stations > 0 || span_deg > 0) {
        // K stations (default: as many as the scan's default) evenly over +-span (default: its span).
        const double span = span_deg > 0 ? span_deg : std::abs(o.azimuths_deg.front());
        const int k_count = stations > 0 ? stations : static_cast<int>(o.azimuths_deg.size());
        o.azimuths_deg.clear();
        for (int k = 0; k < k_count; ++k) o.azimuths_deg.push_back(k_count == 1 ? 0.0 : -span + 2 * span * k / (k_count - 1));
      }
      ++total;
      if (!out_dir.empty()) o.out_dir = fmt::format("{}/{}_{}", out_dir, name, s);
      if (!o.out_dir.empty()) {
        std::error_code ec;
        std::filesystem::create_directories(o.out_dir, ec);
        if (ec) {
          fmt::print(stderr, "scan_study: cannot create {}: {}\n", o.out_dir, ec.message());
          return 1;
        }
      }
      auto r = workcell::ScanAndPick(d, cal, o);
      nlohmann::json row = {{"object", name}, {"scene", s}};
      if (!r.ok()) {
        ++failed_scans;
        // A scan that failed after its second round of stations says so ("with the second round's views").
        if (r.status().message().find("second round") != std::string::npos) ++failed_second_rounds;
        row["error"] = r.status().ToString();
        fmt::print(stderr, "  {} scene {}: {}\n", name, s, r.status().ToString());
        if (r.status().code() == StatusCode::kNotFound && kind != sim::ObjectKind::kCylinder) {
          // Whether the object itself has a grasp (the planner on its true corners and edges), or only the
          // reconstruction lacks what the grasp needs.
          const sim::CellObject& target = twin.target_at_start();
          const sim::ObjectWireframe wire = sim::ObjectCorners(target.shape);
          std::vector<Vec3d> corners;
          for (const Vec3d& v : wire.vertices) corners.push_back(target.world_from_object * v);
          const auto truth =
              PlanTopGrasps(corners, o.table_centre_world.z(), o.grasp, wire.edges, o.grasp_alternatives);
          row["grasps_on_true_model"] = truth.ok() ? static_cast<int>(truth->size()) : 0;
          fmt::print(stderr, "    on the true model the planner finds {}\n",
                     truth.ok() ? fmt::format("{} grasp(s)", truth->size()) : truth.status().ToString());
        }
        all.push_back(row);
        continue;
      }
      const workcell::ScanTruth t = twin.Evaluate(*r, o);
      const workcell::CorrespondenceTruth m = twin.EvaluateCorrespondence(*r, list_over_px);
      for (const std::string& line : m.far_points) fmt::print("  {} {}: {}\n", name, s, line);
      for (const std::string& e : t.false_edge_list) fmt::print("  {} {}: false edge: {}\n", name, s, e);
      true_edges_all += t.true_edges;
      false_edges_all += t.false_edges;
      if (m.scored) {
        match.Add(m);
        row.update({{"pair_true_matches", m.true_matches},
                    {"pair_corners_matched", m.corners_matched},
                    {"pair_false_matches", m.false_matches},
                    {"pair_background_matches", m.background_matches},
                    {"pair_found_in_both", m.found_in_both},
                    {"pair_visible_in_both", m.visible_in_both},
                    {"epipolar_median_px", Median(m.epipolar_px)}});
      } else {
        fmt::print(stderr, "  {} scene {}: frames and views do not line up; correspondence not scored\n", name, s);
      }
      found += t.matched_vertices;
      for (std::size_t k = 0; k < t.vertex_error_mm.size(); ++k) {
        if (t.vertex_error_mm[k] < 0) continue;
        (t.vertex_height_mm[k] < 1.0 ? on_table : above_table).push_back(t.vertex_error_mm[k]);
        (t.vertex_views[k] >= 6 ? six_views : fewer_views).push_back(t.vertex_error_mm[k]);
      }
      possible += t.true_vertices;
      spurious += t.spurious_points;
      objpts += t.object_points;
      if (t.matched_vertices > 0) {
        sum += t.mean_vertex_error_mm * t.matched_vertices;
        matched += t.matched_vertices;
        worst = std::max(worst, t.max_vertex_error_mm);
      }
      held += t.held ? 1 : 0;
      const bool ok_pick = t.held && t.placed && t.collisions == 0;
      placed += ok_pick ? 1 : 0;
      picked += ok_pick ? 1 : 0;
      ms.push_back(r->structure.total_ms);
      ms_all.push_back(r->structure.total_ms);
      second_rounds += r->second_round ? 1 : 0;
      row.update({{"views", r->views.size()},
                  {"second_round", r->second_round},
                  {"matched", t.matched_vertices},
                  {"true_vertices", t.true_vertices},
                  {"mean_mm", t.mean_vertex_error_mm},
                  {"vertex_error_mm", t.vertex_error_mm},
                  {"vertex_height_mm", t.vertex_height_mm},
                  {"vertex_views", t.vertex_views},
                  {"max_mm", t.max_vertex_error_mm},
                  {"spurious", t.spurious_points},
                  {"true_edges", t.true_edges},
                  {"false_edges", t.false_edges},
                  {"object_points", t.object_points},
                  {"held", t.held},
                  {"placed", t.placed},
                  {"collisions", t.collisions},
                  {"grasp", t.grasp_reason},
                  {"outcome", r->pick.outcome},
                  {"grasp_rank", r->pick.grasp_rank},
                  {"structure_ms", r->structure.total_ms},
                  {"cylinder_axis_error_mm", t.cylinder_axis_error_mm},
                  {"cylinder_radius_error_mm", t.cylinder_radius_error_mm},
                  {"cylinder_top_error_mm", t.cylinder_top_error_mm}});
      all.push_back(row);
    }
    if (matched > 0) {
      errors_all.push_back(sum / matched);
      max_err_all = std::max(max_err_all, worst);
    }
    fmt::print(
        "{:9} {:>6} {:>4}/{:<3} {:>9.3f} {:>9.3f} {:>5}/{:<3} {:>4}/{:<2} {:>4}/{:<2} {:>9.1f} {:>7.2f} {:>7.2f} "
        "{:>7.2f} {:>8.4f}\n",
        name,
        scenes,
        found,
        possible,
        matched > 0 ? sum / matched : 0.0,
        worst,
        spurious,
        objpts,
        held,
        scenes,
        placed,
        scenes,
        Median(ms),
        100.0 * match.precision(),
        100.0 * match.recall(),
        100.0 * match.recall_of_visible(),
        Median(match.epipolar_px));
    if (!on_table.empty() || !above_table.empty()) {
      auto mean = [](const std::vector<double>& v) { return v.empty() ? 0.0 : std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size()); };
      auto max = [](const std::vector<double>& v) { return v.empty() ? 0.0 : *std::max_element(v.begin(), v.end()); };
      fmt::print("{:9} corners above the table {} (mean {:.3f}, max {:.3f} mm), on the table {} (mean {:.3f}, max {:.3f} mm)\n", "",
                 above_table.size(), mean(above_table), max(above_table), on_table.size(), mean(on_table), max(on_table));
      fmt::print(
          "{:9} corners seen in 6 views or more {} (mean {:.3f}, max {:.3f} mm), in fewer {} (mean {:.3f}, max {:.3f} "
          "mm)\n",
          "",
          six_views.size(),
          mean(six_views),
          max(six_views),
          fewer_views.size(),
          mean(fewer_views),
          max(fewer_views));
    }
    match_all.Add(match);
  }
  fmt::print(
      "all: {} scenes, {} scans failed, picks succeeded {}/{} ({:.1f} %), worst corner error {:.3f} mm, "
      "structure time median {:.1f} ms; {} scan(s) took the second round of stations ({} of them failed)\n",
      total,
      failed_scans,
      picked,
      total,
      100.0 * picked / total,
      max_err_all,
      Median(ms_all),
      second_rounds + failed_second_rounds,
      failed_second_rounds);
  fmt::print(
      "model edges on the objects of the successful scans: {} true, {} false (joining corners the object does "
      "not join, or a spurious point)\n",
      true_edges_all,
      false_edges_all);
  fmt::print("correspondence over view pairs: {} true, {} false matches: precision {:.2f} %, recall {:.2f} % of the corners "
             "found in both views ({}), {:.2f} % of those visible in both ({}); epipolar error of matches median {:.4f} px\n",
             match_all.true_matches, match_all.false_matches, 100.0 * match_all.precision(), 100.0 * match_all.recall(),
             match_all.found_in_both, 100.0 * match_all.recall_of_visible(), match_all.visible_in_both,
             Median(match_all.epipolar_px));
  fmt::print(
      "  not scored: {} matched pairs of background points (at no true corner, the 3D point over {:g} mm outside "
      "the target's box)\n",
      match_all.background_matches,
      workcell::kBackgroundMarginMm);
  fmt::print("epipolar error median with the adjusted views (each station's rail stop estimated): {:.4f} px over {}\n",
             Median(match_all.epipolar_adjusted_px),
             match_all.epipolar_adjusted_px.size());
  fmt::print(
      "epipolar error median: pairs of one station (both cameras, one head pose) {:.4f} px over {}, pairs across "
      "stations {:.4f} px over {}\n",
      Median(match_all.epipolar_same_station_px),
      match_all.epipolar_same_station_px.size(),
      Median(match_all.epipolar_across_stations_px),
      match_all.epipolar_across_stations_px.size());
  if (!match_all.point_error_px.empty()) {
    std::vector<double> err = match_all.point_error_px, ratio;
    for (std::size_t k = 0; k < err.size(); ++k) ratio.push_back(err[k] / std::max(match_all.point_sigma_px[k], 1e-9));
    std::sort(err.begin(), err.end());
    std::sort(ratio.begin(), ratio.end());
    auto pct = [](const std::vector<double>& v, double q) { return v[static_cast<std::size_t>(q * static_cast<double>(v.size() - 1))]; };
    fmt::print("IDI points against the true corners ({}): error median {:.3f}, 90th {:.3f}, 99th {:.3f} px; "
               "error / own sigma median {:.2f}, 90th {:.2f}\n",
               err.size(), pct(err, 0.5), pct(err, 0.9), pct(err, 0.99), pct(ratio, 0.5), pct(ratio, 0.9));
  }
  if (!json_out.empty()) {
    std::ofstream(json_out) << nlohmann::json{{"scenes", all}, {"oracle", oracle}, {"stations", stations}}.dump(2) << "\n";
  }
  return 0;
}

}  // namespace
}  // namespace idi

int main(int argc, char** argv) { return idi::Main(argc, argv); }
