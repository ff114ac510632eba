// The simulated RMP seen from the bus, with raw frames: what it sends, how it reacts to commands.
#include "rmp/segway/sim_rmp.h"

#include <gtest/gtest.h>

#include <map>
#include <vector>

namespace idi::rmp {
namespace {

constexpr int64_t kSimMs = 1'000'000;

struct SimRmpBench {
  explicit SimRmpBench(SimRmpOptions o = {}) : bus(&clock), rmp(&bus, o), pc(bus.AddEndpoint("pc")) {}
  // Sends `cmd` every `period_ms` until `until_ns`, collecting everything the RMP sends.
  void Run(int64_t until_ns, std::optional<RmpCommandFrame> cmd = std::nullopt, int period_ms = 20) {
    while (clock.NowNs() < until_ns) {
      if (cmd) {
        EXPECT_TRUE(pc->Send(EncodeCommandFrame(*cmd)).ok());
      }
      const int64_t next = std::min(until_ns, clock.NowNs() + period_ms * kSimMs);
      while (true) {
        const int64_t left_ms = (next - clock.NowNs() + kSimMs - 1) / kSimMs;
        if (left_ms <= 0) break;
        auto f = pc->Receive(std::chrono::milliseconds(left_ms));
        ASSERT_TRUE(f.ok());
        if (f->has_value()) received.push_back(**f);
      }
    }
  }
  hal::SimClock clock;
  sim::VirtualCanBus bus;
  SimRmp rmp;
  sim::VirtualCanEndpoint* pc;
  std::vector<hal::CanFrame> received;
};

TEST(SimRmpTest, SendsTheStatusCycleAt100HzInIdOrder) {
  SimRmpBench b;
  b.Run(1005 * kSimMs);  // cycles at 10, 20, ..., 1000 ms
  std::map<uint32_t, int> count;
  for (const hal::CanFrame& f : b.received) ++count[f.id];
  for (uint32_t id = 0x400; id <= 0x407; ++id) EXPECT_EQ(count[id], 100) << std::hex << id;
  EXPECT_EQ(count[0x680], 10);
  // Cycles start every 10 ms and keep their order 0x400..0x407.
  std::vector<int64_t> starts;
  for (std::size_t i = 0; i < b.received.size(); ++i) {
    if (b.received[i].id != 0x400) continue;
    starts.push_back(b.received[i].timestamp_ns);
    for (uint32_t k = 1; k < 8; ++k) ASSERT_EQ(b.received[i + k].id, 0x400 + k);
  }
  for (std::size_t i = 1; i < starts.size(); ++i) EXPECT_EQ(starts[i] - starts[i - 1], 10 * kSimMs);
  // Integrators start where configured (not zero).
  const RmpCodec codec;
  for (const hal::CanFrame& f : b.received) {
    if (f.id != 0x403) continue;
    const auto wi = std::get<RmpWheelIntegratorFrame>(*codec.Decode(f));
    EXPECT_EQ(wi.left_counts, 0xFFFF8000u);
    EXPECT_EQ(wi.right_counts, 0x7FFFC000u);
    break;
  }
}

TEST(SimRmpTest, CommandsDriveTheVehicleThroughTheBootAndConfiguredScales) {
  SimRmpBench b;
  b.Run(3000 * kSimMs, RmpCommandFrame{332, 0, 0, 0});
  EXPECT_NEAR(b.rmp.vehicle().truth().speed_mps, 0.75, 1e-3) << "boot velocity scale 3/4";
  b.Run(3100 * kSimMs, RmpCommandFrame{332, 0, 10, 16});  // velocity scale 100 %
  b.Run(6000 * kSimMs, RmpCommandFrame{332, 0, 0, 0});
  EXPECT_NEAR(b.rmp.vehicle().truth().speed_mps, 1.0, 1e-3);
  EXPECT_EQ(b.rmp.velocity_scale(), 1.0);
  EXPECT_EQ(b.rmp.counters().commands_too_close, 0u);
  EXPECT_EQ(b.rmp.counters().command_gaps_too_long, 0u);
  // The echo carries the last command.
  const RmpCodec codec;
  const hal::CanFrame& last_echo = *std::find_if(b.received.rbegin(), b.received.rend(), [](const hal::CanFrame& f) { return f.id == 0x407; });
  EXPECT_EQ(std::get<RmpCommandEchoFrame>(*codec.Decode(last_echo)).velocity_counts, 332);
}

TEST(SimRmpTest, TurningLeftIsReportedClockwiseNegativeOnTheWire) {
  SimRmpBench b;
  b.Run(2000 * kSimMs, RmpCommandFrame{0, 326, 0, 0});  // ~1 rad/s left
  EXPECT_NEAR(b.rmp.vehicle().truth().yaw_rate_rps, 326 * 3.14159265358979 / 1024, 1e-3);
  const hal::CanFrame& sp = *std::find_if(b.received.rbegin(), b.received.rend(), [](const hal::CanFrame& f) { return f.id == 0x402; });
  const int16_t raw = static_cast<int16_t>((sp.data[4] << 8) | sp.data[5]);
  EXPECT_NEAR(raw, -57.3 * 7.8, 10) << "1 rad/s counter-clockwise = -447 counts (clockwise positive)";
  const RmpCodec codec;
  EXPECT_NEAR(std::get<RmpSpeedFrame>(*codec.Decode(sp)).yaw_rate_rps, 1.0, 0.02);
}

TEST(SimRmpTest, FirmwareTimeoutStopsTheVehicleWhenCommandsStop) {
  SimRmpBench b;
  b.Run(3000 * kSimMs, RmpCommandFrame{332, 0, 10, 16});
  EXPECT_NEAR(b.rmp.vehicle().truth().speed_mps, 1.0, 1e-3);
  b.Run(3350 * kSimMs);
  EXPECT_NEAR(b.rmp.vehicle().truth().speed_mps, 1.0, 1e-3) << "the last command holds for 0.4 s";
  b.Run(6000 * kSimMs);
  EXPECT_NEAR(b.rmp.vehicle().truth().speed_mps, 0.0, 1e-6);
  EXPECT_EQ(b.rmp.counters().command_gaps_too_long, 0u) << "counted when the next command arrives";
  b.Run(6100 * kSimMs, RmpCommandFrame{0, 0, 0, 0});
  EXPECT_EQ(b.rmp.counters().command_gaps_too_long, 1u);
}

TEST(SimRmpTest, ConfigurationModeLockoutAndIntegratorReset) {
  SimRmpBench b;
  b.Run(100 * kSimMs, RmpCommandFrame{0, 0, 15, 1});  // lock out balance
  b.Run(200 * kSimMs, RmpCommandFrame{0, 0, 16, 2});  // ask for balance: refused
  EXPECT_EQ(b.rmp.mode(), OperationalMode::kTractor);
  b.Run(300 * kSimMs, RmpCommandFrame{0, 0, 15, 0});
  b.Run(400 * kSimMs, RmpCommandFrame{0, 0, 16, 2});
  EXPECT_EQ(b.rmp.mode(), OperationalMode::kBalance);
  b.Run(500 * kSimMs, RmpCommandFrame{0, 0, 13, 2});
  EXPECT_EQ(b.rmp.gain_schedule(), GainSchedule::kHeavy);
  b.Run(600 * kSimMs, RmpCommandFrame{0, 0, 14, 128});
  EXPECT_EQ(b.rmp.current_limit_scale(), 0.5);
  b.Run(700 * kSimMs, RmpCommandFrame{0, 0, 12, 8});
  EXPECT_EQ(b.rmp.turn_scale(), 0.5);
  b.Run(800 * kSimMs, RmpCommandFrame{0, 0, 11, 4});
  EXPECT_EQ(b.rmp.accel_scale(), 0.25);
  b.received.clear();
  b.Run(900 * kSimMs, RmpCommandFrame{0, 0, 50, kRmpResetLeftWheel | kRmpResetForeAft});
  const RmpCodec codec;
  const hal::CanFrame& wi_frame = *std::find_if(b.received.rbegin(), b.received.rend(), [](const hal::CanFrame& f) { return f.id == 0x403; });
  const auto wi = std::get<RmpWheelIntegratorFrame>(*codec.Decode(wi_frame));
  EXPECT_EQ(wi.left_counts, 0u);
  EXPECT_EQ(wi.right_counts, 0x7FFFC000u) << "only the wheels asked for";
  EXPECT_EQ(b.rmp.counters().integrator_resets, 5u);

  SimRmpOptions broken;
  broken.integrator_reset_works = false;
  SimRmpBench c(broken);
  c.Run(200 * kSimMs, RmpCommandFrame{0, 0, 50, kRmpResetAll});
  const hal::CanFrame& wi2 = *std::find_if(c.received.rbegin(), c.received.rend(), [](const hal::CanFrame& f) { return f.id == 0x403; });
  EXPECT_EQ(std::get<RmpWheelIntegratorFrame>(*codec.Decode(wi2)).left_counts, 0xFFFF8000u);
}

TEST(SimRmpTest, SilenceFaultBitsLowBatteryAndShutdown) {
  SimRmpBench b;
  b.rmp.SetSilent(true);
  b.Run(500 * kSimMs, RmpCommandFrame{0, 0, 0, 0});
  EXPECT_TRUE(b.received.empty());
  EXPECT_GT(b.rmp.counters().commands, 20u) << "a silent RMP still takes commands";
  b.rmp.SetSilent(false);
  b.rmp.SetInjectedStatusBits(kRmpStatus1MotorFeedbackFault, 0);
  b.rmp.vehicle().SetBatteryDrop(10.0);  // 76 -> 66 V: below the 68 V low-battery bit
  b.Run(1000 * kSimMs, RmpCommandFrame{332, 0, 0, 0});
  const RmpCodec codec;
  const hal::CanFrame& cu_frame = *std::find_if(b.received.rbegin(), b.received.rend(), [](const hal::CanFrame& f) { return f.id == 0x680; });
  const auto cu = std::get<RmpCuStatusFrame>(*codec.Decode(cu_frame));
  EXPECT_TRUE(cu.fault());
  EXPECT_TRUE(cu.low_battery());
  EXPECT_FALSE(cu.motors_enabled());
  EXPECT_EQ(b.rmp.vehicle().truth().speed_mps, 0.0) << "a fault bit keeps the motors off";

  ASSERT_TRUE(b.pc->Send(EncodeShutdownFrame()).ok());
  b.Run(1100 * kSimMs);
  b.received.clear();
  b.Run(1500 * kSimMs);
  EXPECT_TRUE(b.received.empty()) << "powered down";
  EXPECT_EQ(b.rmp.counters().shutdowns, 1u);
}

TEST(SimRmpTest, CommandsTooCloseAreCounted) {
  SimRmpBench b;
  b.Run(200 * kSimMs, RmpCommandFrame{0, 0, 0, 0}, 5);
  EXPECT_GT(b.rmp.counters().commands_too_close, 30u);
}

TEST(SimRmpTest, OptionsAreChecked) {
  SimRmpOptions o;
  EXPECT_TRUE(o.Check().ok());
  o.status_period_s = 0.5;
  EXPECT_EQ(o.Check().code(), StatusCode::kInvalidArgument);
  o = {};
  o.boot_mode = OperationalMode::kPowerDown;
  EXPECT_EQ(o.Check().code(), StatusCode::kInvalidArgument);
  o = {};
  o.vehicle.slip_noise_m_per_sqrt_m = -1;
  EXPECT_NE(o.Check().message().find("slip_noise"), std::string::npos);
}

}  // namespace
}  // namespace idi::rmp
