#include "workcell/devices/staubli/val3_protocol.h"

#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>

namespace idi::workcell {
namespace {

struct Val3VerbInfo {
  Val3Verb verb;
  const char* name;
  int args;
};
constexpr Val3VerbInfo kVal3Verbs[] = {
    {Val3Verb::kHello, "HELLO", 1}, {Val3Verb::kPing, "PING", 0},  {Val3Verb::kStatus, "STATUS", 0},
    {Val3Verb::kJoints, "JOINTS", 0}, {Val3Verb::kMoveJ, "MOVEJ", 7}, {Val3Verb::kStop, "STOP", 0},
    {Val3Verb::kRail, "RAIL", 0},   {Val3Verb::kRailMove, "RAILMOVE", 2},
};

std::vector<std::string_view> Val3Tokens(std::string_view line) {
  std::vector<std::string_view> out;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t' || line[i] == '\r' || line[i] == '\n')) ++i;
    const std::size_t start = i;
    while (i < line.size() && !(line[i] == ' ' || line[i] == '\t' || line[i] == '\r' || line[i] == '\n')) ++i;
    if (i > start) out.push_back(line.substr(start, i - start));
  }
  return out;
}

bool Val3ParseId(std::string_view token, uint32_t* id) {
  const auto [ptr, ec] = std::from_chars(token.data(), token.data() + token.size(), *id);
  return ec == std::errc() && ptr == token.data() + token.size() && *id <= kVal3MaxId;
}

bool Val3ParseNumber(std::string_view token, double* value) {
  // Plain decimals only (what VAL3's toString writes and toNum reads): sign, digits, one '.'.
  if (token.empty() || token.size() > 24) return false;
  int digits = 0, dots = 0;
  for (std::size_t i = 0; i < token.size(); ++i) {
    const char c = token[i];
    if (std::isdigit(static_cast<unsigned char>(c))) {
      ++digits;
    } else if (c == '.') {
      ++dots;
    } else if (!((c == '-' || c == '+') && i == 0)) {
      return false;
    }
  }
  if (digits == 0 || dots > 1) return false;
  const std::string owned(token);
  *value = std::strtod(owned.c_str(), nullptr);
  return std::isfinite(*value);
}

bool Val3IsPrintable(std::string_view line) {
  for (const char c : line) {
    const auto u = static_cast<unsigned char>(c);
    if (u < 0x20 && c != '\r' && c != '\n' && c != '\t') return false;
    if (u >= 0x7f) return false;
  }
  return true;
}

Result<double> Val3Field(const Val3Reply& reply, std::size_t i, const char* what) {
  double v = 0;
  if (i >= reply.fields.size() || !Val3ParseNumber(reply.fields[i], &v)) {
    return ParseError(std::string("reply ") + std::to_string(reply.id) + ": field " + std::to_string(i + 1) + " (" +
                      what + ") missing or not a number");
  }
  return v;
}

Result<bool> Val3Flag(const Val3Reply& reply, std::size_t i, const char* what) {
  IDI_ASSIGN_OR_RETURN(const double v, Val3Field(reply, i, what));
  if (v != 0 && v != 1) {
    return ParseError(std::string("reply ") + std::to_string(reply.id) + ": field " + std::to_string(i + 1) + " (" +
                      what + ") must be 0 or 1");
  }
  return v == 1;
}

}  // namespace

const char* Val3VerbName(Val3Verb verb) {
  for (const auto& info : kVal3Verbs) {
    if (info.verb == verb) return info.name;
  }
  return "?";
}

int Val3VerbArgCount(Val3Verb verb) {
  for (const auto& info : kVal3Verbs) {
    if (info.verb == verb) return info.args;
  }
  return 0;
}

std::string FormatVal3Number(double value) {
  char buf[48];
  std::snprintf(buf, sizeof(buf), "%.4f", value);
  std::string out = buf;
  if (out == "-0.0000") out = "0.0000";
  return out;
}

std::string EncodeVal3Request(const Val3Request& request) {
  std::string line = std::to_string(request.id) + " " + Val3VerbName(request.verb);
  for (const double a : request.args) line += " " + FormatVal3Number(a);
  return line + "\n";
}

Result<Val3Request> ParseVal3Request(std::string_view line) {
  if (line.size() > kVal3MaxLineBytes || !Val3IsPrintable(line)) {
    return ParseError("request too long or not printable");
  }
  const auto tokens = Val3Tokens(line);
  Val3Request request;
  if (tokens.size() < 2 || !Val3ParseId(tokens[0], &request.id)) {
    return ParseError("request is not '<id> <VERB> ...'");
  }
  bool known = false;
  for (const auto& info : kVal3Verbs) {
    if (tokens[1] == info.name) {
      request.verb = info.verb;
      known = true;
    }
  }
  if (!known) return InvalidArgument("unknown verb '" + std::string(tokens[1]) + "'");
  if (static_cast<int>(tokens.size()) - 2 != Val3VerbArgCount(request.verb)) {
    return OutOfRange(std::string(Val3VerbName(request.verb)) + " takes " +
                      std::to_string(Val3VerbArgCount(request.verb)) + " arguments");
  }
  for (std::size_t i = 2; i < tokens.size(); ++i) {
    double v = 0;
    if (!Val3ParseNumber(tokens[i], &v)) return OutOfRange("argument " + std::to_string(i - 1) + " is not a number");
    request.args.push_back(v);
  }
  return request;
}

std::string EncodeVal3Reply(const Val3Reply& reply) {
  std::string line = std::to_string(reply.id);
  if (reply.ok) {
    line += " OK";
    for (const std::string& f : reply.fields) line += " " + f;
  } else {
    line += " ERR " + std::to_string(reply.error_code);
    if (!reply.error_text.empty()) line += " " + reply.error_text;
  }
  return line + "\n";
}

Result<Val3Reply> ParseVal3Reply(std::string_view line) {
  if (line.size() > kVal3MaxLineBytes || !Val3IsPrintable(line)) {
    return ParseError("reply too long or not printable");
  }
  const auto tokens = Val3Tokens(line);
  Val3Reply reply;
  if (tokens.size() < 2 || !Val3ParseId(tokens[0], &reply.id)) {
    return ParseError("reply is not '<id> OK|ERR ...'");
  }
  if (tokens[1] == "OK") {
    for (std::size_t i = 2; i < tokens.size(); ++i) reply.fields.emplace_back(tokens[i]);
    return reply;
  }
  if (tokens[1] == "ERR") {
    reply.ok = false;
    if (tokens.size() < 3 || !std::isdigit(static_cast<unsigned char>(tokens[2][0]))) {
      return ParseError("ERR reply without a code");
    }
    reply.error_code = std::atoi(std::string(tokens[2]).c_str());
    // The text is the rest of the line after the code, spacing kept.
    // Searched for after the verb: the id before it may contain the code's digits ("14 ERR 4 ...").
    const std::size_t at = line.find(tokens[2], line.find(tokens[1]) + tokens[1].size()) + tokens[2].size();
    std::string_view text = line.substr(at);
    while (!text.empty() && (text.front() == ' ' || text.front() == '\t')) text.remove_prefix(1);
    while (!text.empty() && (text.back() == ' ' || text.back() == '\r' || text.back() == '\n')) text.remove_suffix(1);
    reply.error_text = std::string(text);
    return reply;
  }
  return ParseError("reply is neither OK nor ERR");
}

Result<Val3Hello> DecodeVal3Hello(const Val3Reply& reply) {
  if (reply.fields.empty() || reply.fields[0] != kVal3ServerName) {
    return ParseError("HELLO reply does not name the IDI-VAL3 server");
  }
  Val3Hello hello;
  IDI_ASSIGN_OR_RETURN(const double version, Val3Field(reply, 1, "version"));
  hello.version = static_cast<int>(version);
  IDI_ASSIGN_OR_RETURN(hello.has_rail, Val3Flag(reply, 2, "has_rail"));
  return hello;
}

Result<Val3Joints> DecodeVal3Joints(const Val3Reply& reply) {
  if (reply.fields.size() != 7) return ParseError("JOINTS reply needs 7 fields, got " + std::to_string(reply.fields.size()));
  Val3Joints joints;
  for (std::size_t i = 0; i < 6; ++i) {
    IDI_ASSIGN_OR_RETURN(joints.deg[i], Val3Field(reply, i, "joint"));
  }
  IDI_ASSIGN_OR_RETURN(joints.settled, Val3Flag(reply, 6, "settled"));
  return joints;
}

Result<Val3Rail> DecodeVal3Rail(const Val3Reply& reply) {
  if (reply.fields.size() != 2) return ParseError("RAIL reply needs 2 fields, got " + std::to_string(reply.fields.size()));
  Val3Rail rail;
  IDI_ASSIGN_OR_RETURN(rail.mm, Val3Field(reply, 0, "rail mm"));
  IDI_ASSIGN_OR_RETURN(rail.settled, Val3Flag(reply, 1, "settled"));
  return rail;
}

Result<Val3Status> DecodeVal3Status(const Val3Reply& reply) {
  if (reply.fields.size() != 5) return ParseError("STATUS reply needs 5 fields, got " + std::to_string(reply.fields.size()));
  Val3Status status;
  IDI_ASSIGN_OR_RETURN(status.powered, Val3Flag(reply, 0, "powered"));
  IDI_ASSIGN_OR_RETURN(status.estop, Val3Flag(reply, 1, "estop"));
  IDI_ASSIGN_OR_RETURN(status.settled, Val3Flag(reply, 2, "settled"));
  IDI_ASSIGN_OR_RETURN(status.rail_settled, Val3Flag(reply, 3, "rail settled"));
  IDI_ASSIGN_OR_RETURN(const double last, Val3Field(reply, 4, "last error"));
  status.last_error = static_cast<int>(last);
  return status;
}

}  // namespace idi::workcell
