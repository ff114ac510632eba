#include "shared/sim/can/virtual_can_bus.h"

#include <gtest/gtest.h>

#include "shared/hal/can_error.h"

namespace idi::sim {
namespace {

constexpr int64_t kUs = 1000;
constexpr int64_t kMs = 1'000'000;

hal::CanFrame DataFrame(uint32_t id, uint8_t first = 0, uint8_t dlc = 8) {
  hal::CanFrame f;
  f.id = id;
  f.dlc = dlc;
  f.data[0] = first;
  return f;
}

std::optional<hal::CanFrame> Recv(hal::CanBus* bus, int timeout_ms) {
  auto r = bus->Receive(std::chrono::milliseconds(timeout_ms));
  EXPECT_TRUE(r.ok()) << r.status().ToString();
  return r.ok() ? *r : std::nullopt;
}

// A device that sends one frame every `period_ns` starting at `first_ns`, and counts what it reads.
class PeriodicSender final : public SimProcess {
 public:
  PeriodicSender(VirtualCanEndpoint* ep, int64_t first_ns, int64_t period_ns) : ep_(ep), next_ns_(first_ns), period_ns_(period_ns) {}
  int64_t NextWakeNs() const override { return std::min(next_ns_, ep_->next_delivery_ns()); }
  void RunUntil(int64_t t_ns) override {
    while (true) {
      auto f = ep_->Receive(std::chrono::milliseconds(0));
      if (!f.ok() || !f->has_value()) break;
      ++read_;
    }
    while (next_ns_ <= t_ns) {
      EXPECT_TRUE(ep_->Send(DataFrame(0x400, static_cast<uint8_t>(sent_++))).ok());
      next_ns_ += period_ns_;
    }
  }
  int sent_ = 0, read_ = 0;

 private:
  VirtualCanEndpoint* ep_;
  int64_t next_ns_, period_ns_;
};

TEST(VirtualCanBusTest, FrameBitsWithWorstCaseStuffing) {
  EXPECT_EQ(VirtualCanBus::FrameBits(DataFrame(0x413)), 135);  // 8 bytes, standard id: 270 us at 500k
  EXPECT_EQ(VirtualCanBus::FrameBits(DataFrame(0x413, 0, 0)), 55);
  hal::CanFrame ext = DataFrame(0x1234567);
  ext.extended = true;
  EXPECT_EQ(VirtualCanBus::FrameBits(ext), 160);
}

TEST(VirtualCanBusTest, DeliversToOthersAfterTheTransmissionTimeInOrder) {
  hal::SimClock clock(1 * kMs);
  VirtualCanBus bus(&clock);
  VirtualCanEndpoint* a = bus.AddEndpoint("pc");
  VirtualCanEndpoint* b = bus.AddEndpoint("rmp");
  VirtualCanEndpoint* c = bus.AddEndpoint("sniffer");
  for (uint8_t i = 0; i < 3; ++i) ASSERT_TRUE(a->Send(DataFrame(0x413, i)).ok());
  EXPECT_FALSE(Recv(a, 0).has_value()) << "a node does not receive its own frames";
  EXPECT_FALSE(Recv(b, 0).has_value()) << "nothing is delivered before its last bit is on the wire";
  for (uint8_t i = 0; i < 3; ++i) {
    auto f = Recv(b, 10);
    ASSERT_TRUE(f.has_value());
    EXPECT_EQ(f->data[0], i);
    EXPECT_EQ(f->timestamp_ns, 1 * kMs + 270 * kUs * (i + 1)) << "frames queue behind each other on the bus";
  }
  EXPECT_EQ(clock.NowNs(), 1 * kMs + 810 * kUs);
  EXPECT_EQ(c->queued(), 3u);
  EXPECT_EQ(a->counters().sent, 3u);
  EXPECT_EQ(b->counters().received, 3u);
  EXPECT_EQ(bus.stats().busy_ns, 810 * kUs);
}

TEST(VirtualCanBusTest, ReceiveTimeoutRunsProcessesAndAdvancesTheClock) {
  hal::SimClock clock;
  VirtualCanBus bus(&clock);
  VirtualCanEndpoint* pc = bus.AddEndpoint("pc");
  PeriodicSender rmp(bus.AddEndpoint("rmp"), 5 * kMs, 10 * kMs);
  bus.AddProcess(&rmp);
  EXPECT_FALSE(Recv(pc, 3).has_value());
  EXPECT_EQ(clock.NowNs(), 3 * kMs);
  auto f = Recv(pc, 10);
  ASSERT_TRUE(f.has_value());
  EXPECT_EQ(f->timestamp_ns, 5 * kMs + 270 * kUs);
  EXPECT_EQ(clock.NowNs(), f->timestamp_ns);
  // Frames sent by the pc wake the device up when they arrive.
  ASSERT_TRUE(pc->Send(DataFrame(0x413)).ok());
  bus.AdvanceTo(100 * kMs);
  EXPECT_EQ(rmp.read_, 1);
  EXPECT_EQ(rmp.sent_, 10);  // at 5, 15, ..., 95 ms
  EXPECT_EQ(pc->queued(), 9u);
}

// The longest timeouts saturate (a deadline of now + milliseconds::max() overflowed), and time never
// reaches kNeverNs, the bus's "no event" (a deadline there left AdvanceTo in a loop without end).
TEST(VirtualCanBusTest, EndlessTimeoutsAndTimesSaturate) {
  hal::SimClock clock;
  VirtualCanBus bus(&clock);
  VirtualCanEndpoint* pc = bus.AddEndpoint("pc");
  PeriodicSender rmp(bus.AddEndpoint("rmp"), 5 * kMs, 10 * kMs);
  bus.AddProcess(&rmp);
  auto f = pc->Receive(std::chrono::milliseconds::max());
  ASSERT_TRUE(f.ok()) << f.status().ToString();
  ASSERT_TRUE(f->has_value());
  EXPECT_EQ((*f)->timestamp_ns, 5 * kMs + 270 * kUs);

  hal::SimClock idle_clock;
  VirtualCanBus idle(&idle_clock);
  VirtualCanEndpoint* alone = idle.AddEndpoint("alone");
  idle.AdvanceTo(kNeverNs);
  EXPECT_EQ(idle_clock.NowNs(), kNeverNs - 1);
  EXPECT_FALSE(Recv(alone, 1000).has_value()) << "at the end of time, a timeout returns at once";
  idle.InjectBusOff(alone, 10 * kMs);  // the restart time saturates: never (it overflowed to the past)
  idle.AdvanceTo(kNeverNs);
  EXPECT_TRUE(alone->bus_off()) << "restarted at an overflowed time";
}

TEST(VirtualCanBusTest, FiltersAsSocketCan) {
  hal::SimClock clock;
  VirtualCanBus bus(&clock);
  VirtualCanEndpoint* tx = bus.AddEndpoint("tx");
  VirtualCanEndpoint* rx = bus.AddEndpoint("rx");
  rx->SetFilters({{0x400, 0x7F8}});  // 0x400..0x407
  for (uint32_t id : {0x3FFu, 0x400u, 0x407u, 0x408u, 0x680u}) ASSERT_TRUE(tx->Send(DataFrame(id)).ok());
  bus.AdvanceTo(10 * kMs);
  ASSERT_EQ(rx->queued(), 2u);
  EXPECT_EQ(Recv(rx, 0)->id, 0x400u);
  EXPECT_EQ(Recv(rx, 0)->id, 0x407u);
}

TEST(VirtualCanBusTest, DropsAndGarbageAtTheConfiguredRatesAndSeeded) {
  auto run = [](uint64_t seed, int* dropped, int* garbled) {
    hal::SimClock clock;
    VirtualCanBusOptions o;
    o.drop_probability = 0.2;
    o.garbage_probability = 0.1;
    o.seed = seed;
    VirtualCanBus bus(&clock, o);
    VirtualCanEndpoint* tx = bus.AddEndpoint("tx");
    VirtualCanEndpoint* rx = bus.AddEndpoint("rx");
    std::vector<uint8_t> seen;
    *dropped = 0;
    *garbled = 0;
    for (int i = 0; i < 5000; ++i) {
      hal::CanFrame f = DataFrame(0x401);
      f.data = {1, 2, 3, 4, 5, 6, 7, 8};
      EXPECT_TRUE(tx->Send(f).ok());
      auto got = Recv(rx, 5);
      if (!got) {
        ++*dropped;
        continue;
      }
      const bool garbage = got->dlc != 8 || got->data != f.data;
      *garbled += garbage ? 1 : 0;
      seen.push_back(got->dlc);
    }
    EXPECT_EQ(bus.stats().drops_injected, static_cast<uint64_t>(*dropped));
    return seen;
  };
  int dropped = 0, garbled = 0, dropped2 = 0, garbled2 = 0;
  const auto first = run(7, &dropped, &garbled);
  EXPECT_NEAR(dropped / 5000.0, 0.2, 0.02);
  EXPECT_NEAR(garbled / 5000.0, 0.1 * 0.8, 0.015);
  const auto second = run(7, &dropped2, &garbled2);
  EXPECT_EQ(first, second);
  EXPECT_EQ(dropped, dropped2);
  run(8, &dropped2, &garbled2);
  EXPECT_NE(dropped, dropped2) << "another seed gives another sequence";
}

TEST(VirtualCanBusTest, BusOffStopsTheNodeThenRestartsWithErrorFrames) {
  hal::SimClock clock;
  VirtualCanBus bus(&clock);
  VirtualCanEndpoint* pc = bus.AddEndpoint("pc");
  PeriodicSender rmp(bus.AddEndpoint("rmp"), 0, 10 * kMs);
  bus.AddProcess(&rmp);
  bus.AdvanceTo(25 * kMs);
  EXPECT_EQ(pc->queued(), 3u);
  bus.InjectBusOff(pc, 100 * kMs);
  EXPECT_TRUE(pc->bus_off());
  // Already received frames stay readable, then the bus-off error frame.
  for (int i = 0; i < 3; ++i) EXPECT_FALSE(Recv(pc, 0)->error);
  auto off = Recv(pc, 0);
  ASSERT_TRUE(off.has_value());
  ASSERT_TRUE(off->error);
  EXPECT_TRUE(hal::DecodeCanError(*off).bus_off);
  EXPECT_EQ(pc->counters().bus_off, 1u);
  const Status send = pc->Send(DataFrame(0x413));
  EXPECT_EQ(send.code(), StatusCode::kDeviceError);
  EXPECT_NE(send.message().find("bus-off"), std::string::npos);
  // Nothing arrives while off; the restart comes after 100 ms as an error frame.
  auto restarted = Recv(pc, 200);
  ASSERT_TRUE(restarted.has_value());
  ASSERT_TRUE(restarted->error);
  const hal::CanErrorInfo info = hal::DecodeCanError(*restarted);
  EXPECT_TRUE(info.restarted);
  EXPECT_EQ(info.state, hal::CanControllerState::kErrorActive);
  EXPECT_EQ(restarted->timestamp_ns, 125 * kMs);
  EXPECT_FALSE(pc->bus_off());
  EXPECT_TRUE(pc->Send(DataFrame(0x413)).ok());
  auto data = Recv(pc, 20);
  ASSERT_TRUE(data.has_value());
  EXPECT_FALSE(data->error);
  EXPECT_EQ(data->timestamp_ns, 130 * kMs + 270 * kUs);
}

TEST(VirtualCanBusTest, ManualRestartAndNoAckWhenAlone) {
  hal::SimClock clock;
  VirtualCanBus bus(&clock);
  VirtualCanEndpoint* pc = bus.AddEndpoint("pc");
  VirtualCanEndpoint* rmp = bus.AddEndpoint("rmp");
  bus.InjectBusOff(rmp);  // stays off
  ASSERT_TRUE(pc->Send(DataFrame(0x413)).ok());
  ASSERT_TRUE(pc->Send(DataFrame(0x413)).ok());
  auto ack = Recv(pc, 5);
  ASSERT_TRUE(ack.has_value());
  ASSERT_TRUE(ack->error);
  EXPECT_TRUE(hal::DecodeCanError(*ack).no_ack);
  EXPECT_FALSE(Recv(pc, 5).has_value()) << "the missing ACK is reported once per episode";
  clock.AdvanceNs(1000 * kMs);
  EXPECT_TRUE(rmp->bus_off()) << "without restart-ms the node stays off";
  bus.RestartEndpoint(rmp);
  EXPECT_FALSE(rmp->bus_off());
  ASSERT_TRUE(pc->Send(DataFrame(0x413, 9)).ok());
  bool got_data = false;
  for (int i = 0; i < 3; ++i) {
    auto f = Recv(rmp, 5);
    if (f && !f->error) got_data = f->data[0] == 9;
  }
  EXPECT_TRUE(got_data);
}

TEST(VirtualCanBusTest, RejectsInvalidFramesAndOptionsAndOverflows) {
  hal::SimClock clock;
  VirtualCanBusOptions o;
  o.rx_queue_capacity = 4;
  VirtualCanBus bus(&clock, o);
  VirtualCanEndpoint* tx = bus.AddEndpoint("tx");
  VirtualCanEndpoint* rx = bus.AddEndpoint("rx");
  EXPECT_EQ(tx->Send(DataFrame(0x800)).code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(tx->Send(DataFrame(0x400, 0, 9)).code(), StatusCode::kInvalidArgument);
  for (int i = 0; i < 6; ++i) ASSERT_TRUE(tx->Send(DataFrame(0x400)).ok());
  bus.AdvanceTo(10 * kMs);
  EXPECT_EQ(rx->queued(), 4u);
  EXPECT_EQ(rx->counters().dropped, 2u);

  VirtualCanBusOptions bad;
  bad.drop_probability = 1.5;
  EXPECT_NE(bad.Check().message().find("drop_probability"), std::string::npos);
  bad = {};
  bad.bitrate_bps = 5e6;
  EXPECT_EQ(bad.Check().code(), StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace idi::sim
