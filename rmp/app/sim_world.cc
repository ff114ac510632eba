#include "rmp/app/sim_world.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <deque>
#include <functional>
#include <limits>
#include <thread>
#include <tuple>
#include <utility>

#include "shared/util/units.h"

namespace idi::rmp {
namespace {

int64_t SecToNsRound(double s) { return static_cast<int64_t>(std::llround(s * 1e9)); }

}  // namespace

Status SimFaults::Check() const {
  for (const std::string* c : {&frozen_camera, &dead_camera}) {
    if (!c->empty() && *c != "left" && *c != "right") return InvalidArgument("sim faults: camera must be 'left' or 'right', got '" + *c + "'");
  }
  if (!(drop_probability >= 0 && drop_probability < 1)) return InvalidArgument("sim faults: drop_probability must be in [0, 1)");
  if (!(bus_off_duration_s >= 0)) return InvalidArgument("sim faults: bus_off_duration_s must be >= 0");
  if (!(stamp_glitch_s >= 0)) return InvalidArgument("sim faults: stamp_glitch_s must be >= 0");
  // Times on the twin's clock (nanoseconds in 64 bits): negative means never; a week is the limit.
  constexpr double kMaxS = 7 * 24 * 3600.0;
  const std::pair<const char*, double> times[] = {{"frozen_from_s", frozen_from_s},
                                                  {"frozen_to_s", frozen_to_s},
                                                  {"dead_from_s", dead_from_s},
                                                  {"dead_to_s", dead_to_s},
                                                  {"rmp_silent_from_s", rmp_silent_from_s},
                                                  {"rmp_silent_to_s", rmp_silent_to_s},
                                                  {"integrators_missing_from_s", integrators_missing_from_s},
                                                  {"integrators_missing_to_s", integrators_missing_to_s},
                                                  {"bus_off_at_s", bus_off_at_s},
                                                  {"bus_off_duration_s", bus_off_duration_s},
                                                  {"battery_drop_at_s", battery_drop_at_s},
                                                  {"stamp_glitch_at_s", stamp_glitch_at_s},
                                                  {"stamp_glitch_s", stamp_glitch_s}};
  for (const auto& [name, t] : times) {
    if (!(std::isfinite(t) && t <= kMaxS))
      return InvalidArgument(std::string("sim faults: ") + name +
                             " must be a time of at most a week (negative: never)");
  }
  const std::tuple<const char*, double, double> spans[] = {
      {"frozen", frozen_from_s, frozen_to_s},
      {"dead", dead_from_s, dead_to_s},
      {"rmp_silent", rmp_silent_from_s, rmp_silent_to_s},
      {"integrators_missing", integrators_missing_from_s, integrators_missing_to_s}};
  for (const auto& [name, from, to] : spans) {
    if (from >= 0 && to >= 0 && !(to > from)) {
      return InvalidArgument(std::string("sim faults: ") + name + "_to_s must come after " + name + "_from_s");
    }
  }
  for (std::size_t i = 0; i < covered_m.size(); ++i) {
    if (!(covered_m[i].second > covered_m[i].first && covered_m[i].first >= 0)) {
      return InvalidArgument("sim faults: covered_m[" + std::to_string(i) + "] must be [from, to] with 0 <= from < to");
    }
  }
  return Status::Ok();
}

Status SimOptions::Check() const {
  if (!(camera_rate_hz > 0 && camera_rate_hz <= 100)) return InvalidArgument("sim: camera_rate_hz must be in (0, 100]");
  if (!(camera_latency_s >= 0 && camera_latency_s < 1)) return InvalidArgument("sim: camera_latency_s must be in [0, 1)");
  if (!(slip_noise_m_per_sqrt_m >= 0)) return InvalidArgument("sim: slip_noise_m_per_sqrt_m must be >= 0");
  if (!std::isfinite(calibration_pitch_error_deg) || !std::isfinite(calibration_height_error_m)) {
    return InvalidArgument("sim: calibration errors must be finite");
  }
  IDI_RETURN_IF_ERROR(render.Check());
  return faults.Check();
}

// The twin's two cameras: a process on the bus that renders both at every exposure time from the
// vehicle's true pose and delivers the images camera_latency_s later.
class TwinCameras final : public sim::SimProcess, public FrameSource {
 public:
  TwinCameras(SimWorld* world, sim::Scene scene, StereoRig true_rig)
      : world_(world), scene_(std::move(scene)), rig_(std::move(true_rig)), rng_(world->options_.seed * 7919 + 13) {
    period_ns_ = SecToNsRound(1.0 / world->options_.camera_rate_hz);
    latency_ns_ = SecToNsRound(world->options_.camera_latency_s);
    next_ns_ = period_ns_;
    // When both cameras render at once, each gets half the cores (asked once: it reads /sys each time).
    pair_render_threads_ = std::clamp(static_cast<int>(std::thread::hardware_concurrency()) / 2, 1, 4);
  }

  int64_t NextWakeNs() const override { return next_ns_; }
  void RunUntil(int64_t t_ns) override {
    while (next_ns_ <= t_ns) {
      Capture(next_ns_);
      next_ns_ += period_ns_;
    }
  }
  Result<std::vector<hal::Image>> Collect(int64_t now_ns) override {
    if (!error_.ok()) return error_;
    std::vector<hal::Image> out;
    while (!pending_.empty() && pending_.front().first <= now_ns) {
      out.push_back(std::move(pending_.front().second));
      pending_.pop_front();
    }
    return out;
  }

 private:
  Rigid3d WorldFromVehicle() const {
    const sim::VehicleTwin& v = world_->rmp_->vehicle();
    const sim::VehicleTruth& t = v.truth();
    // Balancing, the platform pitches about the wheel axle (the sensors' pitch, noise-free unless
    // tilt noise is configured).
    const double pitch = world_->options_.balance_mode ? v.sensors().pitch_rad : 0.0;
    const double r = v.options().wheel_radius_m;
    return Translation(t.x_m, t.y_m, 0.0) * RotZ(t.yaw_rad) * Translation(0.0, 0.0, r) * RotY(pitch) * Translation(0.0, 0.0, -r);
  }

  void Capture(int64_t t_ns) {
    world_->rmp_->vehicle().AdvanceTo(t_ns);
    const Rigid3d world_from_vehicle = WorldFromVehicle();
    const SimFaults& f = world_->options_.faults;
    const double t_s = static_cast<double>(t_ns) * 1e-9;
    std::uniform_real_distribution<double> u(0.0, 1.0);
    // Which cameras deliver, and which of those render a new image (faults decided in camera order).
    hal::Image img[2];
    bool deliver[2] = {false, false}, render[2] = {false, false};
    for (int k = 0; k < 2; ++k) {
      const std::string name = k == 0 ? "left" : "right";
      ++seq_[k];
      if (name == f.dead_camera && t_s >= f.dead_from_s && t_s < f.dead_to_s) continue;
      if (f.drop_probability > 0 && u(rng_) < f.drop_probability) continue;
      deliver[k] = true;
      img[k].camera = name;
      img[k].sequence = seq_[k];
      img[k].timestamp_ns = t_ns;
      if (f.stamp_glitch_at_s >= 0 && t_s >= f.stamp_glitch_at_s && !glitched_)
        img[k].timestamp_ns += SecToNsRound(f.stamp_glitch_s);
      if (name == f.frozen_camera && t_s >= f.frozen_from_s && t_s < f.frozen_to_s && !last_[k].empty()) {
        img[k].pixels = last_[k];  // the same buffer again
      } else {
        render[k] = true;
      }
    }
    // The two cameras render at once, each on half the cores (one each on a two-core machine; the
    // image does not depend on the threads).
    Result<cv::Mat> rendered[2] = {cv::Mat(), cv::Mat()};
    auto render_camera = [&](int k) {
      const RigCamera& cam = k == 0 ? rig_.left : rig_.right;
      sim::RenderOptions ro = world_->options_.render;
      ro.seed = world_->options_.seed * 1000003 + seq_[k] * 2 + static_cast<uint64_t>(k);
      if (render[0] && render[1] && ro.threads == 0) ro.threads = pair_render_threads_;
      rendered[k] = sim::RenderScene(scene_, cam.intrinsics, (world_from_vehicle * cam.vehicle_from_camera).Inverse(), ro);
    };
    const auto render_start = std::chrono::steady_clock::now();
    if (render[0] && render[1]) {
      std::thread right([&] { render_camera(1); });
      render_camera(0);
      right.join();
    } else {
      for (int k = 0; k < 2; ++k) {
        if (render[k]) render_camera(k);
      }
    }
    world_->render_wall_s_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - render_start).count();
    for (int k = 0; k < 2; ++k) {
      if (!deliver[k]) continue;
      if (render[k]) {
        if (!rendered[k].ok()) {
          error_ = rendered[k].status().WithContext(std::string("twin camera ") + (k == 0 ? "left" : "right"));
          return;
        }
        img[k].pixels = *rendered[k];
        last_[k] = img[k].pixels;
      }
      pending_.emplace_back(t_ns + latency_ns_, std::move(img[k]));
    }
    if (f.stamp_glitch_at_s >= 0 && t_s >= f.stamp_glitch_at_s) glitched_ = true;
    if (world_->following_) CountVisibility(world_from_vehicle);
  }

  // Whether the coming track (the next 0.6 m of tape ahead of the vehicle's true progress) shows in
  // both cameras.
  void CountVisibility(const Rigid3d& world_from_vehicle) {
    const TrackSpec& track = world_->track_;
    double lat = 0.0;
    const sim::VehicleTruth& t = world_->rmp_->vehicle().truth();
    const double s0 = world_->ProgressAt(Vec2d(t.x_m, t.y_m), &lat);
    const double length = track.Length();
    if (length - s0 < 0.15) return;  // at the end: nothing more to follow
    ++world_->truth_.frames_following;
    std::vector<std::pair<double, double>> without = track.gaps_m;
    without.insert(without.end(), world_->options_.faults.covered_m.begin(), world_->options_.faults.covered_m.end());
    auto taped = [&](double s) {
      for (const auto& [a, b] : without) {
        if (s > a && s < b) return false;
      }
      return true;
    };
    const std::vector<double>& vs = world_->vertex_s_;
    double tape_sampled = 0.0, visible = 0.0;
    for (double s = s0; s <= length && tape_sampled < 0.6; s += 0.01) {
      if (!taped(s)) continue;
      tape_sampled += 0.01;
      std::size_t i = 1;
      while (i + 1 < vs.size() && vs[i] < s) ++i;
      const double f = (s - vs[i - 1]) / std::max(1e-12, vs[i] - vs[i - 1]);
      const Vec2d p = track.points_m[i - 1] + f * (track.points_m[i] - track.points_m[i - 1]);
      bool both = true;
      for (const RigCamera* cam : {&rig_.left, &rig_.right}) {
        const Vec3d pc = (world_from_vehicle * cam->vehicle_from_camera).Inverse() * Vec3d(p.x(), p.y(), 0.0);
        const auto px = Project(cam->intrinsics, pc);
        if (!px || !cam->intrinsics.InImage(*px, 2.0)) both = false;
      }
      if (both) visible += 0.01;
    }
    if (visible >= std::min(0.05, 0.8 * tape_sampled)) ++visible_frames_;
    world_->truth_.visible_fraction = static_cast<double>(visible_frames_) / world_->truth_.frames_following;
  }

  SimWorld* world_;
  sim::Scene scene_;
  StereoRig rig_;
  std::mt19937_64 rng_;
  int64_t period_ns_ = 0, latency_ns_ = 0, next_ns_ = 0;
  int pair_render_threads_ = 1;
  uint64_t seq_[2] = {0, 0};
  bool glitched_ = false;  // the stamp glitch of the faults happened
  cv::Mat last_[2];
  std::deque<std::pair<int64_t, hal::Image>> pending_;
  int visible_frames_ = 0;
  Status error_;
};

namespace {

// Applies the scheduled faults on the twin's clock.
class FaultSchedule final : public sim::SimProcess {
 public:
  void Add(double at_s, std::function<void()> action) {
    if (at_s < 0) return;
    events_.emplace_back(SecToNsRound(at_s), std::move(action));
    std::sort(events_.begin(), events_.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  }
  int64_t NextWakeNs() const override { return next_ < events_.size() ? events_[next_].first : sim::kNeverNs; }
  void RunUntil(int64_t t_ns) override {
    while (next_ < events_.size() && events_[next_].first <= t_ns) events_[next_++].second();
  }

 private:
  std::vector<std::pair<int64_t, std::function<void()>>> events_;
  std::size_t next_ = 0;
};

}  // namespace

SimWorld::SimWorld(const TrackSpec& track, const SimOptions& options) : track_(track), options_(options), clock_(0) {}
SimWorld::~SimWorld() = default;

FrameSource* SimWorld::frames() { return cameras_.get(); }

Result<std::unique_ptr<SimWorld>> SimWorld::Create(const TrackSpec& track, const SimOptions& options,
                                                   const StereoRig& calibrated_rig, const SimRmpOptions& rmp_options) {
  IDI_RETURN_IF_ERROR(track.Check());
  IDI_RETURN_IF_ERROR(options.Check());
  IDI_RETURN_IF_ERROR(calibrated_rig.Check());
  std::unique_ptr<SimWorld> w(new SimWorld(track, options));
  w->vertex_s_.push_back(0.0);
  for (std::size_t i = 1; i < track.points_m.size(); ++i) {
    w->vertex_s_.push_back(w->vertex_s_.back() + (track.points_m[i] - track.points_m[i - 1]).norm());
  }
  w->bus_ = std::make_unique<sim::VirtualCanBus>(&w->clock_);
  SimRmpOptions ro = rmp_options;
  track.StartPose(&ro.vehicle.start_x_m, &ro.vehicle.start_y_m, &ro.vehicle.start_yaw_rad);
  ro.vehicle.left_wheel_scale_error = options.left_wheel_scale_error;
  ro.vehicle.right_wheel_scale_error = options.right_wheel_scale_error;
  ro.vehicle.slip_noise_m_per_sqrt_m = options.slip_noise_m_per_sqrt_m;
  ro.vehicle.seed = options.seed;
  IDI_RETURN_IF_ERROR(ro.Check());
  w->rmp_ = std::make_unique<SimRmp>(w->bus_.get(), ro);
  w->endpoint_ = w->bus_->AddEndpoint("idi-rmp");

  TrackSceneOptions so = options.scene;
  so.covered_m = options.faults.covered_m;
  so.seed = options.seed;
  IDI_ASSIGN_OR_RETURN(sim::Scene scene, BuildTrackScene(track, so));
  // The cameras as mounted: the calibration, off by the configured error.
  StereoRig truth = calibrated_rig;
  for (RigCamera* c : {&truth.left, &truth.right}) {
    c->vehicle_from_camera = Translation(0.0, 0.0, options.calibration_height_error_m) * c->vehicle_from_camera *
                             RotX(-DegToRad(options.calibration_pitch_error_deg));
  }
  w->cameras_ = std::make_unique<TwinCameras>(w.get(), std::move(scene), truth);
  w->bus_->AddProcess(w->cameras_.get());

  auto faults = std::make_unique<FaultSchedule>();
  const SimFaults& f = options.faults;
  SimRmp* rmp = w->rmp_.get();
  sim::VirtualCanBus* bus = w->bus_.get();
  sim::VirtualCanEndpoint* ep = w->endpoint_;
  faults->Add(f.rmp_silent_from_s, [rmp] { rmp->SetSilent(true); });
  faults->Add(f.rmp_silent_to_s, [rmp] { rmp->SetSilent(false); });
  faults->Add(f.integrators_missing_from_s, [rmp] { rmp->SetWheelIntegratorsMissing(true); });
  faults->Add(f.integrators_missing_to_s, [rmp] { rmp->SetWheelIntegratorsMissing(false); });
  faults->Add(f.bus_off_at_s, [bus, ep, d = f.bus_off_duration_s] { bus->InjectBusOff(ep, SecToNsRound(d)); });
  faults->Add(f.battery_drop_at_s, [rmp, v = f.battery_drop_v] { rmp->vehicle().SetBatteryDrop(v); });
  w->bus_->AddProcess(faults.get());
  w->faults_ = std::move(faults);
  return w;
}

double SimWorld::ProgressAt(const Vec2d& p, double* lateral) const {
  double best = std::numeric_limits<double>::infinity(), best_s = progress_s_;
  for (std::size_t i = 1; i < track_.points_m.size(); ++i) {
    const double s0 = vertex_s_[i - 1], s1 = vertex_s_[i];
    if (s1 < progress_s_ - 0.3 || s0 > progress_s_ + 1.0) continue;
    const Vec2d a = track_.points_m[i - 1], d = track_.points_m[i] - a;
    const double t = std::clamp((p - a).dot(d) / d.squaredNorm(), 0.0, 1.0);
    const double s = s0 + t * (s1 - s0);
    if (s < progress_s_ - 0.3 || s > progress_s_ + 1.0) continue;
    const double e = (a + t * d - p).norm();
    if (e < best) {
      best = e;
      best_s = s;
    }
  }
  if (std::isfinite(best)) progress_s_ = best_s;
  *lateral = std::isfinite(best) ? best : 0.0;
  return progress_s_;
}

Pose2 SimWorld::TruthPose() const {
  const sim::VehicleTruth& t = rmp_->vehicle().truth();
  return {t.x_m, t.y_m, t.yaw_rad};
}

void SimWorld::AfterTick(const TickRecord& /*tick*/, bool following) {
  following_ = following;
  const sim::VehicleTruth& t = rmp_->vehicle().truth();
  double lat = 0.0;
  const double s = ProgressAt(Vec2d(t.x_m, t.y_m), &lat);
  truth_.path_xy.emplace_back(t.x_m, t.y_m);
  truth_.path_error_m.push_back(following ? lat : -1.0);
  truth_.distance_m = t.distance_m;
  truth_.max_speed_mps = std::max(truth_.max_speed_mps, t.speed_mps);
  truth_.end_distance_m = (Vec2d(t.x_m, t.y_m) - track_.points_m.back()).norm();
  if (following) {
    sum_sq_ += lat * lat;
    ++samples_;
    max_lat_ = std::max(max_lat_, lat);
    truth_.s_m.push_back(s);
    truth_.lateral_m.push_back(lat);
  }
}

SimTruth SimWorld::Truth() const {
  SimTruth out = truth_;
  out.lateral_rms_m = samples_ > 0 ? std::sqrt(sum_sq_ / samples_) : 0.0;
  out.lateral_max_m = max_lat_;
  if (out.frames_following == 0) out.visible_fraction = 0.0;
  return out;
}

}  // namespace idi::rmp
