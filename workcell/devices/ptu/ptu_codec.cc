#include "workcell/devices/ptu/ptu_codec.h"

#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdlib>

#include "shared/util/units.h"

namespace idi::workcell {
namespace {

std::string_view PtuTrimLeft(std::string_view s) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.front()))) s.remove_prefix(1);
  return s;
}

std::string_view PtuTrim(std::string_view s) {
  s = PtuTrimLeft(s);
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.remove_suffix(1);
  return s;
}

bool PtuStartsWithNoCase(std::string_view s, std::string_view prefix) {
  if (prefix.empty() || s.size() < prefix.size()) return false;
  for (std::size_t i = 0; i < prefix.size(); ++i) {
    if (std::toupper(static_cast<unsigned char>(s[i])) != std::toupper(static_cast<unsigned char>(prefix[i]))) {
      return false;
    }
  }
  return true;
}

// Splits on whitespace.
std::vector<std::string_view> PtuTokens(std::string_view text) {
  std::vector<std::string_view> out;
  std::size_t i = 0;
  while (i < text.size()) {
    while (i < text.size() && std::isspace(static_cast<unsigned char>(text[i]))) ++i;
    const std::size_t start = i;
    while (i < text.size() && !std::isspace(static_cast<unsigned char>(text[i]))) ++i;
    if (i > start) out.push_back(text.substr(start, i - start));
  }
  return out;
}

}  // namespace

char PtuAxisLetter(PtuAxis axis) { return axis == PtuAxis::kPan ? 'P' : 'T'; }
const char* PtuAxisName(PtuAxis axis) { return axis == PtuAxis::kPan ? "pan" : "tilt"; }

std::string PtuCommand(std::string_view code) { return std::string(code) + " "; }

std::string PtuSetPositionCommand(PtuAxis axis, int32_t position) {
  return std::string(1, PtuAxisLetter(axis)) + "P" + std::to_string(position) + " ";
}

std::string PtuQueryCommand(PtuAxis axis, PtuQuantity quantity) {
  return std::string(1, PtuAxisLetter(axis)) + static_cast<char>(quantity) + " ";
}

const char* PtuReplyKindName(PtuReplyKind kind) {
  switch (kind) {
    case PtuReplyKind::kNone: return "limit notice";
    case PtuReplyKind::kEcho: return "echo";
    case PtuReplyKind::kAck: return "'*'";
    case PtuReplyKind::kValue: return "'* <value>'";
    case PtuReplyKind::kError: return "'! <message>'";
    case PtuReplyKind::kUnknown: return "unrecognised line";
  }
  return "?";
}

PtuReply ParsePtuReply(std::string_view line, std::string_view sent_command) {
  PtuReply reply;
  std::string_view rest = PtuTrimLeft(line);
  // The echo of the command: the command's text up to its delimiter, then a delimiter or the end.
  const std::string_view command = PtuTrim(sent_command);
  if (PtuStartsWithNoCase(rest, command) &&
      (rest.size() == command.size() || std::isspace(static_cast<unsigned char>(rest[command.size()])))) {
    rest = PtuTrimLeft(rest.substr(command.size()));
    if (rest.empty()) {
      reply.kind = PtuReplyKind::kEcho;
      return reply;
    }
  }
  // Asynchronous limit notices: '!' directly followed by the axis letter (an error has a space).
  while (rest.size() >= 2 && rest[0] == '!' && (std::toupper(static_cast<unsigned char>(rest[1])) == 'P' ||
                                                std::toupper(static_cast<unsigned char>(rest[1])) == 'T')) {
    reply.limit_hits.push_back(std::toupper(static_cast<unsigned char>(rest[1])) == 'P' ? PtuAxis::kPan
                                                                                        : PtuAxis::kTilt);
    rest = PtuTrimLeft(rest.substr(2));
  }
  if (rest.empty()) {
    reply.kind = reply.limit_hits.empty() ? PtuReplyKind::kUnknown : PtuReplyKind::kNone;
    reply.text = std::string(PtuTrim(line));
    return reply;
  }
  if (rest[0] == '*') {
    const std::string_view value = PtuTrim(rest.substr(1));
    reply.kind = value.empty() ? PtuReplyKind::kAck : PtuReplyKind::kValue;
    reply.text = std::string(value);
    return reply;
  }
  if (rest[0] == '!') {
    reply.kind = PtuReplyKind::kError;
    reply.text = std::string(PtuTrim(rest.substr(1)));
    return reply;
  }
  reply.kind = PtuReplyKind::kUnknown;
  reply.text = std::string(PtuTrim(line));
  return reply;
}

Result<double> PtuFirstNumber(std::string_view text) {
  for (const std::string_view token : PtuTokens(text)) {
    const std::string owned(token);
    char* end = nullptr;
    const double value = std::strtod(owned.c_str(), &end);
    if (end == owned.c_str() + owned.size() && std::isfinite(value)) {
      return value;
    }
  }
  return ParseError("no number in PTU reply '" + std::string(text) + "'");
}

Result<int32_t> PtuFirstInteger(std::string_view text) {
  for (const std::string_view token : PtuTokens(text)) {
    int32_t value = 0;
    const char* first = token.data();
    if (!token.empty() && token.front() == '+') ++first;
    const auto [ptr, ec] = std::from_chars(first, token.data() + token.size(), value);
    if (ec == std::errc() && ptr == token.data() + token.size()) {
      return value;
    }
  }
  return ParseError("no integer in PTU reply '" + std::string(text) + "'");
}

double PtuArcSecondsToRad(double arc_seconds) { return DegToRad(arc_seconds / 3600.0); }

}  // namespace idi::workcell
