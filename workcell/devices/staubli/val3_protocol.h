// The IDI-VAL3 protocol between the workcell PC and the VAL3 server program on each CS8 controller
// (the server's source and the full description: targets/workcell-pc/val3/). Bytes <-> structs, no I/O.
//
// TCP, one client at a time. ASCII lines ended by LF (a CR before it is ignored), at most 120 bytes so
// they fit VAL3 strings. Request: "<id> <VERB> [args...]"; reply, exactly one per request and in
// order: "<id> OK [fields...]" or "<id> ERR <code> <text>". The id (1..999999, chosen by the client,
// increasing) ties a reply to its request, so a late reply is recognised and dropped. Numbers are
// decimal with a '.'; joint angles are degrees in the controller's convention, rail positions mm,
// speeds percent of nominal.
//
//   HELLO <version>                  -> OK IDI-VAL3 <version> <has_rail 0|1>
//   PING                             -> OK <controller clock, s>      (heartbeat)
//   STATUS                           -> OK <powered> <estop> <arm settled> <rail settled> <last error>
//   JOINTS                           -> OK <j1..j6 deg> <settled 0|1>
//   MOVEJ <speed %> <j1..j6 deg>     -> OK   (queued; poll JOINTS until settled)
//   STOP                             -> OK   (arm and rail: resetMotion)
//   RAIL                             -> OK <mm> <settled 0|1>
//   RAILMOVE <speed %> <mm>          -> OK   (queued; poll RAIL until settled)
//
// The server stops all motion when the client goes quiet for its watchdog time (1 s) while anything
// moves, and when the connection drops.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "shared/util/status.h"

namespace idi::workcell {

inline constexpr int kVal3ProtocolVersion = 1;
inline constexpr std::string_view kVal3ServerName = "IDI-VAL3";
inline constexpr std::size_t kVal3MaxLineBytes = 120;
inline constexpr uint32_t kVal3MaxId = 999'999;

enum class Val3Verb { kHello, kPing, kStatus, kJoints, kMoveJ, kStop, kRail, kRailMove };
const char* Val3VerbName(Val3Verb verb);
// Number of numeric arguments each verb takes.
int Val3VerbArgCount(Val3Verb verb);

enum class Val3Error : int {
  kMalformed = 1,    // not "<id> <VERB> ...", unknown verb, line too long
  kBadArguments = 2, // wrong count or not numbers
  kOutOfRange = 3,   // joint or rail limit, speed outside 1..100
  kNotPossible = 4,  // power off, E-stop, not in remote mode
  kNoRail = 5,       // this controller drives no rail
  kMotion = 6,       // the controller refused the motion
};

struct Val3Request {
  uint32_t id = 0;
  Val3Verb verb = Val3Verb::kPing;
  std::vector<double> args;
};

struct Val3Reply {
  uint32_t id = 0;
  bool ok = true;
  int error_code = 0;            // when !ok
  std::string error_text;        // when !ok
  std::vector<std::string> fields;  // when ok
};

// Fixed-point with 4 decimals (0.0001 deg is finer than the RX-130's encoders).
std::string FormatVal3Number(double value);

std::string EncodeVal3Request(const Val3Request& request);  // with the LF
Result<Val3Request> ParseVal3Request(std::string_view line);
std::string EncodeVal3Reply(const Val3Reply& reply);  // with the LF
Result<Val3Reply> ParseVal3Reply(std::string_view line);

// Typed views of OK replies; ParseError when fields are missing or not numbers.
struct Val3Hello {
  int version = 0;
  bool has_rail = false;
};
struct Val3Joints {
  std::array<double, 6> deg{};
  bool settled = false;
};
struct Val3Rail {
  double mm = 0;
  bool settled = false;
};
struct Val3Status {
  bool powered = false, estop = false, settled = false, rail_settled = false;
  int last_error = 0;
};
Result<Val3Hello> DecodeVal3Hello(const Val3Reply& reply);
Result<Val3Joints> DecodeVal3Joints(const Val3Reply& reply);
Result<Val3Rail> DecodeVal3Rail(const Val3Reply& reply);
Result<Val3Status> DecodeVal3Status(const Val3Reply& reply);

}  // namespace idi::workcell
