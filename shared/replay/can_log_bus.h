// A hal::CanBus that plays back a candump log: the frames the other nodes sent arrive at their
// logged times (shifted onto the clock's time line), and the frames this node sends are kept so a
// replay can be compared with what was sent when the log was recorded. On a SimClock the replay
// runs as fast as the reader consumes it; on the monotonic clock it keeps the log's pace.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "shared/hal/can_bus.h"
#include "shared/hal/clock.h"
#include "shared/replay/candump_log.h"

namespace idi::replay {

struct CanLogReplayOptions {
  // Frames with these ids are what the replayed node itself sent (for the RMP: 0x412, 0x413); they
  // are not delivered, only counted in logged_transmitted().
  std::vector<uint32_t> own_ids;
  // Lines marked " T" (candump -x) are the node's own frames too.
  bool skip_marked_transmitted = true;
  // When non-empty, only lines of this interface are used.
  std::string interface;
};

class CanLogReplayBus final : public hal::CanBus {
 public:
  // Log time `first record` maps to the clock's time at construction.
  CanLogReplayBus(std::vector<CandumpRecord> records, hal::Clock* clock, CanLogReplayOptions options = {});

  std::string name() const override { return "replay:" + (options_.interface.empty() ? std::string("log") : options_.interface); }
  Status Send(const hal::CanFrame& frame) override;
  Result<std::optional<hal::CanFrame>> Receive(std::chrono::milliseconds timeout) override;
  hal::CanBusCounters counters() const override { return counters_; }

  // True when every frame to deliver has been delivered.
  bool finished() const { return next_ >= incoming_.size(); }
  // Frames sent by the node under replay, stamped with the clock's time.
  const std::vector<hal::CanFrame>& sent() const { return sent_; }
  // The node's own frames as the log recorded them (log time line).
  const std::vector<hal::CanFrame>& logged_transmitted() const { return logged_transmitted_; }
  // Clock time that corresponds to a log time.
  int64_t ClockTimeForLog(int64_t log_ns) const { return log_ns - log_start_ns_ + clock_start_ns_; }

 private:
  hal::Clock* clock_;
  CanLogReplayOptions options_;
  std::vector<hal::CanFrame> incoming_;  // log time line
  std::vector<hal::CanFrame> logged_transmitted_;
  std::vector<hal::CanFrame> sent_;
  std::size_t next_ = 0;
  int64_t log_start_ns_ = 0;
  int64_t clock_start_ns_ = 0;
  hal::CanBusCounters counters_;
};

}  // namespace idi::replay
