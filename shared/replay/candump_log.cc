#include "shared/replay/candump_log.h"

#include <cerrno>
#include <cinttypes>
#include <cstring>
#include <utility>

#include "shared/util/atomic_file.h"

namespace idi::replay {
namespace {

constexpr char kHexDigitsUpper[] = "0123456789ABCDEF";
constexpr std::size_t kMaxInterfaceNameLength = 15;  // IFNAMSIZ - 1

int CandumpHexValue(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

void AppendHex(std::string* out, uint32_t value, int digits) {
  for (int i = digits - 1; i >= 0; --i) {
    out->push_back(kHexDigitsUpper[(value >> (4 * i)) & 0xF]);
  }
}

std::string_view TrimCandump(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r' || s.back() == '\n')) {
    s.remove_suffix(1);
  }
  return s;
}

// Splits at runs of blanks.
std::vector<std::string_view> SplitFields(std::string_view s) {
  std::vector<std::string_view> out;
  std::size_t i = 0;
  while (i < s.size()) {
    while (i < s.size() && (s[i] == ' ' || s[i] == '\t')) ++i;
    const std::size_t start = i;
    while (i < s.size() && s[i] != ' ' && s[i] != '\t') ++i;
    if (i > start) out.push_back(s.substr(start, i - start));
  }
  return out;
}

bool ParseDecimal(std::string_view digits, int64_t* value) {
  if (digits.empty() || digits.size() > 18) return false;
  int64_t v = 0;
  for (char c : digits) {
    if (c < '0' || c > '9') return false;
    v = v * 10 + (c - '0');
  }
  *value = v;
  return true;
}

}  // namespace

std::string FormatCanFrameText(const hal::CanFrame& frame) {
  std::string out;
  out.reserve(8 + 1 + 16);
  if (frame.error) {
    AppendHex(&out, kCandumpErrFlag | (frame.id & 0x1FFFFFFFU), 8);
  } else if (frame.extended) {
    AppendHex(&out, frame.id & 0x1FFFFFFFU, 8);
  } else {
    AppendHex(&out, frame.id & 0x7FFU, 3);
  }
  out.push_back('#');
  const uint8_t len = frame.dlc > 8 ? uint8_t{8} : frame.dlc;
  if (frame.rtr && !frame.error) {
    out.push_back('R');
    if (len > 0) out.push_back(static_cast<char>('0' + len));
    return out;
  }
  for (uint8_t i = 0; i < len; ++i) AppendHex(&out, frame.data[i], 2);
  return out;
}

std::string FormatCandumpLine(const hal::CanFrame& frame, std::string_view interface, CanDirection direction) {
  const int64_t t = frame.timestamp_ns < 0 ? 0 : frame.timestamp_ns;
  const int64_t sec = t / 1'000'000'000;
  const int64_t usec = (t % 1'000'000'000) / 1000;
  char stamp[48];
  std::snprintf(stamp, sizeof(stamp), "(%010" PRId64 ".%06" PRId64 ") ", sec, usec);
  std::string line(stamp);
  line.append(interface);
  line.push_back(' ');
  line += FormatCanFrameText(frame);
  if (direction == CanDirection::kReceived) line += " R";
  if (direction == CanDirection::kTransmitted) line += " T";
  return line;
}

Result<hal::CanFrame> ParseCanFrameText(std::string_view text) {
  const std::size_t hash = text.find('#');
  if (hash == std::string_view::npos) {
    return ParseError("CAN frame '" + std::string(text) + "': no '#' between id and data");
  }
  const std::string_view id_text = text.substr(0, hash);
  std::string_view data_text = text.substr(hash + 1);
  if (!data_text.empty() && data_text.front() == '#') {
    return ParseError("CAN frame '" + std::string(text) + "': CAN FD frames ('##') are not supported");
  }
  if (id_text.size() != 3 && id_text.size() != 8) {
    return ParseError("CAN frame '" + std::string(text) + "': the id must have 3 (standard) or 8 (extended) hex digits, got " +
                      std::to_string(id_text.size()));
  }
  uint32_t id = 0;
  for (char c : id_text) {
    const int v = CandumpHexValue(c);
    if (v < 0) return ParseError("CAN frame '" + std::string(text) + "': '" + std::string(id_text) + "' is not a hex id");
    id = (id << 4) | static_cast<uint32_t>(v);
  }
  hal::CanFrame frame;
  if (id_text.size() == 3) {
    if (id > 0x7FF) {
      return ParseError("CAN frame '" + std::string(text) + "': standard id 0x" + std::string(id_text) + " exceeds 0x7FF");
    }
    frame.id = id;
  } else if (id & kCandumpErrFlag) {
    frame.error = true;
    frame.id = id & 0x1FFFFFFFU;
  } else if (id > 0x1FFFFFFFU) {
    return ParseError("CAN frame '" + std::string(text) + "': extended id exceeds 29 bits");
  } else {
    frame.extended = true;
    frame.id = id;
  }
  if (!data_text.empty() && (data_text.front() == 'R' || data_text.front() == 'r')) {
    frame.rtr = true;
    data_text.remove_prefix(1);
    if (!data_text.empty()) {
      const int len = data_text.front() - '0';
      if (data_text.size() != 1 || len < 0 || len > 8) {
        return ParseError("CAN frame '" + std::string(text) + "': a remote frame takes one length digit 0..8");
      }
      frame.dlc = static_cast<uint8_t>(len);
    }
    return frame;
  }
  uint8_t n = 0;
  std::size_t i = 0;
  while (i < data_text.size()) {
    if (data_text[i] == '.') {
      ++i;
      continue;
    }
    if (data_text[i] == '_') {
      return ParseError("CAN frame '" + std::string(text) + "': raw DLC suffixes ('_') are not supported");
    }
    if (i + 1 >= data_text.size()) {
      return ParseError("CAN frame '" + std::string(text) + "': odd number of hex digits in the data");
    }
    const int hi = CandumpHexValue(data_text[i]);
    const int lo = CandumpHexValue(data_text[i + 1]);
    if (hi < 0 || lo < 0) {
      return ParseError("CAN frame '" + std::string(text) + "': '" + std::string(data_text.substr(i, 2)) + "' is not a hex byte");
    }
    if (n >= 8) return ParseError("CAN frame '" + std::string(text) + "': more than 8 data bytes");
    frame.data[n++] = static_cast<uint8_t>(hi * 16 + lo);
    i += 2;
  }
  frame.dlc = n;
  return frame;
}

Result<CandumpRecord> ParseCandumpLine(std::string_view line, std::string_view where) {
  const std::string_view s = TrimCandump(line);
  auto fail = [&](const std::string& what) {
    return ParseError(std::string(where) + ": " + what + " (line '" + std::string(s.substr(0, 80)) + "')");
  };
  const std::vector<std::string_view> fields = SplitFields(s);
  if (fields.size() < 3 || fields.size() > 4) {
    return fail("expected '(seconds.microseconds) interface id#data'");
  }
  const std::string_view stamp = fields[0];
  if (stamp.size() < 4 || stamp.front() != '(' || stamp.back() != ')') {
    return fail("the timestamp must be '(seconds.microseconds)'");
  }
  const std::string_view inner = stamp.substr(1, stamp.size() - 2);
  const std::size_t dot = inner.find('.');
  int64_t sec = 0, usec = 0;
  if (dot == std::string_view::npos || !ParseDecimal(inner.substr(0, dot), &sec) ||
      inner.size() - dot - 1 != 6 || !ParseDecimal(inner.substr(dot + 1), &usec)) {
    return fail("the timestamp must be '(seconds.microseconds)' with six digits after the point");
  }
  if (sec > 9'000'000'000LL) return fail("timestamp out of range");
  CandumpRecord record;
  record.interface = std::string(fields[1]);
  if (record.interface.size() > kMaxInterfaceNameLength) {
    return fail("interface name '" + record.interface + "' is longer than 15 characters");
  }
  Result<hal::CanFrame> frame = ParseCanFrameText(fields[2]);
  if (!frame.ok()) return fail(frame.status().message());
  record.frame = *frame;
  record.frame.timestamp_ns = sec * 1'000'000'000 + usec * 1000;
  if (fields.size() == 4) {
    if (fields[3] == "R") {
      record.direction = CanDirection::kReceived;
    } else if (fields[3] == "T") {
      record.direction = CanDirection::kTransmitted;
    } else {
      return fail("unexpected trailing field '" + std::string(fields[3]) + "' (only R or T)");
    }
  }
  return record;
}

Result<std::vector<CandumpRecord>> ParseCandumpText(std::string_view text,
                                                    std::string_view source_name,
                                                    std::string* torn_last_line,
                                                    int* torn_line_no) {
  if (torn_last_line != nullptr) torn_last_line->clear();
  if (torn_line_no != nullptr) *torn_line_no = 0;
  std::vector<CandumpRecord> records;
  int line_no = 0;
  std::size_t pos = 0;
  while (pos < text.size()) {
    std::size_t end = text.find('\n', pos);
    const bool unterminated = end == std::string_view::npos;
    if (unterminated) end = text.size();
    const std::string_view line = text.substr(pos, end - pos);
    pos = end + 1;
    ++line_no;
    const std::string_view trimmed = TrimCandump(line);
    if (trimmed.empty() || trimmed.front() != '(') continue;  // comment, as canplayer skips it
    if (unterminated) {                                       // torn (see the header)
      if (torn_last_line != nullptr) *torn_last_line = std::string(trimmed);
      if (torn_line_no != nullptr) *torn_line_no = line_no;
      break;
    }
    Result<CandumpRecord> r = ParseCandumpLine(trimmed, std::string(source_name) + ":" + std::to_string(line_no));
    if (!r.ok()) return r.status();
    r->line = line_no;
    records.push_back(std::move(r).value());
  }
  return records;
}

Result<std::vector<CandumpRecord>> ReadCandumpFile(const std::string& path,
                                                   std::string* torn_last_line,
                                                   int* torn_line_no) {
  IDI_ASSIGN_OR_RETURN(const std::string text, ReadFile(path));
  return ParseCandumpText(text, path, torn_last_line, torn_line_no);
}

Status CandumpWriterOptions::Check() const {
  if (interface.empty() || interface.size() > kMaxInterfaceNameLength) {
    return InvalidArgument("candump writer: interface name '" + interface + "' must have 1..15 characters");
  }
  for (char c : interface) {
    if (c == ' ' || c == '\t' || c == '\n' || c == '(' || c == '#') {
      return InvalidArgument("candump writer: interface name '" + interface + "' contains a blank, '(' or '#'");
    }
  }
  return Status::Ok();
}

Result<std::unique_ptr<CandumpWriter>> CandumpWriter::Open(const std::string& path, const CandumpWriterOptions& options) {
  IDI_RETURN_IF_ERROR(options.Check());
  std::FILE* f = std::fopen(path.c_str(), options.append ? "ab" : "wb");
  if (f == nullptr) {
    return IoError(path + ": cannot open the CAN log for writing: " + std::strerror(errno));
  }
  return std::unique_ptr<CandumpWriter>(new CandumpWriter(path, f, options));
}

CandumpWriter::~CandumpWriter() {
  if (file_ != nullptr) std::fclose(file_);
}

Status CandumpWriter::Write(const hal::CanFrame& frame, CanDirection direction) {
  if (file_ == nullptr) return FailedPrecondition(path_ + ": the CAN log is closed");
  hal::CanFrame shifted = frame;
  shifted.timestamp_ns = frame.timestamp_ns + options_.timestamp_offset_ns;
  if (shifted.timestamp_ns < 0) {
    return InvalidArgument(path_ + ": frame timestamp " + std::to_string(shifted.timestamp_ns) +
                           " ns is negative; candump logs start at the epoch");
  }
  std::string line = FormatCandumpLine(shifted, options_.interface,
                                       options_.mark_direction ? direction : CanDirection::kUnknown);
  line.push_back('\n');
  if (std::fwrite(line.data(), 1, line.size(), file_) != line.size()) {
    return IoError(path_ + ": write failed: " + std::strerror(errno));
  }
  ++lines_written_;
  if (options_.flush_each_line) return Flush();
  return Status::Ok();
}

Status CandumpWriter::Flush() {
  if (file_ == nullptr) return FailedPrecondition(path_ + ": the CAN log is closed");
  if (std::fflush(file_) != 0) return IoError(path_ + ": flush failed: " + std::strerror(errno));
  return Status::Ok();
}

Status CandumpWriter::Close() {
  if (file_ == nullptr) return Status::Ok();
  const int rc = std::fclose(file_);
  file_ = nullptr;
  if (rc != 0) return IoError(path_ + ": close failed: " + std::strerror(errno));
  return Status::Ok();
}

}  // namespace idi::replay
