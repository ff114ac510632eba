#include "workcell/devices/barrett/barrett_codec.h"

#include <cctype>
#include <charconv>

namespace idi::workcell {
namespace {

std::string_view BarrettTrim(std::string_view s) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.front()))) s.remove_prefix(1);
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.remove_suffix(1);
  return s;
}

bool BarrettEndsWithNoCase(std::string_view s, std::string_view suffix) {
  if (suffix.empty() || s.size() < suffix.size()) return false;
  const std::string_view tail = s.substr(s.size() - suffix.size());
  for (std::size_t i = 0; i < suffix.size(); ++i) {
    if (std::toupper(static_cast<unsigned char>(tail[i])) != std::toupper(static_cast<unsigned char>(suffix[i]))) {
      return false;
    }
  }
  return true;
}

std::vector<std::string_view> BarrettLines(std::string_view block) {
  std::vector<std::string_view> lines;
  std::size_t i = 0;
  while (i <= block.size()) {
    const std::size_t end = block.find_first_of("\r\n", i);
    const std::string_view line = BarrettTrim(block.substr(i, end == std::string_view::npos ? block.npos : end - i));
    if (!line.empty()) lines.push_back(line);
    if (end == std::string_view::npos) break;
    i = end + 1;
  }
  return lines;
}

}  // namespace

std::string BarrettMotorPrefix(unsigned motors) {
  motors &= kBarrettWholeHand;
  if (motors == kBarrettWholeHand || motors == 0) return "";
  if (motors == kBarrettFingers) return "G";
  if (motors == kBarrettSpread) return "S";
  std::string out;
  for (unsigned m = 0; m < 4; ++m) {
    if ((motors & (1u << m)) != 0) out += static_cast<char>('1' + m);
  }
  return out;
}

Result<unsigned> ParseBarrettMotorPrefix(std::string_view prefix) {
  if (prefix.empty()) return kBarrettWholeHand;
  unsigned motors = 0;
  for (const char c : prefix) {
    switch (std::toupper(static_cast<unsigned char>(c))) {
      case '1': motors |= kBarrettF1; break;
      case '2': motors |= kBarrettF2; break;
      case '3': motors |= kBarrettF3; break;
      case '4':
      case 'S': motors |= kBarrettSpread; break;
      case 'G': motors |= kBarrettFingers; break;
      default: return InvalidArgument("unknown Barrett motor prefix '" + std::string(prefix) + "'");
    }
  }
  return motors;
}

std::string BarrettCommandText(unsigned motors, std::string_view command, std::string_view args) {
  std::string text = BarrettMotorPrefix(motors) + std::string(command);
  if (!args.empty()) text += " " + std::string(args);
  return text;
}

std::string BarrettCommandBytes(std::string_view text) { return std::string(text) + "\r"; }

BarrettReply ParseBarrettReply(std::string_view block, std::string_view sent_text) {
  BarrettReply reply;
  const std::vector<std::string_view> lines = BarrettLines(block);
  const std::string_view sent = BarrettTrim(sent_text);
  std::size_t first = 0;
  if (sent.empty()) {
    // A bare CR: its echo is an empty line, so everything in the block is output.
    reply.echo_found = true;
  } else {
    for (std::size_t i = lines.size(); i-- > 0;) {
      if (BarrettEndsWithNoCase(lines[i], sent)) {
        reply.echo_found = true;
        first = i + 1;
        reply.dropped_lines = static_cast<int>(i);
        break;
      }
    }
  }
  if (!reply.echo_found) {
    reply.dropped_lines = static_cast<int>(lines.size());
    return reply;
  }
  for (std::size_t i = first; i < lines.size(); ++i) {
    const std::string_view line = lines[i];
    if (line.size() >= 3 && std::toupper(static_cast<unsigned char>(line[0])) == 'E' &&
        std::toupper(static_cast<unsigned char>(line[1])) == 'R' &&
        std::toupper(static_cast<unsigned char>(line[2])) == 'R') {
      reply.error = true;
      reply.error_text = std::string(line);
      const std::string_view code = BarrettTrim(line.substr(3));
      int value = 0;
      const auto [ptr, ec] = std::from_chars(code.data(), code.data() + code.size(), value);
      reply.error_code = ec == std::errc() ? value : -1;
      (void)ptr;
      continue;
    }
    reply.lines.emplace_back(line);
  }
  return reply;
}

Result<std::vector<long>> BarrettIntegers(const std::vector<std::string>& lines) {
  std::vector<long> values;
  for (const std::string& line : lines) {
    std::size_t i = 0;
    while (i < line.size()) {
      while (i < line.size() && std::isspace(static_cast<unsigned char>(line[i]))) ++i;
      const std::size_t start = i;
      while (i < line.size() && !std::isspace(static_cast<unsigned char>(line[i]))) ++i;
      if (i == start) break;
      long value = 0;
      const char* b = line.data() + start;
      const char* e = line.data() + i;
      if (*b == '+') ++b;
      const auto [ptr, ec] = std::from_chars(b, e, value);
      if (ec != std::errc() || ptr != e) {
        return ParseError("not an integer in Barrett reply: '" + line + "'");
      }
      values.push_back(value);
    }
  }
  return values;
}

}  // namespace idi::workcell
