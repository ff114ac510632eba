// A serial port through termios: raw 8N1 without flow control (the framing of the PTU-D46 and the
// Barrett BH8 hand, ../shared/reference/device-protocols.md §2.1, §3), reads with timeouts, and
// line/delimiter framing on top of an internal buffer. Also wraps an already open descriptor (a
// pseudo-terminal master in the device emulators) so both ends share one implementation.
//
// The same framing serves stream sockets (FromFd on a connected TCP socket): writes then use
// MSG_NOSIGNAL, and a closed peer reads as a hang-up (IoError).
//
// Every error names the port and what failed. Not thread-safe: one owner per port.
#pragma once

#include <chrono>
#include <cstddef>
#include <memory>
#include <string>
#include <string_view>

#include "shared/util/status.h"

namespace idi::drivers {

struct SerialOptions {
  int baud = 9600;
  // A line (or delimited block) longer than this without its terminator is garbage: the reader
  // drops it and reports a DeviceError rather than growing without bound.
  std::size_t max_line_bytes = 4096;
  // Ask the kernel for exclusive access (TIOCEXCL) so a second program cannot open the port.
  bool exclusive = true;
  Status Check() const;
};

// The termios speed constant for a baud rate, or InvalidArgument for rates termios lacks.
Result<unsigned int> BaudToTermiosSpeed(int baud);

class SerialPort {
 public:
  // Opens `path` (e.g. /dev/ttyUSB0 or a pty slave), sets raw 8N1 at options.baud and discards stale
  // input. NotFound when the device does not exist, IoError when it cannot be opened or configured.
  static Result<std::unique_ptr<SerialPort>> Open(const std::string& path, const SerialOptions& options);
  // Takes ownership of an open descriptor without changing its termios settings; `name` is used in
  // messages. The descriptor is made non-blocking.
  static std::unique_ptr<SerialPort> FromFd(int fd, std::string name, const SerialOptions& options = {});

  SerialPort(const SerialPort&) = delete;
  SerialPort& operator=(const SerialPort&) = delete;
  ~SerialPort();

  const std::string& name() const { return name_; }
  int fd() const { return fd_; }

  // Writes all bytes within `timeout`; Timeout when the device would not take them, IoError on failure.
  Status Write(std::string_view bytes, std::chrono::milliseconds timeout);

  // Whatever arrives within `timeout` (buffered bytes first); at least one byte, else Timeout.
  Result<std::string> ReadSome(std::chrono::milliseconds timeout);
  // The next line ended by CR or LF, without its terminator; empty lines are skipped. Timeout when no
  // complete line arrives in time (the partial line stays buffered for the next call). A line longer
  // than max_line_bytes is DeviceError, and dropped whole: when it overflowed before its end arrived,
  // the bytes up to that end are dropped too, so its tail is never returned as a line.
  Result<std::string> ReadLine(std::chrono::milliseconds timeout);
  // Everything up to `delimiter` (removed from the stream, not returned), e.g. the BH8's "=> " prompt.
  // A block longer than max_line_bytes is DeviceError and dropped whole, as in ReadLine.
  Result<std::string> ReadUntil(std::string_view delimiter, std::chrono::milliseconds timeout);

  // Drops buffered input, ours and the kernel's. Returns the number of bytes dropped from our buffer (and,
  // on a socket or pipe, those read from the kernel's; a terminal's are flushed uncounted).
  std::size_t DiscardInput();
  // Reads and drops bytes until the line has been quiet for `quiet` (or `max_wait` passed): clears
  // power-up chatter and late replies. Returns what was dropped.
  std::string DrainUntilQuiet(std::chrono::milliseconds quiet, std::chrono::milliseconds max_wait);
  // Bytes received but not yet returned.
  std::size_t buffered() const { return buffer_.size(); }

 private:
  SerialPort(int fd, std::string name, const SerialOptions& options);
  // Waits up to `timeout_ms` for input and appends it to buffer_. Ok(false) on timeout.
  Result<bool> FillBuffer(int timeout_ms);

  int fd_ = -1;
  bool is_socket_ = false;
  std::string name_;
  SerialOptions options_;
  std::string buffer_;
  // After an overflow, the rest of the overlong line (or block) is dropped up to its end: CR/LF when
  // skip_to_line_end_, else skip_to_ (a ReadUntil delimiter) when not empty.
  bool skip_to_line_end_ = false;
  std::string skip_to_;
};

}  // namespace idi::drivers
