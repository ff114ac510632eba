// The arm driver against the emulated VAL3 server on loopback TCP, faults included.
#include "workcell/devices/staubli/staubli_driver.h"

#include <gtest/gtest.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <thread>

#include "shared/util/units.h"
#include "workcell/devices/staubli/staubli_joints.h"
#include "workcell/devices/staubli/val3_emulator.h"

namespace idi::workcell {
namespace {

using std::chrono::milliseconds;

bool StaubliMessageHas(const Status& s, const std::string& text) {
  return s.message().find(text) != std::string::npos;
}

class StaubliDriverTest : public ::testing::Test {
 protected:
  void StartServer(Val3EmulatorOptions options = {}) {
    auto server = Val3Emulator::Start(options);
    ASSERT_TRUE(server.ok()) << server.status().ToString();
    server_ = std::move(server).value();
    options_.name = "arm1";
    options_.host = "127.0.0.1";
    options_.port = server_->port();
    options_.connect_timeout = milliseconds(300);
    options_.reply_timeout = milliseconds(150);
    options_.poll_period = milliseconds(5);
    options_.max_consecutive_failures = 2;
    driver_ = std::make_unique<StaubliDriver>(options_, &clock_);
  }
  void SetUp() override { StartServer(); }
  std::size_t VerbCount(const std::string& verb) const {
    const auto verbs = server_->verbs();
    return static_cast<std::size_t>(std::count(verbs.begin(), verbs.end(), verb));
  }
  static hal::MoveOptions Move(double speed, milliseconds timeout = milliseconds(3000)) {
    hal::MoveOptions m;
    m.speed_fraction = speed;
    m.timeout = timeout;
    return m;
  }

  hal::MonotonicClock clock_;
  StaubliDriverOptions options_;
  std::unique_ptr<Val3Emulator> server_;
  std::unique_ptr<StaubliDriver> driver_;
};

const Joints kStaubliTarget = {0.3, -1.2, 1.4, 0.5, -0.4, 0.8};

TEST_F(StaubliDriverTest, MovesAndReadsJointsInTheModelConvention) {
  ASSERT_TRUE(driver_->Connect().ok());
  EXPECT_TRUE(driver_->has_rail());
  ASSERT_TRUE(driver_->MoveJoints(kStaubliTarget, Move(1.0)).ok());
  const ControllerJointsDeg on_controller = server_->joints_deg();
  const ControllerJointsDeg expected = ModelRadToControllerDeg(kStaubliTarget);
  for (std::size_t i = 0; i < 6; ++i) EXPECT_NEAR(on_controller[i], expected[i], 1e-4) << i;
  // Joint 2: model -1.2 rad = -68.75 deg, +90 on the controller.
  EXPECT_NEAR(on_controller[1], RadToDeg(-1.2) + 90.0, 1e-4);
  const auto state = driver_->ReadJoints();
  ASSERT_TRUE(state.ok()) << state.status().ToString();
  for (std::size_t i = 0; i < 6; ++i) EXPECT_NEAR(state->q_rad[i], kStaubliTarget[i], DegToRad(1e-4)) << i;
  EXPECT_FALSE(state->moving);
  EXPECT_TRUE(driver_->Heartbeat().ok());
  const auto status = driver_->ReadStatus();
  ASSERT_TRUE(status.ok());
  EXPECT_TRUE(status->powered);
}

// An operator's stop from another thread ends the wait for a slow move at the next poll: Cancelled (not
// a Timeout), the arm stopped part-way. Moves are refused until the interrupt is cleared.
TEST_F(StaubliDriverTest, AnInterruptEndsTheWaitForAMoveAndStopsTheArm) {
  Val3EmulatorOptions options;
  options.joint_speed_deg_per_s = 5;  // the move below takes seconds
  StartServer(options);
  ASSERT_TRUE(driver_->Connect().ok());
  const ControllerJointsDeg start = server_->joints_deg();
  Status moved = Status::Ok();
  std::thread mover([&] { moved = driver_->MoveJoints(kStaubliTarget, Move(1.0, milliseconds(30'000))); });
  for (int k = 0; k < 2000 && !server_->moving(); ++k) std::this_thread::sleep_for(milliseconds(2));
  ASSERT_TRUE(server_->moving()) << "the arm never started moving";
  driver_->Interrupt();
  mover.join();
  EXPECT_EQ(moved.code(), StatusCode::kCancelled) << moved.ToString();
  EXPECT_TRUE(StaubliMessageHas(moved, "arm1")) << moved.message();
  EXPECT_TRUE(StaubliMessageHas(moved, "interrupted by a stop")) << moved.message();
  EXPECT_TRUE(StaubliMessageHas(moved, "stop sent")) << moved.message();
  EXPECT_GE(server_->stop_requests(), 1);
  EXPECT_FALSE(server_->moving());
  const ControllerJointsDeg target = ModelRadToControllerDeg(kStaubliTarget);
  EXPECT_GT(std::abs(server_->joints_deg()[1] - target[1]), 1.0) << "the arm was not stopped part-way";
  EXPECT_EQ(driver_->state(), StaubliState::kReady);

  const std::size_t sent = server_->verbs().size();
  const Status refused = driver_->MoveTo(100.0, Move(1.0));
  EXPECT_EQ(refused.code(), StatusCode::kCancelled) << refused.ToString();
  EXPECT_TRUE(StaubliMessageHas(refused, "nothing sent")) << refused.message();
  EXPECT_EQ(server_->verbs().size(), sent);

  driver_->ClearInterrupt();
  ASSERT_TRUE(driver_->MoveJoints(ControllerDegToModelRad(start), Move(1.0, milliseconds(30'000))).ok());
}

TEST_F(StaubliDriverTest, OutOfRangeJointsAreRefusedBeforeSending) {
  ASSERT_TRUE(driver_->Connect().ok());
  Joints q{};
  q[2] = DegToRad(250.0);  // model J3 max: 142.5 + 90 = 232.5 deg
  const Status s = driver_->MoveJoints(q, Move(0.5));
  EXPECT_EQ(s.code(), StatusCode::kOutOfRange);
  EXPECT_TRUE(StaubliMessageHas(s, "arm1: joint 3 = 250.000 deg is outside [-52.5, 232.5]")) << s.message();
  EXPECT_EQ(driver_->MoveJoints(kStaubliTarget, Move(1.5)).code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(VerbCount("MOVEJ"), 0u);
}

TEST_F(StaubliDriverTest, RailMovesAndReads) {
  ASSERT_TRUE(driver_->MoveTo(1000.0, Move(0.5)).ok());  // connects on first use
  EXPECT_NEAR(server_->rail_mm(), 1000.0, 1e-9);
  const auto rail = driver_->Read();
  ASSERT_TRUE(rail.ok());
  EXPECT_NEAR(rail->position_mm, 1000.0, 1e-4);
  EXPECT_EQ(driver_->MoveTo(-5.0, Move(0.5)).code(), StatusCode::kOutOfRange);
  EXPECT_EQ(VerbCount("RAILMOVE"), 1u);
}

TEST_F(StaubliDriverTest, AControllerWithoutARailSaysSo) {
  Val3EmulatorOptions options;
  options.has_rail = false;
  StartServer(options);
  const Status s = driver_->MoveTo(100.0, Move(0.5));
  EXPECT_EQ(s.code(), StatusCode::kFailedPrecondition);
  EXPECT_TRUE(StaubliMessageHas(s, "arm1: this controller drives no rail")) << s.message();
}

TEST_F(StaubliDriverTest, AnErrorReplyFailsTheMoveAndAStopIsSent) {
  ASSERT_TRUE(driver_->Connect().ok());
  server_->SetPowered(false);
  const Status s = driver_->MoveJoints(kStaubliTarget, Move(0.5));
  EXPECT_EQ(s.code(), StatusCode::kFailedPrecondition);
  EXPECT_TRUE(StaubliMessageHas(s, "arm1: controller refused MOVEJ: ERR 4 arm power is off")) << s.message();
  EXPECT_TRUE(StaubliMessageHas(s, "stop sent")) << s.message();
  EXPECT_EQ(server_->stop_requests(), 1);
  EXPECT_EQ(driver_->counters().error_replies, 1u);
  EXPECT_EQ(driver_->counters().stops_sent, 1u);
}

TEST_F(StaubliDriverTest, AGarbageReplyTimesOutTheMoveAndStopsTheArm) {
  ASSERT_TRUE(driver_->Connect().ok());
  // Noise instead of the MOVEJ reply, and a stray NUL that ends up in front of the next reply.
  server_->ReplaceNextReplyWithGarbage(std::string("\x15#%&garbage\x7f\n\0", 14));
  const Status s = driver_->MoveJoints(kStaubliTarget, Move(0.01));
  EXPECT_EQ(s.code(), StatusCode::kTimeout);
  EXPECT_TRUE(StaubliMessageHas(s, "arm1: no reply to MOVEJ")) << s.message();
  EXPECT_TRUE(StaubliMessageHas(s, "garbage received instead")) << s.message();
  EXPECT_TRUE(StaubliMessageHas(s, "stop sent")) << s.message();
  EXPECT_EQ(server_->stop_requests(), 1);
  EXPECT_FALSE(server_->moving());
  EXPECT_EQ(driver_->counters().garbage, 2u);  // the noise line, and the NUL stripped off the STOP reply
  EXPECT_EQ(driver_->counters().timeouts, 1u);
}

TEST_F(StaubliDriverTest, AConnectionDroppedDuringAMoveIsReconnectedToSendTheStop) {
  ASSERT_TRUE(driver_->Connect().ok());
  server_->DropConnectionOnRequest(2);  // MOVEJ goes through, the first JOINTS poll loses the link
  const Status s = driver_->MoveJoints(kStaubliTarget, Move(0.01));
  EXPECT_EQ(s.code(), StatusCode::kIoError);
  EXPECT_TRUE(StaubliMessageHas(s, "arm1: connection lost")) << s.message();
  EXPECT_TRUE(StaubliMessageHas(s, "stop sent")) << s.message();
  EXPECT_EQ(server_->disconnect_stops(), 1);  // the server stopped on its own when the link dropped
  EXPECT_EQ(server_->stop_requests(), 1);     // and the driver's stop arrived after reconnecting
  EXPECT_EQ(server_->connections(), 2);
  EXPECT_EQ(driver_->counters().disconnects, 1u);
  EXPECT_EQ(driver_->counters().reconnects, 1u);
  EXPECT_FALSE(server_->moving());
}

TEST_F(StaubliDriverTest, ASilentServerTimesOutFaultsAndRecovers) {
  ASSERT_TRUE(driver_->Connect().ok());
  server_->SetSilent(true);
  const auto first = driver_->ReadJoints();
  EXPECT_EQ(first.status().code(), StatusCode::kTimeout);
  EXPECT_TRUE(StaubliMessageHas(first.status(), "arm1: no reply to JOINTS")) << first.status().message();
  EXPECT_FALSE(driver_->ReadJoints().ok());
  EXPECT_EQ(driver_->state(), StaubliState::kFault);
  const Status stop = driver_->Stop();  // reconnects, but the HELLO is not answered either
  EXPECT_EQ(stop.code(), StatusCode::kTimeout);
  EXPECT_TRUE(StaubliMessageHas(stop, "stop")) << stop.message();
  EXPECT_TRUE(StaubliMessageHas(stop, "HELLO")) << stop.message();
  server_->SetSilent(false);
  const auto back = driver_->ReadJoints();
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_GE(driver_->counters().timeouts, 3u);
  EXPECT_EQ(driver_->counters().faults, 1u);
}

TEST_F(StaubliDriverTest, AnArmThatSettlesShortOfTheTargetIsAnErrorAndStopped) {
  ASSERT_TRUE(driver_->Connect().ok());
  server_->StopNextMoveHalfway();
  const Status s = driver_->MoveJoints(kStaubliTarget, Move(1.0));
  EXPECT_EQ(s.code(), StatusCode::kDeviceError);
  EXPECT_TRUE(StaubliMessageHas(s, "arm1: the arm settled")) << s.message();
  EXPECT_TRUE(StaubliMessageHas(s, "stop sent")) << s.message();
}

TEST_F(StaubliDriverTest, ConnectionRefusedNamesTheArm) {
  server_.reset();  // nothing listens on the port any more
  const Status s = driver_->Connect();
  EXPECT_FALSE(s.ok());
  EXPECT_TRUE(StaubliMessageHas(s, "arm1")) << s.message();
  EXPECT_TRUE(StaubliMessageHas(s, "127.0.0.1:" + std::to_string(options_.port))) << s.message();
  EXPECT_FALSE(driver_->MoveJoints(kStaubliTarget, Move(0.5)).ok());
}

TEST_F(StaubliDriverTest, TheServerStopsTheArmWhenItsClientGoesQuiet) {
  Val3EmulatorOptions options;
  options.watchdog = milliseconds(100);
  options.joint_speed_deg_per_s = 10;  // a move that outlasts the watchdog
  StartServer(options);
  auto fd = TcpConnect("127.0.0.1", server_->port(), milliseconds(300));
  ASSERT_TRUE(fd.ok());
  const std::string request = "1 MOVEJ 100 0 0 10 0 0 0\n";
  ASSERT_EQ(::send(fd.value(), request.data(), request.size(), MSG_NOSIGNAL), static_cast<ssize_t>(request.size()));
  std::this_thread::sleep_for(milliseconds(400));
  EXPECT_EQ(server_->watchdog_stops(), 1);
  EXPECT_FALSE(server_->moving());
  EXPECT_LT(server_->joints_deg()[2], 10.0);
  ::close(fd.value());
}

}  // namespace
}  // namespace idi::workcell
