// The RMP's CAN path: codec throughput, candump log lines, and how much faster than real time the
// driver runs against the simulated RMP (vehicle twin + virtual bus) on simulated time.
#include <benchmark/benchmark.h>

#include "rmp/segway/rmp_codec.h"
#include "rmp/segway/rmp_driver.h"
#include "rmp/segway/sim_rmp.h"
#include "shared/replay/candump_log.h"

namespace idi::rmp {
namespace {

std::vector<hal::CanFrame> OneStatusCycle(const RmpCodec& codec) {
  return {codec.Encode(RmpBuildFrame{1}),
          codec.Encode(RmpTiltFrame{0.01, 0.02, 0.0, 0.0}),
          codec.Encode(RmpSpeedFrame{1.0, 1.1, 0.2, 7}),
          codec.Encode(RmpWheelIntegratorFrame{0xFFFF0000u, 1234}),
          codec.Encode(RmpBodyIntegratorFrame{99, 0x12345678u}),
          codec.Encode(RmpTorqueFrame{1.0, -1.0}),
          codec.Encode(RmpModeFrame{OperationalMode::kTractor, GainSchedule::kLight, 12.5, 72.0}),
          codec.Encode(RmpCommandEchoFrame{332, -100})};
}

void BM_DecodeStatusCycle(benchmark::State& state) {
  const RmpCodec codec;
  const std::vector<hal::CanFrame> cycle = OneStatusCycle(codec);
  for (auto _ : state) {
    for (const hal::CanFrame& f : cycle) benchmark::DoNotOptimize(codec.Decode(f));
  }
  state.SetItemsProcessed(state.iterations() * static_cast<int64_t>(cycle.size()));
}
BENCHMARK(BM_DecodeStatusCycle);

void BM_EncodeCommand(benchmark::State& state) {
  RmpCommandScaling scaling;
  double v = 0.0;
  for (auto _ : state) {
    v += 1e-3;
    const RmpMotionCounts c = MotionToCounts(v, -v, scaling);
    benchmark::DoNotOptimize(EncodeCommandFrame({c.velocity, c.turn, 0, 0}));
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_EncodeCommand);

void BM_CandumpLineRoundTrip(benchmark::State& state) {
  const RmpCodec codec;
  hal::CanFrame f = codec.Encode(RmpWheelIntegratorFrame{0xFFFF0000u, 1234});
  f.timestamp_ns = 1'700'000'000'123'456'000LL;
  for (auto _ : state) {
    const std::string line = replay::FormatCandumpLine(f, "can0");
    benchmark::DoNotOptimize(replay::ParseCandumpLine(line));
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_CandumpLineRoundTrip);

// One simulated second of the driver at 50 Hz against the simulated RMP (100 Hz status, vehicle
// twin at 1 ms steps) with a 30 Hz control loop. The counter sim_s_per_wall_s is the speed-up over
// real time.
void BM_DriverWithSimulatedRmp(benchmark::State& state) {
  hal::SimClock clock;
  sim::VirtualCanBus bus(&clock);
  SimRmp rmp(&bus, SimRmpOptions{});
  auto driver = std::move(RmpDriver::Create(bus.AddEndpoint("pc"), &clock, RmpDriverOptions{})).value();
  (void)driver->Start();
  (void)driver->RunUntil(1'000'000'000);
  int64_t simulated_ns = 0;
  for (auto _ : state) {
    const int64_t end = clock.NowNs() + 1'000'000'000;
    while (clock.NowNs() < end) {
      const int64_t t = clock.NowNs();
      (void)driver->SetCommand({0.5, 0.2, t - 30'000'000});
      (void)driver->RunUntil(t + 33'000'000);
    }
    simulated_ns += 1'000'000'000;
  }
  state.counters["sim_s_per_wall_s"] =
      benchmark::Counter(static_cast<double>(simulated_ns) * 1e-9, benchmark::Counter::kIsRate);
}
BENCHMARK(BM_DriverWithSimulatedRmp)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace idi::rmp

BENCHMARK_MAIN();
