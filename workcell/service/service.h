// idi-workcell's service state machine (`idi-workcell run`).
//
//   starting -> connecting -> homing -> checking calibration -> idle <-> busy (one job at a time)
//                    \____________\___________\______________________\-> fault (devices stopped)
//   any state -> stopping (operator stop or signal: cancel the job, stop every device) -> idle / exit
//
// Jobs are registered by name with an argument validator and a run function; they run on a worker
// thread, report progress, check a cancel flag, and write their results into a run folder of their
// own under the state directory. Any device fault stops every device and parks the service in
// `fault` until the operator sends `reset`. systemd is told READY once idle the first time, gets
// watchdog pings while the main loop is alive, and STOPPING on the way out.
#pragma once

#include <atomic>
#include <condition_variable>
#include <deque>
#include <functional>
#include <map>
#include <mutex>
#include <string>
#include <thread>

#include "workcell/service/calibration_store.h"
#include "workcell/service/control_protocol.h"

namespace idi::workcell {

enum class ServiceState { kStarting, kConnecting, kHoming, kCheckingCalibration, kIdle, kBusy, kStopping, kFault,
                          kShuttingDown };
const char* ServiceStateName(ServiceState s);

// The cell's devices as the service sees them: bring up, home, stop everything, report health.
class DeviceSet {
 public:
  virtual ~DeviceSet() = default;
  virtual Status Connect() = 0;
  virtual Status Home() = 0;
  // Commands every device to a safe stop; must work from any state and be quick.
  virtual Status StopAll() = 0;
  virtual nlohmann::json Health() = 0;
};

struct JobContext {
  const std::atomic<bool>* cancel = nullptr;
  std::function<void(double fraction, const std::string& what)> progress;
  std::string run_dir;                  // results of this run go here
  CalibrationStore* calibration = nullptr;
  DeviceSet* devices = nullptr;
  bool cancelled() const { return cancel != nullptr && cancel->load(); }
};

struct JobSpec {
  std::string name;
  std::string description;
  // Checks the arguments before the job is queued (InvalidArgument naming the field).
  std::function<Status(const nlohmann::json& args)> validate;
  // Runs the job; returns its summary (written to report.json in the run folder).
  std::function<Result<nlohmann::json>(JobContext& context, const nlohmann::json& args)> run;
};

struct ServiceOptions {
  std::string state_dir = "/var/lib/idi-workcell";
  double calibration_max_age_days = 30;
  bool recalibrate_when_stale = true;
  std::vector<std::string> calibration_jobs;  // queued (in order) when the calibration is missing/stale
  std::vector<std::string> required_calibration_items;  // e.g. robot1, robot2, rail, ptu-left, ptu-right
  // The calibration job that makes each required item. An item a calibration job drops (held before it,
  // not after: a robot's new calibration drops the rail solved with the old arm) gets its job queued
  // after the calibration jobs waiting, before any other, when recalibrate_when_stale and no stop came
  // (else a warning names the job to run), unless that job is queued already or is the one that ran.
  std::map<std::string, std::string> calibration_job_for_item;
  // Queued once at the first start, after any calibration jobs (e.g. the simulated day's scans).
  std::vector<std::pair<std::string, nlohmann::json>> startup_jobs;
  // Run() returns when the queue has run dry (demonstrations, CI): an error when a job failed.
  bool exit_when_idle = false;
};

inline constexpr std::size_t kMaxQueuedJobs = 100;

class WorkcellService {
 public:
  WorkcellService(ServiceOptions options, DeviceSet* devices, std::vector<JobSpec> jobs);
  ~WorkcellService();

  // Handles one operator request (thread-safe; called from the control socket thread).
  nlohmann::json Handle(const ControlRequest& request);
  // Runs until shutdown: the start-up sequence, then jobs. Returns the reason it ended.
  idi::Status Run();
  // Asks Run() to stop safely and return (signals and the `shutdown` command).
  void RequestShutdown();
  ServiceState state() const;
  nlohmann::json StatusJson() const;

 private:
  void SetState(ServiceState s, const std::string& why);
  // Connects, homes and checks the calibration; Cancelled if the operator stopped after `stops_before`
  // (stops_ when this start-up was asked for).
  idi::Status StartUp(uint64_t stops_before);
  void WorkerLoop();
  bool IsCalibrationJob(const std::string& name) const;  // one of options_.calibration_jobs
  // With mu_ held, after a calibration job: queues the jobs of the items it dropped (see
  // ServiceOptions::calibration_job_for_item).
  void QueueDroppedCalibrationLocked(const std::string& after_job, const std::vector<std::string>& dropped);
  void SafeStop(const std::string& why);
  std::string MakeRunDir(const std::string& job);

  ServiceOptions options_;
  DeviceSet* devices_;
  std::map<std::string, JobSpec> jobs_;
  CalibrationStore calibration_;

  mutable std::mutex mu_;
  std::condition_variable cv_;
  ServiceState state_ = ServiceState::kStarting;
  std::string state_reason_;
  struct QueuedJob {
    uint64_t id;
    std::string name;
    nlohmann::json args;
  };
  std::deque<QueuedJob> queue_;
  uint64_t next_job_id_ = 1;
  std::string current_job_;
  uint64_t current_job_id_ = 0;
  double progress_ = 0;
  std::string progress_what_;
  nlohmann::json last_result_;
  std::string last_error_;
  bool reset_requested_ = false;
  // Operator stops so far (SafeStop): a start-up (the first, or a reset) that a stop followed is
  // abandoned, even when the stop came before the devices' Connect, which clears their own stop.
  uint64_t stops_ = 0;
  bool startup_jobs_queued_ = false;
  int jobs_failed_ = 0;
  std::string first_failure_;
  std::atomic<bool> cancel_{false};
  std::atomic<bool> shutdown_{false};
  std::thread worker_;
};

}  // namespace idi::workcell
