// CAN logs in can-utils' `candump -l` format, the one `canplayer` replays (DESIGN.md §6):
//
//   (1234567890.123456) can0 413#0011223344556677
//
// One frame per line: the timestamp in seconds with six decimals, the interface name, then the frame
// as `<id>#<data>`. Standard 11-bit ids are written with 3 hex digits, extended 29-bit ids with 8;
// error frames carry CAN_ERR_FLAG (0x20000000) in an 8-digit id; remote frames are `<id>#R` with an
// optional length digit. Data bytes are two hex digits each (readers also accept '.' between bytes).
// Lines that do not start with '(' are comments, as canplayer treats them. `candump -x` appends a
// direction mark (" R" received, " T" transmitted); canplayer ignores it and so may we.
#pragma once

#include <cstdint>
#include <cstdio>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "shared/hal/can_bus.h"
#include "shared/util/status.h"

namespace idi::replay {

inline constexpr uint32_t kCandumpErrFlag = 0x20000000U;  // CAN_ERR_FLAG in a printed id

enum class CanDirection { kUnknown, kReceived, kTransmitted };

struct CandumpRecord {
  std::string interface;  // "can0"
  hal::CanFrame frame;    // timestamp_ns is the log's time
  CanDirection direction = CanDirection::kUnknown;
  int line = 0;  // 1-based line number in the source, for messages
};

// `<id>#<data>` for a frame ("413#0011223344556677", "12345678#", "20000040#0000000000000000").
std::string FormatCanFrameText(const hal::CanFrame& frame);

// One log line without the newline. `direction` other than kUnknown appends " R" or " T".
// The timestamp must not be negative (checked by the writer).
std::string FormatCandumpLine(const hal::CanFrame& frame, std::string_view interface,
                              CanDirection direction = CanDirection::kUnknown);

// Parses `<id>#<data>`; ParseError saying what is wrong (bad id length, odd number of hex digits,
// more than 8 bytes, CAN FD frames, which this project does not use).
Result<hal::CanFrame> ParseCanFrameText(std::string_view text);

// Parses one line (comments are not accepted here: the caller skips them). Errors name `where`.
Result<CandumpRecord> ParseCandumpLine(std::string_view line, std::string_view where = "candump line");

// Parses a whole log: comment and blank lines are skipped, any malformed frame line is an error
// naming `source_name` and the line number. A last frame line without its newline is one the writer
// was stopped in the middle of (a power cut on the vehicle; candump and CandumpWriter end every line):
// it is dropped even when it parses, since a line cut after an even number of data digits reads as a
// shorter frame; the log up to it is kept, and the dropped text goes to `torn_last_line` and its line
// number to `torn_line_no` when given (0 and empty when there is none).
Result<std::vector<CandumpRecord>> ParseCandumpText(std::string_view text,
                                                    std::string_view source_name,
                                                    std::string* torn_last_line = nullptr,
                                                    int* torn_line_no = nullptr);
Result<std::vector<CandumpRecord>> ReadCandumpFile(const std::string& path,
                                                   std::string* torn_last_line = nullptr,
                                                   int* torn_line_no = nullptr);

struct CandumpWriterOptions {
  std::string interface = "can0";
  // Added to each frame's timestamp when written; candump writes wall-clock time, so a driver on
  // the monotonic clock can pass (realtime - monotonic) here. The simulation leaves it at zero.
  int64_t timestamp_offset_ns = 0;
  bool mark_direction = false;  // append " R" / " T" as `candump -x` does
  bool flush_each_line = false;
  bool append = false;  // append to an existing file instead of truncating it

  Status Check() const;
};

// Writes a log as frames come. Not a results file, so it is streamed rather than written
// atomically: a crash leaves every complete line that was flushed.
class CandumpWriter {
 public:
  static Result<std::unique_ptr<CandumpWriter>> Open(const std::string& path, const CandumpWriterOptions& options = {});
  ~CandumpWriter();
  CandumpWriter(const CandumpWriter&) = delete;
  CandumpWriter& operator=(const CandumpWriter&) = delete;

  Status Write(const hal::CanFrame& frame, CanDirection direction = CanDirection::kUnknown);
  Status Flush();
  Status Close();

  const std::string& path() const { return path_; }
  uint64_t lines_written() const { return lines_written_; }

 private:
  CandumpWriter(std::string path, std::FILE* file, CandumpWriterOptions options)
      : path_(std::move(path)), file_(file), options_(std::move(options)) {}

  std::string path_;
  std::FILE* file_ = nullptr;
  CandumpWriterOptions options_;
  uint64_t lines_written_ = 0;
};

}  // namespace idi::replay
