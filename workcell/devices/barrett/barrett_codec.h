// The Barrett BH8-262 supervisory protocol as bytes <-> structs, with no I/O
// (../shared/reference/device-protocols.md §3). A command is one line ended by CR: an optional motor
// prefix ("1".."3" a finger, "G" the three fingers, "S" the spread, none = the whole hand), the
// command and space-separated arguments ("GC", "SM 1575", "1FGET P"). The hand echoes what it
// receives, prints any output and any error ("ERR <code>"), then the prompt "=> ". Commands run one
// at a time: the prompt after a motion command comes when the motion has finished.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "shared/util/status.h"

namespace idi::workcell {

// Motor set as bits: fingers F1, F2, F3 and the spread.
enum BarrettMotor : unsigned {
  kBarrettF1 = 1u,
  kBarrettF2 = 2u,
  kBarrettF3 = 4u,
  kBarrettSpread = 8u,
};
inline constexpr unsigned kBarrettFingers = kBarrettF1 | kBarrettF2 | kBarrettF3;
inline constexpr unsigned kBarrettWholeHand = kBarrettFingers | kBarrettSpread;

inline constexpr std::string_view kBarrettPrompt = "=> ";

// The prefix for a motor set: "" (whole hand), "G" (fingers), "S" (spread), else motor digits ("13").
std::string BarrettMotorPrefix(unsigned motors);
// Motor set from a prefix; InvalidArgument for an unknown letter.
Result<unsigned> ParseBarrettMotorPrefix(std::string_view prefix);

// The command line without its CR: BarrettCommandText(kBarrettSpread, "M", "1575") == "SM 1575".
std::string BarrettCommandText(unsigned motors, std::string_view command, std::string_view args = {});
// The bytes to send: the text and CR.
std::string BarrettCommandBytes(std::string_view text);

struct BarrettReply {
  bool echo_found = false;          // the echo of the sent command was in the block
  int dropped_lines = 0;            // lines before the echo (noise, a stale reply)
  std::vector<std::string> lines;   // output lines after the echo, ERR lines excluded
  bool error = false;               // an "ERR <code>" line was present
  int error_code = 0;
  std::string error_text;           // the ERR line as printed
};

// Parses the text before a prompt. The echo is the last line that ends with `sent_text` (case
// insensitive; noise may precede it on the line); without it the block is not this command's.
BarrettReply ParseBarrettReply(std::string_view block, std::string_view sent_text);

// Integers in output lines ("1234", "120 130 125"); ParseError on a non-integer token.
Result<std::vector<long>> BarrettIntegers(const std::vector<std::string>& lines);

}  // namespace idi::workcell
