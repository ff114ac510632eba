// ViCKi solve times (issue 5 goals): a 540-reading robot calibration at most 100 ms, the 500-reading
// rail calibration at most 50 ms (median). The data (encoder-rounded readings of a perturbed arm,
// made once) are outside the timed loop.
#include <benchmark/benchmark.h>

#include <random>

#include "shared/calib/calib_test_util.h"
#include "shared/calib/rail_calibration.h"
#include "shared/calib/robot_calibration.h"

namespace idi::calib {
namespace {

const RobotCalibrationData& RobotData() {
  static const RobotCalibrationData d = [] {
    RobotCalibrationData data = testing::ExactRobotData(testing::PerturbedArm(3), Vec3d(600, 4000, 300), 1000.0, 270, 11);
    for (AimReading& r : data.readings) r.q = QuantizeToEncoders(r.q);
    return data;
  }();
  return d;
}

void BM_RobotCalibration540(benchmark::State& state) {
  const RobotCalibrationData& data = RobotData();
  RobotCalibrationOptions o;
  o.noise.spot_sigma_mm = 0.001;
  for (auto _ : state) {
    auto r = CalibrateRobot(data, o);
    if (!r.ok()) state.SkipWithError(r.status().message().c_str());
    benchmark::DoNotOptimize(r);
  }
  state.counters["readings"] = static_cast<double>(data.readings.size());
}
BENCHMARK(BM_RobotCalibration540)->Unit(benchmark::kMillisecond)->MinTime(2.0);

struct RailFixture {
  ArmModel a1 = testing::PerturbedArm(21), a2 = testing::PerturbedArm(22);
  std::vector<RailReading> readings;
};

const RailFixture& RailData() {
  static const RailFixture f = [] {
    RailFixture fx;
    const std::array<double, 4> psi = {5654.0, 3.0, -2.0, 0.0002};
    const std::vector<Vec3d> points = {{1500, 4000, 500}, {3000, 4000, -600}, {4200, 4000, 900},
                                       {1800, -3500, 200}, {3500, -3500, -800}, {2800, 500, -1200}};
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> rail(0.0, 1500.0);
    PlanOptions po;
    for (int i = 0; i < 500; ++i) {
      const Vec3d p = points[static_cast<std::size_t>(i) % points.size()];
      RailReading r;
      r.rail1_mm = rail(rng);
      r.rail2_mm = rail(rng);
      const Vec3d p1 = RailFromBase(fx.a1.rail.value(kPhiL), fx.a1.rail.value(kPhiM), r.rail1_mm).Inverse() * p;
      const Vec3d p2 =
          (Rail1FromRail2(psi.data()) * RailFromBase(fx.a2.rail.value(kPhiL), fx.a2.rail.value(kPhiM), r.rail2_mm)).Inverse() * p;
      po.seed = static_cast<unsigned>(i + 1);
      const auto q1 = PlanAimConfigurations(fx.a1.robot, fx.a1.laser, p1, 1, Rx130JointLimits(), po);
      const auto q2 = PlanAimConfigurations(fx.a2.robot, fx.a2.laser, p2, 1, Rx130JointLimits(), po);
      if (!q1.ok() || !q2.ok()) continue;
      r.q1 = QuantizeToEncoders((*q1)[0]);
      r.q2 = QuantizeToEncoders((*q2)[0]);
      fx.readings.push_back(r);
    }
    return fx;
  }();
  return f;
}

void BM_RailCalibration500(benchmark::State& state) {
  const RailFixture& f = RailData();
  RailCalibrationOptions o;
  o.noise.spot_sigma_mm = 0.001;
  o.noise.rail_sigma_mm = 0.0;
  for (auto _ : state) {
    auto r = CalibrateRail(f.readings, f.a1, f.a2, o);
    if (!r.ok()) state.SkipWithError(r.status().message().c_str());
    benchmark::DoNotOptimize(r);
  }
  state.counters["readings"] = static_cast<double>(f.readings.size());
}
BENCHMARK(BM_RailCalibration500)->Unit(benchmark::kMillisecond)->MinTime(2.0);

}  // namespace
}  // namespace idi::calib

BENCHMARK_MAIN();
