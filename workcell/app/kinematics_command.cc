#include "workcell/app/kinematics_command.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>

#include "shared/kinematics/aiming.h"
#include "shared/kinematics/biclops.h"
#include "shared/kinematics/rtu.h"
#include "shared/kinematics/rx130.h"
#include "shared/runtime/param_file.h"

namespace idi::workcell {
namespace {

struct KinematicsOptions {
  std::string robot_file;
  std::string laser_file;
  std::string joints_deg = "0,-60,100,0,50,0";
  std::string aim_mm;
  bool json = false;
};

nlohmann::json Vec(const Vec3d& v) { return {v.x(), v.y(), v.z()}; }

// --aim-mm's target, at most kMaxParamLengthM from the robot base. The workcell is a few metres across
// (the walls the laser aims at are within reach of the rail's length): a target 100 m away is a unit
// slip, and one near the largest double overflowed the aiming's residual to inf (exit 1, after the
// work). No target: nullopt.
Result<std::optional<Vec3d>> ParseAimTarget(const std::string& text) {
  if (text.empty()) return std::optional<Vec3d>();
  IDI_ASSIGN_OR_RETURN(const std::vector<double> t, ParseNumberList(text, 3, "--aim-mm"));
  const Vec3d target(t[0], t[1], t[2]);
  const double max_mm = kMaxParamLengthM * 1000.0;
  if (!(target.norm() <= max_mm)) {
    return OutOfRange(
        fmt::format("--aim-mm: the target {} mm is out of range (at most {} mm, {} m, from the robot base)",
                    text,
                    max_mm,
                    kMaxParamLengthM));
  }
  return std::optional<Vec3d>(target);
}

Status RunKinematics(const KinematicsOptions& o) {
  IDI_ASSIGN_OR_RETURN(const std::optional<Vec3d> aim_target, ParseAimTarget(o.aim_mm));
  ParamSet robot = Rx130Nominal();
  ParamSet laser = LaserNominal();
  // A `calibrate robot` output's model (procedures/calibration_files.cc); a file of another model (a
  // laser file as --robot) is refused.
  const std::string calibrated_model = "rx130-laser-vicki";
  // Both files may be `calibrate robot` outputs, which hold the arm, the laser, the point, the
  // rail-direction and the run's keys: each read skips the others' keys.
  const std::vector<std::string> run_keys = {"model",
                                             "comment",
                                             "laser",
                                             "calibration",
                                             "statistics",
                                             "method",
                                             "distance_mm",
                                             "point_x_mm",
                                             "point_y_mm",
                                             "point_z_mm",
                                             "phi_l_deg",
                                             "phi_m_deg",
                                             "correlation",
                                             "sim_seed"};
  if (!o.robot_file.empty()) {
    ParamFileOptions pfo;
    pfo.extra_keys = run_keys;
    pfo.models = {"rx130", calibrated_model};
    for (const ParamSpec& spec : LaserParamSpecs()) pfo.extra_keys.push_back(spec.Key());
    IDI_ASSIGN_OR_RETURN(robot, LoadParamFile(o.robot_file, Rx130ParamSpecs(), pfo));
  }
  // The laser: --laser, else the calibrated laser of a `calibrate robot` file given as --robot, else
  // nominal.
  std::string laser_source = "nominal";
  ParamFileOptions lfo;
  lfo.extra_keys = run_keys;
  lfo.models = {"laser", calibrated_model};
  for (const ParamSpec& spec : Rx130ParamSpecs()) lfo.extra_keys.push_back(spec.Key());
  if (!o.laser_file.empty()) {
    IDI_ASSIGN_OR_RETURN(laser, LoadParamFile(o.laser_file, LaserParamSpecs(), lfo));
    laser_source = o.laser_file;
  } else if (!o.robot_file.empty()) {
    YAML::Node root;
    try {
      root = YAML::LoadFile(o.robot_file);
    } catch (const YAML::Exception&) {
      root = YAML::Node();  // read above already; cannot fail differently here
    }
    if (root.IsMap() && root["theta_x_deg"]) {
      lfo.models.clear();  // the --robot file's model was checked above
      IDI_ASSIGN_OR_RETURN(laser, LoadParamFile(o.robot_file, LaserParamSpecs(), lfo));
      laser_source = o.robot_file;
    }
  }
  IDI_ASSIGN_OR_RETURN(const std::vector<double> deg, ParseNumberList(o.joints_deg, 6, "--joints-deg"));
  const Joints q = JointsFromDeg({deg[0], deg[1], deg[2], deg[3], deg[4], deg[5]});
  const JointLimits limits = Rx130JointLimits();
  if (const int bad = limits.FirstViolation(q); bad >= 0) {
    return OutOfRange(fmt::format("--joints-deg: joint {} = {} deg is outside its range [{:.1f}, {:.1f}] deg", bad + 1,
                                  deg[static_cast<std::size_t>(bad)], RadToDeg(limits.min[static_cast<std::size_t>(bad)]),
                                  RadToDeg(limits.max[static_cast<std::size_t>(bad)])));
  }
  const Rigid3d flange = Rx130BaseFromFlange(robot.data(), q.data());
  const TcfPose pose = TcfPoseFromTransform(flange);
  const Line3d line = LaserLineInBase(robot.data(), laser.data(), q.data());

  nlohmann::json out;
  out["robot"] = o.robot_file.empty() ? "nominal (Table 4.1)" : o.robot_file;
  out["laser"] = laser_source;
  out["joints_deg"] = deg;
  out["flange_mm"] = Vec(flange.translation);
  out["flange_zyz_deg"] = {RadToDeg(pose.alpha_rad), RadToDeg(pose.beta_rad), RadToDeg(pose.gamma_rad)};
  out["laser_origin_mm"] = Vec(line.origin);
  out["laser_direction"] = Vec(line.direction);

  if (aim_target) {
    const Vec3d& target = *aim_target;
    const AimAngles aim = AimDirection(line.origin, target);
    out["aim_eq3_7_yaw_deg"] = RadToDeg(aim.yaw_rad);
    out["aim_eq3_8_pitch_deg"] = RadToDeg(aim.pitch_rad);
    IDI_ASSIGN_OR_RETURN(const IkSummary ik, AimLaserAt(robot, laser, q, target, limits));
    const Line3d aimed = LaserLineInBase(robot.data(), laser.data(), ik.q.data());
    out["aim"] = {{"target_mm", Vec(target)},
                  {"joints_deg", JointsToDeg(ik.q)},
                  {"iterations", ik.iterations},
                  {"miss_mm", DistancePointToLine(aimed, target)},
                  {"laser_length_mm", ProjectOntoLine(aimed, target)}};
  }

  if (o.json) {
    std::cout << out.dump() << "\n";
    return Status::Ok();
  }
  std::cout << fmt::format("RX-130 ({}), joints {:.3f} deg\n", out["robot"].get<std::string>(), fmt::join(deg, ", "));
  std::cout << fmt::format("  flange position      {:10.3f} {:10.3f} {:10.3f} mm\n", flange.translation.x(),
                           flange.translation.y(), flange.translation.z());
  std::cout << fmt::format("  flange yaw/pitch/roll {:9.4f} {:10.4f} {:10.4f} deg (eq. 3.10)\n", RadToDeg(pose.alpha_rad),
                           RadToDeg(pose.beta_rad), RadToDeg(pose.gamma_rad));
  std::cout << fmt::format("  laser origin         {:10.3f} {:10.3f} {:10.3f} mm\n", line.origin.x(), line.origin.y(),
                           line.origin.z());
  std::cout << fmt::format("  laser direction      {:10.6f} {:10.6f} {:10.6f}\n", line.direction.x(),
                           line.direction.y(), line.direction.z());
  if (out.contains("aim")) {
    const auto& a = out["aim"];
    std::cout << fmt::format("aim at {:.1f} mm: eqs. 3.7-3.8 yaw {:.4f} deg, pitch {:.4f} deg from the laser origin\n",
                             fmt::join(a["target_mm"].get<std::vector<double>>(), ", "),
                             out["aim_eq3_7_yaw_deg"].get<double>(), out["aim_eq3_8_pitch_deg"].get<double>());
    std::cout << fmt::format("  inverse kinematics: {} iterations, joints {:.5f} deg\n", a["iterations"].get<int>(),
                             fmt::join(a["joints_deg"].get<std::vector<double>>(), ", "));
    std::cout << fmt::format("  laser misses the target by {:.2e} mm at {:.1f} mm along the beam\n",
                             a["miss_mm"].get<double>(), a["laser_length_mm"].get<double>());
  }
  return Status::Ok();
}

struct ParamsOptions {
  std::string model;
  std::string out;
};

Status RunParams(const ParamsOptions& o) {
  ParamSet set;
  if (o.model == "rx130") {
    set = Rx130Nominal();
  } else if (o.model == "laser") {
    set = LaserNominal();
  } else if (o.model == "ptu-left" || o.model == "ptu-right") {
    const BiclopsSide side = o.model == "ptu-left" ? BiclopsSide::kLeft : BiclopsSide::kRight;
    set = ParamSet(PtuParamSpecs(side));
    set.Append(CameraToParamSet(BiclopsNominalCamera(side)));
  } else if (o.model == "rail") {
    set = ParamSet(RailParamSpecs());
  } else {
    set = ParamSet(RobotToRobotParamSpecs());
  }
  if (o.out.empty() || o.out == "-") {
    YAML::Emitter e;
    e << YAML::BeginMap << YAML::Key << "model" << YAML::Value << o.model;
    EmitParamSet(e, set);
    e << YAML::EndMap;
    std::cout << e.c_str() << "\n";
    return Status::Ok();
  }
  IDI_RETURN_IF_ERROR(SaveParamFile(o.out, set, o.model));
  spdlog::info("wrote nominal {} parameters to {}", o.model, o.out);
  return Status::Ok();
}

}  // namespace

void AddKinematicsCommand(CliApp& cli) {
  auto o = std::make_shared<KinematicsOptions>();
  CLI::App* cmd = cli.AddCommand(&cli.app, "kinematics",
                                 "RX-130 forward kinematics with the laser tool; optionally aim the laser at a point",
                                 [o] { return RunKinematics(*o); });
  cmd->add_option("--robot",
                  o->robot_file,
                  "robot parameter file (YAML, Table 4.1 keys, or a `calibrate robot` output); default: nominal")
      ->check(CLI::ExistingFile);
  cmd->add_option("--laser",
                  o->laser_file,
                  "laser tool parameter file (theta_x_deg, theta_y_deg, px_mm, py_mm; a `calibrate robot` output too); "
                  "default: the --robot file's calibrated laser when it has one, else nominal")
      ->check(CLI::ExistingFile);
  cmd->add_option("--joints-deg", o->joints_deg, "six joint readings in degrees, comma separated")
      ->capture_default_str();
  cmd->add_option(
      "--aim-mm", o->aim_mm, "aim the laser at x,y,z (robot base frame, mm, at most 100 m away) by inverse kinematics");
  cmd->add_flag("--json", o->json, "print one JSON object on stdout");
}

void AddParamsCommand(CliApp& cli) {
  auto o = std::make_shared<ParamsOptions>();
  CLI::App* cmd = cli.AddCommand(&cli.app, "params", "write a model's nominal parameter file (a calibration template)",
                                 [o] { return RunParams(*o); });
  cmd->add_option("model", o->model, "rx130, laser, ptu-left, ptu-right, rail or robot-to-robot")
      ->required()
      ->check(CLI::IsMember({"rx130", "laser", "ptu-left", "ptu-right", "rail", "robot-to-robot"}));
  cmd->add_option("--out", o->out, "output YAML file (written atomically); default: stdout");
}

}  // namespace idi::workcell
