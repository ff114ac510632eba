// Issue 9's acceptance on the real binary: killing `idi-workcell run` in the middle of a calibration
// or of a pick leaves the previous calibration current and byte-for-byte intact and the arms commanded
// to stop, and a restart comes back in a known state. The service runs the simulated cell from a
// temporary state folder; the test watches it through its operator socket, as `idi-workcell status`
// does, and kills it with SIGTERM (systemd's stop) or SIGKILL (nothing runs after it).
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <thread>

#include "tests/support/run_command.h"
#include "workcell/service/control_socket.h"

namespace idi::test {
namespace {

namespace fs = std::filesystem;
using workcell::ControlCommand;
using workcell::ControlRequest;

const std::string kWorkcell = IDI_WORKCELL_BIN;

std::string Slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// The service as a child process, its stdout and stderr in `log`.
class Service {
 public:
  Service(const std::string& config, const std::string& log) {
    pid_ = ::fork();
    if (pid_ == 0) {
      const int fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
      if (fd >= 0) {
        ::dup2(fd, 1);
        ::dup2(fd, 2);
      }
      ::execl(kWorkcell.c_str(), kWorkcell.c_str(), "run", "--config", config.c_str(), static_cast<char*>(nullptr));
      ::_exit(127);
    }
  }
  ~Service() {
    if (pid_ > 0 && !exited_) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
    }
  }
  void Signal(int sig) const { ::kill(pid_, sig); }
  // The exit status (as RunCommand reports it), or -1 when it is still running after `limit`.
  int Wait(std::chrono::seconds limit) {
    const auto end = std::chrono::steady_clock::now() + limit;
    while (std::chrono::steady_clock::now() < end) {
      int status = 0;
      if (::waitpid(pid_, &status, WNOHANG) == pid_) {
        exited_ = true;
        return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return -1;
  }

 private:
  pid_t pid_ = -1;
  bool exited_ = false;
};

nlohmann::json Status(const std::string& socket) {
  ControlRequest r;
  r.command = ControlCommand::kStatus;
  auto reply = workcell::SendControlRequest(socket, r, std::chrono::milliseconds(2000));
  return reply.ok() ? *reply : nlohmann::json();
}

std::string JobName(const nlohmann::json& s) {
  return s.contains("job") && s["job"].is_object() ? s["job"].value("name", "") : "";
}
std::string JobWhat(const nlohmann::json& s) {
  return s.contains("job") && s["job"].is_object() ? s["job"].value("what", "") : "";
}
int CalibrationVersion(const nlohmann::json& s) {
  return s.contains("calibration") ? s["calibration"].value("version", 0) : 0;
}

// Polls the service's status until `pred` holds; the last status seen in `last`.
template <typename Pred>
bool WaitForStatus(const std::string& socket, Pred pred, std::chrono::seconds limit, nlohmann::json* last) {
  const auto end = std::chrono::steady_clock::now() + limit;
  while (std::chrono::steady_clock::now() < end) {
    *last = Status(socket);
    if (!last->is_null() && pred(*last)) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(30));
  }
  return false;
}

// The current calibration: where `current` points and every file's bytes.
std::map<std::string, std::string> CurrentCalibration(const fs::path& state) {
  std::map<std::string, std::string> files;
  const fs::path current = state / "calibration" / "current";
  std::error_code ec;
  files["->"] = fs::read_symlink(current, ec).string();
  for (const auto& e : fs::directory_iterator(current, ec)) files[e.path().filename().string()] = Slurp(e.path());
  return files;
}

// The report of the latest run of `job`.
nlohmann::json LastReport(const fs::path& state, const std::string& job) {
  fs::path latest;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(state / "runs", ec)) {
    const std::string name = e.path().filename().string();
    if (name.size() > job.size() && name.compare(name.size() - job.size(), job.size(), job) == 0 &&
        (latest.empty() || name > latest.filename().string())) {
      latest = e.path();
    }
  }
  if (latest.empty() || !fs::exists(latest / "report.json")) return nlohmann::json();
  return nlohmann::json::parse(Slurp(latest / "report.json"), nullptr, false);
}

std::string WriteConfig(const fs::path& dir, const std::string& name, const std::string& extra) {
  const fs::path path = dir / name;
  std::ofstream(path) << "backend: sim\n"
                      << "state_dir: " << (dir / "state").string() << "\n"
                      << "control: {socket: " << (dir / "ctl.sock").string() << "}\n"
                      << "calibration: {max_age_days: 30, recalibrate_when_stale: true}\n"
                      << extra;
  return path.string();
}

TEST(ServiceKillTest, KillDuringACalibrationKeepsThePreviousOneAndARestartResumes) {
  const fs::path dir = MakeTempDir("kill_calibration");
  const std::string socket = (dir / "ctl.sock").string(), log = (dir / "service.log").string();
  // Paced (a simulated second takes 0.5 ms; a robot calibration is about 4 h of simulated moves) so
  // that a calibration lasts seconds on any machine and the kill surely lands inside one.
  const std::string config = WriteConfig(dir, "cell.yaml", "sim: {seed: 3, pace: 0.0005}\n");
  nlohmann::json st;
  std::map<std::string, std::string> before;
  {
    Service svc(config, log);
    // Robot 1's calibration is committed (version 1); robot 2's is running.
    ASSERT_TRUE(WaitForStatus(
        socket, [](const nlohmann::json& s) { return CalibrationVersion(s) == 1 && JobName(s) == "calibrate-robot2"; },
        std::chrono::seconds(300), &st))
        << st.dump() << "\n" << Slurp(log);
    std::this_thread::sleep_for(std::chrono::milliseconds(300));  // well into its acquisition
    before = CurrentCalibration(dir / "state");
    ASSERT_EQ(before.count("robot1.yaml"), 1u);
    svc.Signal(SIGTERM);
    EXPECT_EQ(svc.Wait(std::chrono::seconds(60)), 0) << Slurp(log);
  }
  std::string text = Slurp(log);
  EXPECT_NE(text.find("signal 15 (SIGTERM): stopping safely"), std::string::npos) << text;
  EXPECT_NE(text.find("devices commanded to stop"), std::string::npos) << "stopped at once, not when the job ended\n" << text;
  EXPECT_EQ(CurrentCalibration(dir / "state"), before) << "the previous calibration is current and intact";
  const nlohmann::json report = LastReport(dir / "state", "calibrate-robot2");
  ASSERT_FALSE(report.is_null());
  EXPECT_FALSE(report.value("ok", true));
  EXPECT_TRUE(report.value("cancelled", false)) << report.dump();

  // Restart: it finds version 1 lacking robot 2 and queues the calibrations again (robot 1 first);
  // killed outright (SIGKILL) during that, nothing of it is committed either.
  {
    Service svc(config, log);
    ASSERT_TRUE(WaitForStatus(
        socket, [](const nlohmann::json& s) { return JobName(s) == "calibrate-robot1"; }, std::chrono::seconds(120), &st))
        << st.dump();
    EXPECT_EQ(CalibrationVersion(st), 1);
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    svc.Signal(SIGKILL);
    EXPECT_EQ(svc.Wait(std::chrono::seconds(30)), 128 + SIGKILL);
  }
  EXPECT_EQ(CurrentCalibration(dir / "state"), before);
  {
    Service svc(config, log);
    ASSERT_TRUE(WaitForStatus(
        socket, [](const nlohmann::json& s) { return JobName(s) == "calibrate-robot1"; }, std::chrono::seconds(120), &st))
        << st.dump();
    EXPECT_EQ(st["queue"].size(), 3u) << "robot 2, rail and pan-tilt queued behind it";
    EXPECT_EQ(CalibrationVersion(st), 1) << "the known state after a kill: version 1, the missing items queued";
    EXPECT_EQ(st.value("state", ""), "busy");
    svc.Signal(SIGTERM);
    EXPECT_EQ(svc.Wait(std::chrono::seconds(60)), 0);
  }
  EXPECT_EQ(CurrentCalibration(dir / "state"), before);
  fs::remove_all(dir);
}

TEST(ServiceKillTest, KillDuringAPickStopsTheArmsAndKeepsTheCalibration) {
  const fs::path dir = MakeTempDir("kill_pick");
  const std::string socket = (dir / "ctl.sock").string(), log = (dir / "service.log").string();
  // Calibrate from scratch, as fast as the twin goes, then exit.
  {
    Service svc(WriteConfig(dir, "calibrate.yaml", "sim: {seed: 1}\nexit_when_idle: true\n"), log);
    ASSERT_EQ(svc.Wait(std::chrono::seconds(600)), 0) << Slurp(log);
  }
  const std::map<std::string, std::string> before = CurrentCalibration(dir / "state");
  for (const char* item : {"robot1.yaml", "robot2.yaml", "rail.yaml"}) ASSERT_EQ(before.count(item), 1u) << item;
  // The day's scan of a box, paced at a tenth of real time so the pick can be caught mid-way.
  nlohmann::json st;
  {
    Service svc(WriteConfig(dir, "day.yaml", "sim: {seed: 1, day: [box], pace: 0.1}\n"), log);
    ASSERT_TRUE(WaitForStatus(
        socket, [](const nlohmann::json& s) { return JobName(s) == "day" && JobWhat(s) == "box: lifting"; },
        std::chrono::seconds(300), &st))
        << st.dump() << "\n" << Slurp(log);
    svc.Signal(SIGTERM);
    EXPECT_EQ(svc.Wait(std::chrono::seconds(60)), 0) << Slurp(log);
  }
  const std::string text = Slurp(log);
  EXPECT_NE(text.find("devices commanded to stop"), std::string::npos) << text;
  EXPECT_NE(text.find("both arms commanded to stop"), std::string::npos) << "the pick's own arms stopped\n" << text;
  EXPECT_EQ(CurrentCalibration(dir / "state"), before);
  const nlohmann::json report = LastReport(dir / "state", "day");
  ASSERT_FALSE(report.is_null());
  EXPECT_TRUE(report.value("cancelled", false)) << report.dump();
  // Restarted without the day: idle on the same calibration.
  {
    Service svc(WriteConfig(dir, "idle.yaml", "sim: {seed: 1}\n"), log);
    ASSERT_TRUE(WaitForStatus(
        socket, [](const nlohmann::json& s) { return s.value("state", "") == "idle"; }, std::chrono::seconds(60), &st))
        << st.dump();
    EXPECT_GT(CalibrationVersion(st), 0);
    EXPECT_TRUE(st["queue"].empty()) << "nothing to recalibrate";
    svc.Signal(SIGTERM);
    EXPECT_EQ(svc.Wait(std::chrono::seconds(60)), 0);
  }
  EXPECT_EQ(CurrentCalibration(dir / "state"), before);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace idi::test
