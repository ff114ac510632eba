// StopSignals: SIGTERM, SIGINT and SIGHUP become a stop request while it lives, a signal that was ignored
// when it was made (nohup's SIGHUP) stays ignored, and the dispositions before come back afterwards.
#include "shared/runtime/stop_signals.h"

#include <gtest/gtest.h>

#include <csignal>

namespace idi {
namespace {

// Each test sets the dispositions it starts from (a shell that runs the tests in the background has
// SIGINT ignored already) and puts the process's own back afterwards.
class StopSignalsTest : public ::testing::Test {
 protected:
  void SetUp() override {
    for (std::size_t i = 0; i < kSignals.size(); ++i) sigaction(kSignals[i], nullptr, &saved_[i]);
  }
  void TearDown() override {
    for (std::size_t i = 0; i < kSignals.size(); ++i) sigaction(kSignals[i], &saved_[i], nullptr);
  }
  static void Set(int sig, void (*handler)(int)) {
    struct sigaction sa {};
    sa.sa_handler = handler;
    sigemptyset(&sa.sa_mask);
    ASSERT_EQ(sigaction(sig, &sa, nullptr), 0);
  }
  static void (*HandlerOf(int sig))(int) {
    struct sigaction sa {};
    sigaction(sig, nullptr, &sa);
    return sa.sa_handler;
  }
  static constexpr std::array<int, 3> kSignals = {SIGINT, SIGTERM, SIGHUP};
  std::array<struct sigaction, 3> saved_{};
};

TEST_F(StopSignalsTest, EachSignalIsAStopRequestWithItsNumber) {
  for (const int sig : kSignals) {
    Set(SIGINT, SIG_DFL);
    Set(SIGTERM, SIG_DFL);
    Set(SIGHUP, SIG_DFL);
    StopSignals stop;
    EXPECT_TRUE(stop.catches(sig)) << sig;
    EXPECT_FALSE(stop.requested());
    EXPECT_EQ(stop.signal(), 0);
    ASSERT_EQ(std::raise(sig), 0);  // the default action would end this test's process
    EXPECT_TRUE(stop.requested()) << sig;
    EXPECT_TRUE(stop.flag()->load()) << sig;
    EXPECT_EQ(stop.signal(), sig);
  }
  EXPECT_EQ(StopSignals::Name(SIGTERM), "SIGTERM");
  EXPECT_EQ(StopSignals::Name(SIGHUP), "SIGHUP");
}

TEST_F(StopSignalsTest, ANewOneClearsTheRequestOfTheOneBefore) {
  Set(SIGTERM, SIG_DFL);
  {
    StopSignals stop;
    ASSERT_EQ(std::raise(SIGTERM), 0);
    ASSERT_TRUE(stop.requested());
  }
  StopSignals stop;
  EXPECT_FALSE(stop.requested());
  EXPECT_EQ(stop.signal(), 0);
}

// `nohup idi-rmp run ...` over ssh: the hang-up when the session closes must not stop the vehicle.
TEST_F(StopSignalsTest, ASignalIgnoredBeforeStaysIgnored) {
  Set(SIGTERM, SIG_DFL);
  Set(SIGHUP, SIG_IGN);
  {
    StopSignals stop;
    EXPECT_FALSE(stop.catches(SIGHUP));
    EXPECT_TRUE(stop.catches(SIGTERM));
    EXPECT_EQ(HandlerOf(SIGHUP), SIG_IGN);
    ASSERT_EQ(std::raise(SIGHUP), 0);
    EXPECT_FALSE(stop.requested());
    EXPECT_EQ(stop.signal(), 0);
  }
  EXPECT_EQ(HandlerOf(SIGHUP), SIG_IGN);
}

// Commands run inside longer-lived processes (the tests'): the handlers before come back.
TEST_F(StopSignalsTest, TheDispositionsBeforeComeBack) {
  Set(SIGINT, SIG_DFL);
  Set(SIGTERM, SIG_DFL);
  Set(SIGHUP, SIG_DFL);
  {
    StopSignals stop;
    EXPECT_NE(HandlerOf(SIGTERM), SIG_DFL);
    EXPECT_NE(HandlerOf(SIGINT), SIG_DFL);
    EXPECT_NE(HandlerOf(SIGHUP), SIG_DFL);
  }
  EXPECT_EQ(HandlerOf(SIGTERM), SIG_DFL);
  EXPECT_EQ(HandlerOf(SIGINT), SIG_DFL);
  EXPECT_EQ(HandlerOf(SIGHUP), SIG_DFL);
}

}  // namespace
}  // namespace idi
