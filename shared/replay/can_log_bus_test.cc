#include "shared/replay/can_log_bus.h"

#include <gtest/gtest.h>

namespace idi::replay {
namespace {

CandumpRecord ReplayRecord(int64_t t_ns, uint32_t id, uint8_t first_byte, CanDirection dir = CanDirection::kUnknown) {
  CandumpRecord r;
  r.interface = "can0";
  r.frame.timestamp_ns = t_ns;
  r.frame.id = id;
  r.frame.dlc = 8;
  r.frame.data[0] = first_byte;
  r.direction = dir;
  return r;
}

TEST(CanLogReplayBusTest, DeliversOtherNodesFramesAtLogTimesOnTheClock) {
  hal::SimClock clock(5'000'000'000);
  std::vector<CandumpRecord> log = {ReplayRecord(100'000'000, 0x400, 1), ReplayRecord(100'500'000, 0x413, 2),
                                    ReplayRecord(110'000'000, 0x401, 3),
                                    ReplayRecord(130'000'000, 0x402, 4, CanDirection::kTransmitted)};
  CanLogReplayOptions options;
  options.own_ids = {0x413};
  CanLogReplayBus bus(log, &clock, options);
  EXPECT_EQ(bus.logged_transmitted().size(), 2u);

  auto a = bus.Receive(std::chrono::milliseconds(0));
  ASSERT_TRUE(a.ok());
  ASSERT_TRUE(a->has_value());
  EXPECT_EQ((*a)->id, 0x400u);
  EXPECT_EQ((*a)->timestamp_ns, 5'000'000'000);

  // The next frame is 10 ms later: a 5 ms wait times out and moves the clock by 5 ms.
  auto none = bus.Receive(std::chrono::milliseconds(5));
  ASSERT_TRUE(none.ok());
  EXPECT_FALSE(none->has_value());
  EXPECT_EQ(clock.NowNs(), 5'005'000'000);

  auto b = bus.Receive(std::chrono::milliseconds(50));
  ASSERT_TRUE(b.ok());
  ASSERT_TRUE(b->has_value());
  EXPECT_EQ((*b)->id, 0x401u);
  EXPECT_EQ((*b)->data[0], 3);
  EXPECT_EQ(clock.NowNs(), 5'010'000'000);
  EXPECT_TRUE(bus.finished());

  ASSERT_TRUE(bus.Send(**b).ok());
  ASSERT_EQ(bus.sent().size(), 1u);
  EXPECT_EQ(bus.sent()[0].timestamp_ns, 5'010'000'000);
  EXPECT_EQ(bus.counters().received, 2u);
  EXPECT_EQ(bus.counters().sent, 1u);

  auto end = bus.Receive(std::chrono::milliseconds(20));
  ASSERT_TRUE(end.ok());
  EXPECT_FALSE(end->has_value());
  EXPECT_EQ(clock.NowNs(), 5'030'000'000);
}

TEST(CanLogReplayBusTest, InterfaceFilter) {
  hal::SimClock clock;
  std::vector<CandumpRecord> log = {ReplayRecord(0, 0x400, 1), ReplayRecord(1000, 0x401, 2)};
  log[1].interface = "can1";
  CanLogReplayOptions options;
  options.interface = "can1";
  CanLogReplayBus bus(log, &clock, options);
  auto f = bus.Receive(std::chrono::milliseconds(1));
  ASSERT_TRUE(f.ok() && f->has_value());
  EXPECT_EQ((*f)->id, 0x401u);
  EXPECT_TRUE(bus.finished());
}

}  // namespace
}  // namespace idi::replay
