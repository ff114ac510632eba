#include "workcell/service/service.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <ctime>
#include <filesystem>

#include "shared/runtime/systemd_notify.h"
#include "shared/util/atomic_file.h"

namespace idi::workcell {
namespace fs = std::filesystem;

const char* ServiceStateName(ServiceState s) {
  switch (s) {
    case ServiceState::kStarting: return "starting";
    case ServiceState::kConnecting: return "connecting";
    case ServiceState::kHoming: return "homing";
    case ServiceState::kCheckingCalibration: return "checking-calibration";
    case ServiceState::kIdle: return "idle";
    case ServiceState::kBusy: return "busy";
    case ServiceState::kStopping: return "stopping";
    case ServiceState::kFault: return "fault";
    case ServiceState::kShuttingDown: return "shutting-down";
  }
  return "?";
}

WorkcellService::WorkcellService(ServiceOptions options, DeviceSet* devices, std::vector<JobSpec> jobs)
    : options_(std::move(options)), devices_(devices), calibration_(options_.state_dir) {
  for (JobSpec& j : jobs) jobs_[j.name] = std::move(j);
}

WorkcellService::~WorkcellService() {
  RequestShutdown();
  if (worker_.joinable()) worker_.join();
}

ServiceState WorkcellService::state() const {
  std::lock_guard<std::mutex> lock(mu_);
  return state_;
}

void WorkcellService::SetState(ServiceState s, const std::string& why) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    state_ = s;
    state_reason_ = why;
  }
  spdlog::info("service: {} ({})", ServiceStateName(s), why);
  NotifyStatus(std::string(ServiceStateName(s)) + ": " + why);
  cv_.notify_all();
}

nlohmann::json WorkcellService::StatusJson() const {
  std::lock_guard<std::mutex> lock(mu_);
  nlohmann::json s;
  s["state"] = ServiceStateName(state_);
  s["reason"] = state_reason_;
  s["job"] = current_job_.empty() ? nlohmann::json() : nlohmann::json{{"id", current_job_id_}, {"name", current_job_},
                                                                        {"progress", progress_}, {"what", progress_what_}};
  nlohmann::json q = nlohmann::json::array();
  for (const QueuedJob& j : queue_) q.push_back({{"id", j.id}, {"name", j.name}});
  s["queue"] = q;
  s["last_result"] = last_result_;
  s["last_error"] = last_error_;
  nlohmann::json names = nlohmann::json::array();
  for (const auto& [name, spec] : jobs_) names.push_back({{"name", name}, {"description", spec.description}});
  s["jobs"] = names;
  return s;
}

nlohmann::json WorkcellService::Handle(const ControlRequest& r) {
  switch (r.command) {
    case ControlCommand::kStatus: {
      nlohmann::json s = StatusJson();
      s["devices"] = devices_->Health();
      const auto cal = calibration_.Current();
      if (cal.ok() && cal->has_value()) {
        s["calibration"] = {{"version", (*cal)->number}, {"created_unix_s", (*cal)->created_unix_s},
                            {"items", (*cal)->items}};
      }
      return OkReply(s);
    }
    case ControlCommand::kJob: {
      const auto it = jobs_.find(r.job);
      if (it == jobs_.end()) return ErrorReply("unknown job \"" + r.job + "\"");
      if (it->second.validate) {
        const idi::Status st = it->second.validate(r.args);
        if (!st.ok()) return ErrorReply("job \"" + r.job + "\": " + st.message());
      }
      std::lock_guard<std::mutex> lock(mu_);
      if (state_ == ServiceState::kFault) return ErrorReply("the cell is in fault (" + last_error_ + "): send reset first");
      if (state_ == ServiceState::kShuttingDown) return ErrorReply("the service is shutting down");
      // Jobs run for minutes: a longer queue is a client gone wrong, and every status reply lists it.
      if (queue_.size() >= kMaxQueuedJobs) {
        return ErrorReply("the job queue is full (" + std::to_string(kMaxQueuedJobs) + " jobs waiting)");
      }
      const uint64_t id = next_job_id_++;
      queue_.push_back({id, r.job, r.args});
      cv_.notify_all();
      return OkReply({{"job_id", id}, {"queued", queue_.size()}});
    }
    case ControlCommand::kStop:
      SafeStop("operator stop");
      return OkReply({{"stopped", true}});
    case ControlCommand::kReset: {
      std::lock_guard<std::mutex> lock(mu_);
      if (state_ != ServiceState::kFault) return ErrorReply(std::string("not in fault (state ") + ServiceStateName(state_) + ")");
      reset_requested_ = true;
      cv_.notify_all();
      return OkReply({{"resetting", true}});
    }
    case ControlCommand::kShutdown:
      RequestShutdown();
      return OkReply({{"shutting_down", true}});
  }
  return ErrorReply("unhandled command");
}

void WorkcellService::SafeStop(const std::string& why) {
  {
    // With the queue, under the lock the worker takes a job with: a job taken just before this is
    // cancelled, one not yet taken is gone (set after the worker's reset, never before it).
    std::lock_guard<std::mutex> lock(mu_);
    queue_.clear();
    cancel_ = true;
    // A reset asked for before this stop and not yet begun is dropped; one under way is abandoned
    // (StartUp sees the count change).
    reset_requested_ = false;
    ++stops_;
  }
  const idi::Status st = devices_->StopAll();
  if (!st.ok()) spdlog::error("service: stopping the devices failed: {}", st.message());
  spdlog::warn("service: safe stop: {}", why);
  cv_.notify_all();
}

void WorkcellService::RequestShutdown() {
  {
    std::lock_guard<std::mutex> lock(mu_);  // see SafeStop
    shutdown_ = true;
    cancel_ = true;
  }
  cv_.notify_all();
}

std::string WorkcellService::MakeRunDir(const std::string& job) {
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&now, &tm);
  char stamp[32];
  std::strftime(stamp, sizeof(stamp), "%Y%m%dT%H%M%SZ", &tm);
  fs::path dir = fs::path(options_.state_dir) / "runs" / (std::string(stamp) + "-" + job);
  for (int k = 2; fs::exists(dir); ++k) {
    dir = fs::path(options_.state_dir) / "runs" / (std::string(stamp) + "-" + job + "-" + std::to_string(k));
  }
  std::error_code ec;
  fs::create_directories(dir, ec);
  return dir.string();
}

idi::Status WorkcellService::StartUp(uint64_t stops_before) {
  SetState(ServiceState::kConnecting, "connecting to the devices");
  IDI_RETURN_IF_ERROR(devices_->Connect().WithContext("connecting"));
  // Connect cleared the devices' stop flag: a stop that came after this start-up was asked for and
  // before that (which the devices no longer know of) still ends it; so does one during homing (a
  // device set that does not refuse operations after a stop) or the calibration check.
  auto stopped = [&] { return stops_ != stops_before; };  // with mu_ held
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (stopped()) return idi::Cancelled("connecting: stopped by the operator; send reset to start again");
  }
  SetState(ServiceState::kHoming, "homing");
  IDI_RETURN_IF_ERROR(devices_->Home().WithContext("homing"));
  SetState(ServiceState::kCheckingCalibration, "checking the calibration's age and completeness");
  IDI_ASSIGN_OR_RETURN(const auto current, calibration_.Current());
  std::string why;
  if (!current) {
    why = "no calibration yet";
  } else {
    const double age_days = static_cast<double>(std::time(nullptr) - current->created_unix_s) / 86400.0;
    if (age_days > options_.calibration_max_age_days) why = "calibration is " + FormatNumber(age_days) + " days old";
    for (const std::string& item : options_.required_calibration_items) {
      if (current->items.count(item) == 0) why = "calibration lacks " + item;
    }
  }
  if (!why.empty()) spdlog::warn("service: {}", why);
  // Under the lock a stop clears the queue with: no job is queued after a stop.
  std::lock_guard<std::mutex> lock(mu_);
  if (stopped()) return idi::Cancelled("starting up: stopped by the operator; send reset to start again");
  if (!why.empty() && options_.recalibrate_when_stale) {
    for (const std::string& job : options_.calibration_jobs) {
      if (jobs_.count(job) != 0) queue_.push_back({next_job_id_++, job, nlohmann::json::object()});
    }
  }
  if (!startup_jobs_queued_) {
    startup_jobs_queued_ = true;
    for (const auto& [job, args] : options_.startup_jobs) {
      if (jobs_.count(job) == 0) {
        spdlog::error("service: start-up job '{}' is not served by this cell; skipped", job);
        continue;
      }
      queue_.push_back({next_job_id_++, job, args});
    }
  }
  return idi::Status::Ok();
}

idi::Status WorkcellService::Run() {
  IDI_RETURN_IF_ERROR(calibration_.Open());
  const auto watchdog = WatchdogPeriod();
  const auto tick = watchdog ? std::chrono::duration_cast<std::chrono::milliseconds>(*watchdog / 3)
                             : std::chrono::milliseconds(200);
  // Any stop since the service began (the control socket may already be open) ends the first start-up.
  idi::Status st = StartUp(0);
  if (!st.ok()) {
    {
      std::lock_guard<std::mutex> lock(mu_);  // the control socket may already read it
      last_error_ = st.message();
    }
    (void)devices_->StopAll();
    SetState(ServiceState::kFault, st.message());
  } else {
    SetState(ServiceState::kIdle, "ready");
  }
  NotifyReady();
  worker_ = std::thread([this] { WorkerLoop(); });
  std::unique_lock<std::mutex> lock(mu_);
  idi::Status ended = idi::Status::Ok();
  while (!shutdown_) {
    cv_.wait_for(lock, tick);
    NotifyWatchdog();
    if (options_.exit_when_idle && queue_.empty() && current_job_.empty() &&
        (state_ == ServiceState::kIdle || state_ == ServiceState::kFault)) {
      if (state_ == ServiceState::kFault) {
        ended = idi::DeviceError("service: ended in the fault state: " + state_reason_);
      } else if (jobs_failed_ > 0) {
        ended = idi::Internal("service: " + std::to_string(jobs_failed_) + " job(s) failed; first: " + first_failure_);
      }
      spdlog::info("service: the queue has run dry; exiting (exit_when_idle)");
      shutdown_ = true;
      break;
    }
    if (state_ == ServiceState::kFault && reset_requested_) {
      reset_requested_ = false;
      const uint64_t stops_at_reset = stops_;
      lock.unlock();
      // Connecting and homing take up to about a minute on the real cell (the pan-tilt units' moves,
      // the hand's initialisation, each with its own timeout): the watchdog is kept fed meanwhile, or
      // systemd would abort the service half-way through homing.
      std::atomic<bool> starting{true};
      std::thread pinger([&] {
        while (starting) {
          NotifyWatchdog();
          for (auto waited = std::chrono::milliseconds(0); starting && waited < tick;
               waited += std::chrono::milliseconds(20)) {
            std::this_thread::sleep_for(std::chrono::milliseconds(20));
          }
        }
      });
      const idi::Status again = StartUp(stops_at_reset);
      starting = false;
      pinger.join();
      if (again.ok()) {
        SetState(ServiceState::kIdle, "reset");
      } else {
        (void)devices_->StopAll();
        {
          std::lock_guard<std::mutex> relock(mu_);
          last_error_ = again.message();
        }
        SetState(ServiceState::kFault, again.message());
      }
      lock.lock();
    }
  }
  lock.unlock();
  SetState(ServiceState::kShuttingDown, "shutdown requested");
  NotifyStopping();
  cancel_ = true;
  cv_.notify_all();
  std::string running;
  {
    std::lock_guard<std::mutex> relock(mu_);
    running = current_job_;
  }
  if (!running.empty()) {
    // Stop the devices now, not when the job notices the cancel (a move in flight ends here).
    const idi::Status now = devices_->StopAll();
    spdlog::warn("service: shutting down during job '{}': devices {}", running,
                 now.ok() ? std::string("commanded to stop") : "stop failed: " + now.message());
  }
  if (worker_.joinable()) worker_.join();
  const idi::Status last = devices_->StopAll();
  spdlog::info("service: devices {}", last.ok() ? std::string("stopped") : "stop failed: " + last.message());
  return ended;
}

bool WorkcellService::IsCalibrationJob(const std::string& name) const {
  return std::find(options_.calibration_jobs.begin(), options_.calibration_jobs.end(), name) !=
         options_.calibration_jobs.end();
}

void WorkcellService::QueueDroppedCalibrationLocked(const std::string& after_job,
                                                    const std::vector<std::string>& dropped) {
  for (const std::string& item : dropped) {
    const auto it = options_.calibration_job_for_item.find(item);
    if (it == options_.calibration_job_for_item.end() || jobs_.count(it->second) == 0 || it->second == after_job) {
      spdlog::warn("service: job '{}' left the calibration without {}", after_job, item);
      continue;
    }
    const std::string& job = it->second;
    if (std::any_of(queue_.begin(), queue_.end(), [&job](const QueuedJob& q) { return q.name == job; })) continue;
    if (!options_.recalibrate_when_stale || cancel_ || shutdown_ || queue_.size() >= kMaxQueuedJobs) {
      spdlog::warn("service: job '{}' left the calibration without {}: run job {}", after_job, item, job);
      continue;
    }
    // Before the jobs that need it (a scan queued behind the robot's calibration), after any
    // calibration jobs already waiting.
    auto at =
        std::find_if(queue_.begin(), queue_.end(), [this](const QueuedJob& q) { return !IsCalibrationJob(q.name); });
    at = queue_.insert(at, {next_job_id_++, job, nlohmann::json::object()});
    spdlog::warn("service: job '{}' left the calibration without {}; queued job {} '{}'", after_job, item, at->id, job);
  }
}

void WorkcellService::WorkerLoop() {
  while (true) {
    QueuedJob job;
    {
      std::unique_lock<std::mutex> lock(mu_);
      cv_.wait(lock, [&] { return shutdown_ || (!queue_.empty() && state_ == ServiceState::kIdle); });
      if (shutdown_) return;
      job = queue_.front();
      queue_.pop_front();
      current_job_ = job.name;
      current_job_id_ = job.id;
      progress_ = 0;
      progress_what_.clear();
      state_ = ServiceState::kBusy;
      state_reason_ = "running " + job.name;
      cancel_ = false;  // under the lock: a stop or shutdown from now on cancels this job
    }
    spdlog::info("service: job {} '{}' started", job.id, job.name);
    JobContext ctx;
    ctx.cancel = &cancel_;
    ctx.run_dir = MakeRunDir(job.name);
    ctx.calibration = &calibration_;
    ctx.devices = devices_;
    ctx.progress = [this](double f, const std::string& what) {
      std::lock_guard<std::mutex> lock(mu_);
      progress_ = f;
      progress_what_ = what;
    };
    const bool calibration_job = IsCalibrationJob(job.name);
    std::vector<std::string> items_before;  // the required items the calibration holds before the job
    if (calibration_job) {
      if (const auto before = calibration_.Current(); before.ok() && before->has_value()) {
        for (const std::string& item : options_.required_calibration_items) {
          if ((*before)->items.count(item) != 0) items_before.push_back(item);
        }
      }
    }
    const JobSpec& spec = jobs_.at(job.name);
    Result<nlohmann::json> result = spec.run(ctx, job.args);
    nlohmann::json report;
    report["job"] = job.name;
    report["id"] = job.id;
    report["args"] = job.args;
    bool fault = false;
    std::string error;
    if (result.ok()) {
      report["result"] = *result;
      report["ok"] = true;
    } else {
      error = result.status().message();
      report["ok"] = false;
      report["error"] = error;
      report["cancelled"] = cancel_.load();
      fault = !cancel_.load() && (result.status().code() == StatusCode::kDeviceError ||
                                  result.status().code() == StatusCode::kTimeout);
      (void)devices_->StopAll();
    }
    (void)WriteFileAtomically((fs::path(ctx.run_dir) / "report.json").string(), report.dump(2) + "\n");
    // The items a calibration job dropped: there before it, gone after (read before the lock: it reads
    // files; only this thread commits).
    std::vector<std::string> dropped;
    if (result.ok() && calibration_job) {
      const auto after = calibration_.Current();
      if (after.ok() && after->has_value()) {
        for (const std::string& item : items_before) {
          if ((*after)->items.count(item) == 0) dropped.push_back(item);
        }
      }
    }
    std::lock_guard<std::mutex> lock(mu_);
    last_result_ = report;
    current_job_.clear();
    if (fault) {
      last_error_ = job.name + ": " + error;
      queue_.clear();
      state_ = ServiceState::kFault;
      state_reason_ = last_error_;
      spdlog::error("service: device fault in job {}: {}; devices stopped, waiting for reset", job.name, error);
    } else {
      if (!error.empty()) {
        last_error_ = job.name + ": " + error;
        if (jobs_failed_++ == 0) first_failure_ = last_error_;
        spdlog::error("service: job {} '{}' failed: {}", job.id, job.name, error);
      } else {
        spdlog::info("service: job {} '{}' done, results in {}", job.id, job.name, ctx.run_dir);
      }
      QueueDroppedCalibrationLocked(job.name, dropped);
      state_ = ServiceState::kIdle;
      state_reason_ = "ready";
    }
    cv_.notify_all();
  }
}

}  // namespace idi::workcell
