#include "workcell/service/service.h"

#include <gtest/gtest.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <map>
#include <mutex>
#include <thread>
#include <vector>

#include "shared/runtime/systemd_notify.h"
#include "shared/util/atomic_file.h"
#include "workcell/service/calibration_store.h"
#include "workcell/service/control_socket.h"
#include "workcell/service/service_commands.h"

namespace idi::workcell {
namespace {

namespace fs = std::filesystem;

class FakeDevices : public DeviceSet {
 public:
  Status Connect() override { return connect_status; }
  Status Home() override { return Status::Ok(); }
  Status StopAll() override {
    ++stops;
    return Status::Ok();
  }
  nlohmann::json Health() override { return {{"fake", true}}; }
  Status connect_status = Status::Ok();
  std::atomic<int> stops{0};
};

std::string TempState(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("idi_service_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir.string();
}

template <typename Pred>
bool WaitFor(Pred pred, int ms = 5000) {
  for (int i = 0; i < ms / 5; ++i) {
    if (pred()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return pred();
}

ControlRequest Job(const std::string& name, nlohmann::json args = nlohmann::json::object()) {
  ControlRequest r;
  r.command = ControlCommand::kJob;
  r.job = name;
  r.args = std::move(args);
  return r;
}

JobSpec CountingJob(std::atomic<int>* runs) {
  JobSpec j;
  j.name = "count";
  j.description = "counts";
  j.validate = [](const nlohmann::json& a) {
    return a.contains("n") && !a["n"].is_number_integer() ? InvalidArgument("args.n must be an integer") : Status::Ok();
  };
  j.run = [runs](JobContext& ctx, const nlohmann::json&) -> Result<nlohmann::json> {
    ctx.progress(0.5, "half way");
    ++*runs;
    return nlohmann::json{{"runs", runs->load()}};
  };
  return j;
}

JobSpec SlowJob(std::atomic<bool>* started) {
  JobSpec j;
  j.name = "slow";
  j.run = [started](JobContext& ctx, const nlohmann::json&) -> Result<nlohmann::json> {
    *started = true;
    while (!ctx.cancelled()) std::this_thread::sleep_for(std::chrono::milliseconds(2));
    return Cancelled("stopped by the operator");
  };
  return j;
}

JobSpec FaultyJob() {
  JobSpec j;
  j.name = "faulty";
  j.run = [](JobContext&, const nlohmann::json&) -> Result<nlohmann::json> {
    return DeviceError("arm 1: controller stopped answering");
  };
  return j;
}

// `status` shows the devices to a person: each arm, PTU, camera and the hand on its own line, state
// first; the sim's arms (ok / error) too; a busy snapshot says so; anything that is not health is
// nothing.
TEST(ServiceTest, StatusShowsEachDeviceOnALine) {
  const nlohmann::json hw = nlohmann::json::parse(R"({
    "backend": "hardware", "busy": true,
    "arms": [{"name": "arm1", "state": "ready", "timeouts": 0, "faults": 1}],
    "ptus": [{"name": "ptu-left", "state": "disconnected", "timeouts": 2, "faults": 0}],
    "hand": {"name": "barrett", "state": "ready", "timeouts": 0, "faults": 0},
    "cameras": [{"name": "left", "backend": "v4l2", "device": "/dev/video0", "state": "stopped", "frames": 0,
                 "last_error": "not found: camera left (/dev/video0): no such device node"}]})");
  const std::string text = FormatDeviceHealth(hw);
  EXPECT_EQ(text,
            "devices (hardware, busy: a device operation is in progress, this is from before it):\n"
            "  arm arm1: ready (faults 1, timeouts 0)\n"
            "  ptu ptu-left: disconnected (faults 0, timeouts 2)\n"
            "  camera left: stopped (backend v4l2, device /dev/video0, frames 0, last_error not found: camera left "
            "(/dev/video0): no such device node)\n"
            "  hand barrett: ready (faults 0, timeouts 0)\n");
  const nlohmann::json sim = nlohmann::json::parse(
      R"({"backend": "sim", "arms": [{"name": "rx130-1", "ok": true, "joints_deg": [0, 1]},
                                     {"name": "rx130-2", "ok": false, "error": "stopped"}]})");
  EXPECT_EQ(FormatDeviceHealth(sim),
            "devices (sim):\n  arm rx130-1: ok (joints_deg [0,1])\n  arm rx130-2: error (error stopped)\n");
  EXPECT_EQ(FormatDeviceHealth(nlohmann::json("x")), "");
}

TEST(ServiceTest, RunsJobsAndWritesReports) {
  FakeDevices dev;
  std::atomic<int> runs{0};
  ServiceOptions opt;
  opt.state_dir = TempState("jobs");
  WorkcellService svc(opt, &dev, {CountingJob(&runs)});
  std::thread t([&] { ASSERT_TRUE(svc.Run().ok()); });
  ASSERT_TRUE(WaitFor([&] { return svc.state() == ServiceState::kIdle; }));
  EXPECT_TRUE(svc.Handle(Job("count"))["ok"].get<bool>());
  EXPECT_TRUE(WaitFor([&] { return runs == 1 && svc.state() == ServiceState::kIdle; }));
  // Validation happens before queuing; unknown jobs are refused.
  EXPECT_FALSE(svc.Handle(Job("count", {{"n", "three"}}))["ok"].get<bool>());
  const auto unknown = svc.Handle(Job("dance"));
  EXPECT_FALSE(unknown["ok"].get<bool>());
  EXPECT_NE(unknown["error"].get<std::string>().find("unknown job"), std::string::npos);
  svc.RequestShutdown();
  t.join();
  int reports = 0;
  for (const auto& e : fs::recursive_directory_iterator(fs::path(opt.state_dir) / "runs")) {
    reports += e.path().filename() == "report.json";
  }
  EXPECT_EQ(reports, 1);
  EXPECT_GE(dev.stops, 1);  // devices stopped on the way out
  fs::remove_all(opt.state_dir);
}

// The simulated day's form: start-up jobs run once, then the service returns by itself; a failed job
// makes Run() return an error naming it.
TEST(ServiceTest, StartupJobsRunThenExitWhenIdle) {
  FakeDevices dev;
  std::atomic<int> runs{0};
  ServiceOptions opt;
  opt.state_dir = TempState("day");
  opt.startup_jobs = {{"count", nlohmann::json::object()}, {"count", nlohmann::json::object()}};
  opt.exit_when_idle = true;
  WorkcellService svc(opt, &dev, {CountingJob(&runs)});
  const Status st = svc.Run();  // returns without a shutdown request
  EXPECT_TRUE(st.ok()) << st.ToString();
  EXPECT_EQ(runs, 2);
  EXPECT_GE(dev.stops, 1);
  fs::remove_all(opt.state_dir);

  ServiceOptions bad;
  bad.state_dir = TempState("day_fail");
  bad.startup_jobs = {{"faulty", nlohmann::json::object()}};
  bad.exit_when_idle = true;
  JobSpec failing;
  failing.name = "faulty";
  failing.run = [](JobContext&, const nlohmann::json&) -> Result<nlohmann::json> {
    return NotFound("no object on the table");
  };
  WorkcellService svc2(bad, &dev, {failing});
  const Status st2 = svc2.Run();
  ASSERT_FALSE(st2.ok());
  EXPECT_NE(st2.message().find("no object on the table"), std::string::npos) << st2.ToString();
  fs::remove_all(bad.state_dir);
}

TEST(ServiceTest, StopCancelsTheRunningJobAndStopsDevices) {
  FakeDevices dev;
  std::atomic<bool> started{false};
  ServiceOptions opt;
  opt.state_dir = TempState("stop");
  WorkcellService svc(opt, &dev, {SlowJob(&started)});
  std::thread t([&] { (void)svc.Run(); });
  ASSERT_TRUE(WaitFor([&] { return svc.state() == ServiceState::kIdle; }));
  svc.Handle(Job("slow"));
  ASSERT_TRUE(WaitFor([&] { return started.load(); }));
  EXPECT_EQ(svc.state(), ServiceState::kBusy);
  const int stops_before = dev.stops;
  ControlRequest stop;
  stop.command = ControlCommand::kStop;
  EXPECT_TRUE(svc.Handle(stop)["ok"].get<bool>());
  EXPECT_TRUE(WaitFor([&] { return svc.state() == ServiceState::kIdle; }));
  EXPECT_GT(dev.stops, stops_before);
  svc.RequestShutdown();
  t.join();
  fs::remove_all(opt.state_dir);
}

// The queue is bounded: a client that queues jobs in a loop is told so, and the service goes on.
TEST(ServiceTest, TheJobQueueIsBounded) {
  FakeDevices dev;
  ServiceOptions opt;
  opt.state_dir = TempState("queue");
  std::atomic<bool> started{false};
  WorkcellService svc(opt, &dev, {SlowJob(&started)});
  std::thread t([&] { (void)svc.Run(); });
  ASSERT_TRUE(WaitFor([&] { return svc.state() == ServiceState::kIdle; }));
  ASSERT_TRUE(svc.Handle(Job("slow"))["ok"].get<bool>());
  ASSERT_TRUE(WaitFor([&] { return started.load(); }));  // running, so the rest waits in the queue
  for (std::size_t i = 0; i < kMaxQueuedJobs; ++i) ASSERT_TRUE(svc.Handle(Job("slow"))["ok"].get<bool>()) << i;
  const nlohmann::json full = svc.Handle(Job("slow"));
  EXPECT_FALSE(full["ok"].get<bool>());
  EXPECT_NE(full.dump().find("the job queue is full"), std::string::npos) << full.dump();
  ControlRequest stop;
  stop.command = ControlCommand::kStop;
  EXPECT_TRUE(svc.Handle(stop)["ok"].get<bool>());
  EXPECT_TRUE(WaitFor([&] { return svc.state() == ServiceState::kIdle; }));
  svc.RequestShutdown();
  t.join();
  fs::remove_all(opt.state_dir);
}

TEST(ServiceTest, DeviceFaultParksInFaultUntilReset) {
  FakeDevices dev;
  ServiceOptions opt;
  opt.state_dir = TempState("fault");
  std::atomic<int> runs{0};
  WorkcellService svc(opt, &dev, {FaultyJob(), CountingJob(&runs)});
  std::thread t([&] { (void)svc.Run(); });
  ASSERT_TRUE(WaitFor([&] { return svc.state() == ServiceState::kIdle; }));
  svc.Handle(Job("faulty"));
  ASSERT_TRUE(WaitFor([&] { return svc.state() == ServiceState::kFault; }));
  EXPECT_FALSE(svc.Handle(Job("count"))["ok"].get<bool>());  // refused while in fault
  ControlRequest reset;
  reset.command = ControlCommand::kReset;
  EXPECT_TRUE(svc.Handle(reset)["ok"].get<bool>());
  ASSERT_TRUE(WaitFor([&] { return svc.state() == ServiceState::kIdle; }));
  svc.Handle(Job("count"));
  EXPECT_TRUE(WaitFor([&] { return runs == 1; }));
  svc.RequestShutdown();
  t.join();
  fs::remove_all(opt.state_dir);
}

// An operator's stop sent after a reset and before the devices' Connect (which clears their stop: the
// start of a restart the operator asked for) ends that reset: the cell stays in fault, nothing is
// homed. Before, the reset's Connect erased the later stop and the cell homed and went idle. So does a
// stop during homing on devices that do not refuse operations after a stop (the sim's), and no job is
// queued after it.
TEST(ServiceTest, AStopAfterAResetEndsThatReset) {
  // Devices like the hardware set: Connect clears their stop flag, Home refuses while it is set (unless
  // `home_ignores_stop`). A gated Connect or Home waits until the test has sent its stop.
  class GatedDevices : public FakeDevices {
   public:
    Status Connect() override {
      Wait(gate_connect);
      stopped = false;
      return connect_status;
    }
    Status Home() override {
      Wait(gate_home);
      if (stopped && !home_ignores_stop) return Cancelled("homing: stopped");
      ++homes;
      return Status::Ok();
    }
    Status StopAll() override {
      stopped = true;
      return FakeDevices::StopAll();
    }
    void Wait(const std::atomic<bool>& gate) {
      if (!gate) return;
      entered = true;
      while (!release) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    std::atomic<bool> gate_connect{false}, gate_home{false}, home_ignores_stop{false};
    std::atomic<bool> entered{false}, release{false}, stopped{false};
    std::atomic<int> homes{0};
  } dev;
  dev.connect_status = Timeout("arm 2: no answer");
  ServiceOptions opt;
  opt.state_dir = TempState("stop_after_reset");
  std::atomic<int> runs{0};
  opt.startup_jobs = {{"count", nlohmann::json::object()}};
  WorkcellService svc(opt, &dev, {CountingJob(&runs)});
  std::thread t([&] { (void)svc.Run(); });
  // The service ends and its thread is joined however the test ends (a failed ASSERT too).
  struct Ender {
    WorkcellService& svc;
    GatedDevices& dev;
    std::thread& t;
    ~Ender() {
      dev.release = true;
      svc.RequestShutdown();
      if (t.joinable()) t.join();
    }
  } ender{svc, dev, t};
  ASSERT_TRUE(WaitFor([&] { return svc.state() == ServiceState::kFault; }));
  dev.connect_status = Status::Ok();
  ControlRequest reset;
  reset.command = ControlCommand::kReset;
  ControlRequest stop;
  stop.command = ControlCommand::kStop;
  // A reset whose gated step (`gate`) gets the operator's stop before it goes on: the cell must stay in
  // fault, for that stop.
  auto reset_then_stop = [&](std::atomic<bool>& gate, const std::string& why) {
    dev.gate_connect = false;
    dev.gate_home = false;
    dev.entered = false;
    dev.release = false;
    gate = true;
    ASSERT_TRUE(svc.Handle(reset)["ok"].get<bool>());
    ASSERT_TRUE(WaitFor([&] { return dev.entered.load(); }));
    EXPECT_TRUE(svc.Handle(stop)["ok"].get<bool>());
    dev.release = true;
    EXPECT_TRUE(WaitFor([&] {
      return svc.state() == ServiceState::kFault && svc.StatusJson().dump().find(why) != std::string::npos;
    })) << svc.StatusJson().dump();
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    EXPECT_EQ(svc.state(), ServiceState::kFault);
    EXPECT_TRUE(svc.StatusJson()["queue"].empty()) << "a job was queued after the operator's stop";
    gate = false;
  };
  // The stop while the reset's Connect has not yet cleared the devices' flag.
  reset_then_stop(dev.gate_connect, "connecting: stopped by the operator");
  EXPECT_EQ(dev.homes, 0) << "the cell homed after the operator's stop";
  // The stop while homing, on devices that go on after a stop.
  dev.home_ignores_stop = true;
  reset_then_stop(dev.gate_home, "starting up: stopped by the operator");
  EXPECT_EQ(runs, 0) << "a start-up job ran after the operator's stop";
  // A reset with no stop after it works, and queues the start-up job.
  ASSERT_TRUE(svc.Handle(reset)["ok"].get<bool>());
  EXPECT_TRUE(WaitFor([&] { return runs == 1; }));
  EXPECT_EQ(dev.homes, 2);
  fs::remove_all(opt.state_dir);
}

// A reset reconnects and homes (up to about a minute on the real cell): systemd's watchdog must keep
// hearing from the service meanwhile. The notifications go to a socket of the test's own.
TEST(ServiceTest, ResetKeepsTheWatchdogFed) {
  const std::string dir = TempState("watchdog");
  const std::string sock_path = dir + "/notify.sock";
  const int sock = ::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
  ASSERT_GE(sock, 0);
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  std::strncpy(addr.sun_path, sock_path.c_str(), sizeof(addr.sun_path) - 1);
  ASSERT_EQ(::bind(sock, reinterpret_cast<const sockaddr*>(&addr), sizeof(addr)), 0) << std::strerror(errno);
  ::setenv("NOTIFY_SOCKET", sock_path.c_str(), 1);
  ::setenv("WATCHDOG_USEC", "300000", 1);  // a ping every 100 ms
  ::unsetenv("WATCHDOG_PID");
  if (!WatchdogPeriod()) {
    ::close(sock);
    GTEST_SKIP() << "built without libsystemd: no notifications to count";
  }
  // Pings received so far (other notifications are drained and not counted).
  auto drain_pings = [&] {
    int pings = 0;
    char buf[256];
    ssize_t n;
    while ((n = ::recv(sock, buf, sizeof(buf) - 1, 0)) > 0) {
      buf[n] = 0;
      if (std::strstr(buf, "WATCHDOG=1") != nullptr) ++pings;
    }
    return pings;
  };
  // Devices whose connection takes 1.5 s once they are back.
  class SlowDevices : public FakeDevices {
   public:
    Status Connect() override {
      if (slow) std::this_thread::sleep_for(std::chrono::milliseconds(1500));
      return connect_status;
    }
    std::atomic<bool> slow{false};
  } dev;
  dev.connect_status = Timeout("arm 2: no answer");
  ServiceOptions opt;
  opt.state_dir = dir;
  WorkcellService svc(opt, &dev, {});
  std::thread t([&] { (void)svc.Run(); });
  ASSERT_TRUE(WaitFor([&] { return svc.state() == ServiceState::kFault; }));
  dev.connect_status = Status::Ok();
  dev.slow = true;
  ControlRequest reset;
  reset.command = ControlCommand::kReset;
  ASSERT_TRUE(svc.Handle(reset)["ok"].get<bool>());
  std::this_thread::sleep_for(std::chrono::milliseconds(150));  // the reset has begun connecting
  (void)drain_pings();
  std::this_thread::sleep_for(std::chrono::milliseconds(1000));  // inside the 1.5 s connection
  const int pings = drain_pings();
  EXPECT_GE(pings, 5) << "the watchdog went unfed while the cell reconnected";
  EXPECT_TRUE(WaitFor([&] { return svc.state() == ServiceState::kIdle; }));
  svc.RequestShutdown();
  t.join();
  ::unsetenv("NOTIFY_SOCKET");
  ::unsetenv("WATCHDOG_USEC");
  ::close(sock);
  fs::remove_all(dir);
}

// A calibration job that leaves the calibration without an item (a robot's new calibration drops the
// rail solved with the old arm) gets that item's job queued after it, when the service recalibrates
// what is stale; otherwise nothing is queued (the journal names the job to run).
TEST(ServiceTest, ACalibrationJobThatDropsAnItemQueuesThatItemsJob) {
  for (const bool recalibrate : {true, false}) {
    FakeDevices dev;
    ServiceOptions opt;
    opt.state_dir = TempState(recalibrate ? "dropped_item" : "dropped_item_warn");
    opt.recalibrate_when_stale = recalibrate;
    opt.calibration_jobs = {"cal-robot", "cal-rail"};
    opt.required_calibration_items = {"robot1", "rail"};
    opt.calibration_job_for_item = {{"robot1", "cal-robot"}, {"rail", "cal-rail"}};
    {
      CalibrationStore store(opt.state_dir);
      ASSERT_TRUE(store.Open().ok());
      ASSERT_TRUE(store.Commit({{"robot1", "a: 1\n"}, {"rail", "b: 1\n"}}, std::time(nullptr)).ok());
    }
    std::atomic<int> robot_runs{0}, rail_runs{0};
    JobSpec robot;
    robot.name = "cal-robot";
    robot.run = [&robot_runs](JobContext& ctx, const nlohmann::json&) -> Result<nlohmann::json> {
      IDI_RETURN_IF_ERROR(ctx.calibration->Commit({{"robot1", "a: 2\n"}}, std::time(nullptr), {"rail"}).status());
      ++robot_runs;
      return nlohmann::json::object();
    };
    JobSpec rail;
    rail.name = "cal-rail";
    rail.run = [&rail_runs](JobContext& ctx, const nlohmann::json&) -> Result<nlohmann::json> {
      IDI_RETURN_IF_ERROR(ctx.calibration->Commit({{"rail", "b: 2\n"}}, std::time(nullptr)).status());
      ++rail_runs;
      return nlohmann::json::object();
    };
    WorkcellService svc(opt, &dev, {robot, rail});
    std::thread t([&] { (void)svc.Run(); });
    ASSERT_TRUE(WaitFor([&] { return svc.state() == ServiceState::kIdle; }));
    EXPECT_EQ(rail_runs, 0) << "the calibration was complete at start";
    EXPECT_TRUE(svc.Handle(Job("cal-robot")).value("ok", false));
    ASSERT_TRUE(WaitFor([&] { return robot_runs == 1; }));
    if (recalibrate) {
      EXPECT_TRUE(WaitFor([&] { return rail_runs == 1; })) << "the rail's job was not queued";
    }
    ASSERT_TRUE(WaitFor([&] { return svc.state() == ServiceState::kIdle && svc.StatusJson()["queue"].empty(); }));
    EXPECT_EQ(rail_runs, recalibrate ? 1 : 0);
    EXPECT_EQ(robot_runs, 1);
    CalibrationStore store(opt.state_dir);
    const auto current = store.Current();
    ASSERT_TRUE(current.ok() && current->has_value());
    EXPECT_EQ((*current)->items.count("rail"), recalibrate ? 1u : 0u);
    svc.RequestShutdown();
    t.join();
    fs::remove_all(opt.state_dir);
  }
}

// Jobs that record the order they ran in; "cal-robot" commits robot1 and drops the rail, "cal-rail"
// commits the rail, "cal-ptu" the ptu, "hold" waits until released.
struct OrderedJobs {
  std::mutex mu;
  std::vector<std::string> order;
  std::atomic<bool> release{false};
  void Ran(const std::string& name) {
    std::lock_guard<std::mutex> l(mu);
    order.push_back(name);
  }
  std::vector<std::string> Order() {
    std::lock_guard<std::mutex> l(mu);
    return order;
  }
  JobSpec Committing(const std::string& name, std::map<std::string, std::string> items, std::vector<std::string> drop) {
    JobSpec j;
    j.name = name;
    j.run = [this, name, items, drop](JobContext& ctx, const nlohmann::json&) -> Result<nlohmann::json> {
      IDI_RETURN_IF_ERROR(ctx.calibration->Commit(items, std::time(nullptr), drop).status());
      Ran(name);
      return nlohmann::json::object();
    };
    return j;
  }
  std::vector<JobSpec> All() {
    JobSpec hold;
    hold.name = "hold";
    hold.run = [this](JobContext&, const nlohmann::json&) -> Result<nlohmann::json> {
      while (!release) std::this_thread::sleep_for(std::chrono::milliseconds(2));
      Ran("hold");
      return nlohmann::json::object();
    };
    JobSpec scan;
    scan.name = "scan";
    scan.run = [this](JobContext&, const nlohmann::json&) -> Result<nlohmann::json> {
      Ran("scan");
      return nlohmann::json::object();
    };
    return {hold,
            scan,
            Committing("cal-robot", {{"robot1", "a: 2\n"}}, {"rail"}),
            Committing("cal-rail", {{"rail", "b: 2\n"}}, {}),
            Committing("cal-ptu", {{"ptu", "c: 2\n"}}, {})};
  }
};

// The dropped item's job goes before the jobs queued behind the calibration (a scan that needs the
// rail), and an item that was missing before the job (the operator stopped its calibration) is not
// queued by it.
TEST(ServiceTest, ADroppedItemsJobGoesBeforeOtherJobsAndOnlyDroppedItemsAreQueued) {
  FakeDevices dev;
  ServiceOptions opt;
  opt.state_dir = TempState("dropped_item_order");
  opt.recalibrate_when_stale = true;
  opt.calibration_jobs = {"cal-robot", "cal-rail"};
  opt.required_calibration_items = {"robot1", "rail", "ptu"};
  opt.calibration_job_for_item = {{"robot1", "cal-robot"}, {"rail", "cal-rail"}, {"ptu", "cal-ptu"}};
  {
    CalibrationStore store(opt.state_dir);
    ASSERT_TRUE(store.Open().ok());
    ASSERT_TRUE(store.Commit({{"robot1", "a: 1\n"}, {"rail", "b: 1\n"}}, std::time(nullptr)).ok());  // no ptu
  }
  // The calibration lacks the ptu, so the start-up queues the calibration jobs (here robot and rail;
  // the ptu's job is not among them). Robot's drops the rail, whose job is queued already; the ptu,
  // missing before it, is not queued by it.
  OrderedJobs jobs;
  WorkcellService svc(opt, &dev, jobs.All());
  std::thread t([&] { (void)svc.Run(); });
  ASSERT_TRUE(WaitFor([&] { return svc.state() == ServiceState::kIdle && svc.StatusJson()["queue"].empty(); }));
  const std::size_t at_start = jobs.Order().size();
  EXPECT_EQ(jobs.Order(), (std::vector<std::string>{"cal-robot", "cal-rail"}));
  // Then the operator queues a robot calibration between a job in progress and a scan.
  EXPECT_TRUE(svc.Handle(Job("hold")).value("ok", false));
  EXPECT_TRUE(svc.Handle(Job("cal-robot")).value("ok", false));
  EXPECT_TRUE(svc.Handle(Job("scan")).value("ok", false));
  jobs.release = true;
  ASSERT_TRUE(WaitFor([&] { return jobs.Order().size() >= at_start + 4; })) << jobs.Order().size();
  ASSERT_TRUE(WaitFor([&] { return svc.state() == ServiceState::kIdle && svc.StatusJson()["queue"].empty(); }));
  const std::vector<std::string> order = jobs.Order();
  const std::vector<std::string> after(order.begin() + static_cast<std::ptrdiff_t>(at_start), order.end());
  EXPECT_EQ(after, (std::vector<std::string>{"hold", "cal-robot", "cal-rail", "scan"}));
  EXPECT_EQ(std::count(order.begin(), order.end(), "cal-ptu"), 0) << "the ptu was missing before, not dropped";
  svc.RequestShutdown();
  t.join();
  fs::remove_all(opt.state_dir);
}

TEST(ServiceTest, FailedStartupIsAFaultAndMissingCalibrationQueuesCalibration) {
  FakeDevices dev;
  dev.connect_status = Timeout("arm 2: no answer from 192.168.0.12:4000");
  ServiceOptions opt;
  opt.state_dir = TempState("startup");
  std::atomic<int> runs{0};
  opt.calibration_jobs = {"count"};
  opt.required_calibration_items = {"robot1"};
  WorkcellService svc(opt, &dev, {CountingJob(&runs)});
  std::thread t([&] { (void)svc.Run(); });
  ASSERT_TRUE(WaitFor([&] { return svc.state() == ServiceState::kFault; }));
  EXPECT_NE(svc.StatusJson()["reason"].get<std::string>().find("no answer"), std::string::npos);
  // The devices come back; reset reconnects and the missing calibration queues the calibration job.
  dev.connect_status = Status::Ok();
  ControlRequest reset;
  reset.command = ControlCommand::kReset;
  svc.Handle(reset);
  EXPECT_TRUE(WaitFor([&] { return runs == 1; }));
  svc.RequestShutdown();
  t.join();
  fs::remove_all(opt.state_dir);
}

TEST(CalibrationStoreTest, CommitsAtomicallyAndSurvivesAnInterruptedCommit) {
  const std::string state = TempState("calib");
  CalibrationStore store(state);
  ASSERT_TRUE(store.Open().ok());
  EXPECT_FALSE(store.Current()->has_value());
  auto v1 = store.Commit({{"robot1", "a3_mm: 625.5\n"}}, 1000);
  ASSERT_TRUE(v1.ok()) << v1.status().ToString();
  auto v2 = store.Commit({{"rail", "psi_x_mm: 4000\n"}}, 2000);
  ASSERT_TRUE(v2.ok());
  EXPECT_EQ(v2->number, 2);
  EXPECT_EQ(v2->items.size(), 2u);  // robot1 carried over
  // A commit killed half way leaves a temporary folder; the current calibration is untouched and
  // the leftover is cleaned at the next open.
  fs::create_directories(fs::path(store.root()) / "versions" / ".tmp-0003");
  ASSERT_TRUE(
      WriteFileAtomically((fs::path(store.root()) / "versions" / ".tmp-0003" / "robot1.yaml").string(), "x").ok());
  CalibrationStore reopened(state);
  ASSERT_TRUE(reopened.Open().ok());
  const auto cur = reopened.Current();
  ASSERT_TRUE(cur.ok() && cur->has_value());
  EXPECT_EQ((*cur)->number, 2);
  EXPECT_EQ(ReadFile(*reopened.CurrentItemPath("robot1")).value(), "a3_mm: 625.5\n");
  EXPECT_FALSE(fs::exists(fs::path(store.root()) / "versions" / ".tmp-0003"));
  EXPECT_EQ(reopened.CurrentItemPath("ptu-left").status().code(), StatusCode::kNotFound);
  // A commit killed after its folder became versions/0003 but before `current` was swapped: 0002
  // stays current, and the next commit goes past the orphan (it used to fail on renaming onto it).
  fs::create_directories(fs::path(store.root()) / "versions" / "0003");
  ASSERT_TRUE(WriteFileAtomically((fs::path(store.root()) / "versions" / "0003" / "meta.json").string(), "{}").ok());
  CalibrationStore after_kill(state);
  ASSERT_TRUE(after_kill.Open().ok());
  EXPECT_EQ((*after_kill.Current())->number, 2);
  auto v4 = after_kill.Commit({{"ptu-left", "pan_offset_deg: 0.1\n"}}, 3000);
  ASSERT_TRUE(v4.ok()) << v4.status().ToString();
  EXPECT_EQ(v4->number, 4);
  EXPECT_EQ((*after_kill.Current())->number, 4);
  EXPECT_EQ(ReadFile(*after_kill.CurrentItemPath("robot1")).value(), "a3_mm: 625.5\n");
  fs::remove_all(state);
}

TEST(ControlSocketTest, RoundTripAndValidation) {
  const std::string dir = TempState("socket");
  ControlServerOptions opt;
  opt.path = dir + "/control.sock";
  opt.client_timeout = std::chrono::milliseconds(300);
  auto server = ControlServer::Start(opt, [](const ControlRequest& r) {
    return OkReply({{"echo", ControlCommandName(r.command)}, {"job", r.job}});
  });
  ASSERT_TRUE(server.ok()) << server.status().ToString();
  EXPECT_EQ(fs::status(opt.path).permissions() & fs::perms::all,
            fs::perms::owner_read | fs::perms::owner_write | fs::perms::group_read | fs::perms::group_write);
  const auto reply = SendControlRequest(opt.path, Job("scan", {{"views", 6}}));
  ASSERT_TRUE(reply.ok()) << reply.status().ToString();
  EXPECT_EQ((*reply)["echo"], "job");
  EXPECT_EQ((*reply)["job"], "scan");
  // A second server on the same path is refused while the first listens.
  EXPECT_EQ(ControlServer::Start(opt, [](const ControlRequest&) { return OkReply(); }).status().code(),
            StatusCode::kFailedPrecondition);
  (*server)->Stop();
  EXPECT_FALSE(fs::exists(opt.path));
  EXPECT_EQ(SendControlRequest(opt.path, Job("scan")).status().code(), StatusCode::kFailedPrecondition);
  fs::remove_all(dir);
}

// The socket's folder is made when missing (a config's `results/day.sock` in a fresh checkout), and one
// that cannot be made is named.
TEST(ControlSocketTest, MakesTheSocketFolder) {
  const std::string dir = TempState("socket-folder");
  ControlServerOptions opt;
  opt.path = dir + "/results/run/control.sock";
  ASSERT_FALSE(fs::exists(dir + "/results"));
  auto server = ControlServer::Start(opt, [](const ControlRequest&) { return OkReply(); });
  ASSERT_TRUE(server.ok()) << server.status().ToString();
  for (const std::string& folder : {dir + "/results", dir + "/results/run"}) {
    EXPECT_EQ(fs::status(folder).permissions() & fs::perms::all,
              fs::perms::owner_all | fs::perms::group_read | fs::perms::group_exec | fs::perms::others_read |
                  fs::perms::others_exec)
        << folder;
  }
  const auto reply = SendControlRequest(opt.path, Job("scan"));
  EXPECT_TRUE(reply.ok()) << reply.status().ToString();
  (*server)->Stop();
  // A file where the folder should be.
  ASSERT_TRUE(WriteFileAtomically(dir + "/file", "x\n").ok());
  opt.path = dir + "/file/sub/control.sock";
  const auto refused = ControlServer::Start(opt, [](const ControlRequest&) { return OkReply(); });
  ASSERT_FALSE(refused.ok());
  EXPECT_NE(refused.status().message().find(dir + "/file/sub"), std::string::npos) << refused.status().ToString();
  fs::remove_all(dir);
}

// Connects to the socket at `path` (a client that then says nothing); -1 on failure.
int ConnectSilently(const std::string& path) {
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  std::snprintf(addr.sun_path, sizeof(addr.sun_path), "%s", path.c_str());
  const int fd = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd >= 0 && ::connect(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof(addr)) != 0) {
    ::close(fd);
    return -1;
  }
  return fd;
}

// Clients that connect and say nothing (a hung tool, a stuck script) do not hold the socket: a stop sent
// meanwhile is answered at once, not after their timeouts (60 s here, against the request's 5 s). A
// client that sends its line in pieces is still served.
TEST(ControlSocketTest, SilentClientsDoNotDelayAnotherClient) {
  const std::string dir = TempState("socket-silent");
  ControlServerOptions opt;
  opt.path = dir + "/control.sock";
  opt.client_timeout = std::chrono::milliseconds(60'000);
  auto server = ControlServer::Start(opt, [](const ControlRequest& r) {
    return OkReply({{"echo", ControlCommandName(r.command)}});
  });
  ASSERT_TRUE(server.ok()) << server.status().ToString();
  std::vector<int> silent;
  for (int k = 0; k < 3; ++k) {
    silent.push_back(ConnectSilently(opt.path));
    ASSERT_GE(silent.back(), 0);
  }
  const int slow = ConnectSilently(opt.path);
  ASSERT_GE(slow, 0);
  ASSERT_EQ(::write(slow, "{\"cmd\":", 7), 7);  // half a request

  ControlRequest stop;
  stop.command = ControlCommand::kStop;
  const auto reply = SendControlRequest(opt.path, stop, std::chrono::milliseconds(5000));
  ASSERT_TRUE(reply.ok()) << reply.status().ToString();
  EXPECT_EQ((*reply)["echo"], "stop");

  const std::string rest = "\"status\"}\n";
  ASSERT_EQ(::write(slow, rest.data(), rest.size()), static_cast<ssize_t>(rest.size()));
  std::string answer;
  char buf[256];
  for (ssize_t n; answer.find('\n') == std::string::npos && (n = ::read(slow, buf, sizeof(buf))) > 0;) {
    answer.append(buf, static_cast<std::size_t>(n));
  }
  EXPECT_NE(answer.find("\"echo\":\"status\""), std::string::npos) << answer;
  ::close(slow);
  for (const int fd : silent) ::close(fd);
  (*server)->Stop();
  EXPECT_EQ((*server)->requests_served(), 2u);
  fs::remove_all(dir);
}

TEST(ControlProtocolTest, RejectsMalformedRequests) {
  EXPECT_TRUE(ParseControlRequest(R"({"cmd":"status"})").ok());
  EXPECT_TRUE(ParseControlRequest(R"({"cmd":"job","job":"scan","args":{"views":6}})").ok());
  for (const std::string bad : {"",
                                "nonsense",
                                "[1,2]",
                                R"({"cmd":5})",
                                R"({"cmd":"dance"})",
                                R"({"cmd":"job"})",
                                R"({"cmd":"job","job":""})",
                                R"({"cmd":"job","job":"x","args":3})",
                                R"({"cmd":"status","extra":1})"}) {
    EXPECT_FALSE(ParseControlRequest(bad).ok()) << bad;
  }
  EXPECT_FALSE(ParseControlRequest(std::string(kMaxRequestBytes + 10, ' ')).ok());
}

}  // namespace
}  // namespace idi::workcell
