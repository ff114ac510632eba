#include "workcell/service/control_protocol.h"

namespace idi::workcell {

const char* ControlCommandName(ControlCommand c) {
  switch (c) {
    case ControlCommand::kStatus: return "status";
    case ControlCommand::kJob: return "job";
    case ControlCommand::kStop: return "stop";
    case ControlCommand::kReset: return "reset";
    case ControlCommand::kShutdown: return "shutdown";
  }
  return "?";
}

Result<ControlRequest> ParseControlRequest(const std::string& line) {
  if (line.size() > kMaxRequestBytes) {
    return InvalidArgument("request longer than " + std::to_string(kMaxRequestBytes) + " bytes");
  }
  const nlohmann::json j = nlohmann::json::parse(line, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded()) {
    return InvalidArgument("request is not valid JSON");
  }
  if (!j.is_object()) {
    return InvalidArgument("request must be a JSON object");
  }
  if (!j.contains("cmd") || !j["cmd"].is_string()) {
    return InvalidArgument("request needs a string field \"cmd\"");
  }
  const std::string cmd = j["cmd"].get<std::string>();
  ControlRequest r;
  bool found = false;
  for (ControlCommand c : {ControlCommand::kStatus, ControlCommand::kJob, ControlCommand::kStop, ControlCommand::kReset,
                           ControlCommand::kShutdown}) {
    if (cmd == ControlCommandName(c)) {
      r.command = c;
      found = true;
    }
  }
  if (!found) {
    return InvalidArgument("unknown command \"" + cmd + "\" (expected status, job, stop, reset or shutdown)");
  }
  for (const auto& [key, value] : j.items()) {
    const bool allowed = key == "cmd" || (r.command == ControlCommand::kJob && (key == "job" || key == "args"));
    if (!allowed) {
      return InvalidArgument("unexpected field \"" + key + "\" for command \"" + cmd + "\"");
    }
  }
  if (r.command == ControlCommand::kJob) {
    if (!j.contains("job") || !j["job"].is_string() || j["job"].get<std::string>().empty()) {
      return InvalidArgument("command \"job\" needs a non-empty string field \"job\"");
    }
    r.job = j["job"].get<std::string>();
    if (j.contains("args")) {
      if (!j["args"].is_object()) {
        return InvalidArgument("field \"args\" must be an object");
      }
      r.args = j["args"];
    }
  }
  return r;
}

std::string SerializeControlRequest(const ControlRequest& request) {
  nlohmann::json j;
  j["cmd"] = ControlCommandName(request.command);
  if (request.command == ControlCommand::kJob) {
    j["job"] = request.job;
    j["args"] = request.args;
  }
  return j.dump();
}

nlohmann::json OkReply(nlohmann::json fields) {
  fields["ok"] = true;
  return fields;
}

nlohmann::json ErrorReply(const std::string& error) { return {{"ok", false}, {"error", error}}; }

}  // namespace idi::workcell
