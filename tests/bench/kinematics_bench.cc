// One RX-130 forward kinematics + laser line, in double and in Ceres Jets (the calibration's inner
// loop). Goal (issue 2): under 1 µs in double.
#include <benchmark/benchmark.h>
#include <ceres/jet.h>

#include <random>

#include "shared/kinematics/aiming.h"
#include "shared/kinematics/rx130.h"

namespace idi {
namespace {

std::vector<Joints> RandomJoints(int n) {
  std::mt19937 rng(1);
  const JointLimits lim = Rx130JointLimits();
  std::vector<Joints> out(static_cast<std::size_t>(n));
  for (auto& q : out) {
    for (std::size_t i = 0; i < q.size(); ++i) {
      q[i] = std::uniform_real_distribution<double>(lim.min[i], lim.max[i])(rng);
    }
  }
  return out;
}

void BM_LaserLineDouble(benchmark::State& state) {
  const ParamSet robot = Rx130Nominal();
  const ParamSet laser = LaserNominal();
  const auto qs = RandomJoints(256);
  std::size_t i = 0;
  for (auto _ : state) {
    const Line3d line = LaserLineInBase(robot.data(), laser.data(), qs[i++ & 255].data());
    benchmark::DoNotOptimize(line);
  }
}
BENCHMARK(BM_LaserLineDouble);

// Jets carrying derivatives with respect to the 22 robot + laser parameters (what the ViCKi solve uses).
void BM_LaserLineJet22(benchmark::State& state) {
  using J = ceres::Jet<double, 22>;
  const ParamSet robot = Rx130Nominal();
  const ParamSet laser = LaserNominal();
  std::array<J, 22> p;
  for (int k = 0; k < 18; ++k) p[static_cast<std::size_t>(k)] = J(robot.value(static_cast<std::size_t>(k)), k);
  for (int k = 0; k < 4; ++k) p[static_cast<std::size_t>(18 + k)] = J(laser.value(static_cast<std::size_t>(k)), 18 + k);
  const auto qs = RandomJoints(256);
  std::size_t i = 0;
  for (auto _ : state) {
    const Joints& qd = qs[i++ & 255];
    std::array<J, 6> q;
    for (std::size_t k = 0; k < 6; ++k) q[k] = J(qd[k]);
    const Line3<J> line = LaserLineInBase(p.data(), p.data() + 18, q.data());
    benchmark::DoNotOptimize(line);
  }
}
BENCHMARK(BM_LaserLineJet22);

void BM_AimLaser(benchmark::State& state) {
  const ParamSet robot = Rx130Nominal();
  const ParamSet laser = LaserNominal();
  const JointLimits limits = Rx130JointLimits();
  const Joints start = JointsFromDeg({5, -60, 100, 10, 90, 0});
  for (auto _ : state) {
    auto r = AimLaserAt(robot, laser, start, Vec3d(3000, 300, 900), limits);
    benchmark::DoNotOptimize(r);
  }
}
BENCHMARK(BM_AimLaser);

}  // namespace
}  // namespace idi

BENCHMARK_MAIN();
