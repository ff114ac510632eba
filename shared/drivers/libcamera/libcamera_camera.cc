#include "shared/drivers/libcamera/libcamera_camera.h"

#include <libcamera/camera.h>
#include <libcamera/camera_manager.h>
#include <libcamera/control_ids.h>
#include <libcamera/controls.h>
#include <libcamera/formats.h>
#include <libcamera/framebuffer.h>
#include <libcamera/framebuffer_allocator.h>
#include <libcamera/logging.h>
#include <libcamera/request.h>
#include <libcamera/stream.h>
#include <linux/dma-buf.h>
#include <sys/ioctl.h>
#include <sys/mman.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <utility>

#include "shared/drivers/libcamera/libcamera_format.h"
#include "shared/drivers/v4l2/v4l2_format.h"
#include "shared/hal/clock.h"

namespace idi::drivers {
namespace {

std::string LibcameraErrno(int negative_errno) { return std::strerror(-negative_errno); }

// libcamera allows one CameraManager per process (a second one aborts): every camera and
// ListLibcameraCameras share this one while any of them holds it.
Result<std::shared_ptr<libcamera::CameraManager>> LibcameraSharedManager() {
  static std::mutex mutex;
  static std::weak_ptr<libcamera::CameraManager> shared;
  std::lock_guard<std::mutex> lock(mutex);
  if (auto manager = shared.lock()) return manager;
  auto manager = std::make_shared<libcamera::CameraManager>();
  // libcamera logs at INFO to stderr (its version on every start, stream configurations); keep its
  // warnings and errors unless the user asked for more with its own variable. The category only
  // exists once a manager has logged, so the very first version line still comes out.
  if (std::getenv("LIBCAMERA_LOG_LEVELS") == nullptr) libcamera::logSetLevel("Camera", "WARN");
  const int r = manager->start();
  if (r < 0) return DeviceError("libcamera: the camera manager did not start: " + LibcameraErrno(r));
  shared = manager;
  return manager;
}

std::string LibcameraCameraList(const std::vector<std::shared_ptr<libcamera::Camera>>& cameras) {
  std::string list;
  for (std::size_t i = 0; i < cameras.size(); ++i) {
    list += (list.empty() ? "" : ", ") + std::to_string(i) + ": '" + cameras[i]->id() + "'";
  }
  return list;
}

// "0", "12": an index into the camera list; anything else is an id.
std::optional<std::size_t> LibcameraIndex(const std::string& s) {
  if (s.empty() || s.size() > 3 || !std::all_of(s.begin(), s.end(), [](char c) { return c >= '0' && c <= '9'; })) {
    return std::nullopt;
  }
  return static_cast<std::size_t>(std::stoul(s));
}

// The sizes a stream offers in a format, for error messages.
std::string LibcameraOfferedSizes(const libcamera::StreamFormats& formats, const libcamera::PixelFormat& format) {
  std::string sizes;
  for (const libcamera::Size& s : formats.sizes(format)) sizes += (sizes.empty() ? "" : ", ") + s.toString();
  return sizes.empty() ? formats.range(format).toString() : sizes;
}

// Begins (start) or ends CPU reads of a DMA buffer, so cached mappings see what the device wrote.
// Best effort: buffers that are not dma-bufs do not need it.
void LibcameraDmaSync(int fd, bool start) {
  if (fd < 0) return;
  dma_buf_sync sync{};
  sync.flags = (start ? DMA_BUF_SYNC_START : DMA_BUF_SYNC_END) | DMA_BUF_SYNC_READ;
  int r;
  do {
    r = ::ioctl(fd, DMA_BUF_IOCTL_SYNC, &sync);
  } while (r == -1 && errno == EINTR);
}

uint32_t LibcameraNv12Fourcc() { return libcamera::formats::NV12.fourcc(); }
uint32_t LibcameraR8Fourcc() { return libcamera::formats::R8.fourcc(); }

}  // namespace

Status LibcameraCameraOptions::Check() const {
  if (camera.empty()) return InvalidArgument("libcamera camera: 'camera' is empty (an id, or an index 0, 1, ...)");
  if (name.empty()) return InvalidArgument("libcamera camera " + camera + ": 'name' is empty");
  if (buffer_count < 2 || buffer_count > 32) {
    return InvalidArgument("libcamera camera " + camera + ": buffer_count " + std::to_string(buffer_count) +
                           " outside 2..32");
  }
  if (!std::isfinite(frame_rate_hz) || frame_rate_hz < 0 || frame_rate_hz > 1000) {
    return InvalidArgument("libcamera camera " + camera + ": frame_rate_hz " + FormatNumber(frame_rate_hz) +
                           " outside 0..1000");
  }
  return Status::Ok();
}

Result<std::vector<std::string>> ListLibcameraCameras() {
  IDI_ASSIGN_OR_RETURN(std::shared_ptr<libcamera::CameraManager> manager, LibcameraSharedManager());
  std::vector<std::string> ids;
  for (const auto& camera : manager->cameras()) ids.push_back(camera->id());
  return ids;
}

LibcameraCamera::LibcameraCamera(LibcameraCameraOptions options) : options_(std::move(options)) {}

LibcameraCamera::~LibcameraCamera() { Teardown(); }

std::string LibcameraCamera::Where() const {
  return "camera " + options_.name + " (libcamera " + (negotiated_.id.empty() ? options_.camera : negotiated_.id) + ")";
}

Status LibcameraCamera::Start(const hal::CameraSettings& settings) {
  IDI_RETURN_IF_ERROR(options_.Check());
  IDI_RETURN_IF_ERROR(hal::CheckCameraSettings(settings, Where()));
  Teardown();
  settings_ = settings;
  if (settings.exposure_us > 0) exposure_us_ = settings.exposure_us;
  negotiated_ = LibcameraNegotiated{};
  last_sequence_.reset();
  // libcamera counts from 0 in every start: a restarted camera's frames follow those delivered before.
  sequence_base_ = last_delivered_ ? *last_delivered_ + 1 : 0;
  Status s = FindCamera();
  if (s.ok()) s = Configure();
  if (s.ok()) s = AllocateAndMap();
  if (!s.ok()) {
    Teardown();
    return s;
  }

  // Exposure and gain go with start, so the first frame has them.
  auto controls = MakeExposureControls(exposure_us_.value_or(-1.0), settings_.gain_db);
  if (!controls.ok()) {
    Teardown();
    return controls.status();
  }
  libcamera::ControlList start_controls(camera_->controls());
  if (controls->ae_enable) start_controls.set(libcamera::controls::AeEnable, *controls->ae_enable);
  if (controls->exposure_time_us) start_controls.set(libcamera::controls::ExposureTime, *controls->exposure_time_us);
  if (controls->analogue_gain) start_controls.set(libcamera::controls::AnalogueGain, *controls->analogue_gain);
  if (options_.frame_rate_hz > 0) {
    if (camera_->controls().count(&libcamera::controls::FrameDurationLimits) == 0) {
      Teardown();
      return FailedPrecondition(Where() + ": frame_rate_hz is set but the camera has no frame duration control");
    }
    const auto frame_us = static_cast<int64_t>(std::llround(1e6 / options_.frame_rate_hz));
    const std::array<int64_t, 2> limits = {frame_us, frame_us};  // min = max: a fixed rate
    start_controls.set(libcamera::controls::FrameDurationLimits, libcamera::Span<const int64_t, 2>(limits));
  }

  camera_->requestCompleted.connect(this, &LibcameraCamera::OnRequestCompleted);
  camera_->disconnected.connect(this, &LibcameraCamera::OnDisconnected);
  const int r = camera_->start(&start_controls);
  if (r < 0) {
    Teardown();
    return DeviceError(Where() + ": start failed: " + LibcameraErrno(r));
  }
  started_ = true;
  for (const auto& request : requests_) {
    const int q = camera_->queueRequest(request.get());
    if (q < 0) {
      Teardown();
      return DeviceError(Where() + ": queueing a request failed: " + LibcameraErrno(q));
    }
  }
  return Status::Ok();
}

Status LibcameraCamera::FindCamera() {
  IDI_ASSIGN_OR_RETURN(manager_, LibcameraSharedManager());
  const std::vector<std::shared_ptr<libcamera::Camera>> cameras = manager_->cameras();
  if (cameras.empty()) {
    return NotFound(Where() + ": libcamera finds no cameras on this machine (is the sensor's driver loaded? " +
                    "`cam --list` shows what libcamera sees)");
  }
  camera_ = manager_->get(options_.camera);
  if (!camera_) {
    if (auto index = LibcameraIndex(options_.camera); index && *index < cameras.size()) camera_ = cameras[*index];
  }
  if (!camera_) {
    return NotFound(Where() +
                    ": libcamera has no camera with that id or index; available: " + LibcameraCameraList(cameras));
  }
  negotiated_.id = camera_->id();
  const int r = camera_->acquire();
  if (r < 0) {
    return DeviceError(Where() + ": cannot acquire it (" + LibcameraErrno(r) +
                       (r == -EBUSY ? "; in use by another program or camera object)" : ")"));
  }
  acquired_ = true;
  return Status::Ok();
}

Status LibcameraCamera::Configure() {
  std::unique_ptr<libcamera::CameraConfiguration> config =
      camera_->generateConfiguration({libcamera::StreamRole::Viewfinder});
  if (!config || config->size() != 1) return DeviceError(Where() + ": the camera offers no viewfinder stream");
  libcamera::StreamConfiguration& stream_config = config->at(0);
  std::vector<uint32_t> offered;
  for (const libcamera::PixelFormat& f : stream_config.formats().pixelformats()) {
    if (f.modifier() == 0) offered.push_back(f.fourcc());  // tiled or compressed layouts are not read
  }
  auto chosen = ChooseLibcameraFormat(offered, settings_.gray);
  if (!chosen.ok()) return chosen.status().WithContext(Where());
  const libcamera::PixelFormat format(*chosen);
  const libcamera::Size size(static_cast<unsigned>(settings_.width), static_cast<unsigned>(settings_.height));
  stream_config.pixelFormat = format;
  stream_config.size = size;
  stream_config.bufferCount = static_cast<unsigned>(options_.buffer_count);
  const libcamera::CameraConfiguration::Status validation = config->validate();
  if (validation == libcamera::CameraConfiguration::Invalid) {
    return InvalidArgument(Where() + ": the camera rejected the configuration " + size.toString() + "-" +
                           format.toString());
  }
  // The camera may adjust what it cannot do; a calibrated camera must not silently change resolution.
  if (stream_config.pixelFormat != format || stream_config.size != size) {
    return InvalidArgument(Where() + ": cannot capture " + size.toString() + " in " + format.toString() +
                           " (the camera offered " + stream_config.toString() +
                           "); sizes: " + LibcameraOfferedSizes(stream_config.formats(), format));
  }
  const int r = camera_->configure(config.get());
  if (r < 0)
    return DeviceError(Where() + ": configuring " + stream_config.toString() + " failed: " + LibcameraErrno(r));
  stream_ = stream_config.stream();
  IDI_ASSIGN_OR_RETURN(const LibcameraConversion conversion, LibcameraConversionFor(*chosen, settings_.gray));
  luma_plane_only_ = conversion.luma_plane_only;
  negotiated_.fourcc = *chosen;
  negotiated_.width = settings_.width;
  negotiated_.height = settings_.height;
  negotiated_.stride = stream_config.stride;
  negotiated_.buffers = static_cast<int>(stream_config.bufferCount);
  if (negotiated_.stride == 0) return DeviceError(Where() + ": the camera reports a stride of 0");
  return Status::Ok();
}

Status LibcameraCamera::AllocateAndMap() {
  allocator_ = std::make_unique<libcamera::FrameBufferAllocator>(camera_);
  const int n = allocator_->allocate(stream_);
  if (n < 0) return DeviceError(Where() + ": allocating frame buffers failed: " + LibcameraErrno(n));
  const auto& buffers = allocator_->buffers(stream_);
  if (buffers.size() < 2) {
    return DeviceError(Where() + ": libcamera allocated " + std::to_string(buffers.size()) + " buffers, need 2");
  }
  negotiated_.buffers = static_cast<int>(buffers.size());
  const std::size_t luma_bytes =
      static_cast<std::size_t>(negotiated_.stride) * static_cast<std::size_t>(negotiated_.height);
  for (std::size_t i = 0; i < buffers.size(); ++i) {
    libcamera::FrameBuffer* buffer = buffers[i].get();
    buffer->setCookie(i);
    const std::vector<libcamera::FrameBuffer::Plane>& planes = buffer->planes();
    if (planes.empty()) return DeviceError(Where() + ": a frame buffer has no planes");
    // Map the first plane's file once, over every plane it holds.
    const int fd = planes[0].fd.get();
    std::size_t map_length = 0;
    for (const auto& p : planes) {
      if (p.fd.get() == fd) map_length = std::max<std::size_t>(map_length, std::size_t{p.offset} + p.length);
    }
    void* start = ::mmap(nullptr, map_length, PROT_READ, MAP_SHARED, fd, 0);
    if (start == MAP_FAILED) return DeviceError(Where() + ": mmap of a frame buffer failed: " + std::strerror(errno));
    mappings_.push_back({start, map_length});
    BufferView view;
    view.fd = fd;
    view.first_plane = static_cast<const uint8_t*>(start) + planes[0].offset;
    view.length = planes[0].length;
    if (planes.size() >= 2 && planes[1].fd.get() == fd && planes[1].offset == planes[0].offset + luma_bytes) {
      view.chroma_follows_luma = true;
      view.length = luma_bytes + planes[1].length;
    }
    views_.push_back(view);
    std::unique_ptr<libcamera::Request> request = camera_->createRequest(i);
    if (!request) return DeviceError(Where() + ": creating a request failed");
    const int r = request->addBuffer(stream_, buffer);
    if (r < 0) return DeviceError(Where() + ": adding a buffer to a request failed: " + LibcameraErrno(r));
    requests_.push_back(std::move(request));
  }
  // Colour from NV12 reads both planes as one block.
  const bool needs_chroma = !luma_plane_only_ && negotiated_.fourcc == LibcameraNv12Fourcc();
  if (needs_chroma &&
      !std::all_of(views_.begin(), views_.end(), [](const BufferView& v) { return v.chroma_follows_luma; })) {
    return InvalidArgument(Where() + ": colour from NV12 needs the chroma plane right after the luma plane, and " +
                           "this camera's buffers are laid out otherwise; capture gray");
  }
  return Status::Ok();
}

Result<LibcameraCamera::ExposureControls> LibcameraCamera::MakeExposureControls(double exposure_us,
                                                                                double gain_db) const {
  namespace controls = libcamera::controls;
  const libcamera::ControlInfoMap& info = camera_->controls();
  ExposureControls c;
  if (exposure_us > 0) {
    const auto it = info.find(&controls::ExposureTime);
    if (it == info.end()) return FailedPrecondition(Where() + ": the camera has no exposure control (ExposureTime)");
    const double us = std::round(exposure_us);
    const libcamera::ControlInfo& limits = it->second;
    if (limits.min().type() == libcamera::ControlTypeInteger32 &&
        limits.max().type() == libcamera::ControlTypeInteger32 &&
        (us < limits.min().get<int32_t>() || us > limits.max().get<int32_t>())) {
      return OutOfRange(Where() + ": exposure " + FormatNumber(exposure_us) + " us outside the camera's " +
                        std::to_string(limits.min().get<int32_t>()) + ".." +
                        std::to_string(limits.max().get<int32_t>()) + " us");
    }
    if (us > std::numeric_limits<int32_t>::max()) return OutOfRange(Where() + ": exposure is too long");
    c.exposure_time_us = static_cast<int32_t>(us);
    if (info.count(&controls::AeEnable) != 0) c.ae_enable = false;
  } else if (exposure_us == 0 && info.count(&controls::AeEnable) != 0) {
    c.ae_enable = true;
  }
  if (gain_db != 0) {
    const auto it = info.find(&controls::AnalogueGain);
    if (it == info.end()) return FailedPrecondition(Where() + ": the camera has no gain control (AnalogueGain)");
    const double gain = std::pow(10.0, gain_db / 20.0);  // dB of amplitude -> a linear factor
    const libcamera::ControlInfo& limits = it->second;
    if (limits.min().type() == libcamera::ControlTypeFloat && limits.max().type() == libcamera::ControlTypeFloat &&
        (gain < limits.min().get<float>() || gain > limits.max().get<float>())) {
      return OutOfRange(Where() + ": gain " + FormatNumber(gain_db) + " dB (x" + FormatNumber(gain) +
                        ") outside the camera's x" + FormatNumber(limits.min().get<float>()) + "..x" +
                        FormatNumber(limits.max().get<float>()));
    }
    c.analogue_gain = static_cast<float>(gain);
  }
  return c;
}

Status LibcameraCamera::Stop() {
  Status s = Status::Ok();
  if (started_) {
    const int r = camera_->stop();  // cancels the requests in flight; they complete before it returns
    bool lost;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      lost = lost_;
    }
    if (r < 0 && !lost) s = DeviceError(Where() + ": stop failed: " + LibcameraErrno(r));
    started_ = false;
  }
  Teardown();
  return s;
}

void LibcameraCamera::Teardown() {
  if (started_) {
    (void)camera_->stop();  // fails only on a camera already gone
    started_ = false;
  }
  if (camera_) {
    camera_->requestCompleted.disconnect(this);
    camera_->disconnected.disconnect(this);
  }
  {
    std::lock_guard<std::mutex> lock(mutex_);
    completed_.clear();
    lost_ = false;
  }
  lost_reported_ = false;
  requests_.clear();  // before the buffers they point to
  views_.clear();
  for (const Mapping& m : mappings_) ::munmap(m.start, m.length);
  mappings_.clear();
  if (allocator_ && stream_ != nullptr) (void)allocator_->free(stream_);
  allocator_.reset();
  stream_ = nullptr;
  if (acquired_) (void)camera_->release();
  acquired_ = false;
  camera_.reset();
  manager_.reset();  // the last camera to let go stops the process's camera manager
  pending_controls_ = ExposureControls{};
}

void LibcameraCamera::OnRequestCompleted(libcamera::Request* request) {
  if (request->status() == libcamera::Request::RequestCancelled) return;  // Stop is under way
  {
    std::lock_guard<std::mutex> lock(mutex_);
    completed_.push_back(request);
  }
  completed_cv_.notify_one();
}

void LibcameraCamera::OnDisconnected() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    lost_ = true;
  }
  completed_cv_.notify_one();
}

Result<hal::Image> LibcameraCamera::Grab(std::chrono::milliseconds timeout) {
  if (!started_) return FailedPrecondition(Where() + ": Grab before Start");
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  for (;;) {
    libcamera::Request* request = nullptr;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      completed_cv_.wait_until(lock, deadline, [this] { return lost_ || !completed_.empty(); });
      if (lost_) {
        lock.unlock();
        if (!lost_reported_) ++counters_.device_errors;
        lost_reported_ = true;
        return DeviceError(Where() + ": the camera was disconnected; Stop and Start it again when it is back");
      }
      if (completed_.empty()) {
        return Timeout(Where() + ": no frame within " + std::to_string(timeout.count()) + " ms");
      }
      request = completed_.front();
      completed_.pop_front();
    }
    Result<hal::Image> image = ConvertRequest(request);
    IDI_RETURN_IF_ERROR(Requeue(request));
    if (!image.ok() && image.status().code() == StatusCode::kCancelled) continue;  // a failed frame, skipped
    return image;
  }
}

Result<hal::Image> LibcameraCamera::ConvertRequest(libcamera::Request* request) {
  const int64_t now_ns = hal::MonotonicClock().NowNs();
  const libcamera::FrameBuffer* buffer = request->findBuffer(stream_);
  if (buffer == nullptr || buffer->cookie() >= views_.size()) {
    return DeviceError(Where() + ": a completed request holds no buffer of the stream");
  }
  const libcamera::FrameMetadata& frame = buffer->metadata();
  if (last_sequence_ && frame.sequence > *last_sequence_ + 1) counters_.dropped += frame.sequence - *last_sequence_ - 1;
  last_sequence_ = frame.sequence;
  if (frame.status != libcamera::FrameMetadata::FrameSuccess) {
    ++counters_.corrupted;
    return Cancelled("frame " + std::to_string(frame.sequence) + " failed");
  }
  const BufferView& view = views_[buffer->cookie()];
  std::size_t used = view.length;
  const auto planes = frame.planes();
  if (!planes.empty() && planes[0].bytesused > 0) {
    used = std::min<std::size_t>(view.length, planes[0].bytesused);
    if (view.chroma_follows_luma && !luma_plane_only_ && planes.size() >= 2) {
      used = std::min<std::size_t>(
          view.length,
          std::size_t{negotiated_.stride} * static_cast<std::size_t>(negotiated_.height) + planes[1].bytesused);
    }
  }
  const LibcameraFrameLayout layout{luma_plane_only_ ? LibcameraR8Fourcc() : negotiated_.fourcc,
                                    negotiated_.width,
                                    negotiated_.height,
                                    negotiated_.stride};
  LibcameraDmaSync(view.fd, true);
  Result<cv::Mat> pixels = ConvertLibcameraFrame(layout, view.first_plane, used, settings_.gray);
  LibcameraDmaSync(view.fd, false);
  if (!pixels.ok()) return pixels.status().WithContext(Where() + " frame " + std::to_string(frame.sequence));

  // hal::Image wants the middle of the exposure on the monotonic clock. SensorTimestamp is the start
  // of the first row's exposure, taken from the V4L2 buffer's CLOCK_MONOTONIC stamp by the pipelines
  // (libcamera documents CLOCK_BOOTTIME, which differs only after a suspend).
  const libcamera::ControlList& metadata = request->metadata();
  int64_t t_ns = now_ns;
  if (auto sensor = metadata.get(libcamera::controls::SensorTimestamp); sensor && *sensor > 0) {
    t_ns = *sensor;
  } else if (frame.timestamp > 0) {
    t_ns = static_cast<int64_t>(frame.timestamp);
  }
  if (auto exposure = metadata.get(libcamera::controls::ExposureTime); exposure && *exposure > 0) {
    t_ns += int64_t{*exposure} * 500;  // + exposure / 2
  } else if (exposure_us_ && *exposure_us_ > 0) {
    t_ns += static_cast<int64_t>(*exposure_us_ * 500.0);
  }
  hal::Image image;
  image.timestamp_ns = t_ns;
  image.sequence = sequence_base_ + frame.sequence;
  last_delivered_ = image.sequence;
  image.camera = options_.name;
  image.pixels = std::move(pixels).value();
  ++counters_.frames;
  return image;
}

Status LibcameraCamera::Requeue(libcamera::Request* request) {
  request->reuse(libcamera::Request::ReuseBuffers);
  libcamera::ControlList& controls = request->controls();
  if (pending_controls_.ae_enable) controls.set(libcamera::controls::AeEnable, *pending_controls_.ae_enable);
  if (pending_controls_.exposure_time_us) {
    controls.set(libcamera::controls::ExposureTime, *pending_controls_.exposure_time_us);
  }
  if (pending_controls_.analogue_gain)
    controls.set(libcamera::controls::AnalogueGain, *pending_controls_.analogue_gain);
  pending_controls_ = ExposureControls{};
  const int r = camera_->queueRequest(request);
  if (r < 0) return DeviceError(Where() + ": queueing a request again failed: " + LibcameraErrno(r));
  return Status::Ok();
}

Status LibcameraCamera::SetExposure(double exposure_us) {
  if (!std::isfinite(exposure_us) || exposure_us < 0) {
    return InvalidArgument(Where() + ": exposure " + FormatNumber(exposure_us) + " us is invalid");
  }
  if (!started_) {
    exposure_us_ = exposure_us;  // applied at Start
    return Status::Ok();
  }
  IDI_ASSIGN_OR_RETURN(ExposureControls controls, MakeExposureControls(exposure_us, 0.0));
  exposure_us_ = exposure_us;
  if (controls.ae_enable) pending_controls_.ae_enable = controls.ae_enable;
  if (controls.exposure_time_us) pending_controls_.exposure_time_us = controls.exposure_time_us;
  return Status::Ok();
}

}  // namespace idi::drivers
