#include "shared/replay/can_log_bus.h"

#include <algorithm>
#include <utility>

namespace idi::replay {

CanLogReplayBus::CanLogReplayBus(std::vector<CandumpRecord> records, hal::Clock* clock, CanLogReplayOptions options)
    : clock_(clock), options_(std::move(options)) {
  IDI_CHECK(clock_ != nullptr, "CanLogReplayBus needs a clock");
  // canplayer replays in file order; a log whose time goes backwards is replayed in file order too,
  // with the late frames delivered at once.
  bool first = true;
  for (const CandumpRecord& r : records) {
    if (!options_.interface.empty() && r.interface != options_.interface) continue;
    if (first) {
      log_start_ns_ = r.frame.timestamp_ns;
      first = false;
    }
    const bool own = std::find(options_.own_ids.begin(), options_.own_ids.end(), r.frame.id) != options_.own_ids.end() &&
                     !r.frame.error;
    const bool marked_tx = options_.skip_marked_transmitted && r.direction == CanDirection::kTransmitted;
    if (own || marked_tx) {
      logged_transmitted_.push_back(r.frame);
    } else {
      incoming_.push_back(r.frame);
    }
  }
  clock_start_ns_ = clock_->NowNs();
}

Status CanLogReplayBus::Send(const hal::CanFrame& frame) {
  hal::CanFrame f = frame;
  f.timestamp_ns = clock_->NowNs();
  sent_.push_back(f);
  ++counters_.sent;
  return Status::Ok();
}

Result<std::optional<hal::CanFrame>> CanLogReplayBus::Receive(std::chrono::milliseconds timeout) {
  const int64_t now = clock_->NowNs();
  const int64_t deadline = now + std::max<int64_t>(0, static_cast<int64_t>(timeout.count())) * 1'000'000;
  if (next_ < incoming_.size()) {
    hal::CanFrame f = incoming_[next_];
    const int64_t t = ClockTimeForLog(f.timestamp_ns);
    if (t <= deadline) {
      clock_->SleepUntilNs(t);
      ++next_;
      f.timestamp_ns = std::max(t, now);
      if (f.error) {
        ++counters_.error_frames;
      } else {
        ++counters_.received;
      }
      return std::optional<hal::CanFrame>(f);
    }
  }
  clock_->SleepUntilNs(deadline);
  return std::optional<hal::CanFrame>();
}

}  // namespace idi::replay
