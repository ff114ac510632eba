// The operator control protocol of idi-workcell's service (`idi-workcell run`): one JSON object per
// line over a local Unix-domain socket, one JSON object per line back.
//
//   {"cmd": "status"}
//   {"cmd": "job", "job": "<name>", "args": {...}}     queue a job (see `idi-workcell job --help`)
//   {"cmd": "stop"}                                    safe stop: cancel jobs, stop every device
//   {"cmd": "reset"}                                   leave the fault state: reconnect, home
//   {"cmd": "shutdown"}                                stop safely and exit
// Replies: {"ok": true, ...} or {"ok": false, "error": "<what was wrong>"}.
#pragma once

#include <nlohmann/json.hpp>

#include <string>

#include "shared/util/status.h"

namespace idi::workcell {

inline constexpr std::size_t kMaxRequestBytes = 64 * 1024;

enum class ControlCommand { kStatus, kJob, kStop, kReset, kShutdown };
const char* ControlCommandName(ControlCommand c);

struct ControlRequest {
  ControlCommand command = ControlCommand::kStatus;
  std::string job;                                     // for kJob
  nlohmann::json args = nlohmann::json::object();     // for kJob
};

// Parses and validates one request line. InvalidArgument naming the problem for anything else:
// not JSON, not an object, unknown or missing "cmd", wrong field types, unknown fields, too long.
Result<ControlRequest> ParseControlRequest(const std::string& line);
std::string SerializeControlRequest(const ControlRequest& request);

nlohmann::json OkReply(nlohmann::json fields = nlohmann::json::object());
nlohmann::json ErrorReply(const std::string& error);

}  // namespace idi::workcell
