// The Directed Perception PTU-D46 ASCII protocol as bytes <-> structs, with no I/O
// (../shared/reference/device-protocols.md §2). Commands are a code, an optional signed number and
// a delimiter (we use a space, as the FLIR and MRPT drivers do). Replies are lines:
//   "*"                 success
//   "* <value>"         query result; terse ("* 185.1428") or verbose ("* Current Pan position is 0")
//   "! <message>"       failure, e.g. "! Maximum allowable Pan position is 3090"
//   "!P" / "!T"         asynchronous: the pan / tilt axis hit a limit; may prefix another reply
// With echo enabled the unit repeats the command before its reply ("PP * 1200").
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "shared/util/status.h"

namespace idi::workcell {

enum class PtuAxis { kPan, kTilt };
char PtuAxisLetter(PtuAxis axis);      // 'P' / 'T'
const char* PtuAxisName(PtuAxis axis);  // "pan" / "tilt"

// What a per-axis query asks for: the second letter of the command.
enum class PtuQuantity : char {
  kPosition = 'P',    // PP / TP
  kResolution = 'R',  // PR / TR, arc-seconds per position
  kMinimum = 'N',     // PN / TN
  kMaximum = 'X',     // PX / TX
};

// A command with its delimiter: PtuCommand("FT") == "FT ".
std::string PtuCommand(std::string_view code);
// "PP1200 " / "TP-300 ".
std::string PtuSetPositionCommand(PtuAxis axis, int32_t position);
// "PR ", "TN ", ...
std::string PtuQueryCommand(PtuAxis axis, PtuQuantity quantity);

enum class PtuReplyKind {
  kNone,     // only asynchronous limit notices on this line
  kEcho,     // the echo of the command just sent, on a line of its own
  kAck,      // "*"
  kValue,    // "* <value>"
  kError,    // "! <message>"
  kUnknown,  // anything else: power-up chatter, line noise, a reply to something else
};
const char* PtuReplyKindName(PtuReplyKind kind);

struct PtuReply {
  PtuReplyKind kind = PtuReplyKind::kUnknown;
  std::string text;                  // the value, the error message, or the whole line (kUnknown)
  std::vector<PtuAxis> limit_hits;  // "!P" / "!T" notices at the start of the line, in order
};

// Parses one reply line (without its CR/LF). `sent_command` (e.g. "PP ") lets the parser remove the
// unit's echo of it.
PtuReply ParsePtuReply(std::string_view line, std::string_view sent_command = {});

// The first whitespace-separated token of `text` that is a whole number: works for terse ("-3090")
// and verbose ("Minimum Pan position is -3090") values. ParseError naming the text otherwise.
Result<double> PtuFirstNumber(std::string_view text);
Result<int32_t> PtuFirstInteger(std::string_view text);

// One position step in radians from the PR/TR reply (arc-seconds per position).
double PtuArcSecondsToRad(double arc_seconds);

}  // namespace idi::workcell
