#include "shared/util/timed_call.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <thread>

namespace idi {
namespace {

using std::chrono::milliseconds;

// A call that blocks until the test opens a gate, like a driver read waiting for a frame.
struct Gate {
  std::mutex mu;
  std::condition_variable cv;
  bool open = false;
  std::atomic<int> entered{0};
  void Open() {
    std::lock_guard<std::mutex> l(mu);
    open = true;
    cv.notify_all();
  }
  int Pass() {
    const int n = ++entered;
    std::unique_lock<std::mutex> l(mu);
    cv.wait(l, [this] { return open; });
    return n;
  }
};

TEST(TimedCallTest, AFastCallReturnsItsResultEachTime) {
  auto n = std::make_shared<int>(0);  // shared: a call that outlived a failed wait still has it
  TimedCall<int> call([n] { return ++*n; });
  EXPECT_EQ(call.Wait(milliseconds(2000)), 1);
  EXPECT_EQ(call.Wait(milliseconds(2000)), 2);
  EXPECT_EQ(call.started(), 2u);
  EXPECT_FALSE(call.running());
}

// A blocked call does not hold its caller beyond the timeout, is not started a second time while it
// runs, and its late result is what the next wait gets.
TEST(TimedCallTest, ABlockedCallTimesOutAndItsLateResultIsKeptForTheNextWait) {
  auto gate = std::make_shared<Gate>();
  TimedCall<int> call([gate] { return gate->Pass(); });
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_FALSE(call.Wait(milliseconds(50)).has_value());
  EXPECT_GE(std::chrono::steady_clock::now() - t0, milliseconds(50));
  EXPECT_TRUE(call.running());
  EXPECT_FALSE(call.Wait(milliseconds(20)).has_value());
  EXPECT_EQ(call.started(), 1u) << "a second call was started while the first was blocked";
  EXPECT_EQ(gate->entered.load(), 1);

  gate->Open();
  EXPECT_TRUE(call.Settle(milliseconds(5000)));
  EXPECT_FALSE(call.running());
  EXPECT_EQ(call.Wait(milliseconds(0)), 1) << "the late result is the next wait's";
  EXPECT_EQ(call.started(), 1u);
  // Then a new call.
  EXPECT_EQ(call.Wait(milliseconds(5000)), 2);
  EXPECT_EQ(call.started(), 2u);
}

// WaitNext answers with a call that returns after it began: the late result of a call that outlasted
// an earlier wait is dropped (a camera's old frame), and a new call is made.
TEST(TimedCallTest, WaitNextDropsAResultFromBeforeItAndMakesANewCall) {
  auto gate = std::make_shared<Gate>();
  TimedCall<int> call([gate] { return gate->Pass(); });
  EXPECT_FALSE(call.WaitNext(milliseconds(20)).has_value());
  gate->Open();
  ASSERT_TRUE(call.Settle(milliseconds(5000)));
  EXPECT_EQ(call.WaitNext(milliseconds(5000)), 2) << "the first call's result came before this wait";
  EXPECT_EQ(call.dropped(), 1u);
  EXPECT_EQ(call.started(), 2u);
  // A call still running when WaitNext begins counts (it returns after).
  auto gate2 = std::make_shared<Gate>();
  TimedCall<int> slow([gate2] { return gate2->Pass(); });
  EXPECT_FALSE(slow.Wait(milliseconds(10)).has_value());
  std::thread opener([gate2] {
    std::this_thread::sleep_for(milliseconds(20));
    gate2->Open();
  });
  EXPECT_EQ(slow.WaitNext(milliseconds(5000)), 1);
  EXPECT_EQ(slow.dropped(), 0u);
  opener.join();
}

// An exception thrown by the call comes out of the wait that takes its result, on the caller's thread;
// the next wait starts a new call.
TEST(TimedCallTest, AnExceptionOfTheCallIsRethrownByTheWait) {
  auto n = std::make_shared<int>(0);
  TimedCall<int> call([n] {
    if (++*n == 1) throw std::runtime_error("driver failed");
    return *n;
  });
  EXPECT_THROW(call.Wait(milliseconds(5000)), std::runtime_error);
  EXPECT_FALSE(call.running());
  EXPECT_EQ(call.Wait(milliseconds(5000)), 2);
  EXPECT_THROW(TimedCall<int>(std::function<int()>()), std::invalid_argument);
}

// The object can go while its call is blocked: the call keeps what it needs and finishes on its own.
TEST(TimedCallTest, DestroyingItWhileACallIsBlockedNeitherWaitsNorBreaksTheCall) {
  auto gate = std::make_shared<Gate>();
  auto finished = std::make_shared<std::atomic<bool>>(false);
  {
    TimedCall<int> call([gate, finished] {
      const int r = gate->Pass();
      *finished = true;
      return r;
    });
    EXPECT_FALSE(call.Wait(milliseconds(10)).has_value());
    EXPECT_FALSE(call.Settle(milliseconds(10)));
  }
  gate->Open();
  for (int k = 0; k < 5000 && !*finished; ++k) std::this_thread::sleep_for(milliseconds(1));
  EXPECT_TRUE(*finished);
}

}  // namespace
}  // namespace idi
