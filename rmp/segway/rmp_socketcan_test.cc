// The RMP driver on real SocketCAN (IDI_TEST_CAN_IFACE, vcan0 in tools/kernel-test), in real time,
// against a minimal RMP responder on a second socket of the same interface. Skips without the
// variable; a missing interface is a failure.
#include <gtest/gtest.h>
#include <unistd.h>
#include <net/if.h>

#include <algorithm>
#include <atomic>
#include <cstdlib>
#include <filesystem>
#include <thread>

#include "rmp/segway/rmp_driver.h"
#include "shared/drivers/socketcan/socketcan_bus.h"

namespace idi::rmp {
namespace {

constexpr int64_t kRtMs = 1'000'000;

// Sends the status cycle every 10 ms and follows the configuration commands it receives.
class RmpResponder {
 public:
  explicit RmpResponder(std::unique_ptr<drivers::SocketCanBus> bus) : bus_(std::move(bus)) {}
  void Run() {
    hal::MonotonicClock clock;
    RmpCodec codec;
    int64_t next_cycle = clock.NowNs();
    uint32_t left = 0x7FFF0000u, right = 0xFFFFFF00u;
    int64_t last_cmd = -1;
    while (!stop_) {
      const int64_t now = clock.NowNs();
      if (now >= next_cycle) {
        next_cycle += 10 * kRtMs;
        if (next_cycle < now) next_cycle = now + 10 * kRtMs;
        if (!silent_) {
          RmpModeFrame mode;
          mode.mode = static_cast<OperationalMode>(mode_.load());
          mode.gain_schedule = static_cast<GainSchedule>(gain_.load());
          mode.ui_battery_v = 12.5;
          mode.base_battery_v = 74.0;
          for (const hal::CanFrame& f :
               {codec.Encode(RmpBuildFrame{7}), codec.Encode(RmpTiltFrame{}), codec.Encode(RmpSpeedFrame{}),
                codec.Encode(RmpWheelIntegratorFrame{left, right}), codec.Encode(RmpBodyIntegratorFrame{left, 0}),
                codec.Encode(RmpTorqueFrame{}), codec.Encode(mode), codec.Encode(RmpCommandEchoFrame{})}) {
            (void)bus_->Send(f);
          }
        }
      }
      auto r = bus_->Receive(std::chrono::milliseconds(std::max<int64_t>(1, (next_cycle - clock.NowNs()) / kRtMs)));
      if (!r.ok() || !r->has_value() || (*r)->id != kRmpIdCommand) continue;
      Result<RmpCommandFrame> c = DecodeCommandFrame(**r);
      if (!c.ok()) continue;
      const int64_t t = clock.NowNs();
      if (last_cmd >= 0) max_gap_ns_ = std::max<int64_t>(max_gap_ns_, t - last_cmd);
      last_cmd = t;
      ++commands_;
      last_velocity_ = c->velocity_counts;
      if (c->config_id == static_cast<uint16_t>(RmpConfigId::kOperationalMode)) mode_ = c->config_param;
      if (c->config_id == static_cast<uint16_t>(RmpConfigId::kGainSchedule)) gain_ = c->config_param;
      if (c->config_id == static_cast<uint16_t>(RmpConfigId::kResetIntegrators)) left = right = 0;
    }
  }
  std::atomic<bool> stop_{false}, silent_{false};
  std::atomic<int> commands_{0}, last_velocity_{0};
  std::atomic<int64_t> max_gap_ns_{0};

 private:
  std::unique_ptr<drivers::SocketCanBus> bus_;
  std::atomic<uint16_t> mode_{0}, gain_{1};
};

TEST(RmpSocketCanTest, DriverConfiguresDrivesAndStopsOverARealCanInterface) {
  const char* iface = std::getenv("IDI_TEST_CAN_IFACE");
  if (iface == nullptr || *iface == '\0') GTEST_SKIP() << "IDI_TEST_CAN_IFACE not set (tools/kernel-test sets it)";
  ASSERT_NE(::if_nametoindex(iface), 0u) << "IDI_TEST_CAN_IFACE=" << iface << " does not exist";

  drivers::SocketCanOptions rmp_side;
  rmp_side.interface = iface;
  rmp_side.filters = {{kRmpIdCommand, 0x7FF, false, false}};
  auto rmp_bus = drivers::SocketCanBus::Open(rmp_side);
  ASSERT_TRUE(rmp_bus.ok()) << rmp_bus.status().ToString();
  RmpResponder responder(std::move(rmp_bus).value());
  std::thread rmp_thread([&] { responder.Run(); });

  hal::MonotonicClock clock;
  drivers::SocketCanOptions pc_side;
  pc_side.interface = iface;
  pc_side.filters = {{0x400, 0x7F8, false, false}, {kRmpIdCuStatus, 0x7FF, false, false}};
  auto pc_bus = drivers::SocketCanBus::Open(pc_side, &clock);
  ASSERT_TRUE(pc_bus.ok()) << pc_bus.status().ToString();
  const std::string log_path = (std::filesystem::path(::testing::TempDir()) / ("rmp_socketcan_" + std::to_string(::getpid()) + ".log")).string();
  replay::CandumpWriterOptions log_options;
  log_options.interface = iface;
  auto log = replay::CandumpWriter::Open(log_path, log_options);
  ASSERT_TRUE(log.ok());
  RmpDriverOptions options;
  options.status_timeout_s = 0.3;  // a slow emulated machine may delay a cycle
  auto created = RmpDriver::Create(pc_bus->get(), &clock, options);
  ASSERT_TRUE(created.ok());
  RmpDriver& driver = **created;
  driver.SetFrameLog(log->get());
  ASSERT_TRUE(driver.Start().ok());

  const int64_t t0 = clock.NowNs();
  while (clock.NowNs() < t0 + 4000 * kRtMs) {
    const int64_t t = clock.NowNs();
    (void)driver.SetCommand({0.5, 0.0, t - 10 * kRtMs});
    ASSERT_TRUE(driver.RunUntil(t + 33 * kRtMs).ok());
  }
  EXPECT_EQ(driver.health().state, RmpDriverState::kRunning) << driver.health().last_event;
  EXPECT_TRUE(driver.health().config_verified);
  EXPECT_EQ(driver.health().odometry_reset, OdometryResetResult::kConfirmed);
  EXPECT_EQ(responder.last_velocity_.load(), 166) << "0.5 m/s at 332 counts per m/s";
  EXPECT_GT(responder.commands_.load(), 50);
  EXPECT_LT(responder.max_gap_ns_.load(), 300 * kRtMs) << "the RMP needs a command at least every 300 ms";
  EXPECT_EQ(driver.health().counters.send_errors, 0u);
  EXPECT_EQ(driver.health().counters.decode_errors, 0u);

  responder.silent_ = true;
  const int64_t t1 = clock.NowNs();
  while (clock.NowNs() < t1 + 1000 * kRtMs) {
    const int64_t t = clock.NowNs();
    (void)driver.SetCommand({0.5, 0.0, t - 10 * kRtMs});
    ASSERT_TRUE(driver.RunUntil(t + 33 * kRtMs).ok());
  }
  EXPECT_TRUE(driver.health().inhibit & kRmpInhibitStatusStale);
  ASSERT_TRUE(driver.Shutdown().ok());
  EXPECT_EQ(driver.recent_sent().back().frame.velocity_counts, 0);
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  EXPECT_EQ(responder.last_velocity_.load(), 0);
  responder.stop_ = true;
  rmp_thread.join();

  ASSERT_TRUE((*log)->Close().ok());
  auto records = replay::ReadCandumpFile(log_path);
  ASSERT_TRUE(records.ok()) << records.status().ToString();
  EXPECT_EQ(records->size(), (*log)->lines_written());
  EXPECT_EQ(records->front().interface, iface);
  std::filesystem::remove(log_path);
}

}  // namespace
}  // namespace idi::rmp
