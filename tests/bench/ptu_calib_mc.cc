// Monte Carlo study of the single-point pan-tilt calibration (chapter 6; issue 6 acceptance).
//
//   solver   N trials, each a different built head (true cameras drawn around the design like
//            Table 6.1) and noise 0.2 px: 60 planned poses per camera, both cameras sharing the unknown
//            point; held-out poses for validation. Then the same head calibrated from a second unknown
//            point 400 mm away: each parameter's difference between the two solves against the std
//            both report (the comparison of Table 6.1).
//   twin     N runs of the whole procedure in the digital twin (workcell/procedures/ptu_twin.h): the
//            laser arm aims at an unknown point, the survey, the plan, the calibration images and the
//            held-out images, with the arm's encoders and the PTUs' position resolution; geometric
//            spots (0.2 px) or, with `image`, rendered images through the spot detector.
//
// Usage: ptu_calib_mc [trials=20] [solver|twin|image|all]
// Reports the validation RMS against the noise, the point's error, the two-point agreement and what
// the remaining pixel error means for a point triangulated at 1 m.
#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "shared/calib/ptu/ptu_calibration.h"
#include "shared/calib/ptu/ptu_simulation.h"
#include "workcell/procedures/ptu_procedure.h"
#include "workcell/procedures/ptu_twin.h"

namespace idi {
namespace {

using calib::PtuCameraModel;

struct Stats {
  std::vector<double> v;
  void Add(double x) { v.push_back(x); }
  double Mean() const {
    double s = 0;
    for (double x : v) s += x;
    return v.empty() ? 0 : s / static_cast<double>(v.size());
  }
  double Max() const { return v.empty() ? 0 : *std::max_element(v.begin(), v.end()); }
  double Min() const { return v.empty() ? 0 : *std::min_element(v.begin(), v.end()); }
};

std::size_t ParamCount(const PtuCameraModel& m) { return m.ptu.size() + m.intrinsics.size(); }
double Value(const PtuCameraModel& m, std::size_t k) {
  return k < m.ptu.size() ? m.ptu.value(k) : m.intrinsics.value(k - m.ptu.size());
}
double Std(const PtuCameraModel& m, std::size_t k) {
  return k < m.ptu.size() ? m.ptu.stddev(k) : m.intrinsics.stddev(k - m.ptu.size());
}

calib::PtuSyntheticOptions SolverOptions(uint64_t seed, const Vec3d& point) {
  calib::PtuSyntheticOptions o;
  o.seed = seed;
  o.noise_px = 0.2;
  o.point_mm = point;
  o.plan.validation_poses = 60;
  return o;
}

// What a validation RMS of `rms_px` per axis means for a point triangulated at `range_mm` by the two
// cameras `baseline_mm` apart: lateral error per camera ray, and the depth error of the stereo pair.
void PrintTriangulation(double rms_px, double fx_px) {
  const double range = 1000.0, baseline = 300.0;  // Biclops cameras are about 0.3 m apart
  const double lateral = rms_px / fx_px * range;
  const double depth = range * range / (baseline * fx_px) * rms_px * std::sqrt(2.0);
  fmt::print("  at 1 m (fx {:.0f} px, 0.3 m baseline): {:.3f} mm across each ray, {:.3f} mm in depth\n", fx_px,
             lateral, depth);
}

int RunSolver(int trials) {
  fmt::print("=== solver: {} built heads, 0.2 px spot noise, 60 poses per camera, shared unknown point ===\n", trials);
  Stats val_ratio, point_err, fx, agree_2sigma, worst_z;
  int failed = 0, pairs = 0, pairs_within = 0;
  const Vec3d point_a(500, -3198, 1368), point_b(900, -3198, 1368);
  for (int t = 0; t < trials; ++t) {
    const uint64_t seed = 1000 + static_cast<uint64_t>(t);
    auto da = calib::SimulatePtuDataset(SolverOptions(seed, point_a));
    auto db = calib::SimulatePtuDataset(SolverOptions(seed, point_b));
    if (!da.ok() || !db.ok()) {
      ++failed;
      fmt::print("trial {}: data: {}\n", t, (!da.ok() ? da.status() : db.status()).ToString());
      continue;
    }
    // The same head: the truth depends on the seed only.
    for (std::size_t c = 0; c < 2; ++c) {
      for (std::size_t k = 0; k < ParamCount(da->truth[c]); ++k) {
        IDI_CHECK(Value(da->truth[c], k) == Value(db->truth[c], k), "the two points must see the same head");
      }
    }
    auto ra = calib::CalibratePtu(da->calibration, {});
    auto rb = calib::CalibratePtu(db->calibration, {});
    if (!ra.ok() || !rb.ok()) {
      ++failed;
      fmt::print("trial {}: solve: {}\n", t, (!ra.ok() ? ra.status() : rb.status()).ToString());
      continue;
    }
    auto va = calib::ValidatePtu(*ra, da->validation);
    if (!va.ok()) {
      ++failed;
      continue;
    }
    val_ratio.Add(va->rms_px / 0.2);
    point_err.Add((ra->point_mm - da->point_mm).norm());
    fx.Add(ra->cameras[0].model.intrinsics.value(0));
    double worst = 0;
    for (std::size_t c = 0; c < 2; ++c) {
      const PtuCameraModel& a = ra->cameras[c].model;
      const PtuCameraModel& b = rb->cameras[c].model;
      for (std::size_t k = 0; k < ParamCount(a); ++k) {
        const double sa = Std(a, k), sb = Std(b, k);
        if (!std::isfinite(sa) || !std::isfinite(sb)) continue;  // held fixed
        const double z = std::abs(Value(a, k) - Value(b, k)) / std::hypot(sa, sb);
        worst = std::max(worst, z);
        ++pairs;
        if (z <= 2.0) ++pairs_within;
      }
    }
    worst_z.Add(worst);
  }
  fmt::print("trials: {} ({} failed)\n", trials, failed);
  fmt::print("validation RMS / noise: mean {:.3f}, max {:.3f} (goal <= 1.2)\n", val_ratio.Mean(), val_ratio.Max());
  fmt::print("point error: mean {:.3f} mm, max {:.3f} mm (goal <= 0.5 mm)\n", point_err.Mean(), point_err.Max());
  fmt::print("two unknown points 400 mm apart: {} of {} parameter differences within 2 combined std ({:.1f} %; "
             "Gaussian: 95.4 %), worst |diff|/std per trial: mean {:.2f}, max {:.2f}\n",
             pairs_within, pairs, 100.0 * pairs_within / std::max(pairs, 1), worst_z.Mean(), worst_z.Max());
  fmt::print("against the dissertation's 0.5-2.8 px (mean about 1 px): validation RMS {:.3f} px per axis, "
             "{:.1f}x below 1 px\n", 0.2 * val_ratio.Mean(), 1.0 / (0.2 * val_ratio.Mean()));
  PrintTriangulation(0.2 * val_ratio.Mean(), fx.Mean());
  return failed == 0 ? 0 : 1;
}

int RunTwin(int trials, bool image) {
  fmt::print("=== twin: {} runs of the whole procedure, {} ===\n", trials,
             image ? "rendered images through the spot detector" : "geometric spots, 0.2 px");
  Stats val_rms, point_err, fx, ms;
  int failed = 0;
  for (int t = 0; t < trials; ++t) {
    workcell::PtuTwinOptions to;
    to.seed = 100 + static_cast<unsigned>(t);
    if (image) to.mode = workcell::PtuSpotMode::kImage;
    workcell::PtuTwin twin(to);
    const Status aimed = twin.AimLaser();
    if (!aimed.ok()) {
      ++failed;
      fmt::print("run {}: {}\n", t, aimed.ToString());
      continue;
    }
    workcell::PtuDevices dev = twin.Devices();
    workcell::PtuProcedureOptions o;
    o.robot = twin.arm_model();
    o.approx_point_mm = twin.approx_point_in_base();
    o.seed = to.seed;
    const auto r = workcell::RunPtuCalibrationProcedure(dev, o);
    const auto truth = twin.true_point_in_base();
    if (!r.ok() || !truth) {
      ++failed;
      fmt::print("run {}: {}\n", t, r.ok() ? std::string("no true point") : r.status().ToString());
      continue;
    }
    val_rms.Add(r->validation_errors.rms_px);
    point_err.Add((r->result.point_mm - *truth).norm());
    fx.Add(r->result.cameras[0].model.intrinsics.value(0));
    ms.Add(r->result.time_ms);
  }
  fmt::print("runs: {} ({} failed)\n", trials, failed);
  fmt::print("validation RMS per axis: mean {:.3f} px, min {:.3f}, max {:.3f}{}\n", val_rms.Mean(), val_rms.Min(),
             val_rms.Max(), image ? "" : fmt::format(" (noise 0.2 px: ratio mean {:.2f}, max {:.2f})", val_rms.Mean() / 0.2,
                                                     val_rms.Max() / 0.2));
  fmt::print("point error: mean {:.3f} mm, max {:.3f} mm\n", point_err.Mean(), point_err.Max());
  fmt::print("solve (both cameras, 120 images): mean {:.1f} ms\n", ms.Mean());
  PrintTriangulation(val_rms.Mean(), fx.Mean());
  return failed == 0 ? 0 : 1;
}

}  // namespace
}  // namespace idi

int main(int argc, char** argv) {
  const std::string first = argc > 1 ? argv[1] : "";
  const std::string what = argc > 2 ? argv[2] : "all";
  const bool help = first == "--help" || first == "-h";
  const bool bad_trials = argc > 1 && !help && std::atoi(argv[1]) < 1;
  const bool bad_what = what != "solver" && what != "twin" && what != "image" && what != "all";
  if (help || bad_trials || bad_what || argc > 3) {
    if (!help) std::fprintf(stderr, "ptu_calib_mc: bad arguments\n");
    std::fprintf(help ? stdout : stderr,
                 "usage: ptu_calib_mc [TRIALS=20] [solver|twin|image|all]\n"
                 "  Monte Carlo study of the single-point pan-tilt calibration (chapter 6): TRIALS heads\n"
                 "  solved from planned poses (solver), the whole procedure in the twin with geometric\n"
                 "  spots (twin) or rendered images through the spot detector (image). Tables on stdout;\n"
                 "  exit 1 when a trial failed to solve.\n");
    return help ? 0 : 2;
  }
  const int trials = argc > 1 ? std::atoi(argv[1]) : 20;
  spdlog::set_level(spdlog::level::warn);
  int rc = 0;
  if (what == "solver" || what == "all") rc |= idi::RunSolver(trials);
  if (what == "twin" || what == "all") rc |= idi::RunTwin(trials, false);
  if (what == "image" || what == "all") rc |= idi::RunTwin(trials, true);
  return rc;
}
