// An operator's stop reaching a driver while another thread waits in it for a move to end.
//
// The drivers are not thread-safe: one thread talks to a device at a time, so a stop from another
// thread has to wait for the call in progress. A wait for a motion's end can be long (a pan-tilt move,
// the hand's initialisation: up to 30 s). The stopping thread requests an interrupt first; the waiting
// call looks at it between short slices of its wait, ends with Cancelled and sends its device's stop as
// after any failed move, and the stopping thread then gets the device at once. Only waits for motion
// are sliced: a command's own reply is short and is always read to its end.
//
// The request stays in force (motions are refused before anything is sent) until it is cleared, which
// the stopping thread does once it holds the device and has stopped it.
#pragma once

#include <algorithm>
#include <atomic>
#include <chrono>

namespace idi {

class MotionInterrupt {
 public:
  // How long a sliced wait reads before looking at the request again.
  static constexpr std::chrono::milliseconds kSlice{50};

  // Thread-safe.
  void Request() { requested_.store(true); }
  void Clear() { requested_.store(false); }
  bool requested() const { return requested_.load(); }

  // The part of `left` to wait before looking again.
  static std::chrono::milliseconds Slice(std::chrono::milliseconds left) { return std::min(left, kSlice); }

 private:
  std::atomic<bool> requested_{false};
};

}  // namespace idi
