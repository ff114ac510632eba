// Speed of the vehicle's closed loop in the digital twin (issue 3: "a closed-loop vehicle run with two
// cameras at 30 Hz at least 5x faster than real time"): `idi-rmp sim` on the standard track with the
// default configuration except the cameras at 30 Hz (two rendered 640x480 cameras, stereo tape
// perception, planner, the RMP over the virtual CAN bus), run N times. Reports per run the simulated
// time (first to last control tick), the wall time, the process CPU time and the speed factor
// (simulated seconds per wall second), then the median factor, and where each run's wall time went:
// rendering the two cameras (one thread each), the pair's perception (features on two threads, then
// stereo and the ground plane), the track model's update, and the rest (planner, RMP twin, CAN, driver).
//
// Wall time depends on what else the machine runs; the CPU time beside it shows the work itself.
// Run: build/<dir>/tests/bench/rmp_closed_loop_bench [--runs 3] [--rate-hz 30] [--track TRACK.yaml]
//        [--shading-tolerance-dn T] (the renderer's interpolation of smooth shading; 0 = every pixel exactly)
//        [--serial-perception] (the two images' features on one thread instead of two)
#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <vector>

#include "rmp/app/sim_render_command.h"
#include "rmp/app/sim_run.h"
#include "rmp/app/track_spec.h"

namespace idi {
namespace {

double ProcessCpuSeconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
         1e-6 * static_cast<double>(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

int Main(int argc, char** argv) {
  int runs = 3;
  double rate_hz = 30.0;
  std::string track_file;
  double shading_tolerance_dn = -1;
  bool serial_perception = false;
  for (int i = 1; i < argc; i += 2) {
    const std::string a = argv[i];
    if (a == "--help" || a == "-h") {
      fmt::print(
          "usage: rmp_closed_loop_bench [--runs N=3] [--rate-hz HZ=30] [--track TRACK.yaml]\n"
          "                             [--shading-tolerance-dn T] [--serial-perception]\n"
          "  Speed of `idi-rmp sim` in closed loop: two rendered 640x480 cameras, stereo tape perception,\n"
          "  planner and the RMP over the virtual CAN bus, on the standard track (or TRACK). Prints per\n"
          "  run the simulated, wall and CPU seconds and the speed factor (simulated / wall seconds).\n"
          "  --shading-tolerance-dn  the renderer's interpolation of smooth shading, in [0, 1] DN (0: every\n"
          "                          pixel shaded exactly; default: the configuration's)\n"
          "  --serial-perception     the two images' features on one thread instead of two\n");
      return 0;
    }
    if (a == "--serial-perception") {
      serial_perception = true;
      --i;
      continue;
    }
    if (i + 1 >= argc) {
      fmt::print(stderr, "option {} needs a value\n", a);
      return 2;
    }
    if (a == "--runs") {
      runs = std::max(1, std::atoi(argv[i + 1]));
    } else if (a == "--rate-hz") {
      rate_hz = std::atof(argv[i + 1]);
    } else if (a == "--shading-tolerance-dn") {
      shading_tolerance_dn = std::atof(argv[i + 1]);
    } else if (a == "--track") {
      track_file = argv[i + 1];
    } else {
      fmt::print(stderr, "unknown option {}\n", a);
      return 2;
    }
  }
  spdlog::set_level(spdlog::level::err);
  rmp::SimRunOptions o;
  if (track_file.empty()) {
    o.track = rmp::StandardTrack();
  } else {
    auto t = rmp::LoadTrackFile(track_file);
    if (!t.ok()) {
      fmt::print(stderr, "{}\n", t.status().ToString());
      return 1;
    }
    o.track = *t;
  }
  if (o.track.speed_mps == 0) o.track.speed_mps = o.config.planner.cruise_speed_mps;
  o.config.sim.camera_rate_hz = rate_hz;
  if (shading_tolerance_dn >= 0) o.config.sim.render.shading_tolerance_dn = shading_tolerance_dn;
  o.config.perception.parallel_views = !serial_perception;
  fmt::print(
      "closed loop, {} track, cameras at {:g} Hz, shading tolerance {:g} DN, features of the two images on {}, {} "
      "run(s)\n\n",
      track_file.empty() ? "standard" : track_file,
      rate_hz,
      o.config.sim.render.shading_tolerance_dn,
      serial_perception ? "one thread" : "two threads",
      runs);
  fmt::print("| run | completed | stereo pairs | simulated s | wall s | CPU s | speed factor (sim/wall) |\n");
  fmt::print("|---|---|---|---|---|---|---|\n");
  std::vector<double> factors;
  std::vector<std::string> split;
  for (int r = 0; r < runs; ++r) {
    int64_t first_ns = -1, last_ns = -1;
    o.on_tick = [&](const rmp::TickRecord& tick, rmp::SimWorld&, const rmp::ControlLoop&) {
      if (first_ns < 0) first_ns = tick.t_ns;
      last_ns = tick.t_ns;
    };
    const double cpu0 = ProcessCpuSeconds();
    const auto t0 = std::chrono::steady_clock::now();
    auto res = rmp::RunSimulation(o);
    const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const double cpu = ProcessCpuSeconds() - cpu0;
    if (!res.ok()) {
      fmt::print(stderr, "run {}: {}\n", r + 1, res.status().ToString());
      return 1;
    }
    const double sim_s = static_cast<double>(last_ns - first_ns) * 1e-9;
    factors.push_back(sim_s / wall);
    fmt::print("| {} | {} | {} | {:.2f} | {:.2f} | {:.2f} | {:.2f} |\n", r + 1, res->report.completed ? "yes" : "no",
               res->report.frames, sim_s, wall, cpu, sim_s / wall);
    const double perception_s = res->stats.perception_ms.sum() * 1e-3;
    const double track_s = res->stats.track_update_ms.sum() * 1e-3;
    const double rest = wall - res->render_wall_s - perception_s - track_s;
    split.push_back(
        fmt::format("| {} | {:.2f} ({:.0f} %) | {:.2f} ({:.0f} %) | {:.2f} ({:.0f} %) | {:.2f} ({:.0f} %) |",
                    r + 1,
                    res->render_wall_s,
                    100 * res->render_wall_s / wall,
                    perception_s,
                    100 * perception_s / wall,
                    track_s,
                    100 * track_s / wall,
                    rest,
                    100 * rest / wall));
  }
  std::sort(factors.begin(), factors.end());
  fmt::print("\nmedian speed factor: {:.2f}x real time\n", factors[factors.size() / 2]);
  fmt::print("\nWall seconds by stage (each stage's own threads run at once; the stages one after another):\n\n");
  fmt::print("| run | rendering | perception | track model | rest |\n|---|---|---|---|---|\n");
  for (const std::string& row : split) fmt::print("{}\n", row);
  return 0;
}

}  // namespace
}  // namespace idi

int main(int argc, char** argv) { return idi::Main(argc, argv); }
