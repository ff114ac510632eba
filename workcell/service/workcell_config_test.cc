#include "workcell/service/workcell_config.h"

#include <gtest/gtest.h>

namespace idi::workcell {
namespace {

TEST(WorkcellConfigTest, ParsesAFullHardwareConfig) {
  const auto c = ParseWorkcellConfig(R"(
backend: hardware
state_dir: /var/lib/idi-workcell
control: {socket: /run/idi-workcell/control.sock, group: idi}
calibration: {max_age_days: 14, recalibrate_when_stale: false}
hardware:
  arms: [{name: arm1, host: 10.0.0.11, port: 5100}, {name: arm2, host: 10.0.0.12, port: 5100}]
  ptus: [{name: left, device: /dev/ttyUSB0}, {name: right, device: /dev/ttyUSB1, baud: 38400}]
  hand: {device: /dev/ttyUSB2}
  cameras: [{name: left, device: /dev/video0}, {name: right, backend: mrpt, device: "0", width: 656, height: 490,
             exposure_us: 8000}]
)",
                                     "workcell.yaml");
  ASSERT_TRUE(c.ok()) << c.status().ToString();
  EXPECT_EQ(c->arms[1].host, "10.0.0.12");
  EXPECT_EQ(c->ptus[1].baud, 38400);
  EXPECT_EQ(c->ptus[0].baud, 9600);
  EXPECT_EQ(c->cameras[1].backend, "mrpt");
  EXPECT_EQ(c->cameras[0].width, 640);  // the defaults
  EXPECT_EQ(c->cameras[0].height, 480);
  EXPECT_EQ(c->cameras[0].exposure_us, 0);
  EXPECT_EQ(c->cameras[1].width, 656);
  EXPECT_EQ(c->cameras[1].height, 490);
  EXPECT_EQ(c->cameras[1].exposure_us, 8000);
  EXPECT_EQ(c->control_group, "idi");
  EXPECT_DOUBLE_EQ(c->calibration_max_age_days, 14);
  EXPECT_FALSE(c->recalibrate_when_stale);
}

TEST(WorkcellConfigTest, DefaultsToTheSimulation) {
  const auto c = ParseWorkcellConfig("backend: sim\n", "w.yaml");
  ASSERT_TRUE(c.ok());
  EXPECT_EQ(c->backend, "sim");
}

TEST(WorkcellConfigTest, ReadsTheSimulatedDay) {
  const auto c =
      ParseWorkcellConfig("backend: sim\nsim: {seed: 4, day: [box, bracket], pace: 0.5}\nexit_when_idle: true\n", "d.yaml");
  ASSERT_TRUE(c.ok()) << c.status().ToString();
  EXPECT_EQ(c->sim_seed, 4u);
  EXPECT_DOUBLE_EQ(c->sim_pace, 0.5);
  EXPECT_EQ(c->sim_day, (std::vector<std::string>{"box", "bracket"}));
  EXPECT_TRUE(c->exit_when_idle);
}

TEST(WorkcellConfigTest, RejectsBadConfigsNamingFileLineAndKey) {
  struct Case {
    const char* text;
    const char* expect;
  };
  for (const Case& k : std::initializer_list<Case>{
           {"backend: sim\nbogus: 1\n", "w.yaml:2: unknown key 'bogus'"},
           {"backend: sim\nbackend: hardware\n", "w.yaml:2: key 'backend' given twice"},
           {"backend: robots\n", "backend 'robots'"},
           {"backend: sim\ncalibration: {max_age_days: -3}\n", "max_age_days' must be positive"},
           {"backend: sim\ncontrol: {socket: [1]}\n", "'control.socket' has the wrong type"},
           {"backend: hardware\n", "needs hardware.arms"},
           {"backend: sim\nhardware: {arms: [{name: a, host: h, port: 99999}]}\n", "port in 1..65535"},
           {"backend: [", "malformed YAML"},
           // A map where a list is expected, a list where a name is expected: the file named, no exception.
           {"backend: hardware\nhardware: {arms: {name: a, host: h, port: 1}}\n", "w.yaml"},
           {"backend: sim\ncontrol: {[socket]: /run/x}\n", "w.yaml"},
           {"", "empty configuration"},
           {"backend: sim\nsim: {day: [box, teapot]}\n", "'sim.day' entries are box, prism, bracket or cylinder"},
           {"backend: sim\nsim: {day: box}\n", "'sim.day' must be a list"},
           {"backend: sim\nexit_when_idle: maybe\n", "exit_when_idle"},
           {"backend: sim\nsim: {pace: -1}\n", "w.yaml:2: 'sim.pace' must be in [0, 100]"},
           {"backend: sim\nsim: {pace: .nan}\n", "'sim.pace' must be in [0, 100]"},
           {"backend: sim\nhardware: {cameras: [{name: l, device: /dev/video0, width: 0}]}\n",
            "w.yaml:2: 'hardware.cameras' width and height must be in 16..8192, got 0 x 480"},
           {"backend: sim\nhardware: {cameras: [{name: l, device: /dev/video0, height: -480}]}\n", "got 640 x -480"},
           {"backend: sim\nhardware: {cameras: [{name: l, device: /dev/video0, exposure_us: -5}]}\n",
            "'hardware.cameras.exposure_us' must be in [0, 1e7]"},
           {"backend: sim\nhardware: {cameras: [{name: l, device: /dev/video0, exposure_us: .nan}]}\n",
            "'hardware.cameras.exposure_us' must be in [0, 1e7]"},
           {"backend: sim\nhardware: {cameras: [{name: l, device: /dev/video0, width: wide}]}\n",
            "'hardware.cameras.width' has the wrong type"},
           {"backend: sim\nhardware: {cameras: [{name: l, device: /dev/video0, fps: 30}]}\n",
            "unknown key 'hardware.cameras.fps'"},
       }) {
    const auto c = ParseWorkcellConfig(k.text, "w.yaml");
    ASSERT_FALSE(c.ok()) << k.text;
    EXPECT_NE(c.status().message().find(k.expect), std::string::npos) << c.status().message();
  }
}

}  // namespace
}  // namespace idi::workcell
