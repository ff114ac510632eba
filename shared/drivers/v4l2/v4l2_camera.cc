#include "shared/drivers/v4l2/v4l2_camera.h"

#include <fcntl.h>
#include <linux/videodev2.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <thread>
#include <utility>

#include "shared/drivers/v4l2/v4l2_format.h"
#include "shared/hal/clock.h"

namespace idi::drivers {
namespace {

// ioctl that retries when a signal interrupted it.
int V4l2Ioctl(int fd, unsigned long request, void* arg) {
  int r;
  do {
    r = ::ioctl(fd, request, arg);
  } while (r == -1 && errno == EINTR);
  return r;
}

std::string V4l2Errno(const char* what) { return std::string(what) + ": " + std::strerror(errno); }

std::string V4l2CString(const uint8_t* s, std::size_t n) {
  const auto* c = reinterpret_cast<const char*>(s);
  return std::string(c, strnlen(c, n));
}

// Device capabilities of a node: device_caps when the driver fills it, else the whole device's.
uint32_t V4l2NodeCaps(const v4l2_capability& cap) {
  return (cap.capabilities & V4L2_CAP_DEVICE_CAPS) ? cap.device_caps : cap.capabilities;
}

int64_t V4l2TimevalNs(const timeval& tv) {
  return static_cast<int64_t>(tv.tv_sec) * hal::kNsPerSec + static_cast<int64_t>(tv.tv_usec) * 1000;
}

// The sizes a device offers for a format, for error messages ("640x480, 1280x720" or a range).
std::string V4l2OfferedSizes(int fd, uint32_t fourcc) {
  std::string sizes;
  v4l2_frmsizeenum fs{};
  fs.pixel_format = fourcc;
  for (fs.index = 0; V4l2Ioctl(fd, VIDIOC_ENUM_FRAMESIZES, &fs) == 0; ++fs.index) {
    if (fs.type == V4L2_FRMSIZE_TYPE_DISCRETE) {
      sizes += (sizes.empty() ? "" : ", ") + std::to_string(fs.discrete.width) + "x" +
               std::to_string(fs.discrete.height);
    } else {
      sizes = std::to_string(fs.stepwise.min_width) + "x" + std::to_string(fs.stepwise.min_height) + " to " +
              std::to_string(fs.stepwise.max_width) + "x" + std::to_string(fs.stepwise.max_height) + " in steps of " +
              std::to_string(fs.stepwise.step_width) + "x" + std::to_string(fs.stepwise.step_height);
      break;
    }
  }
  return sizes.empty() ? "(the device does not list its sizes)" : sizes;
}

}  // namespace

Status V4l2CameraOptions::Check() const {
  if (device.empty()) return InvalidArgument("V4L2 camera: 'device' is empty (e.g. /dev/video0)");
  if (name.empty()) return InvalidArgument("V4L2 camera " + device + ": 'name' is empty");
  if (buffer_count < 2 || buffer_count > 32) {
    return InvalidArgument("V4L2 camera " + device + ": buffer_count " + std::to_string(buffer_count) +
                           " outside 2..32");
  }
  if (!std::isfinite(frame_rate_hz) || frame_rate_hz < 0 || frame_rate_hz > 1000) {
    return InvalidArgument("V4L2 camera " + device + ": frame_rate_hz " + FormatNumber(frame_rate_hz) +
                           " outside 0..1000");
  }
  if (reconnect_interval.count() < 0) return InvalidArgument("V4L2 camera " + device + ": negative reconnect_interval");
  return Status::Ok();
}

const char* V4l2CameraStateName(V4l2CameraState state) {
  switch (state) {
    case V4l2CameraState::kStopped:
      return "stopped";
    case V4l2CameraState::kStreaming:
      return "streaming";
    case V4l2CameraState::kLost:
      return "lost";
  }
  return "?";
}

std::vector<V4l2DeviceInfo> ListV4l2CaptureDevices() {
  std::vector<V4l2DeviceInfo> found;
  std::error_code ec;
  for (const auto& entry : std::filesystem::directory_iterator("/dev", ec)) {
    const std::string path = entry.path().string();
    if (entry.path().filename().string().rfind("video", 0) != 0) continue;
    const int fd = ::open(path.c_str(), O_RDWR | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0) continue;
    v4l2_capability cap{};
    if (V4l2Ioctl(fd, VIDIOC_QUERYCAP, &cap) == 0) {
      const uint32_t caps = V4l2NodeCaps(cap);
      if ((caps & V4L2_CAP_VIDEO_CAPTURE) && (caps & V4L2_CAP_STREAMING)) {
        found.push_back({path, V4l2CString(cap.driver, sizeof(cap.driver)), V4l2CString(cap.card, sizeof(cap.card)),
                         V4l2CString(cap.bus_info, sizeof(cap.bus_info))});
      }
    }
    ::close(fd);
  }
  std::sort(found.begin(), found.end(), [](const auto& a, const auto& b) { return a.path < b.path; });
  return found;
}

V4l2Camera::V4l2Camera(V4l2CameraOptions options) : options_(std::move(options)) {}

V4l2Camera::~V4l2Camera() { CloseDevice(); }

std::string V4l2Camera::Where() const {
  return "camera " + options_.name + " (" + (negotiated_.path.empty() ? options_.device : negotiated_.path) + ")";
}

Status V4l2Camera::Start(const hal::CameraSettings& settings) {
  IDI_RETURN_IF_ERROR(options_.Check());
  IDI_RETURN_IF_ERROR(hal::CheckCameraSettings(settings, Where()));
  if (settings.gain_db != 0) {
    return InvalidArgument(Where() + ": gain_db " + FormatNumber(settings.gain_db) +
                           " cannot be set: V4L2 gain is in device-specific units; leave it 0");
  }
  CloseDevice();
  settings_ = settings;
  if (settings.exposure_us > 0) exposure_us_ = settings.exposure_us;
  identity_card_.clear();
  identity_bus_info_.clear();
  last_sequence_.reset();
  Status s = OpenAndStream();
  state_ = s.ok() ? V4l2CameraState::kStreaming : V4l2CameraState::kStopped;
  return s;
}

Status V4l2Camera::Stop() {
  CloseDevice();
  state_ = V4l2CameraState::kStopped;
  return Status::Ok();
}

Status V4l2Camera::OpenAndStream() {
  Status s = OpenNode(options_.device);
  // After a reconnect the camera may sit on another node: look for the same card and bus.
  if (!s.ok() && !identity_bus_info_.empty()) {
    for (const auto& dev : ListV4l2CaptureDevices()) {
      if (dev.card == identity_card_ && dev.bus_info == identity_bus_info_) {
        s = OpenNode(dev.path);
        if (s.ok()) break;
      }
    }
  }
  IDI_RETURN_IF_ERROR(s);
  s = NegotiateFormat();
  if (s.ok()) s = ApplyExposure();
  if (s.ok()) s = MapBuffersAndStream();
  if (!s.ok()) {
    CloseDevice();
    return s;
  }
  if (identity_bus_info_.empty()) {
    identity_card_ = negotiated_.card;
    identity_bus_info_ = negotiated_.bus_info;
  }
  return Status::Ok();
}

Status V4l2Camera::OpenNode(const std::string& path) {
  CloseDevice();
  negotiated_ = V4l2Negotiated{};
  negotiated_.path = path;
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) {
    return NotFound(Where() + ": " + V4l2Errno("no such device node"));
  }
  if (!S_ISCHR(st.st_mode)) return InvalidArgument(Where() + ": not a character device");
  fd_ = ::open(path.c_str(), O_RDWR | O_NONBLOCK | O_CLOEXEC);
  if (fd_ < 0) return DeviceError(Where() + ": " + V4l2Errno("open"));
  v4l2_capability cap{};
  if (V4l2Ioctl(fd_, VIDIOC_QUERYCAP, &cap) != 0) {
    const std::string msg = V4l2Errno("VIDIOC_QUERYCAP (not a V4L2 device?)");
    CloseDevice();
    return DeviceError(Where() + ": " + msg);
  }
  negotiated_.driver = V4l2CString(cap.driver, sizeof(cap.driver));
  negotiated_.card = V4l2CString(cap.card, sizeof(cap.card));
  negotiated_.bus_info = V4l2CString(cap.bus_info, sizeof(cap.bus_info));
  const uint32_t caps = V4l2NodeCaps(cap);
  if (!(caps & V4L2_CAP_VIDEO_CAPTURE) || !(caps & V4L2_CAP_STREAMING)) {
    CloseDevice();
    return DeviceError(Where() + ": '" + negotiated_.card + "' is not a single-planar video capture node " +
                       "with streaming I/O");
  }
  if (!identity_bus_info_.empty() &&
      (negotiated_.card != identity_card_ || negotiated_.bus_info != identity_bus_info_)) {
    const std::string other = negotiated_.card + " at " + negotiated_.bus_info;
    CloseDevice();
    return NotFound(Where() + ": holds " + other + ", not the camera started (" + identity_card_ + " at " +
                    identity_bus_info_ + ")");
  }
  return Status::Ok();
}

Status V4l2Camera::NegotiateFormat() {
  std::vector<uint32_t> offered;
  v4l2_fmtdesc desc{};
  desc.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  for (desc.index = 0; V4l2Ioctl(fd_, VIDIOC_ENUM_FMT, &desc) == 0; ++desc.index) {
    offered.push_back(desc.pixelformat);
  }
  auto chosen = ChooseV4l2Format(offered, settings_.gray);
  if (!chosen.ok()) return chosen.status().WithContext(Where());
  v4l2_format fmt{};
  fmt.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  fmt.fmt.pix.width = static_cast<uint32_t>(settings_.width);
  fmt.fmt.pix.height = static_cast<uint32_t>(settings_.height);
  fmt.fmt.pix.pixelformat = *chosen;
  fmt.fmt.pix.field = V4L2_FIELD_NONE;
  if (V4l2Ioctl(fd_, VIDIOC_S_FMT, &fmt) != 0) {
    return DeviceError(Where() + ": " + V4l2Errno(errno == EBUSY ? "VIDIOC_S_FMT (in use by another program?)"
                                                                  : "VIDIOC_S_FMT"));
  }
  // Drivers adjust what they cannot do; a calibrated camera must not silently change resolution.
  if (fmt.fmt.pix.width != static_cast<uint32_t>(settings_.width) ||
      fmt.fmt.pix.height != static_cast<uint32_t>(settings_.height)) {
    return InvalidArgument(Where() + ": cannot capture " + std::to_string(settings_.width) + "x" +
                           std::to_string(settings_.height) + " in " + FourccToString(*chosen) +
                           " (the driver offered " + std::to_string(fmt.fmt.pix.width) + "x" +
                           std::to_string(fmt.fmt.pix.height) + "); sizes: " + V4l2OfferedSizes(fd_, *chosen));
  }
  if (fmt.fmt.pix.pixelformat != *chosen) {
    return DeviceError(Where() + ": asked for " + FourccToString(*chosen) + ", driver set " +
                       FourccToString(fmt.fmt.pix.pixelformat));
  }
  if (fmt.fmt.pix.field != V4L2_FIELD_NONE && fmt.fmt.pix.field != V4L2_FIELD_ANY) {
    return DeviceError(Where() + ": interlaced capture (field " + std::to_string(fmt.fmt.pix.field) +
                       ") is not supported");
  }
  negotiated_.fourcc = fmt.fmt.pix.pixelformat;
  negotiated_.width = static_cast<int>(fmt.fmt.pix.width);
  negotiated_.height = static_cast<int>(fmt.fmt.pix.height);
  negotiated_.bytes_per_line = fmt.fmt.pix.bytesperline;
  if (negotiated_.bytes_per_line == 0) {  // some drivers leave it to us for packed formats
    negotiated_.bytes_per_line = static_cast<uint32_t>(negotiated_.width) *
                                 (negotiated_.fourcc == V4L2_PIX_FMT_GREY || negotiated_.fourcc == V4L2_PIX_FMT_NV12 ? 1u
                                  : negotiated_.fourcc == V4L2_PIX_FMT_YUYV || negotiated_.fourcc == V4L2_PIX_FMT_UYVY
                                      ? 2u
                                      : 3u);
  }
  IDI_RETURN_IF_ERROR(V4l2FrameBytes({negotiated_.fourcc, negotiated_.width, negotiated_.height,
                                      negotiated_.bytes_per_line})
                          .status()
                          .WithContext(Where()));

  v4l2_streamparm parm{};
  parm.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  if (options_.frame_rate_hz > 0) {
    parm.parm.capture.timeperframe.numerator = 1000;
    parm.parm.capture.timeperframe.denominator = static_cast<uint32_t>(std::lround(options_.frame_rate_hz * 1000));
    if (V4l2Ioctl(fd_, VIDIOC_S_PARM, &parm) != 0) {
      return DeviceError(Where() + ": " + V4l2Errno("VIDIOC_S_PARM (frame rate)"));
    }
  }
  parm = v4l2_streamparm{};
  parm.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  if (V4l2Ioctl(fd_, VIDIOC_G_PARM, &parm) == 0 && parm.parm.capture.timeperframe.denominator != 0) {
    negotiated_.frame_interval_ns = static_cast<int64_t>(parm.parm.capture.timeperframe.numerator) *
                                    hal::kNsPerSec / parm.parm.capture.timeperframe.denominator;
  }
  return Status::Ok();
}

Status V4l2Camera::ApplyExposure() {
  if (!exposure_us_) return Status::Ok();
  v4l2_queryctrl q{};
  q.id = V4L2_CID_EXPOSURE_ABSOLUTE;
  if (V4l2Ioctl(fd_, VIDIOC_QUERYCTRL, &q) != 0 || (q.flags & V4L2_CTRL_FLAG_DISABLED)) {
    return FailedPrecondition(Where() + ": '" + negotiated_.card + "' has no exposure control");
  }
  v4l2_control auto_ctrl{};
  auto_ctrl.id = V4L2_CID_EXPOSURE_AUTO;
  v4l2_control abs_ctrl{};
  abs_ctrl.id = V4L2_CID_EXPOSURE_ABSOLUTE;
  if (*exposure_us_ == 0) {
    auto_ctrl.value = V4L2_EXPOSURE_APERTURE_PRIORITY;  // what UVC cameras call automatic
    if (V4l2Ioctl(fd_, VIDIOC_S_CTRL, &auto_ctrl) != 0) {
      auto_ctrl.value = V4L2_EXPOSURE_AUTO;
      if (V4l2Ioctl(fd_, VIDIOC_S_CTRL, &auto_ctrl) != 0) {
        return DeviceError(Where() + ": " + V4l2Errno("automatic exposure"));
      }
    }
    return Status::Ok();
  }
  const double units = *exposure_us_ / 100.0;  // V4L2_CID_EXPOSURE_ABSOLUTE counts 100 µs
  if (units < q.minimum || units > q.maximum) {
    return OutOfRange(Where() + ": exposure " + FormatNumber(*exposure_us_) + " us outside the device's " +
                      std::to_string(q.minimum * 100) + ".." + std::to_string(q.maximum * 100) + " us");
  }
  auto_ctrl.value = V4L2_EXPOSURE_MANUAL;
  (void)V4l2Ioctl(fd_, VIDIOC_S_CTRL, &auto_ctrl);  // absent on cameras that are always manual
  abs_ctrl.value = std::max(q.minimum, static_cast<int32_t>(std::lround(units)));
  if (V4l2Ioctl(fd_, VIDIOC_S_CTRL, &abs_ctrl) != 0) {
    return DeviceError(Where() + ": " + V4l2Errno("VIDIOC_S_CTRL exposure"));
  }
  return Status::Ok();
}

Status V4l2Camera::MapBuffersAndStream() {
  v4l2_requestbuffers req{};
  req.count = static_cast<uint32_t>(options_.buffer_count);
  req.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  req.memory = V4L2_MEMORY_MMAP;
  if (V4l2Ioctl(fd_, VIDIOC_REQBUFS, &req) != 0) {
    return DeviceError(Where() + ": " + V4l2Errno(errno == EBUSY ? "VIDIOC_REQBUFS (in use by another program?)"
                                                                  : "VIDIOC_REQBUFS"));
  }
  if (req.count < 2) return DeviceError(Where() + ": driver gave " + std::to_string(req.count) + " buffers, need 2");
  for (uint32_t i = 0; i < req.count; ++i) {
    v4l2_buffer buf{};
    buf.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    buf.memory = V4L2_MEMORY_MMAP;
    buf.index = i;
    if (V4l2Ioctl(fd_, VIDIOC_QUERYBUF, &buf) != 0) return DeviceError(Where() + ": " + V4l2Errno("VIDIOC_QUERYBUF"));
    void* p = ::mmap(nullptr, buf.length, PROT_READ | PROT_WRITE, MAP_SHARED, fd_, buf.m.offset);
    if (p == MAP_FAILED) return DeviceError(Where() + ": " + V4l2Errno("mmap"));
    buffers_.push_back({p, buf.length});
    if (i == 0) {
      timestamps_monotonic_ =
          (buf.flags & V4L2_BUF_FLAG_TIMESTAMP_MASK) == V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC;
      timestamp_at_start_of_exposure_ = (buf.flags & V4L2_BUF_FLAG_TSTAMP_SRC_MASK) == V4L2_BUF_FLAG_TSTAMP_SRC_SOE;
    }
    if (V4l2Ioctl(fd_, VIDIOC_QBUF, &buf) != 0) return DeviceError(Where() + ": " + V4l2Errno("VIDIOC_QBUF"));
  }
  negotiated_.buffers = static_cast<int>(req.count);
  int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  if (V4l2Ioctl(fd_, VIDIOC_STREAMON, &type) != 0) return DeviceError(Where() + ": " + V4l2Errno("VIDIOC_STREAMON"));
  streaming_ = true;
  last_sequence_.reset();
  // STREAMON restarts the driver's count at 0: the frames of this stream follow those delivered before
  // (a reconnect), so that a sequence number names one frame of this camera.
  sequence_base_ = last_delivered_ ? *last_delivered_ + 1 : 0;
  return Status::Ok();
}

void V4l2Camera::CloseDevice() {
  if (fd_ >= 0 && streaming_) {
    int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    (void)V4l2Ioctl(fd_, VIDIOC_STREAMOFF, &type);  // fails on a vanished device; closing still frees it
  }
  streaming_ = false;
  for (const Buffer& b : buffers_) ::munmap(b.start, b.length);
  buffers_.clear();
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
}

Status V4l2Camera::LoseDevice(const std::string& what) {
  const std::string where = Where();
  CloseDevice();
  state_ = V4l2CameraState::kLost;
  ++counters_.device_errors;
  lost_reason_ = what;
  next_reconnect_ = std::chrono::steady_clock::now() + options_.reconnect_interval;
  return DeviceError(where + " failed while streaming: " + what + "; will try to reopen it");
}

Result<hal::Image> V4l2Camera::Grab(std::chrono::milliseconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  if (state_ == V4l2CameraState::kStopped) return FailedPrecondition(Where() + ": Grab before Start");
  if (state_ == V4l2CameraState::kLost) {
    // Wait for the next reopen attempt if it falls within this call's time, else report still lost.
    if (next_reconnect_ > deadline) {
      std::this_thread::sleep_until(deadline);
      return DeviceError(Where() + " is lost (" + lost_reason_ + "); next reopen attempt pending");
    }
    std::this_thread::sleep_until(next_reconnect_);
    Status s = OpenAndStream();
    if (!s.ok()) {
      next_reconnect_ = std::chrono::steady_clock::now() + options_.reconnect_interval;
      return DeviceError(Where() + " is lost (" + lost_reason_ + "); reopening failed: " + s.message());
    }
    state_ = V4l2CameraState::kStreaming;
    ++counters_.reconnects;
  }
  return DequeueFrame(deadline, timeout);
}

Result<hal::Image> V4l2Camera::DequeueFrame(std::chrono::steady_clock::time_point deadline,
                                             std::chrono::milliseconds timeout) {
  for (;;) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now());
    pollfd pfd{fd_, POLLIN, 0};
    const int n = ::poll(&pfd, 1, static_cast<int>(std::max<int64_t>(0, left.count())));
    if (n < 0) {
      if (errno == EINTR) continue;
      return LoseDevice(V4l2Errno("poll"));
    }
    if (n == 0) {
      return Timeout(Where() + ": no frame within " + std::to_string(timeout.count()) + " ms");
    }
    if (pfd.revents & (POLLERR | POLLHUP | POLLNVAL)) {
      return LoseDevice("poll reported " + std::string(pfd.revents & POLLHUP ? "hang-up" : "an error"));
    }
    v4l2_buffer buf{};
    buf.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    buf.memory = V4L2_MEMORY_MMAP;
    if (V4l2Ioctl(fd_, VIDIOC_DQBUF, &buf) != 0) {
      if (errno == EAGAIN) continue;
      return LoseDevice(V4l2Errno("VIDIOC_DQBUF"));
    }
    const int64_t now_ns = hal::MonotonicClock().NowNs();
    if (buf.index >= buffers_.size()) return LoseDevice("driver returned buffer " + std::to_string(buf.index));
    if (last_sequence_ && buf.sequence > *last_sequence_ + 1) counters_.dropped += buf.sequence - *last_sequence_ - 1;
    last_sequence_ = buf.sequence;

    Result<cv::Mat> pixels = InvalidArgument("corrupted");
    const bool corrupted = (buf.flags & V4L2_BUF_FLAG_ERROR) != 0;
    if (!corrupted) {
      const std::size_t used = std::min<std::size_t>(buf.bytesused, buffers_[buf.index].length);
      pixels = ConvertV4l2Frame({negotiated_.fourcc, negotiated_.width, negotiated_.height, negotiated_.bytes_per_line},
                                static_cast<const uint8_t*>(buffers_[buf.index].start), used, settings_.gray);
    }
    // The frame is copied: hand the buffer back to the driver before anything else can fail.
    // QBUF rewrites the struct, so keep what we still need from it.
    const timeval stamp = buf.timestamp;
    const uint32_t sequence = buf.sequence;
    if (V4l2Ioctl(fd_, VIDIOC_QBUF, &buf) != 0) return LoseDevice(V4l2Errno("VIDIOC_QBUF"));
    if (corrupted) {
      ++counters_.corrupted;
      continue;
    }
    if (!pixels.ok()) return pixels.status().WithContext(Where() + " frame " + std::to_string(sequence));

    // hal::Image wants the middle of the exposure on the monotonic clock. Drivers stamp the start of
    // exposure (SOE) or the end of the frame (EOF, typically UVC); without a monotonic stamp use now.
    int64_t t_ns = timestamps_monotonic_ ? V4l2TimevalNs(stamp) : now_ns;
    if (timestamps_monotonic_ && timestamp_at_start_of_exposure_) {
      if (exposure_us_ && *exposure_us_ > 0) t_ns += static_cast<int64_t>(*exposure_us_ * 500.0);  // + exposure / 2
    } else {
      t_ns -= negotiated_.frame_interval_ns / 2;
    }
    hal::Image image;
    image.timestamp_ns = t_ns;
    image.sequence = sequence_base_ + sequence;
    last_delivered_ = image.sequence;
    image.camera = options_.name;
    image.pixels = std::move(pixels).value();
    ++counters_.frames;
    return image;
  }
}

Status V4l2Camera::SetExposure(double exposure_us) {
  if (!std::isfinite(exposure_us) || exposure_us < 0) {
    return InvalidArgument(Where() + ": exposure " + FormatNumber(exposure_us) + " us is invalid");
  }
  const std::optional<double> previous = exposure_us_;
  exposure_us_ = exposure_us;
  if (fd_ < 0) return Status::Ok();  // applied at Start / reconnect
  Status s = ApplyExposure();
  if (!s.ok()) exposure_us_ = previous;
  return s;
}

}  // namespace idi::drivers
