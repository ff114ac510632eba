#include "shared/sim/can/virtual_can_bus.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "shared/hal/can_error.h"

namespace idi::sim {
namespace {

std::string VcanHexId(uint32_t id) {
  char buf[16];
  std::snprintf(buf, sizeof(buf), "0x%03X", id);
  return buf;
}

}  // namespace

Status VirtualCanBusOptions::Check() const {
  if (!(bitrate_bps >= 10'000.0 && bitrate_bps <= 1'000'000.0)) {
    return InvalidArgument("virtual CAN bus: bitrate_bps " + FormatNumber(bitrate_bps) +
                           " is outside 10 kbit/s .. 1 Mbit/s (classic CAN)");
  }
  if (!(drop_probability >= 0.0 && drop_probability <= 1.0)) {
    return InvalidArgument("virtual CAN bus: drop_probability " + FormatNumber(drop_probability) + " is not in [0, 1]");
  }
  if (!(garbage_probability >= 0.0 && garbage_probability <= 1.0)) {
    return InvalidArgument("virtual CAN bus: garbage_probability " + FormatNumber(garbage_probability) +
                           " is not in [0, 1]");
  }
  if (rx_queue_capacity == 0) return InvalidArgument("virtual CAN bus: rx_queue_capacity must be positive");
  return Status::Ok();
}

// ---- endpoint ----

bool VirtualCanEndpoint::Accepts(const hal::CanFrame& frame) const {
  if (frame.error || filters_.empty()) return true;
  for (const VirtualCanFilter& f : filters_) {
    if ((frame.id & f.mask) == (f.id & f.mask)) return true;
  }
  return false;
}

std::optional<hal::CanFrame> VirtualCanEndpoint::PopDelivered(int64_t t_ns) {
  if (rx_.empty() || rx_.front().timestamp_ns > t_ns) return std::nullopt;
  hal::CanFrame f = rx_.front();
  rx_.pop_front();
  if (f.error) {
    ++counters_.error_frames;
  } else {
    ++counters_.received;
  }
  return f;
}

Status VirtualCanEndpoint::Send(const hal::CanFrame& frame) { return bus_->Transmit(this, frame); }

Result<std::optional<hal::CanFrame>> VirtualCanEndpoint::Receive(std::chrono::milliseconds timeout) {
  hal::SimClock* clock = bus_->clock_;
  // Saturating, and short of kNeverNs (a deadline there would never be reached by AdvanceTo).
  const int64_t start = clock->NowNs();
  const int64_t max_ms = (kNeverNs - 1 - start) / 1'000'000;
  const int64_t deadline = start + std::clamp<int64_t>(static_cast<int64_t>(timeout.count()), 0, max_ms) * 1'000'000;
  if (!bus_->running_processes_) bus_->AdvanceTo(clock->NowNs());
  while (true) {
    const int64_t now = clock->NowNs();
    if (!rx_.empty() && rx_.front().timestamp_ns <= now) {
      hal::CanFrame f = rx_.front();
      rx_.pop_front();
      if (f.error) {
        ++counters_.error_frames;
      } else {
        ++counters_.received;
      }
      return std::optional<hal::CanFrame>(f);
    }
    // A process reading its own endpoint never moves time; nor does a zero timeout.
    if (now >= deadline || bus_->running_processes_) return std::optional<hal::CanFrame>();
    int64_t next = std::min(deadline, bus_->NextEventNs());
    if (!rx_.empty()) next = std::min(next, rx_.front().timestamp_ns);
    bus_->AdvanceTo(std::max(next, now));
  }
}

// ---- bus ----

VirtualCanBus::VirtualCanBus(hal::SimClock* clock, VirtualCanBusOptions options)
    : clock_(clock), options_(std::move(options)), rng_(options_.seed) {
  IDI_CHECK(clock_ != nullptr, "VirtualCanBus needs a SimClock");
  const Status st = options_.Check();
  IDI_CHECK(st.ok(), st.ToString());
  bus_free_ns_ = clock_->NowNs();
}

VirtualCanEndpoint* VirtualCanBus::AddEndpoint(const std::string& name) {
  endpoints_.push_back(std::unique_ptr<VirtualCanEndpoint>(new VirtualCanEndpoint(this, name)));
  return endpoints_.back().get();
}

void VirtualCanBus::AddProcess(SimProcess* process) {
  IDI_CHECK(process != nullptr, "null SimProcess");
  processes_.push_back(process);
}

int VirtualCanBus::FrameBits(const hal::CanFrame& frame) {
  // Classic CAN: SOF, arbitration, control, data, CRC, delimiters, ACK, EOF = 44 bits (standard
  // id) or 64 (extended) plus the data; stuff bits can be inserted in the first 34 (54) + 8n bits,
  // at most one per four; then 3 bits of intermission.
  const int n = frame.rtr ? 0 : std::min<int>(frame.dlc, 8);
  const int stuffable = (frame.extended ? 54 : 34) + 8 * n;
  return (frame.extended ? 64 : 44) + 8 * n + (stuffable - 1) / 4 + 3;
}

Status VirtualCanBus::Transmit(VirtualCanEndpoint* sender, const hal::CanFrame& frame) {
  if (frame.dlc > 8) {
    return InvalidArgument(sender->name_ + ": CAN frame " + VcanHexId(frame.id) + " has DLC " + std::to_string(frame.dlc) +
                           " (classic CAN allows 0..8)");
  }
  if (frame.id > (frame.extended ? 0x1FFFFFFFU : 0x7FFU) || frame.error) {
    return InvalidArgument(sender->name_ + ": CAN id " + VcanHexId(frame.id) + " is not a valid " +
                           (frame.extended ? "extended" : "standard") + " data frame id");
  }
  if (sender->bus_off_) {
    ++sender->counters_.dropped;
    return DeviceError(sender->name_ + ": controller is bus-off; frame " + VcanHexId(frame.id) + " not sent");
  }
  const int64_t now = clock_->NowNs();
  int64_t end = now;
  if (options_.model_transmission_time) {
    const int64_t start = std::max(now, bus_free_ns_);
    const int64_t duration = static_cast<int64_t>(std::llround(FrameBits(frame) * 1e9 / options_.bitrate_bps));
    end = start + duration;
    bus_free_ns_ = end;
    stats_.busy_ns += duration;
  }
  ++sender->counters_.sent;

  bool acked = false;
  for (const auto& ep : endpoints_) {
    if (ep.get() != sender && !ep->bus_off_) acked = true;
  }
  if (!acked) {
    // Nobody acknowledges: the controller reports the missing ACK (once per episode) and the frame
    // never reaches anyone.
    if (!sender->reported_no_ack_) {
      sender->reported_no_ack_ = true;
      Deliver(sender, hal::MakeCanErrorFrame(end, hal::kCanErrAck | hal::kCanErrCrtl, hal::kCanErrCrtlTxWarning));
    }
    return Status::Ok();
  }
  sender->reported_no_ack_ = false;
  ++stats_.frames_on_bus;

  hal::CanFrame wire = frame;
  wire.timestamp_ns = end;
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  if (options_.garbage_probability > 0.0 && unit(rng_) < options_.garbage_probability) {
    ++stats_.garbage_injected;
    if (wire.dlc > 0 && unit(rng_) < 0.5) {
      wire.dlc = static_cast<uint8_t>(std::uniform_int_distribution<int>(0, wire.dlc - 1)(rng_));
    } else {
      for (uint8_t& b : wire.data) b = static_cast<uint8_t>(std::uniform_int_distribution<int>(0, 255)(rng_));
    }
  }
  for (const auto& ep : endpoints_) {
    if (ep.get() == sender || ep->bus_off_ || !ep->Accepts(wire)) continue;
    if (options_.drop_probability > 0.0 && unit(rng_) < options_.drop_probability) {
      ++stats_.drops_injected;
      ++ep->counters_.dropped;
      continue;
    }
    Deliver(ep.get(), wire);
  }
  return Status::Ok();
}

void VirtualCanBus::Deliver(VirtualCanEndpoint* to, const hal::CanFrame& frame) {
  if (to->rx_.size() >= options_.rx_queue_capacity) {
    ++to->counters_.dropped;
    return;
  }
  auto it = std::upper_bound(to->rx_.begin(), to->rx_.end(), frame.timestamp_ns,
                             [](int64_t t, const hal::CanFrame& f) { return t < f.timestamp_ns; });
  to->rx_.insert(it, frame);
}

int64_t VirtualCanBus::NextEventNs() const {
  int64_t next = kNeverNs;
  for (const SimProcess* p : processes_) next = std::min(next, p->NextWakeNs());
  for (const auto& ep : endpoints_) next = std::min(next, ep->restart_at_ns_);
  return next;
}

void VirtualCanBus::RunDue(int64_t now_ns) {
  running_processes_ = true;
  for (const auto& ep : endpoints_) {
    if (ep->restart_at_ns_ <= now_ns) RestartEndpoint(ep.get());
  }
  for (SimProcess* p : processes_) {
    if (p->NextWakeNs() <= now_ns) {
      p->RunUntil(now_ns);
      IDI_CHECK(p->NextWakeNs() > now_ns, "a SimProcess did not move its wake-up time past the time it ran to");
    }
  }
  running_processes_ = false;
}

void VirtualCanBus::AdvanceTo(int64_t t_ns) {
  IDI_CHECK(!running_processes_, "VirtualCanBus::AdvanceTo called from inside a SimProcess");
  // kNeverNs is "no event": time never reaches it (the loop below would not end there).
  t_ns = std::min(t_ns, kNeverNs - 1);
  while (true) {
    const int64_t next = NextEventNs();
    if (next > t_ns) break;
    clock_->SleepUntilNs(next);
    RunDue(clock_->NowNs());
  }
  clock_->SleepUntilNs(t_ns);
}

void VirtualCanBus::InjectBusOff(VirtualCanEndpoint* endpoint, int64_t duration_ns) {
  IDI_CHECK(endpoint != nullptr && endpoint->bus_ == this, "InjectBusOff: endpoint of another bus");
  const int64_t now = clock_->NowNs();
  // Frames still on the wire towards it are lost; what the socket already holds stays readable.
  while (!endpoint->rx_.empty() && endpoint->rx_.back().timestamp_ns > now) endpoint->rx_.pop_back();
  endpoint->bus_off_ = true;
  ++endpoint->counters_.bus_off;
  endpoint->restart_at_ns_ = duration_ns >= 0 && duration_ns < kNeverNs - now ? now + duration_ns : kNeverNs;
  Deliver(endpoint, hal::MakeCanErrorFrame(now, hal::kCanErrBusOff));
}

void VirtualCanBus::RestartEndpoint(VirtualCanEndpoint* endpoint) {
  IDI_CHECK(endpoint != nullptr && endpoint->bus_ == this, "RestartEndpoint: endpoint of another bus");
  endpoint->restart_at_ns_ = kNeverNs;
  if (!endpoint->bus_off_) return;
  endpoint->bus_off_ = false;
  endpoint->reported_no_ack_ = false;
  Deliver(endpoint, hal::MakeCanErrorFrame(clock_->NowNs(), hal::kCanErrRestarted | hal::kCanErrCrtl, hal::kCanErrCrtlActive));
}

}  // namespace idi::sim
