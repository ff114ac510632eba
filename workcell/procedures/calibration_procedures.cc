#include "workcell/procedures/calibration_procedures.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <Eigen/Eigenvalues>
#include <chrono>
#include <cmath>
#include <limits>
#include <random>

#include "shared/optim/vicki_costs.h"

namespace idi::workcell {
namespace {

double NowSeconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

Result<Joints> MoveAndRead(hal::ArmDevice& arm, const Joints& q) {
  IDI_RETURN_IF_ERROR(arm.MoveJoints(q, {}));
  IDI_ASSIGN_OR_RETURN(const hal::JointState s, arm.ReadJoints());
  return s.q_rad;
}

Result<double> MoveRail(hal::RailDevice& rail, double position_mm) {
  IDI_RETURN_IF_ERROR(rail.MoveTo(position_mm, {}));
  IDI_ASSIGN_OR_RETURN(const hal::RailState s, rail.Read());
  return s.position_mm;
}

Status CheckDevices(const ArmDevices& d, const char* which) {
  if (d.arm == nullptr || d.rail == nullptr || d.laser == nullptr || !d.observe) {
    return InvalidArgument(std::string(which) + ": arm, rail, laser and spot camera are all needed");
  }
  return Status::Ok();
}

// A configuration whose spot could not be brought onto its point: the loop did not converge, the spot
// was not seen on the wall, or a joint limit was in the way. The acquisition goes on with the next.
// Any other error (a device that timed out or reported a fault, a spot camera that failed, a cancel)
// ends it.
bool IsAimingMiss(const Status& s) {
  return s.code() == StatusCode::kNotConverged || s.code() == StatusCode::kNotFound ||
         s.code() == StatusCode::kOutOfRange;
}

// Ends an acquisition on a device fault: stops the arms and rails and turns the lasers off (best
// effort; the fault is what is returned), and says how far the acquisition got.
Status AbortAcquisition(const std::vector<ArmDevices*>& devices,
                        const Status& fault,
                        const std::string& what,
                        int readings_taken) {
  for (ArmDevices* d : devices) {
    if (const Status s = d->arm->Stop(); !s.ok()) spdlog::error("{}: stopping the arm: {}", what, s.ToString());
    if (const Status s = d->rail->Stop(); !s.ok()) spdlog::error("{}: stopping the rail: {}", what, s.ToString());
    if (const Status s = d->laser->SetOn(false); !s.ok()) {
      spdlog::error("{}: turning the laser off: {}", what, s.ToString());
    }
  }
  return fault.WithContext(fmt::format("{}: stopped after {} readings", what, readings_taken));
}

double ScaledCondition(const Eigen::MatrixXd& info) {
  const Eigen::VectorXd d = info.diagonal().cwiseMax(1e-300).cwiseSqrt().cwiseInverse();
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(d.asDiagonal() * info * d.asDiagonal());
  const Eigen::VectorXd ev = es.eigenvalues();
  return ev(0) > 0 ? ev(ev.size() - 1) / ev(0) : std::numeric_limits<double>::infinity();
}

}  // namespace

Status CheckCancel(const CancelCheck& cancelled, const std::string& what) {
  if (cancelled && cancelled()) return Cancelled(what + ": cancelled");
  return Status::Ok();
}

ProgressLog::ProgressLog(std::string what) : what_(std::move(what)), start_s_(NowSeconds()) {}

void ProgressLog::operator()(int done, int total) {
  const double now = NowSeconds();
  const int percent = total > 0 ? 100 * done / total : 100;
  if (done < total && now - last_s_ < 5.0 && percent - last_percent_ < 10) return;
  last_s_ = now;
  last_percent_ = percent;
  const double elapsed = now - start_s_;
  const double remaining = done > 0 ? elapsed * (total - done) / done : 0.0;
  spdlog::info("{}: {}/{} ({}%), {:.1f} s elapsed, about {:.1f} s to go", what_, done, total, percent, elapsed, remaining);
}

Status RobotAcquisitionOptions::Check() const {
  IDI_RETURN_IF_ERROR(plan.Check());
  IDI_RETURN_IF_ERROR(loop.Check());
  if (!(distance_mm > 0) || per_set < 10 || !(pool_factor >= 1) || held_out < 0 ||
      !(max_failure_fraction >= 0 && max_failure_fraction < 1) || wall < -1 || !(preferred_wall_distance_mm > 0)) {
    return InvalidArgument("robot acquisition: invalid options (distance > 0, at least 10 readings per set, ...)");
  }
  return Status::Ok();
}

Status RailAcquisitionOptions::Check() const {
  IDI_RETURN_IF_ERROR(plan.Check());
  IDI_RETURN_IF_ERROR(loop.Check());
  if (readings < 20 || walls.empty() || points < 2 || !(rail_max_mm >= 0)) {
    return InvalidArgument("rail acquisition: invalid options (at least 20 readings, 2 points, one wall)");
  }
  return Status::Ok();
}

Rigid3d NominalWorldFromBase(int arm_index, const calib::ArmModel& model, const CellSetup& setup, double rail_mm) {
  const Rigid3d rail_from_base = RailFromBase(model.rail.value(kPhiL), model.rail.value(kPhiM), rail_mm);
  return arm_index == 0 ? rail_from_base : Rail1FromRail2(setup.psi.data()) * rail_from_base;
}

namespace {

// AcquireRobotData into `out`, which keeps what was measured when this ends with an error.
Status AcquireRobotDataInto(ArmDevices& dev,
                            int arm_index,
                            const CellSetup& setup,
                            const calib::ArmModel& model,
                            const RobotAcquisitionOptions& o,
                            RobotAcquisition& out) {
  IDI_RETURN_IF_ERROR(o.Check());
  IDI_RETURN_IF_ERROR(CheckDevices(dev, "robot acquisition"));
  if (o.wall >= static_cast<int>(setup.world_from_wall.size())) {
    return InvalidArgument("robot acquisition: no wall " + std::to_string(o.wall) + " in the setup");
  }
  const bool translate = o.method == calib::TranslationMethod::kTranslate;
  const std::array<double, 2> rail_mm = {o.rail_start_mm, o.rail_start_mm + (translate ? o.distance_mm : 0.0)};
  out.wall = o.wall;
  if (out.wall < 0) {
    const Vec3d base = NominalWorldFromBase(arm_index, model, setup, rail_mm[0]).translation;
    double best = std::numeric_limits<double>::infinity();
    for (std::size_t w = 0; w < setup.world_from_wall.size(); ++w) {
      const Rigid3d& wf = setup.world_from_wall[w];
      if (std::abs(wf.rotation(2, 2)) > 0.5) continue;  // floors and ceilings
      const double dist = std::abs((wf.Inverse() * base).z());
      if (std::abs(dist - o.preferred_wall_distance_mm) < best) {
        best = std::abs(dist - o.preferred_wall_distance_mm);
        out.wall = static_cast<int>(w);
      }
    }
    if (out.wall < 0) return InvalidArgument("robot acquisition: the setup has no upright wall to observe the spot on");
  }
  const int wall = out.wall;
  const Rigid3d& world_from_wall = setup.world_from_wall[static_cast<std::size_t>(wall)];
  // The targets: on the wall near the middle of the arm's base positions; the second point D further
  // along the wall for the two-points method.
  const Vec3d base_mid = NominalWorldFromBase(arm_index, model, setup, 0.5 * (rail_mm[0] + rail_mm[1])).translation;
  const Vec3d mid_on_wall = world_from_wall.Inverse() * base_mid;
  const Vec2d target1 = Vec2d(mid_on_wall.x(), 0.0) + o.target_offset_mm;
  const std::array<Vec2d, 2> targets = {target1, translate ? target1 : Vec2d(target1 + Vec2d(o.distance_mm, 0.0))};
  std::array<Rigid3d, 2> base_from_wall;
  std::array<Vec3d, 2> point_in_base;
  for (std::size_t s = 0; s < 2; ++s) {
    base_from_wall[s] = NominalWorldFromBase(arm_index, model, setup, rail_mm[s]).Inverse() * world_from_wall;
    point_in_base[s] = base_from_wall[s] * Vec3d(targets[s].x(), targets[s].y(), 0.0);
  }
  out.plane_normal_in_base = base_from_wall[0].rotation.col(2);
  out.targets_on_wall = targets;
  out.approx_point_in_base = point_in_base[0];
  const JointLimits limits = Rx130JointLimits();

  // Plan candidates for both sets (nominal model), then select for conditioning.
  calib::RobotCalibrationData pool;
  pool.method = o.method;
  pool.distance_mm = o.distance_mm;
  const int pool_per_set = static_cast<int>(std::ceil(o.per_set * o.pool_factor));
  for (int s = 0; s < 2; ++s) {
    calib::PlanOptions po = o.plan;
    po.seed = o.seed * 7u + static_cast<unsigned>(s);
    ProgressLog progress(fmt::format("robot {}: planning set {} configurations", arm_index + 1, s + 1));
    IDI_ASSIGN_OR_RETURN(const std::vector<Joints> cand,
                         calib::PlanAimConfigurations(model.robot, model.laser, point_in_base[static_cast<std::size_t>(s)],
                                                      pool_per_set, limits, po, std::ref(progress)));
    for (const Joints& q : cand) pool.readings.push_back({s + 1, q, 0});
  }
  ParamSet rail_dir = model.rail;
  if (!translate) {
    const Vec3d t = (point_in_base[1] - point_in_base[0]).normalized();
    rail_dir.set_value(kPhiL, std::atan2(t.y(), t.x()));
    rail_dir.set_value(kPhiM, std::atan2(-t.z(), std::hypot(t.x(), t.y())));
  }
  calib::RobotNoiseModel noise;
  noise.plane_normal = out.plane_normal_in_base;
  IDI_ASSIGN_OR_RETURN(out.selection,
                       calib::SelectForConditioning(
                           pool, calib::PackRobotCalibration(model.robot, model.laser, point_in_base[0], rail_dir), noise,
                           o.per_set, o.a_optimal ? calib::FileUnitWeights() : std::vector<double>{}));
  spdlog::info("robot {}: chose {} of {} planned configurations; information matrix condition number {:.3g} (first {}: {:.3g})",
               arm_index + 1, out.selection.chosen.size(), pool.readings.size(), out.selection.condition_number,
               out.selection.chosen.size(), out.selection.condition_number_first);

  // Measure: each set at its rail position, every chosen configuration driven onto its point.
  IDI_RETURN_IF_ERROR(dev.laser->SetOn(true));
  out.data.method = o.method;
  int iterations = 0, aimed = 0;
  const int total = static_cast<int>(out.selection.chosen.size()) + o.held_out;
  ProgressLog progress(fmt::format("robot {}: aiming", arm_index + 1));
  auto aim = [&](const Rigid3d& bfw, const Vec2d& target, const Joints& start) -> Result<Joints> {
    auto move = [&](const Joints& q) { return MoveAndRead(*dev.arm, q); };
    auto observe = [&]() { return dev.observe(wall); };
    const auto r = calib::AimClosedLoop(model.robot, model.laser, bfw, target, start, limits, move, observe, o.loop);
    if (!r.ok()) return r.status();
    iterations += r->iterations;
    ++aimed;
    return r->reading;
  };
  for (int s = 0; s < 2; ++s) {
    IDI_ASSIGN_OR_RETURN(out.rail_readings_mm[static_cast<std::size_t>(s)], MoveRail(*dev.rail, rail_mm[static_cast<std::size_t>(s)]));
    for (int i : out.selection.chosen) {
      const calib::AimReading& c = pool.readings[static_cast<std::size_t>(i)];
      if (c.set != s + 1) continue;
      IDI_RETURN_IF_ERROR(CheckCancel(o.cancelled, fmt::format("robot {}: acquisition", arm_index + 1)));
      const auto q = aim(base_from_wall[static_cast<std::size_t>(s)], targets[static_cast<std::size_t>(s)], c.q);
      if (!q.ok() && !IsAimingMiss(q.status())) {
        return AbortAcquisition({&dev},
                                q.status(),
                                fmt::format("robot {}: acquisition", arm_index + 1),
                                static_cast<int>(out.data.readings.size()));
      }
      if (!q.ok()) {
        ++out.loop_failures;
        spdlog::debug("robot {}: a configuration could not be aimed: {}", arm_index + 1, q.status().message());
      } else {
        out.data.readings.push_back({s + 1, *q, static_cast<int>(out.data.readings.size()) + 2});
      }
      progress(static_cast<int>(out.data.readings.size()) + out.loop_failures, total);
    }
  }
  out.data.distance_mm = translate ? out.rail_readings_mm[1] - out.rail_readings_mm[0] : o.distance_mm;
  // Held-out readings at another point, at the last rail position.
  if (o.held_out > 0) {
    const Vec2d target_h = targets[1] + Vec2d(-400.0, -250.0);
    out.held_out_target_on_wall = target_h;
    const Vec3d p = base_from_wall[1] * Vec3d(target_h.x(), target_h.y(), 0.0);
    calib::PlanOptions po = o.plan;
    po.seed = o.seed * 7u + 5u;
    IDI_ASSIGN_OR_RETURN(const std::vector<Joints> cand,
                         calib::PlanAimConfigurations(model.robot, model.laser, p, o.held_out, limits, po));
    for (const Joints& c : cand) {
      IDI_RETURN_IF_ERROR(CheckCancel(o.cancelled, fmt::format("robot {}: held-out acquisition", arm_index + 1)));
      const auto q = aim(base_from_wall[1], target_h, c);
      if (!q.ok() && !IsAimingMiss(q.status())) {
        return AbortAcquisition({&dev},
                                q.status(),
                                fmt::format("robot {}: held-out acquisition", arm_index + 1),
                                static_cast<int>(out.data.readings.size() + out.held_out.size()));
      }
      if (q.ok()) {
        out.held_out.push_back(*q);
      } else {
        ++out.loop_failures;
      }
      progress(static_cast<int>(out.data.readings.size() + out.held_out.size()) + out.loop_failures, total);
    }
  }
  out.mean_loop_iterations = aimed > 0 ? static_cast<double>(iterations) / aimed : 0.0;
  if (out.loop_failures > o.max_failure_fraction * total + 2) {
    return NotConverged(fmt::format("robot {}: {} of {} configurations could not be aimed at the point", arm_index + 1,
                                    out.loop_failures, total));
  }
  return Status::Ok();
}

// AcquireRailData into `out`, which keeps the readings taken when this ends with an error.
Status AcquireRailDataInto(ArmDevices& d1,
                           ArmDevices& d2,
                           const CellSetup& setup,
                           const calib::ArmModel& m1,
                           const calib::ArmModel& m2,
                           const RailAcquisitionOptions& o,
                           RailAcquisition& out) {
  IDI_RETURN_IF_ERROR(o.Check());
  IDI_RETURN_IF_ERROR(CheckDevices(d1, "rail acquisition, robot 1"));
  IDI_RETURN_IF_ERROR(CheckDevices(d2, "rail acquisition, robot 2"));
  const JointLimits limits = Rx130JointLimits();
  std::mt19937_64 rng(o.seed);
  std::uniform_real_distribution<double> rail(0.0, o.rail_max_mm);
  const std::array<const calib::ArmModel*, 2> models = {&m1, &m2};
  calib::PlanOptions po = o.plan;
  po.max_draws = 200000;
  // One planned reading (both arms aimed, models only) at a world point; nullopt if unreachable.
  auto plan_reading = [&](const Vec3d& p_world, double r1, double r2) -> std::optional<calib::RailReading> {
    calib::RailReading r;
    r.rail1_mm = r1;
    r.rail2_mm = r2;
    for (int k = 0; k < 2; ++k) {
      const Vec3d p = NominalWorldFromBase(k, *models[static_cast<std::size_t>(k)], setup, k == 0 ? r1 : r2).Inverse() * p_world;
      po.seed = static_cast<unsigned>(rng());
      const auto q = calib::PlanAimConfigurations(models[static_cast<std::size_t>(k)]->robot,
                                                  models[static_cast<std::size_t>(k)]->laser, p, 1, limits, po);
      if (!q.ok()) return std::nullopt;
      (k == 0 ? r.q1 : r.q2) = (*q)[0];
    }
    return r;
  };
  // Candidate shared points: a grid on each candidate wall between the two robots.
  struct Candidate {
    int wall;
    Vec2d on_wall;
    Vec3d world;
    Eigen::Matrix4d info = Eigen::Matrix4d::Zero();
  };
  std::vector<Candidate> cands;
  for (int w : o.walls) {
    if (w < 0 || w >= static_cast<int>(setup.world_from_wall.size())) {
      return InvalidArgument("rail acquisition: no wall " + std::to_string(w) + " in the setup");
    }
    const Rigid3d& wf = setup.world_from_wall[static_cast<std::size_t>(w)];
    const Vec3d centre = wf.Inverse() * Vec3d(0.5 * setup.psi[0], 0.0, 0.0);
    for (double dx : {-1500.0, 0.0, 1500.0}) {
      for (double dy : {-500.0, 500.0}) {
        Candidate c;
        c.wall = w;
        c.on_wall = Vec2d(centre.x() + dx, (std::abs(wf.rotation(2, 2)) > 0.7 ? centre.y() : 0.0) + dy);
        c.world = wf * Vec3d(c.on_wall.x(), c.on_wall.y(), 0.0);
        int ok = 0;
        for (int s = 0; s < 3; ++s) {
          const auto r = plan_reading(c.world, rail(rng), rail(rng));
          if (!r) continue;
          // One reading's information J^T J about psi (rank one).
          const calib::RailReading& rr = *r;
          const Line3d a = calib::ArmLineInRailFrame(m1, rr.q1, rr.rail1_mm);
          const Line3d b = calib::ArmLineInRailFrame(m2, rr.q2, rr.rail2_mm);
          const optim::RailResidual res(a, b, 0.1);
          std::array<double, 4> psi = setup.psi;
          std::array<double, 4> j{};
          double* jp = j.data();
          const double* pp = psi.data();
          double v = 0;
          if (!res.Evaluate(&pp, &v, &jp)) continue;
          const Eigen::Map<const Eigen::Vector4d> jv(j.data());
          c.info += jv * jv.transpose();
          ++ok;
        }
        if (ok >= 2) cands.push_back(c);
      }
    }
  }
  if (cands.size() < 2) return NotFound("rail acquisition: fewer than 2 candidate points are reachable by both arms");
  // Greedy D-optimal choice of the shared points (parameters scaled by the candidates' total information).
  Eigen::Matrix4d total = Eigen::Matrix4d::Zero();
  for (const Candidate& c : cands) total += c.info;
  const Eigen::Vector4d scale = total.diagonal().cwiseSqrt().cwiseInverse();
  Eigen::Matrix4d chosen_info = 1e-9 * Eigen::Matrix4d::Identity();
  std::vector<bool> used(cands.size(), false);
  std::vector<int> chosen;
  for (int k = 0; k < std::min<int>(o.points, static_cast<int>(cands.size())); ++k) {
    int best = -1;
    double best_gain = -1e300;
    for (std::size_t i = 0; i < cands.size(); ++i) {
      if (used[i]) continue;
      const Eigen::Matrix4d m = scale.asDiagonal() * (chosen_info + cands[i].info) * scale.asDiagonal();
      const double g = std::log(std::max(1e-300, m.determinant()));
      if (g > best_gain) {
        best_gain = g;
        best = static_cast<int>(i);
      }
    }
    used[static_cast<std::size_t>(best)] = true;
    chosen.push_back(best);
    chosen_info += cands[static_cast<std::size_t>(best)].info;
    out.points_world.push_back(cands[static_cast<std::size_t>(best)].world);
    out.point_walls.push_back(cands[static_cast<std::size_t>(best)].wall);
  }
  out.condition_number = ScaledCondition(chosen_info);
  {
    Eigen::Matrix4d one = 1e-12 * Eigen::Matrix4d::Identity();
    for (const Candidate& c : cands) {
      if (c.wall == o.walls.front()) one += c.info;
    }
    out.condition_number_one_wall = ScaledCondition(one);
  }
  spdlog::info("rail: {} shared points on walls {}; predicted condition number {:.3g} (points on one wall only: {:.3g})",
               out.points_world.size(), fmt::join(out.point_walls, ","), out.condition_number, out.condition_number_one_wall);

  IDI_RETURN_IF_ERROR(d1.laser->SetOn(true));
  IDI_RETURN_IF_ERROR(d2.laser->SetOn(true));
  ProgressLog progress("rail: readings");
  for (int i = 0; i < o.readings; ++i) {
    IDI_RETURN_IF_ERROR(CheckCancel(o.cancelled, "rail: acquisition"));
    const Candidate& c = cands[static_cast<std::size_t>(chosen[static_cast<std::size_t>(i) % chosen.size()])];
    IDI_ASSIGN_OR_RETURN(const double r1, MoveRail(*d1.rail, rail(rng)));
    IDI_ASSIGN_OR_RETURN(const double r2, MoveRail(*d2.rail, rail(rng)));
    const auto planned = plan_reading(c.world, r1, r2);
    if (!planned) {
      ++out.loop_failures;
      continue;
    }
    calib::RailReading reading;
    reading.rail1_mm = r1;
    reading.rail2_mm = r2;
    bool ok = true;
    // Robot 2 first, then robot 1 onto the same point (§5.3.2).
    for (int k = 1; k >= 0 && ok; --k) {
      ArmDevices& d = k == 0 ? d1 : d2;
      const calib::ArmModel& m = *models[static_cast<std::size_t>(k)];
      const Rigid3d bfw = NominalWorldFromBase(k, m, setup, k == 0 ? r1 : r2).Inverse() *
                          setup.world_from_wall[static_cast<std::size_t>(c.wall)];
      auto move = [&](const Joints& q) { return MoveAndRead(*d.arm, q); };
      auto observe = [&]() { return d.observe(c.wall); };
      const auto r = calib::AimClosedLoop(m.robot, m.laser, bfw, c.on_wall, k == 0 ? planned->q1 : planned->q2, limits,
                                          move, observe, o.loop);
      if (!r.ok() && !IsAimingMiss(r.status())) {
        return AbortAcquisition({&d1, &d2},
                                r.status(),
                                fmt::format("rail: acquisition (robot {})", k + 1),
                                static_cast<int>(out.readings.size()));
      }
      if (!r.ok()) {
        ok = false;
        break;
      }
      (k == 0 ? reading.q1 : reading.q2) = r->reading;
    }
    if (!ok) {
      ++out.loop_failures;
      continue;
    }
    reading.row = static_cast<int>(out.readings.size()) + 2;
    out.readings.push_back(reading);
    progress(i + 1, o.readings);
  }
  if (out.loop_failures > o.max_failure_fraction * o.readings + 2) {
    return NotConverged(fmt::format("rail: {} of {} readings could not be aimed", out.loop_failures, o.readings));
  }
  return Status::Ok();
}

}  // namespace

Result<RobotAcquisition> AcquireRobotData(ArmDevices& dev,
                                          int arm_index,
                                          const CellSetup& setup,
                                          const calib::ArmModel& model,
                                          const RobotAcquisitionOptions& o) {
  RobotAcquisition out;
  const Status s = AcquireRobotDataInto(dev, arm_index, setup, model, o, out);
  if (s.ok()) return out;
  if (o.partial != nullptr) *o.partial = std::move(out);
  return s;
}

Result<RailAcquisition> AcquireRailData(ArmDevices& d1,
                                        ArmDevices& d2,
                                        const CellSetup& setup,
                                        const calib::ArmModel& m1,
                                        const calib::ArmModel& m2,
                                        const RailAcquisitionOptions& o) {
  RailAcquisition out;
  const Status s = AcquireRailDataInto(d1, d2, setup, m1, m2, o, out);
  if (s.ok()) return out;
  if (o.partial != nullptr) *o.partial = std::move(out);
  return s;
}

}  // namespace idi::workcell
