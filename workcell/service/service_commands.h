// `idi-workcell run --config FILE` (the service) and its operator clients `status`, `job`, `stop`.
#pragma once

#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "shared/runtime/cli.h"
#include "workcell/service/service.h"
#include "workcell/service/workcell_config.h"

namespace idi::workcell {

// What the service runs: the devices for the configured backend and the jobs they serve.
struct Cell {
  std::unique_ptr<DeviceSet> devices;
  std::vector<JobSpec> jobs;
  std::vector<std::string> calibration_jobs;      // run (in order) when the calibration is missing/stale
  std::vector<std::string> calibration_items;     // what a complete calibration holds
  std::map<std::string, std::string> calibration_job_for_item;       // the job that makes each item
  std::vector<std::pair<std::string, nlohmann::json>> startup_jobs;  // queued after the calibration check
};
using CellFactory = std::function<Result<Cell>(const WorkcellConfig& config)>;

// The devices' health (DeviceSet::Health, as `status --json` gives it under "devices") as lines for a
// person: one per arm, PTU, hand and camera, its state first, then what else it reports.
std::string FormatDeviceHealth(const nlohmann::json& devices);

// Registers run/status/job/stop. `make_cell` builds the devices and jobs for a configuration.
void AddServiceCommands(CliApp& cli, CellFactory make_cell);

}  // namespace idi::workcell
