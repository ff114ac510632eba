// A call that can block without end (a driver's read that takes no timeout of its own, such as MRPT's
// CCameraSensor::getNextFrame) made on its own thread, so that the caller waits at most a timeout.
//
// One call runs at a time. A call that outlasts the caller's wait goes on; its result is kept and is
// what the next Wait returns, so nothing is run twice and no result is lost. The thread is detached and
// shares the state with this object, so destroying the object while a call is still blocked neither
// waits for it nor leaves the thread with freed memory: whatever the call touches must be kept alive by
// the call itself (capture it by shared_ptr).
#pragma once

#include <chrono>
#include <condition_variable>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>
#include <utility>

namespace idi {

template <typename T>
class TimedCall {
 public:
  explicit TimedCall(std::function<T()> call) : state_(std::make_shared<State>()) { state_->call = std::move(call); }
  TimedCall(const TimedCall&) = delete;
  TimedCall& operator=(const TimedCall&) = delete;

  // The result of the call: of one already finished and not yet taken, else of one already running,
  // else of one started now; nullopt when it has not returned within `timeout` (it goes on running).
  std::optional<T> Wait(std::chrono::milliseconds timeout) {
    std::unique_lock<std::mutex> lock(state_->mu);
    if (!state_->result && !state_->running) {
      state_->running = true;
      ++state_->started;
      std::thread([s = state_] {
        T r = s->call();
        std::lock_guard<std::mutex> l(s->mu);
        s->result = std::move(r);
        s->running = false;
        s->done.notify_all();
      }).detach();
    }
    if (!state_->done.wait_for(lock, timeout, [this] { return state_->result.has_value(); })) return std::nullopt;
    std::optional<T> out = std::move(state_->result);
    state_->result.reset();
    return out;
  }

  // A call is running (it has not returned).
  bool running() const {
    std::lock_guard<std::mutex> lock(state_->mu);
    return state_->running;
  }
  // Calls started so far.
  unsigned long started() const {
    std::lock_guard<std::mutex> lock(state_->mu);
    return state_->started;
  }
  // Waits up to `timeout` for a running call to return (its result is kept for the next Wait); true when
  // none is running.
  bool Settle(std::chrono::milliseconds timeout) const {
    std::unique_lock<std::mutex> lock(state_->mu);
    return state_->done.wait_for(lock, timeout, [this] { return !state_->running; });
  }

 private:
  struct State {
    std::function<T()> call;
    mutable std::mutex mu;
    std::condition_variable done;
    bool running = false;
    unsigned long started = 0;
    std::optional<T> result;
  };
  std::shared_ptr<State> state_;
};

}  // namespace idi
