// The Barrett driver against the emulated hand on a pseudo-terminal, faults included.
#include "workcell/devices/barrett/barrett_driver.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <thread>

#include "workcell/devices/barrett/barrett_emulator.h"

namespace idi::workcell {
namespace {

using std::chrono::milliseconds;

bool BarrettMessageHas(const Status& s, const std::string& text) {
  return s.message().find(text) != std::string::npos;
}

class BarrettDriverTest : public ::testing::Test {
 protected:
  void SetUp() override {
    auto emulator = BarrettEmulator::Start();
    ASSERT_TRUE(emulator.ok()) << emulator.status().ToString();
    emulator_ = std::move(emulator).value();
    options_.name = "barrett-hand";
    options_.port = emulator_->port_path();
    options_.reply_timeout = milliseconds(150);
    options_.motion_timeout = milliseconds(1000);
    options_.init_timeout = milliseconds(1000);
    options_.quiet_period = milliseconds(30);
    options_.drain_limit = milliseconds(400);
    options_.max_consecutive_failures = 2;
    driver_ = std::make_unique<BarrettDriver>(options_, &clock_);
  }
  bool Sent(const std::string& command) const {
    const auto commands = emulator_->commands();
    return std::find(commands.begin(), commands.end(), command) != commands.end();
  }

  hal::MonotonicClock clock_;
  BarrettDriverOptions options_;
  std::unique_ptr<BarrettEmulator> emulator_;
  std::unique_ptr<BarrettDriver> driver_;
};

TEST_F(BarrettDriverTest, InitialisesOpensClosesSpreadsAndReads) {
  ASSERT_TRUE(driver_->Connect().ok());  // through the power-up banner
  EXPECT_EQ(driver_->state(), BarrettState::kConnected);
  const Status early = driver_->Close();
  EXPECT_EQ(early.code(), StatusCode::kFailedPrecondition);
  EXPECT_TRUE(BarrettMessageHas(early, "barrett-hand")) << early.message();
  EXPECT_FALSE(Sent("GC"));

  ASSERT_TRUE(driver_->Initialize().ok());
  EXPECT_TRUE(emulator_->initialized());
  EXPECT_EQ(driver_->state(), BarrettState::kReady);
  ASSERT_TRUE(driver_->Close().ok());
  EXPECT_EQ(emulator_->positions()[0], 17800);
  ASSERT_TRUE(driver_->SetSpread(M_PI / 2).ok());
  EXPECT_EQ(emulator_->positions()[3], 1575);
  EXPECT_TRUE(Sent("SM 1575"));
  const auto state = driver_->Read();
  ASSERT_TRUE(state.ok()) << state.status().ToString();
  EXPECT_TRUE(state->initialized);
  for (const double f : state->finger_rad) EXPECT_NEAR(f, 140.0 * M_PI / 180.0, 1e-9);
  EXPECT_NEAR(state->spread_rad, M_PI / 2, 1.0 / options_.spread_counts_per_rad);
  ASSERT_TRUE(driver_->Open().ok());
  EXPECT_EQ(emulator_->positions()[1], 0);
}

TEST_F(BarrettDriverTest, ClosingOnAnObjectStallsThoseFingers) {
  ASSERT_TRUE(driver_->Initialize().ok());  // connects on first use
  emulator_->SetObject(0, 9000);
  emulator_->SetObject(1, 9100);
  ASSERT_TRUE(driver_->Close().ok());
  const auto state = driver_->Read();
  ASSERT_TRUE(state.ok());
  EXPECT_NEAR(state->finger_rad[0], 9000 / options_.finger_counts_per_rad, 1e-9);
  EXPECT_NEAR(state->finger_rad[1], 9100 / options_.finger_counts_per_rad, 1e-9);
  EXPECT_NEAR(state->finger_rad[2], 17800 / options_.finger_counts_per_rad, 1e-9);
}

// An operator's stop from another thread ends a slow close at once: the hand takes no other command
// while one runs, so the driver aborts it (Control-C: the fingers stop where they are), then sends the
// stop. Cancelled, not a Timeout; motions are refused until the interrupt is cleared; the hand then
// opens again, in step.
TEST_F(BarrettDriverTest, AnInterruptAbortsTheMotionInProgressAndStopsTheHand) {
  BarrettEmulatorOptions slow;
  slow.speed_counts_per_s = 2000;  // a close takes about 9 s
  auto emulator = BarrettEmulator::Start(slow);
  ASSERT_TRUE(emulator.ok()) << emulator.status().ToString();
  emulator_ = std::move(emulator).value();
  options_.port = emulator_->port_path();
  options_.motion_timeout = milliseconds(30'000);
  driver_ = std::make_unique<BarrettDriver>(options_, &clock_);
  ASSERT_TRUE(driver_->Initialize().ok());

  Status closed = Status::Ok();
  std::thread closer([&] { closed = driver_->Close(); });
  for (int k = 0; k < 2000 && emulator_->positions()[0] < 20; ++k) std::this_thread::sleep_for(milliseconds(2));
  ASSERT_GE(emulator_->positions()[0], 20) << "the fingers never started closing";
  driver_->Interrupt();
  closer.join();
  EXPECT_EQ(closed.code(), StatusCode::kCancelled) << closed.ToString();
  EXPECT_TRUE(BarrettMessageHas(closed, "barrett-hand")) << closed.message();
  EXPECT_TRUE(BarrettMessageHas(closed, "interrupted by a stop; Control-C sent")) << closed.message();
  EXPECT_TRUE(BarrettMessageHas(closed, "stop sent")) << closed.message();
  EXPECT_EQ(emulator_->aborts(), 1);
  EXPECT_GE(emulator_->stops(), 1);
  const long stopped_at = emulator_->positions()[0];
  EXPECT_LT(stopped_at, 17800);
  EXPECT_NE(driver_->state(), BarrettState::kFault);  // a stop is not a failure of the hand

  const std::size_t sent = emulator_->commands().size();
  const Status refused = driver_->Open();
  EXPECT_EQ(refused.code(), StatusCode::kCancelled) << refused.ToString();
  EXPECT_TRUE(BarrettMessageHas(refused, "nothing sent")) << refused.message();
  EXPECT_EQ(emulator_->commands().size(), sent);
  EXPECT_EQ(emulator_->positions()[0], stopped_at);

  driver_->ClearInterrupt();
  ASSERT_TRUE(driver_->Open().ok());
  EXPECT_EQ(emulator_->positions()[0], 0);
}

TEST_F(BarrettDriverTest, SpreadOutOfRangeIsRefusedBeforeSending) {
  ASSERT_TRUE(driver_->Initialize().ok());
  const std::size_t before = emulator_->commands().size();
  const Status s = driver_->SetSpread(4.0);
  EXPECT_EQ(s.code(), StatusCode::kOutOfRange);
  EXPECT_TRUE(BarrettMessageHas(s, "barrett-hand: spread 4 rad")) << s.message();
  EXPECT_EQ(driver_->SetSpread(-0.1).code(), StatusCode::kOutOfRange);
  EXPECT_EQ(driver_->SetSpread(std::nan("")).code(), StatusCode::kOutOfRange);
  EXPECT_EQ(emulator_->commands().size(), before);
}

TEST_F(BarrettDriverTest, ErrReplyIsADeviceErrorAndTheHandIsStopped) {
  ASSERT_TRUE(driver_->Initialize().ok());
  emulator_->FailNextCommand(17);
  const Status s = driver_->Close();
  EXPECT_EQ(s.code(), StatusCode::kDeviceError);
  EXPECT_TRUE(BarrettMessageHas(s, "barrett-hand: 'GC' failed: 'ERR 17'")) << s.message();
  EXPECT_TRUE(BarrettMessageHas(s, "stop sent")) << s.message();
  EXPECT_EQ(emulator_->stops(), 1);
  EXPECT_EQ(driver_->counters().error_replies, 1u);
  EXPECT_EQ(driver_->counters().stops_sent, 1u);
  EXPECT_TRUE(driver_->Close().ok());
}

TEST_F(BarrettDriverTest, NoiseBeforeAReplyIsSkippedAndCounted) {
  ASSERT_TRUE(driver_->Initialize().ok());
  const uint64_t before = driver_->counters().garbage;
  emulator_->InjectGarbageBeforeNextReply(std::string("\x05\x7fnoise\r\n", 9));
  const auto state = driver_->Read();
  ASSERT_TRUE(state.ok()) << state.status().ToString();
  EXPECT_GT(driver_->counters().garbage, before);
}

TEST_F(BarrettDriverTest, AHandThatStopsAnsweringTimesOutFaultsAndRecovers) {
  ASSERT_TRUE(driver_->Initialize().ok());
  emulator_->SetSilent(true);
  const Status s = driver_->Close();
  EXPECT_EQ(s.code(), StatusCode::kTimeout);
  EXPECT_TRUE(BarrettMessageHas(s, "barrett-hand: no prompt after 'GC'")) << s.message();
  EXPECT_TRUE(BarrettMessageHas(s, "stop failed")) << s.message();
  EXPECT_EQ(driver_->state(), BarrettState::kFault);
  EXPECT_GE(driver_->counters().timeouts, 2u);
  emulator_->SetSilent(false);
  const auto state = driver_->Read();
  ASSERT_TRUE(state.ok()) << state.status().ToString();
  EXPECT_EQ(driver_->counters().reconnects, 1u);
}

TEST_F(BarrettDriverTest, APowerCycleIsDetectedAndTheHandReinitialised) {
  ASSERT_TRUE(driver_->Initialize().ok());
  emulator_->PowerCycle();  // banner and an unsolicited prompt, hand uninitialised
  std::this_thread::sleep_for(milliseconds(20));
  const auto state = driver_->Read();
  ASSERT_TRUE(state.ok()) << state.status().ToString();
  EXPECT_GE(driver_->counters().out_of_step, 1u);  // the banner's prompt was not taken as a reply
  const Status s = driver_->Close();
  EXPECT_EQ(s.code(), StatusCode::kDeviceError);  // the hand says it is not initialised
  EXPECT_TRUE(BarrettMessageHas(s, "ERR 3")) << s.message();
  ASSERT_TRUE(driver_->Initialize().ok());
  EXPECT_TRUE(driver_->Close().ok());
}

TEST_F(BarrettDriverTest, MissingPortNamesTheDevice) {
  BarrettDriverOptions options = options_;
  options.port = "/dev/no-such-hand";
  BarrettDriver absent(options, &clock_);
  const Status s = absent.Initialize();
  EXPECT_EQ(s.code(), StatusCode::kNotFound);
  EXPECT_TRUE(BarrettMessageHas(s, "barrett-hand")) << s.message();
  EXPECT_EQ(absent.Stop().code(), StatusCode::kNotFound);
}

}  // namespace
}  // namespace idi::workcell
