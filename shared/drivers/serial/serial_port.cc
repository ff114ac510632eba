#include "shared/drivers/serial/serial_port.h"

#include <fcntl.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <termios.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <utility>

namespace idi::drivers {
namespace {

using SerialClock = std::chrono::steady_clock;

std::string SerialErrnoText(int err) { return std::string(std::strerror(err)); }

// Milliseconds left until `deadline`, clamped to [0, INT_MAX].
int SerialMsLeft(SerialClock::time_point deadline) {
  const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - SerialClock::now()).count();
  return static_cast<int>(std::clamp<long long>(left, 0, 1'000'000'000));
}

}  // namespace

Status SerialOptions::Check() const {
  if (!BaudToTermiosSpeed(baud).ok()) {
    return InvalidArgument("serial: unsupported baud rate " + std::to_string(baud));
  }
  if (max_line_bytes < 16) {
    return InvalidArgument("serial: max_line_bytes must be at least 16, got " + std::to_string(max_line_bytes));
  }
  return Status::Ok();
}

Result<unsigned int> BaudToTermiosSpeed(int baud) {
  switch (baud) {
    case 600: return static_cast<unsigned int>(B600);
    case 1200: return static_cast<unsigned int>(B1200);
    case 2400: return static_cast<unsigned int>(B2400);
    case 4800: return static_cast<unsigned int>(B4800);
    case 9600: return static_cast<unsigned int>(B9600);
    case 19200: return static_cast<unsigned int>(B19200);
    case 38400: return static_cast<unsigned int>(B38400);
    case 57600: return static_cast<unsigned int>(B57600);
    case 115200: return static_cast<unsigned int>(B115200);
    case 230400: return static_cast<unsigned int>(B230400);
    default: break;
  }
  return InvalidArgument("unsupported baud rate " + std::to_string(baud) +
                         " (600, 1200, 2400, 4800, 9600, 19200, 38400, 57600, 115200, 230400)");
}

Result<std::unique_ptr<SerialPort>> SerialPort::Open(const std::string& path, const SerialOptions& options) {
  IDI_RETURN_IF_ERROR(options.Check().WithContext(path));
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) {
    const int err = errno;
    if (err == ENOENT) {
      return NotFound("serial port " + path + " does not exist");
    }
    return IoError("serial port " + path + ": " + SerialErrnoText(err));
  }
  const int fd = ::open(path.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) {
    const int err = errno;
    return IoError("cannot open serial port " + path + ": " + SerialErrnoText(err));
  }
  // From here on the port owns fd and closes it on every early return.
  std::unique_ptr<SerialPort> port(new SerialPort(fd, path, options));
  if (!::isatty(fd)) {
    return InvalidArgument(path + " is not a serial device (not a tty)");
  }
  if (options.exclusive && ::ioctl(fd, TIOCEXCL) != 0) {
    const int err = errno;
    return IoError("serial port " + path + ": cannot get exclusive access: " + SerialErrnoText(err));
  }
  termios tio{};
  if (::tcgetattr(fd, &tio) != 0) {
    const int err = errno;
    return IoError("serial port " + path + ": tcgetattr: " + SerialErrnoText(err));
  }
  ::cfmakeraw(&tio);
  tio.c_cflag &= ~static_cast<tcflag_t>(CSIZE | PARENB | CSTOPB | CRTSCTS);
  tio.c_cflag |= CS8 | CLOCAL | CREAD;
  tio.c_iflag &= ~static_cast<tcflag_t>(IXON | IXOFF | IXANY);
  tio.c_cc[VMIN] = 0;
  tio.c_cc[VTIME] = 0;
  const auto speed = static_cast<speed_t>(BaudToTermiosSpeed(options.baud).value());
  if (::cfsetispeed(&tio, speed) != 0 || ::cfsetospeed(&tio, speed) != 0) {
    const int err = errno;
    return IoError("serial port " + path + ": cannot set " + std::to_string(options.baud) +
                   " baud: " + SerialErrnoText(err));
  }
  if (::tcsetattr(fd, TCSANOW, &tio) != 0) {
    const int err = errno;
    return IoError("serial port " + path + ": tcsetattr: " + SerialErrnoText(err));
  }
  ::tcflush(fd, TCIOFLUSH);
  return port;
}

std::unique_ptr<SerialPort> SerialPort::FromFd(int fd, std::string name, const SerialOptions& options) {
  const int flags = ::fcntl(fd, F_GETFL);
  if (flags >= 0) {
    ::fcntl(fd, F_SETFL, flags | O_NONBLOCK);
  }
  return std::unique_ptr<SerialPort>(new SerialPort(fd, std::move(name), options));
}

SerialPort::SerialPort(int fd, std::string name, const SerialOptions& options)
    : fd_(fd), name_(std::move(name)), options_(options) {
  struct stat st {};
  is_socket_ = ::fstat(fd_, &st) == 0 && S_ISSOCK(st.st_mode);
}

SerialPort::~SerialPort() {
  if (fd_ >= 0) {
    ::close(fd_);
  }
}

Status SerialPort::Write(std::string_view bytes, std::chrono::milliseconds timeout) {
  const auto deadline = SerialClock::now() + timeout;
  std::size_t done = 0;
  while (done < bytes.size()) {
    // On a socket, send without SIGPIPE: a peer that went away is an IoError, not a dead process.
    const ssize_t n = is_socket_ ? ::send(fd_, bytes.data() + done, bytes.size() - done, MSG_NOSIGNAL)
                                 : ::write(fd_, bytes.data() + done, bytes.size() - done);
    if (n > 0) {
      done += static_cast<std::size_t>(n);
      continue;
    }
    const int err = errno;
    if (n < 0 && err == EINTR) {
      continue;
    }
    if (n < 0 && err != EAGAIN && err != EWOULDBLOCK) {
      return IoError(name_ + ": write failed: " + SerialErrnoText(err));
    }
    pollfd pfd{fd_, POLLOUT, 0};
    const int ready = ::poll(&pfd, 1, SerialMsLeft(deadline));
    if (ready == 0) {
      return Timeout(name_ + ": write of " + std::to_string(bytes.size()) + " bytes timed out after " +
                     std::to_string(done) + " bytes");
    }
    if (ready < 0 && errno != EINTR) {
      const int perr = errno;
      return IoError(name_ + ": poll for write failed: " + SerialErrnoText(perr));
    }
    if (ready > 0 && (pfd.revents & (POLLERR | POLLNVAL)) != 0) {
      return IoError(name_ + ": device error while writing");
    }
  }
  return Status::Ok();
}

Result<bool> SerialPort::FillBuffer(int timeout_ms) {
  pollfd pfd{fd_, POLLIN, 0};
  int ready = 0;
  do {
    ready = ::poll(&pfd, 1, timeout_ms);
  } while (ready < 0 && errno == EINTR);
  if (ready < 0) {
    const int err = errno;
    return IoError(name_ + ": poll failed: " + SerialErrnoText(err));
  }
  if (ready == 0) {
    return false;
  }
  if ((pfd.revents & POLLNVAL) != 0) {
    return IoError(name_ + ": port is not open");
  }
  char chunk[512];
  const ssize_t n = ::read(fd_, chunk, sizeof(chunk));
  if (n > 0) {
    buffer_.append(chunk, static_cast<std::size_t>(n));
    return true;
  }
  if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR)) {
    return false;
  }
  if (n < 0) {
    const int err = errno;
    return IoError(name_ + ": read failed (device unplugged or hung up?): " + SerialErrnoText(err));
  }
  // n == 0 after POLLIN/POLLHUP: the other end is gone.
  return IoError(name_ + ": device hung up");
}

Result<std::string> SerialPort::ReadSome(std::chrono::milliseconds timeout) {
  const auto deadline = SerialClock::now() + timeout;
  while (buffer_.empty()) {
    IDI_ASSIGN_OR_RETURN(const bool got, FillBuffer(SerialMsLeft(deadline)));
    if (!got && SerialClock::now() >= deadline) {
      return Timeout(name_ + ": no data within " + std::to_string(timeout.count()) + " ms");
    }
  }
  return std::exchange(buffer_, std::string());
}

Result<std::string> SerialPort::ReadLine(std::chrono::milliseconds timeout) {
  const auto deadline = SerialClock::now() + timeout;
  while (true) {
    if (skip_to_line_end_) {
      // The tail of a line that overflowed: dropped up to its end.
      const std::size_t end = buffer_.find_first_of("\r\n");
      if (end == std::string::npos) {
        buffer_.clear();
      } else {
        buffer_.erase(0, end);
        skip_to_line_end_ = false;
      }
    }
    if (!skip_to_line_end_) {
      // Skip terminators left from a previous line (CR LF, or blank lines).
      const std::size_t start = buffer_.find_first_not_of("\r\n");
      if (start == std::string::npos) {
        buffer_.clear();
      } else if (start > 0) {
        buffer_.erase(0, start);
      }
      const std::size_t end = buffer_.find_first_of("\r\n");
      if (end != std::string::npos && end > options_.max_line_bytes) {
        buffer_.erase(0, end + 1);
        return DeviceError(name_ + ": a line of " + std::to_string(end) + " bytes (more than " +
                           std::to_string(options_.max_line_bytes) + "; garbage?); dropped");
      }
      if (end != std::string::npos) {
        std::string line = buffer_.substr(0, end);
        buffer_.erase(0, end + 1);
        return line;
      }
      if (buffer_.size() > options_.max_line_bytes) {
        const std::size_t dropped = buffer_.size();
        buffer_.clear();
        skip_to_line_end_ = true;
        return DeviceError(name_ + ": " + std::to_string(dropped) +
                           " bytes without a line end (garbage?); dropped, with the rest of that line");
      }
    }
    IDI_ASSIGN_OR_RETURN(const bool got, FillBuffer(SerialMsLeft(deadline)));
    if (!got && SerialClock::now() >= deadline) {
      // A line that stayed quiet this long has ended: what comes next is a new line, not its tail.
      if (std::exchange(skip_to_line_end_, false)) buffer_.clear();
      return Timeout(name_ + ": no complete line within " + std::to_string(timeout.count()) + " ms" +
                     (buffer_.empty() ? std::string() : " (partial: " + std::to_string(buffer_.size()) + " bytes)"));
    }
  }
}

Result<std::string> SerialPort::ReadUntil(std::string_view delimiter, std::chrono::milliseconds timeout) {
  IDI_CHECK(!delimiter.empty(), "ReadUntil needs a delimiter");
  const auto deadline = SerialClock::now() + timeout;
  while (true) {
    if (!skip_to_.empty()) {
      // The rest of a block that overflowed, up to and with its delimiter (a delimiter split across
      // reads keeps its first bytes buffered).
      const std::size_t pos = buffer_.find(skip_to_);
      if (pos == std::string::npos) {
        const std::size_t keep = std::min(buffer_.size(), skip_to_.size() - 1);
        buffer_.erase(0, buffer_.size() - keep);
      } else {
        buffer_.erase(0, pos + skip_to_.size());
        skip_to_.clear();
      }
    }
    if (skip_to_.empty()) {
      const std::size_t pos = buffer_.find(delimiter);
      if (pos != std::string::npos && pos > options_.max_line_bytes) {
        buffer_.erase(0, pos + delimiter.size());
        return DeviceError(name_ + ": a block of " + std::to_string(pos) + " bytes before the delimiter (more than " +
                           std::to_string(options_.max_line_bytes) + "; garbage?); dropped");
      }
      if (pos != std::string::npos) {
        std::string block = buffer_.substr(0, pos);
        buffer_.erase(0, pos + delimiter.size());
        return block;
      }
      if (buffer_.size() > options_.max_line_bytes + delimiter.size()) {
        // Kept: the last bytes, which may be the start of the delimiter.
        const std::size_t keep = delimiter.size() - 1;
        const std::size_t dropped = buffer_.size() - keep;
        buffer_.erase(0, dropped);
        skip_to_ = std::string(delimiter);
        return DeviceError(name_ + ": " + std::to_string(dropped) +
                           " bytes without the delimiter (garbage?); dropped, with the rest of that block");
      }
    }
    IDI_ASSIGN_OR_RETURN(const bool got, FillBuffer(SerialMsLeft(deadline)));
    if (!got && SerialClock::now() >= deadline) {
      if (!skip_to_.empty()) {  // as in ReadLine: after the quiet, a new block
        skip_to_.clear();
        buffer_.clear();
      }
      return Timeout(name_ + ": delimiter not seen within " + std::to_string(timeout.count()) + " ms");
    }
  }
}

std::size_t SerialPort::DiscardInput() {
  std::size_t dropped = buffer_.size();
  buffer_.clear();
  skip_to_line_end_ = false;
  skip_to_.clear();
  if (::isatty(fd_)) {
    ::tcflush(fd_, TCIFLUSH);
  } else {
    // A socket or pipe has no tcflush: what the kernel holds is read and dropped (a late reply would
    // otherwise be taken for the answer to the next command).
    for (int k = 0; k < 4096; ++k) {
      auto got = FillBuffer(0);
      if (!got.ok() || !got.value()) break;
      dropped += buffer_.size();
      buffer_.clear();
    }
  }
  return dropped;
}

std::string SerialPort::DrainUntilQuiet(std::chrono::milliseconds quiet, std::chrono::milliseconds max_wait) {
  const auto deadline = SerialClock::now() + max_wait;
  std::string dropped = std::exchange(buffer_, std::string());
  skip_to_line_end_ = false;  // whatever arrives after the quiet is a fresh start
  skip_to_.clear();
  while (SerialClock::now() < deadline) {
    const int wait_ms = std::min(static_cast<int>(quiet.count()), SerialMsLeft(deadline));
    auto got = FillBuffer(wait_ms);
    if (!got.ok() || !got.value()) {
      break;
    }
    dropped += std::exchange(buffer_, std::string());
  }
  return dropped;
}

}  // namespace idi::drivers
