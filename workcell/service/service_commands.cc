#include "workcell/service/service_commands.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <atomic>
#include <iostream>
#include <thread>

#include "shared/runtime/stop_signals.h"
#include "workcell/service/control_socket.h"

namespace idi::workcell {
namespace {

const char* kDefaultSocket = "/run/idi-workcell/control.sock";

struct RunOptions {
  std::string config;
  std::string socket;  // overrides the config's
};

Status RunService(const RunOptions& o, const CellFactory& make_cell) {
  IDI_ASSIGN_OR_RETURN(WorkcellConfig config, LoadWorkcellConfig(o.config));
  if (!o.socket.empty()) config.control_socket = o.socket;
  IDI_ASSIGN_OR_RETURN(Cell cell, make_cell(config));
  ServiceOptions so;
  so.state_dir = config.state_dir;
  so.calibration_max_age_days = config.calibration_max_age_days;
  so.recalibrate_when_stale = config.recalibrate_when_stale;
  so.calibration_jobs = cell.calibration_jobs;
  so.required_calibration_items = cell.calibration_items;
  so.calibration_job_for_item = cell.calibration_job_for_item;
  so.startup_jobs = cell.startup_jobs;
  so.exit_when_idle = config.exit_when_idle;
  WorkcellService service(so, cell.devices.get(), std::move(cell.jobs));
  ControlServerOptions co;
  co.path = config.control_socket;
  co.group = config.control_group;
  IDI_ASSIGN_OR_RETURN(auto server, ControlServer::Start(co, [&](const ControlRequest& r) { return service.Handle(r); }));
  spdlog::info("idi-workcell service: backend {}, state in {}, operator socket {}", config.backend, config.state_dir,
               config.control_socket);
  // SIGTERM (systemd's stop), SIGINT and SIGHUP (a closed terminal, unless started with nohup) stop it
  // safely: the devices are commanded to stop and a running job is cancelled (a calibration keeps the
  // readings it took).
  const StopSignals signals;
  std::atomic<bool> done{false};
  std::thread signal_watch([&] {
    while (!done) {
      if (signals.requested()) {
        spdlog::warn("idi-workcell service: signal {} ({}): stopping safely",
                     signals.signal(),
                     StopSignals::Name(signals.signal()));
        service.RequestShutdown();
        return;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
  });
  const Status st = service.Run();
  done = true;
  signal_watch.join();
  server->Stop();
  return st;
}

struct ClientOptions {
  std::string socket = kDefaultSocket;
  bool json = false;
};

Status PrintReply(const nlohmann::json& reply, bool json) {
  if (json) {
    std::cout << reply.dump() << "\n";
  }
  if (!reply.value("ok", false)) {
    return FailedPrecondition("the service refused: " + reply.value("error", std::string("(no reason given)")));
  }
  return Status::Ok();
}

Status RunStatus(const ClientOptions& o) {
  ControlRequest r;
  r.command = ControlCommand::kStatus;
  IDI_ASSIGN_OR_RETURN(const nlohmann::json reply, SendControlRequest(o.socket, r));
  if (o.json) return PrintReply(reply, true);
  IDI_RETURN_IF_ERROR(PrintReply(reply, false));
  std::cout << fmt::format("state: {} ({})\n", reply.value("state", "?"), reply.value("reason", ""));
  if (reply.contains("job") && reply["job"].is_object()) {
    const auto& j = reply["job"];
    std::cout << fmt::format("job {}: {} {:.0f}% {}\n", j.value("id", 0), j.value("name", ""),
                             100.0 * j.value("progress", 0.0), j.value("what", ""));
  }
  if (reply.contains("queue")) std::cout << fmt::format("queued jobs: {}\n", reply["queue"].size());
  if (reply.contains("calibration")) {
    std::cout << fmt::format("calibration version {}\n", reply["calibration"].value("version", 0));
  } else {
    std::cout << "calibration: none\n";
  }
  if (!reply.value("last_error", std::string()).empty()) std::cout << "last error: " << reply["last_error"].get<std::string>() << "\n";
  if (reply.contains("devices")) std::cout << FormatDeviceHealth(reply["devices"]);
  return Status::Ok();
}

struct JobOptions {
  ClientOptions client;
  std::string name;
  std::vector<std::string> args;  // key=value
};

Status RunJob(const JobOptions& o) {
  ControlRequest r;
  r.command = ControlCommand::kJob;
  r.job = o.name;
  for (const std::string& kv : o.args) {
    const auto eq = kv.find('=');
    if (eq == std::string::npos || eq == 0) {
      return InvalidArgument("--arg '" + kv + "': expected key=value");
    }
    const std::string key = kv.substr(0, eq), value = kv.substr(eq + 1);
    // Numbers and booleans are sent as such, everything else as a string.
    const nlohmann::json parsed = nlohmann::json::parse(value, nullptr, false);
    r.args[key] = (!parsed.is_discarded() && (parsed.is_number() || parsed.is_boolean())) ? parsed : nlohmann::json(value);
  }
  IDI_ASSIGN_OR_RETURN(const nlohmann::json reply, SendControlRequest(o.client.socket, r));
  IDI_RETURN_IF_ERROR(PrintReply(reply, o.client.json));
  if (!o.client.json) std::cout << fmt::format("queued job {} ({})\n", reply.value("job_id", 0), o.name);
  return Status::Ok();
}

Status RunStop(const ClientOptions& o, ControlCommand command) {
  ControlRequest r;
  r.command = command;
  IDI_ASSIGN_OR_RETURN(const nlohmann::json reply, SendControlRequest(o.socket, r));
  IDI_RETURN_IF_ERROR(PrintReply(reply, o.json));
  if (!o.json) std::cout << ControlCommandName(command) << ": done\n";
  return Status::Ok();
}

void AddClientFlags(CLI::App* cmd, ClientOptions* o) {
  cmd->add_option("--socket", o->socket, "the service's control socket")->capture_default_str();
  cmd->add_flag("--json", o->json, "print the service's JSON reply on stdout");
}

}  // namespace

std::string FormatDeviceHealth(const nlohmann::json& devices) {
  if (!devices.is_object()) return "";
  // A field of the expected type, or `otherwise` (health is the service's own, but a client must not
  // throw on an odd one).
  auto text = [](const nlohmann::json& o, const char* key, const std::string& otherwise) {
    const auto it = o.find(key);
    return it != o.end() && it->is_string() ? it->get<std::string>() : otherwise;
  };
  const auto busy = devices.find("busy");
  std::string out = fmt::format("devices ({}{}):\n",
                                text(devices, "backend", "?"),
                                busy != devices.end() && busy->is_boolean() && busy->get<bool>()
                                    ? ", busy: a device operation is in progress, this is from before it"
                                    : "");
  auto line = [&](const char* kind, const nlohmann::json& d) {
    if (!d.is_object()) return;
    std::string state = text(d, "state", "");
    if (const auto ok = d.find("ok"); state.empty() && ok != d.end() && ok->is_boolean()) {
      state = ok->get<bool>() ? "ok" : "error";
    }
    std::string rest;
    for (const auto& [key, value] : d.items()) {
      if (key == "name" || key == "state" || key == "ok") continue;
      rest += fmt::format(
          "{}{} {}", rest.empty() ? "" : ", ", key, value.is_string() ? value.get<std::string>() : value.dump());
    }
    out += fmt::format("  {} {}: {}{}\n",
                       kind,
                       text(d, "name", "?"),
                       state.empty() ? "?" : state,
                       rest.empty() ? "" : " (" + rest + ")");
  };
  for (const auto& [key, kind] : {std::pair{"arms", "arm"}, std::pair{"ptus", "ptu"}, std::pair{"cameras", "camera"}}) {
    const auto list = devices.find(key);
    if (list == devices.end() || !list->is_array()) continue;
    for (const nlohmann::json& d : *list) line(kind, d);
  }
  if (const auto hand = devices.find("hand"); hand != devices.end()) line("hand", *hand);
  return out;
}

void AddServiceCommands(CliApp& cli, CellFactory make_cell) {
  auto run = std::make_shared<RunOptions>();
  CLI::App* run_cmd = cli.AddCommand(&cli.app, "run", "run the workcell service (systemd Type=notify)",
                                     [run, make_cell] { return RunService(*run, make_cell); });
  run_cmd->add_option("--config", run->config, "service configuration (YAML)")->required()->check(CLI::ExistingFile);
  run_cmd->add_option("--socket", run->socket, "operator control socket (overrides the configuration)");

  auto status = std::make_shared<ClientOptions>();
  AddClientFlags(cli.AddCommand(&cli.app, "status", "ask the running service for its state", [status] {
    return RunStatus(*status);
  }), status.get());

  auto job = std::make_shared<JobOptions>();
  CLI::App* job_cmd =
      cli.AddCommand(&cli.app, "job", "queue a job on the running service (`status --json` lists the jobs)",
                     [job] { return RunJob(*job); });
  job_cmd->add_option("name", job->name, "job name (e.g. calibrate-robot, calibrate-rail, calibrate-ptu, scan, pick, day)")
      ->required();
  job_cmd->add_option("--arg", job->args, "job argument key=value (repeatable)");
  AddClientFlags(job_cmd, &job->client);

  auto stop = std::make_shared<ClientOptions>();
  AddClientFlags(cli.AddCommand(&cli.app, "stop", "safe stop: cancel jobs and stop every device", [stop] {
    return RunStop(*stop, ControlCommand::kStop);
  }), stop.get());
  auto reset = std::make_shared<ClientOptions>();
  AddClientFlags(cli.AddCommand(&cli.app, "reset", "leave the fault state (reconnect and home)", [reset] {
    return RunStop(*reset, ControlCommand::kReset);
  }), reset.get());
}

}  // namespace idi::workcell
