// The PTU driver against the emulated unit on a pseudo-terminal, faults included.
#include "workcell/devices/ptu/ptu_driver.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <thread>

#include "workcell/devices/ptu/ptu_emulator.h"

namespace idi::workcell {
namespace {

using std::chrono::milliseconds;

bool PtuMessageHas(const Status& s, const std::string& text) { return s.message().find(text) != std::string::npos; }

class PtuDriverTest : public ::testing::Test {
 protected:
  void StartEmulator(PtuEmulatorOptions options = {}) {
    auto emulator = PtuEmulator::Start(options);
    ASSERT_TRUE(emulator.ok()) << emulator.status().ToString();
    emulator_ = std::move(emulator).value();
    PtuDriverOptions driver_options;
    driver_options.name = "ptu-left";
    driver_options.port = emulator_->port_path();
    driver_options.reply_timeout = milliseconds(150);
    driver_options.quiet_period = milliseconds(30);
    driver_options.drain_limit = milliseconds(400);
    driver_options.init_attempts = 2;
    driver_options.max_consecutive_failures = 2;
    driver_ = std::make_unique<PtuDriver>(driver_options, &clock_);
  }
  void SetUp() override { StartEmulator(); }

  std::size_t CommandCount(const std::string& prefix) const {
    const auto commands = emulator_->commands();
    return static_cast<std::size_t>(std::count_if(commands.begin(), commands.end(), [&](const std::string& c) {
      return c.rfind(prefix, 0) == 0;
    }));
  }

  hal::MonotonicClock clock_;
  std::unique_ptr<PtuEmulator> emulator_;
  std::unique_ptr<PtuDriver> driver_;
};

TEST_F(PtuDriverTest, ConnectsThroughPowerUpChatterAndReadsResolutionAndLimitsFromTheUnit) {
  // A tilt resolution unlike the pan's: the driver must use what TR says, not a built-in value.
  PtuEmulatorOptions options;
  options.tilt_arcsec = 46.2857;
  StartEmulator(options);
  ASSERT_TRUE(driver_->Connect().ok());
  EXPECT_EQ(driver_->state(), PtuState::kReady);
  const auto limits = driver_->Limits();
  ASSERT_TRUE(limits.ok());
  EXPECT_NEAR(limits->pan_resolution_rad, PtuArcSecondsToRad(185.1428), 1e-12);
  EXPECT_NEAR(limits->tilt_resolution_rad, PtuArcSecondsToRad(46.2857), 1e-12);
  EXPECT_NEAR(limits->pan_max_rad, 3090 * PtuArcSecondsToRad(185.1428), 1e-9);
  EXPECT_NEAR(limits->tilt_min_rad, -907 * PtuArcSecondsToRad(46.2857), 1e-9);
  for (const char* c : {"FT", "ED", "PR", "TR", "PN", "PX", "TN", "TX"}) {
    EXPECT_EQ(CommandCount(c), 1u) << c;
  }
  // The banner and the late mode announcement were seen and skipped.
  EXPECT_GE(driver_->counters().garbage_lines, 1u);
}

TEST_F(PtuDriverTest, MoveToQuantisesToPositionsAndReadsBack) {
  ASSERT_TRUE(driver_->Connect().ok());
  const double res = PtuArcSecondsToRad(185.1428);
  ASSERT_TRUE(driver_->MoveTo(0.5, -0.2, milliseconds(2000)).ok());
  EXPECT_EQ(emulator_->pan_position(), std::lround(0.5 / res));
  EXPECT_EQ(emulator_->tilt_position(), std::lround(-0.2 / res));
  const auto state = driver_->Read();
  ASSERT_TRUE(state.ok());
  EXPECT_NEAR(state->pan_rad, 0.5, res / 2);
  EXPECT_NEAR(state->tilt_rad, -0.2, res / 2);
  EXPECT_GT(state->timestamp_ns, 0);
  EXPECT_EQ(driver_->counters().timeouts, 0u);
}

// An operator's stop from another thread ends the wait for a long move at once (the move would take
// 15 s, longer than the wait allowed): Cancelled, not a Timeout, and the unit halted part-way. Moves are
// refused until the interrupt is cleared; then the driver moves again (the late await reply skipped).
TEST_F(PtuDriverTest, AnInterruptEndsTheWaitForAMoveAndHaltsTheUnit) {
  PtuEmulatorOptions options;
  options.chatter_on_first_input = false;
  options.speed_pos_per_s = 200;
  StartEmulator(options);
  ASSERT_TRUE(driver_->Connect().ok());
  const double res = PtuArcSecondsToRad(185.1428);
  Status moved = Status::Ok();
  std::thread mover([&] { moved = driver_->MoveTo(3000 * res, 0.0, milliseconds(10'000)); });
  for (int k = 0; k < 2000 && emulator_->pan_position() < 20; ++k) std::this_thread::sleep_for(milliseconds(2));
  ASSERT_GE(emulator_->pan_position(), 20) << "the unit never started moving";
  driver_->Interrupt();
  mover.join();
  EXPECT_EQ(moved.code(), StatusCode::kCancelled) << moved.ToString();
  EXPECT_TRUE(PtuMessageHas(moved, "ptu-left")) << moved.message();
  EXPECT_TRUE(PtuMessageHas(moved, "interrupted by a stop")) << moved.message();
  EXPECT_TRUE(PtuMessageHas(moved, "halt sent")) << moved.message();
  EXPECT_GE(emulator_->halts(), 1);
  const int32_t halted_at = emulator_->pan_position();
  EXPECT_LT(halted_at, 3000);
  EXPECT_EQ(driver_->state(), PtuState::kReady);  // a stop is not a failure of the unit

  const std::size_t sent = emulator_->commands().size();
  const Status refused = driver_->MoveTo(0.0, 0.0, milliseconds(10'000));
  EXPECT_EQ(refused.code(), StatusCode::kCancelled) << refused.ToString();
  EXPECT_TRUE(PtuMessageHas(refused, "nothing sent")) << refused.message();
  EXPECT_EQ(emulator_->commands().size(), sent);
  EXPECT_EQ(emulator_->pan_position(), halted_at);

  driver_->ClearInterrupt();
  ASSERT_TRUE(driver_->MoveTo((halted_at - 10) * res, 0.0, milliseconds(10'000)).ok());
  EXPECT_EQ(emulator_->pan_position(), halted_at - 10);
}

TEST_F(PtuDriverTest, OutOfRangeIsRefusedBeforeAnythingIsSent) {
  ASSERT_TRUE(driver_->Connect().ok());
  const std::size_t before = emulator_->commands().size();
  const Status s = driver_->MoveTo(3.0, 0.0, milliseconds(1000));  // pan max is 3090 * 0.000898 = 2.77 rad
  EXPECT_EQ(s.code(), StatusCode::kOutOfRange);
  EXPECT_TRUE(PtuMessageHas(s, "ptu-left")) << s.message();
  EXPECT_TRUE(PtuMessageHas(s, "[-3090, 3090]")) << s.message();
  EXPECT_EQ(emulator_->commands().size(), before);
  EXPECT_EQ(driver_->MoveTo(0.0, -1.0, milliseconds(1000)).code(), StatusCode::kOutOfRange);  // tilt min -0.815
  EXPECT_EQ(driver_->MoveTo(std::nan(""), 0.0, milliseconds(1000)).code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(emulator_->commands().size(), before);
}

TEST_F(PtuDriverTest, ErrorReplyFailsTheMoveNamesTheDeviceAndHalts) {
  ASSERT_TRUE(driver_->Connect().ok());
  emulator_->FailNextCommand("Illegal Command argument");
  const Status s = driver_->MoveTo(0.1, 0.1, milliseconds(1000));
  EXPECT_EQ(s.code(), StatusCode::kDeviceError);
  EXPECT_TRUE(PtuMessageHas(s, "ptu-left")) << s.message();
  EXPECT_TRUE(PtuMessageHas(s, "Illegal Command argument")) << s.message();
  EXPECT_TRUE(PtuMessageHas(s, "halt sent")) << s.message();
  EXPECT_EQ(emulator_->halts(), 1);
  EXPECT_EQ(driver_->counters().error_replies, 1u);
  EXPECT_EQ(driver_->counters().halts_sent, 1u);
  // The next move works.
  EXPECT_TRUE(driver_->MoveTo(0.1, 0.1, milliseconds(1000)).ok());
}

TEST_F(PtuDriverTest, AsynchronousLimitReplyDuringAMoveFailsItAndHalts) {
  ASSERT_TRUE(driver_->Connect().ok());
  emulator_->LimitHitDuringNextMove(PtuAxis::kPan);
  const Status s = driver_->MoveTo(1.0, 0.0, milliseconds(2000));
  EXPECT_EQ(s.code(), StatusCode::kDeviceError);
  EXPECT_TRUE(PtuMessageHas(s, "'!P'")) << s.message();
  EXPECT_TRUE(PtuMessageHas(s, "pan hit its limit")) << s.message();
  EXPECT_EQ(driver_->counters().limit_hits, 1u);
  EXPECT_EQ(emulator_->halts(), 1);
  EXPECT_LT(emulator_->pan_position(), std::lround(1.0 / PtuArcSecondsToRad(185.1428)));
}

TEST_F(PtuDriverTest, GarbageBeforeAReplyIsSkippedAndCounted) {
  ASSERT_TRUE(driver_->Connect().ok());
  ASSERT_TRUE(driver_->MoveTo(0.2, 0.0, milliseconds(1000)).ok());
  const uint64_t garbage_before = driver_->counters().garbage_lines;
  emulator_->InjectGarbageBeforeNextReply(std::string("\x01\x02~~noise\xfe\r\n", 11));
  const auto state = driver_->Read();
  ASSERT_TRUE(state.ok()) << state.status().ToString();
  EXPECT_NEAR(state->pan_rad, 0.2, PtuArcSecondsToRad(185.1428));
  EXPECT_EQ(driver_->counters().garbage_lines, garbage_before + 1);
}

TEST_F(PtuDriverTest, ALateReplyIsATimeoutThenTheDriverResynchronises) {
  ASSERT_TRUE(driver_->Connect().ok());
  ASSERT_TRUE(driver_->MoveTo(0.3, 0.1, milliseconds(1000)).ok());
  emulator_->DelayNextReply(milliseconds(250));  // longer than the 150 ms reply timeout
  const auto late = driver_->Read();
  ASSERT_EQ(late.status().code(), StatusCode::kTimeout);
  EXPECT_TRUE(PtuMessageHas(late.status(), "ptu-left: no reply to 'PP'")) << late.status().message();
  // The late "* <pan>" must not be taken as the answer to a later query.
  const auto state = driver_->Read();
  ASSERT_TRUE(state.ok()) << state.status().ToString();
  EXPECT_NEAR(state->pan_rad, 0.3, PtuArcSecondsToRad(185.1428));
  EXPECT_NEAR(state->tilt_rad, 0.1, PtuArcSecondsToRad(185.1428));
  EXPECT_EQ(driver_->counters().timeouts, 1u);
  EXPECT_GE(driver_->counters().resyncs, 1u);
}

TEST_F(PtuDriverTest, AUnitThatStopsAnsweringFaultsTheDriverWhichRecoversWhenItAnswersAgain) {
  ASSERT_TRUE(driver_->Connect().ok());
  emulator_->SetSilent(true);
  const auto first = driver_->Read();
  EXPECT_EQ(first.status().code(), StatusCode::kTimeout);
  EXPECT_TRUE(PtuMessageHas(first.status(), "ptu-left")) << first.status().message();
  const auto second = driver_->Read();
  EXPECT_FALSE(second.ok());
  EXPECT_EQ(driver_->state(), PtuState::kFault);
  const Status halt = driver_->Halt();
  EXPECT_EQ(halt.code(), StatusCode::kTimeout);
  EXPECT_TRUE(PtuMessageHas(halt, "halt")) << halt.message();
  EXPECT_GE(driver_->counters().timeouts, 2u);
  EXPECT_GE(driver_->counters().faults, 1u);

  emulator_->SetSilent(false);
  const auto back = driver_->Read();
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(driver_->state(), PtuState::kReady);
  EXPECT_EQ(driver_->counters().reconnects, 1u);
}

TEST_F(PtuDriverTest, APowerCycleMidSessionIsSurvived) {
  ASSERT_TRUE(driver_->Connect().ok());
  ASSERT_TRUE(driver_->MoveTo(0.4, 0.0, milliseconds(1000)).ok());
  // Chatter, echo back on, verbose feedback, positions back to zero.
  emulator_->PowerCycle();
  std::this_thread::sleep_for(milliseconds(60));
  const auto state = driver_->Read();
  ASSERT_TRUE(state.ok()) << state.status().ToString();
  EXPECT_EQ(state->pan_rad, 0.0);
  ASSERT_TRUE(driver_->MoveTo(-0.4, 0.05, milliseconds(1000)).ok());
  EXPECT_EQ(emulator_->pan_position(), std::lround(-0.4 / PtuArcSecondsToRad(185.1428)));
}

TEST_F(PtuDriverTest, HaltWorksWithoutAnInitialisedConnection) {
  EXPECT_TRUE(driver_->Halt().ok());
  EXPECT_EQ(emulator_->halts(), 1);
}

// The serial adapter drops off and comes back (here: the unit's pseudo-terminal goes away, and the
// port's path now leads to a new one): the old descriptor only gives I/O errors, and the halt opens
// the port again rather than failing on it.
TEST_F(PtuDriverTest, HaltReopensAPortThatDied) {
  const std::string link = ::testing::TempDir() + "idi_ptu_link_" + std::to_string(::getpid());
  std::filesystem::remove(link);
  std::filesystem::create_symlink(emulator_->port_path(), link);
  PtuDriverOptions o;
  o.name = "ptu-left";
  o.port = link;
  o.reply_timeout = milliseconds(150);
  o.quiet_period = milliseconds(30);
  o.drain_limit = milliseconds(400);
  o.init_attempts = 2;
  PtuDriver driver(o, &clock_);
  ASSERT_TRUE(driver.Connect().ok());
  emulator_.reset();  // the old pseudo-terminal is gone: its slave side now fails with EIO
  auto fresh = PtuEmulator::Start();
  ASSERT_TRUE(fresh.ok()) << fresh.status().ToString();
  std::filesystem::remove(link);
  std::filesystem::create_symlink((*fresh)->port_path(), link);
  const Status halted = driver.Halt();
  EXPECT_TRUE(halted.ok()) << halted.ToString();
  EXPECT_EQ((*fresh)->halts(), 1);
  std::filesystem::remove(link);
}

TEST_F(PtuDriverTest, ConnectFailuresNameTheDevice) {
  emulator_->SetSilent(true);
  const Status silent = driver_->Connect();
  EXPECT_EQ(silent.code(), StatusCode::kTimeout);
  EXPECT_TRUE(PtuMessageHas(silent, "ptu-left: initialisation on " + emulator_->port_path() + " failed after 2"))
      << silent.message();

  PtuDriverOptions missing;
  missing.name = "ptu-right";
  missing.port = "/dev/no-such-ptu";
  PtuDriver absent(missing, &clock_);
  const Status s = absent.Connect();
  EXPECT_EQ(s.code(), StatusCode::kNotFound);
  EXPECT_TRUE(PtuMessageHas(s, "ptu-right")) << s.message();
  EXPECT_EQ(absent.MoveTo(0, 0, milliseconds(100)).code(), StatusCode::kNotFound);
}

}  // namespace
}  // namespace idi::workcell
