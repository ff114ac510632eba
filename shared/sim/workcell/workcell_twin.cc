#include "shared/sim/workcell/workcell_twin.h"

#include <algorithm>
#include <cmath>

#include "shared/geometry/lines.h"
#include "shared/util/units.h"

namespace idi::sim {

class SimArm final : public hal::ArmDevice {
 public:
  SimArm(WorkcellTwin* twin, int k) : twin_(twin), k_(k) {}
  std::string name() const override { return "sim-rx130-" + std::to_string(k_ + 1); }
  Status MoveJoints(const Joints& q_rad, const hal::MoveOptions& options) override;
  Result<hal::JointState> ReadJoints() override;
  Status Stop() override { return Status::Ok(); }

 private:
  WorkcellTwin* twin_;
  int k_;
};

class SimRail final : public hal::RailDevice {
 public:
  SimRail(WorkcellTwin* twin, int k) : twin_(twin), k_(k) {}
  Status MoveTo(double position_mm, const hal::MoveOptions& options) override;
  Result<hal::RailState> Read() override;
  Status Stop() override { return Status::Ok(); }

 private:
  WorkcellTwin* twin_;
  int k_;
};

class SimLaser final : public hal::LaserDevice {
 public:
  SimLaser(WorkcellTwin* twin, int k) : twin_(twin), k_(k) {}
  Status SetOn(bool on) override;

 private:
  WorkcellTwin* twin_;
  int k_;
};

struct WorkcellTwin::ArmState {
  ParamSet robot = Rx130Nominal();
  ParamSet laser = LaserNominal();
  ParamSet rail = ParamSet(RailParamSpecs());
  Joints q{};                 // realised joints (= reading)
  double rail_true_mm = 0;    // where the rail actually is
  double rail_reading_mm = 0; // what it reports
  bool laser_on = false;
  std::unique_ptr<SimArm> arm_device;
  std::unique_ptr<SimRail> rail_device;
  std::unique_ptr<SimLaser> laser_device;
};

namespace {

Rigid3d WallFrame(const Vec3d& x, const Vec3d& y, const Vec3d& origin) {
  Rigid3d t;
  t.rotation.col(0) = x;
  t.rotation.col(1) = y;
  t.rotation.col(2) = x.cross(y);
  t.translation = origin;
  return t;
}

// A small random rotation of about `sigma_rad` per axis.
Mat3d SmallRotation(std::mt19937_64& rng, double sigma_rad) {
  std::normal_distribution<double> n(0.0, sigma_rad);
  const Vec3d w(n(rng), n(rng), n(rng));
  const double a = w.norm();
  if (a == 0) return Mat3d::Identity();
  return Eigen::AngleAxisd(a, w / a).toRotationMatrix();
}

}  // namespace

Status WorkcellTwinOptions::Check() const {
  // Every value finite (an infinite wall distance or spot noise passed the >= tests and gave NaN walls
  // and spots), psi's sigmas too.
  const double all[] = {joint_offset_sigma_deg,
                        twist_sigma_deg,
                        length_sigma_mm,
                        arm_length_sigma_mm,
                        laser_angle_sigma_deg,
                        laser_offset_sigma_mm,
                        rail_angle_sigma_deg,
                        wall_distance_min_mm,
                        wall_distance_max_mm,
                        floor_height_mm,
                        spot_sigma_mm,
                        rail_repeatability_mm,
                        rail_length_mm,
                        setup_wall_position_error_mm,
                        setup_wall_angle_error_deg};
  for (const double v : all) {
    if (!std::isfinite(v)) return InvalidArgument("workcell twin: invalid options (a value is not finite)");
  }
  for (const double s : psi_sigma) {
    if (!(s >= 0 && std::isfinite(s))) return InvalidArgument("workcell twin: psi_sigma must be finite and >= 0");
  }
  const bool ok = joint_offset_sigma_deg >= 0 && twist_sigma_deg >= 0 && length_sigma_mm >= 0 && arm_length_sigma_mm >= 0 &&
                  laser_angle_sigma_deg >= 0 && laser_offset_sigma_mm >= 0 && rail_angle_sigma_deg >= 0 &&
                  wall_distance_min_mm >= 1500 && wall_distance_max_mm >= wall_distance_min_mm && floor_height_mm < -500 &&
                  spot_sigma_mm >= 0 && rail_repeatability_mm >= 0 && rail_length_mm > 0 &&
                  setup_wall_position_error_mm >= 0 && setup_wall_angle_error_deg >= 0;
  if (!ok) return InvalidArgument("workcell twin: invalid options (negative noise, walls closer than 1.5 m, ...)");
  return Status::Ok();
}

WorkcellTwin::WorkcellTwin(const WorkcellTwinOptions& o)
    : options_(o), truth_rng_(o.seed), spot_rng_(o.seed * 7919u + 1u), rail_rng_(o.seed * 104729u + 2u) {
  IDI_CHECK(o.Check().ok(), o.Check().message());
  std::normal_distribution<double> n(0.0, 1.0);
  for (int k = 0; k < 2; ++k) {
    auto a = std::make_unique<ArmState>();
    auto perturb = [&](ParamSet& set, std::size_t i, double sigma, bool degrees) {
      set.set_value(i, set.value(i) + (degrees ? DegToRad(sigma) : sigma) * n(truth_rng_));
    };
    for (std::size_t i : {static_cast<std::size_t>(kTheta2), static_cast<std::size_t>(kTheta3),
                          static_cast<std::size_t>(kTheta4), static_cast<std::size_t>(kTheta5)}) {
      perturb(a->robot, i, o.joint_offset_sigma_deg, true);
    }
    for (std::size_t i : {static_cast<std::size_t>(kAlpha2), static_cast<std::size_t>(kAlpha3),
                          static_cast<std::size_t>(kBeta3), static_cast<std::size_t>(kAlpha4),
                          static_cast<std::size_t>(kAlpha5), static_cast<std::size_t>(kAlpha6)}) {
      perturb(a->robot, i, o.twist_sigma_deg, true);
    }
    for (std::size_t i : {static_cast<std::size_t>(kA2), static_cast<std::size_t>(kD2), static_cast<std::size_t>(kA4),
                          static_cast<std::size_t>(kA5), static_cast<std::size_t>(kD5), static_cast<std::size_t>(kA6)}) {
      perturb(a->robot, i, o.length_sigma_mm, false);
    }
    perturb(a->robot, kA3, o.arm_length_sigma_mm, false);
    perturb(a->robot, kD4, o.arm_length_sigma_mm, false);
    perturb(a->laser, kLaserThetaX, o.laser_angle_sigma_deg, true);
    perturb(a->laser, kLaserThetaY, o.laser_angle_sigma_deg, true);
    perturb(a->laser, kLaserPx, o.laser_offset_sigma_mm, false);
    perturb(a->laser, kLaserPy, o.laser_offset_sigma_mm, false);
    perturb(a->rail, kPhiL, o.rail_angle_sigma_deg, true);
    perturb(a->rail, kPhiM, o.rail_angle_sigma_deg, true);
    a->q = JointsFromDeg({0, -60, 100, 0, 50, 0});
    if (o.quantize_joints) a->q = QuantizeToEncoders(a->q);
    a->arm_device = std::make_unique<SimArm>(this, k);
    a->rail_device = std::make_unique<SimRail>(this, k);
    a->laser_device = std::make_unique<SimLaser>(this, k);
    arms_[static_cast<std::size_t>(k)] = std::move(a);
  }
  const std::array<double, 4> nominal_psi = {5650.0, 0.0, 0.0, 0.0};
  for (std::size_t i = 0; i < 4; ++i) {
    psi_[i] = nominal_psi[i] + (i == 3 ? DegToRad(o.psi_sigma[i]) : o.psi_sigma[i]) * n(truth_rng_);
  }
  std::uniform_real_distribution<double> wall_distance(o.wall_distance_min_mm, o.wall_distance_max_mm);
  const double mid = 0.5 * nominal_psi[0];
  const double w_left = wall_distance(truth_rng_), w_right = wall_distance(truth_rng_);
  walls_.push_back({"left", WallFrame({1, 0, 0}, {0, 0, 1}, {mid, w_left, 0}), 9000, 3000});
  walls_.push_back({"right", WallFrame({-1, 0, 0}, {0, 0, 1}, {mid, -w_right, 0}), 9000, 3000});
  walls_.push_back({"floor", WallFrame({1, 0, 0}, {0, 1, 0}, {mid, 0.5 * (w_left - w_right), o.floor_height_mm}), 9000,
                    0.5 * (w_left + w_right)});
  std::normal_distribution<double> pos(0.0, o.setup_wall_position_error_mm);
  for (const Wall& w : walls_) {
    Wall s = w;
    s.world_from_wall.rotation = SmallRotation(truth_rng_, DegToRad(o.setup_wall_angle_error_deg)) * w.world_from_wall.rotation;
    s.world_from_wall.translation += Vec3d(pos(truth_rng_), pos(truth_rng_), pos(truth_rng_));
    setup_walls_.push_back(s);
  }
}

WorkcellTwin::~WorkcellTwin() = default;

hal::ArmDevice& WorkcellTwin::arm(int k) { return *arms_.at(static_cast<std::size_t>(k))->arm_device; }
hal::RailDevice& WorkcellTwin::rail(int k) { return *arms_.at(static_cast<std::size_t>(k))->rail_device; }
hal::LaserDevice& WorkcellTwin::laser(int k) { return *arms_.at(static_cast<std::size_t>(k))->laser_device; }
const ParamSet& WorkcellTwin::true_robot(int k) const { return arms_.at(static_cast<std::size_t>(k))->robot; }
const ParamSet& WorkcellTwin::true_laser(int k) const { return arms_.at(static_cast<std::size_t>(k))->laser; }
const ParamSet& WorkcellTwin::true_rail(int k) const { return arms_.at(static_cast<std::size_t>(k))->rail; }
Joints WorkcellTwin::true_joints(int k) const { return arms_.at(static_cast<std::size_t>(k))->q; }
double WorkcellTwin::true_rail_position(int k) const { return arms_.at(static_cast<std::size_t>(k))->rail_true_mm; }
bool WorkcellTwin::laser_on(int k) const { return arms_.at(static_cast<std::size_t>(k))->laser_on; }

WorkcellSetup WorkcellTwin::Setup() const {
  WorkcellSetup s;
  s.walls = setup_walls_;
  return s;
}

Rigid3d WorkcellTwin::WorldFromBase(int k) const {
  const ArmState& a = *arms_.at(static_cast<std::size_t>(k));
  const Rigid3d rail_from_base = RailFromBase(a.rail.value(kPhiL), a.rail.value(kPhiM), a.rail_true_mm);
  return k == 0 ? rail_from_base : Rail1FromRail2(psi_.data()) * rail_from_base;
}

std::optional<Vec2d> WorkcellTwin::TrueSpot(int k, int wall) const {
  const ArmState& a = *arms_.at(static_cast<std::size_t>(k));
  const Line3d base_line = LaserLineInBase(a.robot.data(), a.laser.data(), a.q.data());
  const Rigid3d world_from_base = WorldFromBase(k);
  const Line3d line{world_from_base * base_line.origin, world_from_base.RotateVector(base_line.direction)};
  auto hit = [&](const Wall& w) -> std::optional<std::pair<double, Vec2d>> {
    const Rigid3d wall_from_world = w.world_from_wall.Inverse();
    const Vec3d o = wall_from_world * line.origin;
    const Vec3d d = wall_from_world.RotateVector(line.direction);
    if (std::abs(d.z()) < 1e-12) return std::nullopt;
    const double s = -o.z() / d.z();
    if (!(s > 0)) return std::nullopt;
    const Vec2d p(o.x() + s * d.x(), o.y() + s * d.y());
    if (std::abs(p.x()) > w.half_width_mm || std::abs(p.y()) > w.half_height_mm) return std::nullopt;
    return std::make_pair(s, p);
  };
  const auto target = hit(walls_.at(static_cast<std::size_t>(wall)));
  if (!target) return std::nullopt;
  for (std::size_t i = 0; i < walls_.size(); ++i) {
    if (static_cast<int>(i) == wall) continue;
    const auto other = hit(walls_[i]);
    if (other && other->first < target->first) return std::nullopt;  // another wall is in the way
  }
  return target->second;
}

Result<Vec2d> WorkcellTwin::ObserveSpot(int k, int wall) {
  if (k < 0 || k > 1 || wall < 0 || wall >= static_cast<int>(walls_.size())) {
    return InvalidArgument("twin: no arm " + std::to_string(k) + " or wall " + std::to_string(wall));
  }
  if (!arms_[static_cast<std::size_t>(k)]->laser_on) {
    return NotFound("twin camera on the " + walls_[static_cast<std::size_t>(wall)].name + " wall: no spot (laser " +
                    std::to_string(k + 1) + " is off)");
  }
  const auto spot = TrueSpot(k, wall);
  if (!spot) {
    return NotFound("twin camera on the " + walls_[static_cast<std::size_t>(wall)].name + " wall: laser " +
                    std::to_string(k + 1) + "'s spot is not on this wall");
  }
  clock_.SleepForNs(40 * hal::kNsPerMs);  // one camera frame
  const double s = options_.spot_sigma_mm;
  if (s == 0) return *spot;
  if (options_.spot_noise == SpotNoise::kUniform) {
    std::uniform_real_distribution<double> u(-s, s);
    return Vec2d(spot->x() + u(spot_rng_), spot->y() + u(spot_rng_));
  }
  std::normal_distribution<double> n(0.0, s);
  return Vec2d(spot->x() + n(spot_rng_), spot->y() + n(spot_rng_));
}

Status SimArm::MoveJoints(const Joints& q_rad, const hal::MoveOptions& options) {
  const JointLimits limits = Rx130JointLimits();
  if (const int bad = limits.FirstViolation(q_rad); bad >= 0) {
    return OutOfRange(name() + ": joint " + std::to_string(bad + 1) + " command " +
                      FormatNumber(RadToDeg(q_rad[static_cast<std::size_t>(bad)])) + " deg is outside its range");
  }
  if (!(options.speed_fraction > 0 && options.speed_fraction <= 1)) {
    return InvalidArgument(name() + ": speed_fraction must be in (0, 1]");
  }
  WorkcellTwin::ArmState& a = *twin_->arms_[static_cast<std::size_t>(k_)];
  double largest = 0;
  for (std::size_t i = 0; i < q_rad.size(); ++i) largest = std::max(largest, std::abs(q_rad[i] - a.q[i]));
  // Joint speed about 1 rad/s at full speed, plus settling.
  twin_->clock_.SleepForNs(hal::SecToNs(largest / options.speed_fraction + 0.2));
  a.q = twin_->options_.quantize_joints ? QuantizeToEncoders(q_rad) : q_rad;
  return Status::Ok();
}

Result<hal::JointState> SimArm::ReadJoints() {
  hal::JointState s;
  s.timestamp_ns = twin_->clock_.NowNs();
  s.q_rad = twin_->arms_[static_cast<std::size_t>(k_)]->q;  // the encoder counts, converted
  return s;
}

Status SimRail::MoveTo(double position_mm, const hal::MoveOptions& options) {
  if (!std::isfinite(position_mm) || position_mm < 0 || position_mm > twin_->options_.rail_length_mm) {
    return OutOfRange("sim rail " + std::to_string(k_ + 1) + ": position " + FormatNumber(position_mm) +
                      " mm is outside [0, " + FormatNumber(twin_->options_.rail_length_mm) + "] mm");
  }
  // As the arm (and the real controller): a NaN was clamped to NaN and became a NaN sleep.
  if (!(options.speed_fraction > 0 && options.speed_fraction <= 1)) {
    return InvalidArgument("sim rail " + std::to_string(k_ + 1) + ": speed_fraction must be in (0, 1]");
  }
  WorkcellTwin::ArmState& a = *twin_->arms_[static_cast<std::size_t>(k_)];
  const double speed_mmps = 500.0 * std::max(options.speed_fraction, 0.01);
  twin_->clock_.SleepForNs(hal::SecToNs(std::abs(position_mm - a.rail_reading_mm) / speed_mmps + 0.5));
  std::normal_distribution<double> n(0.0, 1.0);
  a.rail_true_mm = position_mm + twin_->options_.rail_repeatability_mm * n(twin_->rail_rng_);
  a.rail_reading_mm = position_mm;
  return Status::Ok();
}

Result<hal::RailState> SimRail::Read() {
  hal::RailState s;
  s.timestamp_ns = twin_->clock_.NowNs();
  s.position_mm = twin_->arms_[static_cast<std::size_t>(k_)]->rail_reading_mm;
  return s;
}

Status SimLaser::SetOn(bool on) {
  twin_->arms_[static_cast<std::size_t>(k_)]->laser_on = on;
  return Status::Ok();
}

}  // namespace idi::sim
