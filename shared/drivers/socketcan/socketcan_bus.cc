#include "shared/drivers/socketcan/socketcan_bus.h"

#include <linux/can/netlink.h>
#include <linux/can/raw.h>
#include <linux/if_link.h>
#include <linux/netlink.h>
#include <linux/rtnetlink.h>
#include <net/if.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/uio.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>

namespace idi::drivers {
namespace {

std::string ErrnoName(int err) { return std::string(std::strerror(err)) + " (errno " + std::to_string(err) + ")"; }

// Timeouts run on the steady clock, whatever clock stamps the frames (a simulated one that does not
// advance would make them endless), and are capped at a day (a "forever" of milliseconds::max()
// overflowed the conversion to ns).
int64_t SteadyNs() { return hal::MonotonicClock().NowNs(); }
int64_t DeadlineNs(std::chrono::milliseconds timeout) {
  constexpr int64_t kDayMs = 86'400'000;
  return SteadyNs() + std::clamp<int64_t>(timeout.count(), 0, kDayMs) * hal::kNsPerMs;
}

bool InterfaceDownErrno(int err) { return err == ENETDOWN || err == ENODEV || err == ENXIO; }

// Appends an rtnetlink attribute to a message buffer; returns its offset (for nesting).
std::size_t AddRtAttr(std::vector<char>* buf, unsigned short type, const void* data, std::size_t len) {
  const std::size_t offset = NLMSG_ALIGN(buf->size());
  const std::size_t attr_len = RTA_LENGTH(len);
  buf->resize(offset + RTA_ALIGN(attr_len), 0);
  rtattr* rta = reinterpret_cast<rtattr*>(buf->data() + offset);
  rta->rta_type = type;
  rta->rta_len = static_cast<unsigned short>(attr_len);
  if (len > 0) std::memcpy(RTA_DATA(rta), data, len);
  return offset;
}

void EndNest(std::vector<char>* buf, std::size_t offset) {
  rtattr* rta = reinterpret_cast<rtattr*>(buf->data() + offset);
  rta->rta_len = static_cast<unsigned short>(buf->size() - offset);
}

}  // namespace

Status SocketCanOptions::Check() const {
  if (interface.empty() || interface.size() >= IFNAMSIZ) {
    return InvalidArgument("SocketCAN: interface name '" + interface + "' must have 1.." + std::to_string(IFNAMSIZ - 1) +
                           " characters");
  }
  if (interface.find('/') != std::string::npos || interface.find(' ') != std::string::npos) {
    return InvalidArgument("SocketCAN: interface name '" + interface + "' contains '/' or a blank");
  }
  for (const SocketCanFilter& f : filters) {
    const uint32_t max = f.extended ? CAN_EFF_MASK : CAN_SFF_MASK;
    if (f.id > max || f.mask > max) {
      return InvalidArgument("SocketCAN " + interface + ": filter id/mask beyond " + (f.extended ? "29" : "11") + " bits");
    }
  }
  if (error_mask & ~hal::kCanErrClassMask) return InvalidArgument("SocketCAN " + interface + ": unknown error class bits");
  if (send_timeout.count() < 0 || reopen_interval.count() < 0) {
    return InvalidArgument("SocketCAN " + interface + ": timeouts must not be negative");
  }
  return Status::Ok();
}

SocketCanBus::SocketCanBus(const SocketCanOptions& options, hal::Clock* clock) : options_(options), clock_(clock) {
  if (clock_ == nullptr) {
    own_clock_ = std::make_unique<hal::MonotonicClock>();
    clock_ = own_clock_.get();
  }
}

SocketCanBus::~SocketCanBus() { CloseSocket(); }

Result<std::unique_ptr<SocketCanBus>> SocketCanBus::Open(const SocketCanOptions& options, hal::Clock* clock) {
  IDI_RETURN_IF_ERROR(options.Check());
  std::unique_ptr<SocketCanBus> bus(new SocketCanBus(options, clock));
  IDI_RETURN_IF_ERROR(bus->OpenSocket());
  return bus;
}

void SocketCanBus::CloseSocket() {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
}

Status SocketCanBus::OpenSocket() {
  kernel_drops_ = 0;  // a new socket's overflow counter starts at 0
  CloseSocket();
  const std::string& ifname = options_.interface;
  const int fd = ::socket(PF_CAN, SOCK_RAW | SOCK_CLOEXEC | SOCK_NONBLOCK, CAN_RAW);
  if (fd < 0) {
    const int err = errno;
    if (err == EAFNOSUPPORT || err == EPROTONOSUPPORT) {
      return IoError("SocketCAN " + ifname + ": this kernel has no SocketCAN raw sockets (modules can, can-raw): " +
                     ErrnoName(err));
    }
    return IoError("SocketCAN " + ifname + ": socket(PF_CAN, SOCK_RAW, CAN_RAW) failed: " + ErrnoName(err));
  }
  fd_ = fd;
  ifindex_ = static_cast<int>(::if_nametoindex(ifname.c_str()));
  if (ifindex_ == 0) {
    const int err = errno;
    CloseSocket();
    return NotFound("SocketCAN: no network interface '" + ifname + "' (" + ErrnoName(err) +
                    "); create it with e.g. `ip link set " + ifname + " up type can bitrate 500000 restart-ms 100`");
  }
  auto set = [&](int level, int option, const void* value, socklen_t len, const char* what) -> Status {
    if (::setsockopt(fd_, level, option, value, len) != 0) {
      const int err = errno;
      CloseSocket();
      return IoError("SocketCAN " + ifname + ": setsockopt " + what + " failed: " + ErrnoName(err));
    }
    return Status::Ok();
  };
  std::vector<can_filter> filters;
  for (const SocketCanFilter& f : options_.filters) filters.push_back(ToKernelFilter(f));
  if (!filters.empty()) {
    IDI_RETURN_IF_ERROR(set(SOL_CAN_RAW, CAN_RAW_FILTER, filters.data(),
                            static_cast<socklen_t>(filters.size() * sizeof(can_filter)), "CAN_RAW_FILTER"));
  }
  const can_err_mask_t err_mask = options_.error_mask;
  IDI_RETURN_IF_ERROR(set(SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &err_mask, sizeof(err_mask), "CAN_RAW_ERR_FILTER"));
  const int loopback = options_.loopback ? 1 : 0;
  IDI_RETURN_IF_ERROR(set(SOL_CAN_RAW, CAN_RAW_LOOPBACK, &loopback, sizeof(loopback), "CAN_RAW_LOOPBACK"));
  const int own = options_.receive_own_messages ? 1 : 0;
  IDI_RETURN_IF_ERROR(set(SOL_CAN_RAW, CAN_RAW_RECV_OWN_MSGS, &own, sizeof(own), "CAN_RAW_RECV_OWN_MSGS"));
  const int one = 1;
  IDI_RETURN_IF_ERROR(set(SOL_SOCKET, SO_RXQ_OVFL, &one, sizeof(one), "SO_RXQ_OVFL"));

  sockaddr_can addr;
  std::memset(&addr, 0, sizeof(addr));
  addr.can_family = AF_CAN;
  addr.can_ifindex = ifindex_;
  if (::bind(fd_, reinterpret_cast<const sockaddr*>(&addr), sizeof(addr)) != 0) {
    const int err = errno;
    CloseSocket();
    return IoError("SocketCAN " + ifname + ": bind failed: " + ErrnoName(err));
  }
  return Status::Ok();
}

Status SocketCanBus::Reopen() {
  last_reopen_ns_ = SteadyNs();
  IDI_RETURN_IF_ERROR(OpenSocket());
  state_ = hal::CanControllerState::kErrorActive;
  return Status::Ok();
}

Status SocketCanBus::MaybeReopen() {
  if (fd_ >= 0) return Status::Ok();
  const int64_t now = SteadyNs();
  if (now - last_reopen_ns_ < static_cast<int64_t>(options_.reopen_interval.count()) * hal::kNsPerMs) {
    return DeviceError("SocketCAN " + options_.interface + ": interface unavailable, reopening later");
  }
  return Reopen();
}

Status SocketCanBus::InterfaceGone(const std::string& what, int err) {
  // The socket stays bound to a vanished or downed interface; start afresh later.
  CloseSocket();
  last_reopen_ns_ = SteadyNs();
  return DeviceError("SocketCAN " + options_.interface + ": " + what + ": " + ErrnoName(err) +
                     (err == ENETDOWN ? " (interface down or controller bus-off)" : ""));
}

Status SocketCanBus::Send(const hal::CanFrame& frame) {
  IDI_ASSIGN_OR_RETURN(const can_frame out, ToSocketCanFrame(frame));
  IDI_RETURN_IF_ERROR(MaybeReopen());
  if (bus_off()) {
    ++counters_.dropped;
    return DeviceError("SocketCAN " + options_.interface + ": controller is bus-off; frame not sent");
  }
  const int64_t deadline = DeadlineNs(options_.send_timeout);
  while (true) {
    const ssize_t n = ::write(fd_, &out, sizeof(out));
    if (n == static_cast<ssize_t>(sizeof(out))) {
      ++counters_.sent;
      return Status::Ok();
    }
    const int err = n < 0 ? errno : EIO;
    if (err == EINTR) continue;
    if (InterfaceDownErrno(err)) {
      ++counters_.dropped;
      return InterfaceGone("send", err);
    }
    if (err != ENOBUFS && err != EAGAIN) {
      ++counters_.dropped;
      return IoError("SocketCAN " + options_.interface + ": write failed: " + ErrnoName(err));
    }
    // TX queue full (the bus is busy or nobody acknowledges): wait for room until the deadline.
    const int64_t left_ns = deadline - SteadyNs();
    if (left_ns <= 0) {
      ++counters_.dropped;
      return Timeout("SocketCAN " + options_.interface + ": TX queue full for " +
                     std::to_string(options_.send_timeout.count()) + " ms (no ACK from other nodes?)");
    }
    pollfd p{fd_, POLLOUT, 0};
    // ENOBUFS does not always clear through POLLOUT; poll in short slices.
    (void)::poll(&p, 1, static_cast<int>(std::min<int64_t>(2, (left_ns + hal::kNsPerMs - 1) / hal::kNsPerMs)));
  }
}

void SocketCanBus::TrackError(const hal::CanFrame& frame) {
  const hal::CanErrorInfo info = hal::DecodeCanError(frame);
  if (info.bus_off && state_ != hal::CanControllerState::kBusOff) ++counters_.bus_off;
  if (info.has_state) state_ = info.state;
}

Result<std::optional<hal::CanFrame>> SocketCanBus::Receive(std::chrono::milliseconds timeout) {
  IDI_RETURN_IF_ERROR(MaybeReopen());
  const int64_t deadline = DeadlineNs(timeout);
  while (true) {
    can_frame in;
    char control[CMSG_SPACE(sizeof(uint32_t))];
    iovec iov{&in, sizeof(in)};
    msghdr msg;
    std::memset(&msg, 0, sizeof(msg));
    msg.msg_iov = &iov;
    msg.msg_iovlen = 1;
    msg.msg_control = control;
    msg.msg_controllen = sizeof(control);
    const ssize_t n = ::recvmsg(fd_, &msg, 0);
    if (n == static_cast<ssize_t>(sizeof(in))) {
      for (cmsghdr* c = CMSG_FIRSTHDR(&msg); c != nullptr; c = CMSG_NXTHDR(&msg, c)) {
        if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SO_RXQ_OVFL) {
          uint32_t drops = 0;
          std::memcpy(&drops, CMSG_DATA(c), sizeof(drops));
          if (drops > kernel_drops_) counters_.dropped += drops - kernel_drops_;
          kernel_drops_ = drops;
        }
      }
      hal::CanFrame f = FromSocketCanFrame(in, clock_->NowNs());
      if (f.error) {
        ++counters_.error_frames;
        TrackError(f);
      } else {
        ++counters_.received;
        // Data arriving means the controller is on the bus, whatever the last error frame said.
        if (state_ == hal::CanControllerState::kBusOff) state_ = hal::CanControllerState::kErrorActive;
      }
      return std::optional<hal::CanFrame>(f);
    }
    if (n >= 0) {
      return DeviceError("SocketCAN " + options_.interface + ": short read of " + std::to_string(n) + " bytes (CAN FD frame?)");
    }
    const int err = errno;
    if (err == EINTR) continue;
    if (InterfaceDownErrno(err)) return InterfaceGone("receive", err);
    if (err != EAGAIN && err != EWOULDBLOCK) {
      return IoError("SocketCAN " + options_.interface + ": read failed: " + ErrnoName(err));
    }
    const int64_t left_ns = deadline - SteadyNs();
    if (left_ns <= 0) return std::optional<hal::CanFrame>();
    pollfd p{fd_, POLLIN, 0};
    const int rc = ::poll(&p, 1, static_cast<int>((left_ns + hal::kNsPerMs - 1) / hal::kNsPerMs));
    if (rc < 0 && errno != EINTR) return IoError("SocketCAN " + options_.interface + ": poll failed: " + ErrnoName(errno));
    if (rc > 0 && (p.revents & (POLLERR | POLLHUP | POLLNVAL)) && !(p.revents & POLLIN)) {
      int so_error = 0;
      socklen_t len = sizeof(so_error);
      ::getsockopt(fd_, SOL_SOCKET, SO_ERROR, &so_error, &len);
      if (InterfaceDownErrno(so_error)) return InterfaceGone("receive", so_error);
      return IoError("SocketCAN " + options_.interface + ": socket error: " + ErrnoName(so_error));
    }
  }
}

Status SocketCanBus::Restart() {
  const std::string& ifname = options_.interface;
  const int nl = ::socket(AF_NETLINK, SOCK_RAW | SOCK_CLOEXEC, NETLINK_ROUTE);
  if (nl < 0) {
    const int err = errno;
    // Under idi-rmp.service (RestrictAddressFamilies=AF_UNIX AF_CAN, no capabilities) rtnetlink is not
    // reachable at all: the kernel must restart the controller itself.
    if (err == EAFNOSUPPORT || err == EPERM || err == EACCES) {
      return FailedPrecondition("SocketCAN " + ifname + ": cannot ask for a restart here (" + ErrnoName(err) +
                                "); configure the interface with restart-ms (`ip link set " + ifname +
                                " type can restart-ms 100`) so that the kernel restarts it");
    }
    return IoError("SocketCAN " + ifname + ": rtnetlink socket failed: " + ErrnoName(err));
  }
  // RTM_NEWLINK { ifinfomsg, IFLA_LINKINFO { IFLA_INFO_KIND "can", IFLA_INFO_DATA { IFLA_CAN_RESTART 1 } } }
  std::vector<char> buf(NLMSG_LENGTH(sizeof(ifinfomsg)), 0);
  nlmsghdr* hdr = reinterpret_cast<nlmsghdr*>(buf.data());
  hdr->nlmsg_type = RTM_NEWLINK;
  hdr->nlmsg_flags = NLM_F_REQUEST | NLM_F_ACK;
  hdr->nlmsg_seq = 1;
  ifinfomsg* ifi = reinterpret_cast<ifinfomsg*>(NLMSG_DATA(hdr));
  ifi->ifi_family = AF_UNSPEC;
  ifi->ifi_index = ifindex_;
  const std::size_t linkinfo = AddRtAttr(&buf, IFLA_LINKINFO, nullptr, 0);
  AddRtAttr(&buf, IFLA_INFO_KIND, "can", 4);
  const std::size_t data = AddRtAttr(&buf, IFLA_INFO_DATA, nullptr, 0);
  const uint32_t restart = 1;
  AddRtAttr(&buf, IFLA_CAN_RESTART, &restart, sizeof(restart));
  EndNest(&buf, data);
  EndNest(&buf, linkinfo);
  hdr = reinterpret_cast<nlmsghdr*>(buf.data());
  hdr->nlmsg_len = static_cast<uint32_t>(buf.size());

  sockaddr_nl kernel;
  std::memset(&kernel, 0, sizeof(kernel));
  kernel.nl_family = AF_NETLINK;
  Status result = Status::Ok();
  if (::sendto(nl, buf.data(), buf.size(), 0, reinterpret_cast<const sockaddr*>(&kernel), sizeof(kernel)) < 0) {
    result = IoError("SocketCAN " + ifname + ": rtnetlink send failed: " + ErrnoName(errno));
  } else {
    char reply[4096];
    pollfd p{nl, POLLIN, 0};
    const ssize_t n = ::poll(&p, 1, 1000) > 0 ? ::recv(nl, reply, sizeof(reply), 0) : -1;
    if (n < static_cast<ssize_t>(NLMSG_LENGTH(sizeof(nlmsgerr)))) {
      result = Timeout("SocketCAN " + ifname + ": no rtnetlink answer to the restart request");
    } else {
      const nlmsghdr* r = reinterpret_cast<const nlmsghdr*>(reply);
      const int err = r->nlmsg_type == NLMSG_ERROR ? -reinterpret_cast<const nlmsgerr*>(NLMSG_DATA(r))->error : 0;
      if (err == EPERM || err == EACCES) {
        result = FailedPrecondition("SocketCAN " + ifname + ": restarting the controller needs CAP_NET_ADMIN (" +
                                    ErrnoName(err) +
                                    "); configure the interface with restart-ms so that the kernel restarts it");
      } else if (err == EOPNOTSUPP || err == EINVAL) {
        result = DeviceError("SocketCAN " + ifname + ": the interface cannot be restarted (not a CAN controller, e.g. vcan): " +
                             ErrnoName(err));
      } else if (err == EBUSY) {
        result = DeviceError("SocketCAN " + ifname + ": restart refused, the controller is not bus-off: " + ErrnoName(err));
      } else if (err != 0) {
        result = DeviceError("SocketCAN " + ifname + ": restart failed: " + ErrnoName(err));
      }
    }
  }
  ::close(nl);
  return result;
}

}  // namespace idi::drivers
