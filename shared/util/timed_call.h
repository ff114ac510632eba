// A call that can block without end (a driver's read that takes no timeout of its own, such as MRPT's
// CCameraSensor::getNextFrame) made on its own thread, so that the caller waits at most a timeout.
//
// One call runs at a time. A call that outlasts the caller's wait goes on; its result is kept and is
// what the next Wait returns, so nothing is run twice and no result is lost. The thread is detached and
// shares the state with this object, so destroying the object while a call is still blocked neither
// waits for it nor leaves the thread with freed memory: whatever the call touches must be kept alive by
// the call itself (capture it by shared_ptr). An exception the call throws is kept as its result and
// rethrown by the Wait that takes it, on the caller's thread.
#pragma once

#include <chrono>
#include <condition_variable>
#include <exception>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <thread>
#include <utility>

namespace idi {

template <typename T>
class TimedCall {
 public:
  // std::invalid_argument for an empty call.
  explicit TimedCall(std::function<T()> call) : state_(std::make_shared<State>()) {
    if (!call) throw std::invalid_argument("TimedCall: no call");
    state_->call = std::move(call);
  }
  TimedCall(const TimedCall&) = delete;
  TimedCall& operator=(const TimedCall&) = delete;

  // The result of the call: of one already finished and not yet taken, else of one already running,
  // else of one started now; nullopt when it has not returned within `timeout` (it goes on running).
  std::optional<T> Wait(std::chrono::milliseconds timeout) {
    std::unique_lock<std::mutex> lock(state_->mu);
    StartLocked();
    if (!state_->done.wait_for(lock, timeout, [this] { return state_->finished(); })) return std::nullopt;
    return TakeLocked();
  }

  // As Wait, but only a call that returns after this wait began counts: a result kept from before (a
  // call that outlasted an earlier wait) is dropped, and a new call is started. For reads whose result
  // ages (a camera's frame): the answer is the next one.
  std::optional<T> WaitNext(std::chrono::milliseconds timeout) {
    const auto start = std::chrono::steady_clock::now();
    std::unique_lock<std::mutex> lock(state_->mu);
    if (state_->finished() && state_->finished_at < start) {
      state_->result.reset();
      state_->error = nullptr;
      ++state_->dropped;
    }
    StartLocked();
    if (!state_->done.wait_for(lock, timeout, [this] { return state_->finished(); })) return std::nullopt;
    return TakeLocked();
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
  // Results WaitNext dropped as older than its wait.
  unsigned long dropped() const {
    std::lock_guard<std::mutex> lock(state_->mu);
    return state_->dropped;
  }
  // Waits up to `timeout` for a running call to return (its result is kept for the next Wait); true when
  // none is running.
  bool Settle(std::chrono::milliseconds timeout) const {
    std::unique_lock<std::mutex> lock(state_->mu);
    return state_->done.wait_for(lock, timeout, [this] { return !state_->running; });
  }

 private:
  // With state_->mu held: a call on its own thread unless one runs or a result waits to be taken.
  void StartLocked() {
    if (state_->finished() || state_->running) return;
    state_->running = true;
    try {
      std::thread([s = state_] {
        std::optional<T> r;
        std::exception_ptr e;
        try {
          r.emplace(s->call());
        } catch (...) {
          e = std::current_exception();
        }
        std::lock_guard<std::mutex> l(s->mu);
        s->result = std::move(r);
        s->error = e;
        s->finished_at = std::chrono::steady_clock::now();
        s->running = false;
        s->done.notify_all();
      }).detach();
    } catch (...) {
      state_->running = false;  // no thread: nothing runs
      throw;
    }
    ++state_->started;
  }
  // With state_->mu held and a call finished: its result, or its exception rethrown.
  std::optional<T> TakeLocked() {
    if (state_->error) {
      const std::exception_ptr e = state_->error;
      state_->error = nullptr;
      std::rethrow_exception(e);
    }
    std::optional<T> out = std::move(state_->result);
    state_->result.reset();
    return out;
  }

  struct State {
    std::function<T()> call;
    mutable std::mutex mu;
    std::condition_variable done;
    bool running = false;
    unsigned long started = 0, dropped = 0;
    std::optional<T> result;
    std::chrono::steady_clock::time_point finished_at;
    std::exception_ptr error;
    bool finished() const { return result.has_value() || error != nullptr; }
  };
  std::shared_ptr<State> state_;
};

}  // namespace idi
