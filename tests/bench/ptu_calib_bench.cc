// The single-point pan-tilt calibration's solve (chapter 6): 60 poses per camera (§6.4.4), from the
// as-designed start model, with gauge check, robust stages and covariance. Goal (issue 6): at most
// 50 ms per camera.
#include <benchmark/benchmark.h>

#include "shared/calib/ptu/ptu_calibration.h"
#include "shared/calib/ptu/ptu_simulation.h"
#include "shared/optim/ptu/ptu_cost.h"

namespace idi::calib {
namespace {

const PtuSyntheticData& BenchData() {
  static const PtuSyntheticData data = [] {
    PtuSyntheticOptions o;
    o.seed = 11;
    auto d = SimulatePtuDataset(o);
    IDI_CHECK(d.ok(), d.status().ToString());
    return *d;
  }();
  return data;
}

void BM_PtuSolve60OneCamera(benchmark::State& state) {
  const std::vector<PtuObservation> left = SelectCamera(BenchData().calibration, BiclopsSide::kLeft);
  for (auto _ : state) {
    auto r = CalibratePtu(left, {});
    IDI_CHECK(r.ok(), r.status().ToString());
    benchmark::DoNotOptimize(r->point_mm);
  }
  state.counters["observations"] = static_cast<double>(left.size());
}
BENCHMARK(BM_PtuSolve60OneCamera)->Unit(benchmark::kMillisecond);

void BM_PtuSolve60BothCamerasSharedPoint(benchmark::State& state) {
  for (auto _ : state) {
    auto r = CalibratePtu(BenchData().calibration, {});
    IDI_CHECK(r.ok(), r.status().ToString());
    benchmark::DoNotOptimize(r->point_mm);
  }
  state.counters["observations"] = static_cast<double>(BenchData().calibration.size());
}
BENCHMARK(BM_PtuSolve60BothCamerasSharedPoint)->Unit(benchmark::kMillisecond);

// One residual with its 26 derivatives (the solve's inner loop).
void BM_PtuResidualWithJacobian(benchmark::State& state) {
  const PtuObservation& o = BenchData().calibration.front();
  const PtuCameraModel m = PtuCameraModel::Nominal(o.camera);
  std::vector<double> ptu = m.ptu.values(), intr = m.intrinsics.values();
  double x[3] = {500, -3198, 1368};
  const optim::PtuSpotResidual f(BaseFromTcf(o.tcf), o.pan_rad, o.tilt_rad, o.pixel_px, 1.0);
  const std::vector<double*> blocks = optim::PtuSpotBlocks(ptu.data(), intr.data(), x);
  std::vector<std::array<double, 6>> storage(blocks.size());
  std::vector<double*> jac(blocks.size());
  for (std::size_t b = 0; b < blocks.size(); ++b) jac[b] = storage[b].data();
  double r[2];
  for (auto _ : state) {
    benchmark::DoNotOptimize(f.Evaluate(blocks.data(), r, jac.data()));
  }
}
BENCHMARK(BM_PtuResidualWithJacobian);

}  // namespace
}  // namespace idi::calib

BENCHMARK_MAIN();
