// Speed of the digital twin's renderer (issue 3): one 640x480 frame of the standard workcell scene
// (shared/sim/scene: four objects on the rotary table, six clutter objects, tiled floor, walls) from
// the Biclops head's left camera. Goal: median under 25 ms per frame.
//
// The renderer integrates each pixel's area exactly (shared/sim/render/render.h, step 1: exact
// coverage of every visible face inside the pixel), which is the limit of n x n supersampling as
// n grows; so "8x8 supersampling" is met by a stronger method at no extra cost. Variants time the
// stages: noise-free, without the PSF, with ground truth, in colour, and the vehicle twin's camera
// view of the standard track (the closed loop renders two of those per 30 Hz frame).
//
// Frames render with one thread per core (RenderOptions::threads = 0, at most 4); *OneThread variants
// time a single thread.
// Run: build/<dir>/tests/bench/render_bench --benchmark_repetitions=10 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include "rmp/app/sim_render_command.h"
#include "rmp/app/track_spec.h"
#include "shared/sim/render/render.h"
#include "shared/sim/scene/scene_file.h"

namespace idi {
namespace {

const sim::BuiltWorkcellScene& StandardScene() {
  static const sim::BuiltWorkcellScene built = [] {
    auto b = sim::BuildWorkcellScene(sim::StandardWorkcellScene());
    if (!b.ok()) std::abort();
    return *b;
  }();
  return built;
}

void RenderWorkcell(benchmark::State& state, bool noise, double psf, bool truth, bool color, int threads = 0) {
  const sim::BuiltWorkcellScene& built = StandardScene();
  const sim::SceneView& view = built.views.front();
  sim::RenderOptions ro = view.render;
  ro.sensor.noise = noise;
  ro.psf_sigma_px = psf;
  ro.color = color;
  ro.threads = threads;
  uint64_t seed = 1;
  for (auto _ : state) {
    ro.seed = seed++;
    sim::GroundTruth gt;
    auto image = sim::RenderScene(built.scene, view.camera, view.cam_from_world, ro, truth ? &gt : nullptr);
    if (!image.ok()) {
      state.SkipWithError(image.status().ToString().c_str());
      break;
    }
    benchmark::DoNotOptimize(image->data);
  }
  state.counters["px"] = view.camera.width * view.camera.height;
}

void BM_WorkcellFrame(benchmark::State& s) { RenderWorkcell(s, true, 1.0, false, false); }
void BM_WorkcellFrameOneThread(benchmark::State& s) { RenderWorkcell(s, true, 1.0, false, false, 1); }
void BM_WorkcellFrameNoiseFree(benchmark::State& s) { RenderWorkcell(s, false, 1.0, false, false); }
void BM_WorkcellFrameNoPsf(benchmark::State& s) { RenderWorkcell(s, true, 0.0, false, false); }
void BM_WorkcellFrameWithTruth(benchmark::State& s) { RenderWorkcell(s, true, 1.0, true, false); }
void BM_WorkcellFrameColour(benchmark::State& s) { RenderWorkcell(s, true, 1.0, false, true); }
BENCHMARK(BM_WorkcellFrame)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_WorkcellFrameOneThread)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_WorkcellFrameNoiseFree)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_WorkcellFrameNoPsf)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_WorkcellFrameWithTruth)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_WorkcellFrameColour)->Unit(benchmark::kMillisecond)->UseRealTime();

// The vehicle twin: the left camera of the default rig at the start of the standard track.
// The sensor alone (shot and read noise, rounding) on a 640 x 480 irradiance image with a gradient
// from 5 to 250 DN.
void BM_Sensor(benchmark::State& state) {
  cv::Mat irradiance(480, 640, CV_32FC1);
  for (int r = 0; r < irradiance.rows; ++r) {
    for (int c = 0; c < irradiance.cols; ++c)
      irradiance.at<float>(r, c) = 5.0f + 245.0f * static_cast<float>(c) / 639.0f;
  }
  const sim::SensorOptions sensor;
  uint64_t seed = 1;
  for (auto _ : state) {
    const cv::Mat out = sim::ApplySensor(irradiance, sensor, seed++);
    benchmark::DoNotOptimize(out.data);
  }
}
BENCHMARK(BM_Sensor)->Unit(benchmark::kMillisecond)->UseRealTime();

void TrackFrame(benchmark::State& state, int threads, double shading_tolerance_dn = -1) {
  const rmp::RmpConfig config = rmp::DefaultRmpConfig();
  const rmp::TrackSpec track = rmp::StandardTrack();
  rmp::TrackSceneOptions so = config.sim.scene;
  auto scene = rmp::BuildTrackScene(track, so);
  if (!scene.ok()) {
    state.SkipWithError(scene.status().ToString().c_str());
    return;
  }
  double x = 0, y = 0, yaw = 0;
  track.StartPose(&x, &y, &yaw);
  const Rigid3d world_from_vehicle = Translation(x, y, 0.0) * RotZ(yaw);
  const rmp::RigCamera& cam = config.rig.left;
  const Rigid3d cam_from_world = (world_from_vehicle * cam.vehicle_from_camera).Inverse();
  sim::RenderOptions ro = config.sim.render;
  ro.threads = threads;
  if (shading_tolerance_dn >= 0) ro.shading_tolerance_dn = shading_tolerance_dn;
  uint64_t seed = 1;
  for (auto _ : state) {
    ro.seed = seed++;
    auto image = sim::RenderScene(*scene, cam.intrinsics, cam_from_world, ro);
    if (!image.ok()) {
      state.SkipWithError(image.status().ToString().c_str());
      break;
    }
    benchmark::DoNotOptimize(image->data);
  }
}
void BM_TrackFrame(benchmark::State& s) { TrackFrame(s, 0); }
void BM_TrackFrameOneThread(benchmark::State& s) { TrackFrame(s, 1); }
BENCHMARK(BM_TrackFrame)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_TrackFrameOneThread)->Unit(benchmark::kMillisecond)->UseRealTime();
// Smooth shading in covered tiles interpolated within 0.25 DN (the default shades every pixel exactly).
void BM_TrackFrameOneThreadInterpolated(benchmark::State& s) { TrackFrame(s, 1, 0.25); }
BENCHMARK(BM_TrackFrameOneThreadInterpolated)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace idi

BENCHMARK_MAIN();
