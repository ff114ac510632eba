#include "shared/util/timed_call.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <memory>
#include <mutex>

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
  int n = 0;
  TimedCall<int> call([&n] { return ++n; });
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
