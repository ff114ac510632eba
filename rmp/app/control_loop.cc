#include "rmp/app/control_loop.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>

#include "shared/runtime/systemd_notify.h"

namespace idi::rmp {
namespace {

// A hash of the pixels: a frozen camera repeats its last buffer bit for bit (sensor noise makes two
// real frames differ). Four independent multiply-rotate chains over 8-byte words (FNV-1a byte by byte
// was one serial multiply per byte: 1.2 ms per 640 x 480 frame on the loop's thread), the rest of
// each row byte by byte.
uint64_t ContentHash(const cv::Mat& m) {
  constexpr uint64_t kPrime = 1099511628211ull;
  const auto mix = [](uint64_t h, uint64_t w) {
    h = (h ^ w) * kPrime;
    return (h << 29) | (h >> 35);
  };
  uint64_t h[4] = {1469598103934665603ull, 0x9E3779B97F4A7C15ull, 0xC2B2AE3D27D4EB4Full, 0x165667B19E3779F9ull};
  for (int r = 0; r < m.rows; ++r) {
    const uint8_t* p = m.ptr<uint8_t>(r);
    const std::size_t n = static_cast<std::size_t>(m.cols) * m.elemSize();
    std::size_t i = 0;
    for (; i + 32 <= n; i += 32) {
      uint64_t w[4];
      std::memcpy(w, p + i, sizeof(w));
      for (int k = 0; k < 4; ++k) h[k] = mix(h[k], w[k]);
    }
    for (; i < n; ++i) h[0] = mix(h[0], p[i]);
    h[1] = mix(h[1], static_cast<uint64_t>(r));  // rows of different lengths or order hash apart
  }
  return mix(mix(mix(h[0], h[1]), h[2]), h[3]);
}

int CameraIndex(const std::string& name) {
  if (name == "left") return 0;
  if (name == "right") return 1;
  return -1;
}

void PingWatchdog() {
  static auto last = std::chrono::steady_clock::time_point{};
  const auto now = std::chrono::steady_clock::now();
  if (now - last < std::chrono::milliseconds(200)) return;
  last = now;
  NotifyWatchdog();
}

}  // namespace

const char* DecisionName(Decision d) {
  switch (d) {
    case Decision::kDrive: return "drive";
    case Decision::kStopRequested: return "stop-requested";
    case Decision::kRmpNotRunning: return "rmp-not-running";
    case Decision::kRmpStatusStale: return "rmp-status-stale";
    case Decision::kOdometryStale:
      return "odometry-stale";
    case Decision::kBusOff: return "bus-off";
    case Decision::kLowBattery: return "low-battery";
    case Decision::kRmpFault: return "rmp-fault";
    case Decision::kNoPerception: return "no-perception";
    case Decision::kPerceptionStale: return "perception-stale";
    case Decision::kTrackLost: return "track-lost";
    case Decision::kAtEnd: return "at-end";
  }
  return "?";
}

Status ControlLoopOptions::Check() const {
  if (!(max_perception_age_s > 0 && max_perception_age_s <= kMaxInputAgeLimitS)) {
    return InvalidArgument("control: max_perception_age_s = " + FormatNumber(max_perception_age_s) +
                           " must be in (0, " + FormatNumber(kMaxInputAgeLimitS) + "] s");
  }
  if (!(max_odometry_age_s > 0 && max_odometry_age_s <= kMaxOdometryAgeLimitS)) {
    return InvalidArgument("control: max_odometry_age_s = " + FormatNumber(max_odometry_age_s) + " must be in (0, " +
                           FormatNumber(kMaxOdometryAgeLimitS) + "] s");
  }
  if (!(track_lost_s > 0 && track_lost_s <= kTrackLostLimitS)) {
    return InvalidArgument("control: track_lost_s = " + FormatNumber(track_lost_s) + " must be in (0, " +
                           FormatNumber(kTrackLostLimitS) + "] s");
  }
  if (!(stereo_max_skew_s > 0)) return InvalidArgument("control: stereo_max_skew_s must be positive");
  if (!(finish_hold_s >= 0)) return InvalidArgument("control: finish_hold_s must be >= 0");
  if (!(start_timeout_s > 0)) return InvalidArgument("control: start_timeout_s must be positive");
  if (!(max_run_s >= 0 && std::isfinite(max_run_s)))
    return InvalidArgument("control: max_run_s must be >= 0 (0: no limit)");
  return Status::Ok();
}

ControlLoop::ControlLoop(const ControlLoopOptions& options, hal::Clock* clock, RmpDriver* driver, FrameSource* frames,
                         TrackPerception* perception, const PlannerOptions& planner, const TrackModelOptions& track,
                         replay::DriveLogWriter* log)
    : options_(options),
      clock_(clock),
      driver_(driver),
      frames_(frames),
      perception_(perception),
      planner_(planner),
      track_(track),
      log_(log) {}

Status ControlLoop::Start() {
  if (log_ != nullptr) driver_->SetFrameLog(log_->can_log());
  return driver_->Start();
}

void ControlLoop::RequestStop(const std::string& why) {
  if (!stop_requested_) spdlog::info("stop requested: {}", why);
  stop_requested_ = true;
  stop_reason_ = why;
  driver_->RequestStop(why);
}

Status ControlLoop::Shutdown() {
  stop_requested_ = true;
  return driver_->Shutdown();
}

std::optional<Pose2> ControlLoop::OdometryAt(int64_t t_ns) const {
  if (odom_history_.empty() || t_ns < odom_history_.front().first) return std::nullopt;
  if (static_cast<double>(t_ns - odom_history_.back().first) * 1e-9 > options_.max_odometry_age_s) return std::nullopt;
  for (std::size_t i = 1; i < odom_history_.size(); ++i) {
    const auto& [t1, p1] = odom_history_[i];
    if (t1 < t_ns) continue;
    const auto& [t0, p0] = odom_history_[i - 1];
    // Not across an outage of the integrators: no pose is known between its ends.
    if (static_cast<double>(t1 - t0) * 1e-9 > options_.max_odometry_age_s) return std::nullopt;
    const double f = t1 > t0 ? static_cast<double>(t_ns - t0) / static_cast<double>(t1 - t0) : 1.0;
    return Pose2{p0.x + f * (p1.x - p0.x), p0.y + f * (p1.y - p0.y), p0.yaw + f * (p1.yaw - p0.yaw)};
  }
  return odom_history_.back().second;
}

void ControlLoop::PerceivePair(const hal::Image& left, const hal::Image& right, TickRecord* rec) {
  const int64_t exposure = (left.timestamp_ns + right.timestamp_ns) / 2;
  ++stats_.pairs;
  // Fused only where the odometry knows the vehicle's pose: a pair placed at a held or default pose
  // (integrators missing, none yet) would put its tape in the wrong place, and could replace the
  // model's tail with it.
  const std::optional<Pose2> at_exposure = OdometryAt(exposure);
  if (!at_exposure) {
    ++stats_.pairs_without_pose;
    spdlog::debug("pair {}/{} not perceived: no odometry pose at its exposure", left.sequence, right.sequence);
    return;
  }
  auto result = perception_->Process(left.pixels, right.pixels, exposure);
  if (!result.ok()) {
    ++stats_.perception_errors;
    spdlog::warn("perception failed on pair {}/{}: {}", left.sequence, right.sequence, result.status().ToString());
    return;
  }
  ++stats_.perceptions;
  stats_.perception_ms.Add(result->stats.total_ms);
  const auto update_start = std::chrono::steady_clock::now();
  auto upd = track_.Update(result->observation, *at_exposure);
  stats_.track_update_ms.Add(
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - update_start).count());
  if (!upd.ok()) {
    spdlog::warn("track update refused: {}", upd.status().ToString());
  } else if (spdlog::should_log(spdlog::level::trace)) {
    std::string shapes;
    for (const CentreLinePiece& p : result->observation.pieces) {
      shapes += fmt::format(" [{} pts {:.2f},{:.2f}..{:.2f},{:.2f}]", p.points_m.size(), p.points_m.front().x(),
                            p.points_m.front().y(), p.points_m.back().x(), p.points_m.back().y());
    }
    const PerceptionStats& ps = result->stats;
    spdlog::trace("perception: lines {}/{}, points {}/{}, matches {} points {}+{} lines ({} off the plane), triangulated {} points {} "
                  "lines, {} edges, {} strips; track update: {} pieces ({} associated, {} appended, {} ignored), {} "
                  "samples dropped, {:.2f} m ahead;{}",
                  ps.lines[0], ps.lines[1], ps.points[0], ps.points[1], ps.point_matches, ps.line_matches_topology,
                  ps.line_matches_transfer, ps.line_matches_rejected_by_plane, ps.points_triangulated, ps.lines_triangulated, ps.edges, ps.strips,
                  upd->pieces, upd->pieces_associated, upd->pieces_appended, upd->pieces_ignored,
                  upd->samples_dropped, track_.Ahead(4.0).length_m, shapes);
  }
  last_perception_ns_ = exposure;
  rec->perceived = true;
  rec->left_seq = static_cast<int64_t>(left.sequence);
  rec->right_seq = static_cast<int64_t>(right.sequence);
  rec->perception_exposure_ns = exposure;
  rec->perception_ms = result->stats.total_ms;
  last_result_ = std::move(*result);
}

Decision ControlLoop::Decide(int64_t now_ns, PlanOutput* plan, const Pose2& odom) {
  const RmpDriverHealth& h = driver_->health();
  if (stop_requested_) return Decision::kStopRequested;
  if (h.state != RmpDriverState::kRunning) return Decision::kRmpNotRunning;
  if (h.bus_off) return Decision::kBusOff;
  if (!h.status_fresh) return Decision::kRmpStatusStale;
  if (h.low_battery) return Decision::kLowBattery;
  if (h.rmp_fault) return Decision::kRmpFault;
  // The pose that the perception is fused at and the planner starts from: never older than the limit.
  const RmpOdometry& od = driver_->odometry();
  if (!od.initialized() || static_cast<double>(now_ns - od.pose().timestamp_ns) * 1e-9 > options_.max_odometry_age_s) {
    return Decision::kOdometryStale;
  }
  if (last_perception_ns_ < 0) return Decision::kNoPerception;
  if (track_.initialised() && track_.end_known()) {
    // Arrived at the track's known end: nothing more to see (the last tape lies under the vehicle). This
    // commands zero, so it needs no fresh perception: were it decided after the staleness check, every
    // late or dropped frame while the vehicle stands at the end would restart finish_hold_s (with 30 %
    // of frames dropped, finishing took 16-35 s instead of under 20 s over noise seeds 1-8).
    const TrackAhead ahead = track_.Ahead(1.0, 0.0);
    if (ahead.end_known && ahead.length_m < 0.02) return Decision::kAtEnd;
  }
  if (static_cast<double>(now_ns - last_perception_ns_) * 1e-9 > options_.max_perception_age_s)
    return Decision::kPerceptionStale;
  // The track must have been seen recently - except while the planner turns a blind acute corner on
  // the spot towards a leg it saw on the approach (bounded in time and angle by the planner itself).
  if (!track_.initialised() ||
      (static_cast<double>(now_ns - track_.last_associated_ns()) * 1e-9 > options_.track_lost_s && !planner_.corner_turn_active())) {
    return Decision::kTrackLost;
  }
  PlannerInput in;
  in.now_ns = now_ns;
  in.odom_from_vehicle = odom;
  const RmpStatusSnapshot& s = driver_->status();
  if (s.speeds_ns >= 0 && now_ns - s.speeds_ns < 100'000'000) {
    in.speed_mps = 0.5 * (s.speeds.left_wheel_mps + s.speeds.right_wheel_mps);
    in.yaw_rate_rps = s.speeds.yaw_rate_rps;
  }
  in.track = track_.Ahead(4.0);
  in.footprints_m = perception_->footprints();
  const bool corner_turn = planner_.corner_turn_active();
  *plan = planner_.Plan(in);
  if (corner_turn && !planner_.corner_turn_active() && !planner_.corner_turn_failure().empty()) {
    spdlog::warn("{}", planner_.corner_turn_failure());
  }
  if (plan->state == PlanState::kAtEnd) return Decision::kAtEnd;
  if (plan->state == PlanState::kNoTrack || plan->state == PlanState::kOffTrack) return Decision::kTrackLost;
  return Decision::kDrive;
}

// A pair's exposure may be this far past the tick (a camera's clock a little ahead) before it is
// taken for one from the future.
constexpr int64_t kFutureToleranceNs = 20'000'000;

Result<TickRecord> ControlLoop::Step() {
  const int64_t t = driver_->next_send_ns();
  if (first_tick_) start_ns_ = t;
  IDI_RETURN_IF_ERROR(driver_->RunUntil(t - 1));
  TickRecord rec;
  rec.t_ns = t;
  const bool running = driver_->health().state == RmpDriverState::kRunning;
  if (running && stats_.running_since_ns < 0) stats_.running_since_ns = t;
  if (!running && stats_.running_since_ns < 0 && static_cast<double>(t - start_ns_) * 1e-9 > options_.start_timeout_s) {
    return DeviceError("the RMP driver did not reach running within " + FormatNumber(options_.start_timeout_s) +
                       " s (state " + RmpDriverStateName(driver_->health().state) + ", " +
                       driver_->health().last_event + ")");
  }
  // Odometry.
  const RmpOdometryPose& op = driver_->odometry().pose();
  const Pose2 odom{op.x_m, op.y_m, op.yaw_rad};
  if (driver_->odometry().initialized() && (odom_history_.empty() || op.timestamp_ns > odom_history_.back().first)) {
    odom_history_.emplace_back(op.timestamp_ns, odom);
    while (odom_history_.size() > 200) odom_history_.pop_front();
  }
  rec.odom = odom;

  // Frames: the newest per camera; frozen ones (a repeat of the previous buffer) are not used.
  const int64_t collected_ns = clock_->NowNs();
  IDI_ASSIGN_OR_RETURN(std::vector<hal::Image> frames, frames_->Collect(collected_ns));
  for (hal::Image& f : frames) {
    ++stats_.frames;
    if (log_ != nullptr) {
      IDI_RETURN_IF_ERROR(log_->AddFrame(f));
      IDI_RETURN_IF_ERROR(log_->AddDelivered(clock_->NowNs(), f.camera, f.sequence));
    }
    const int cam = CameraIndex(f.camera);
    if (cam < 0 || f.pixels.empty()) continue;
    const uint64_t hash = ContentHash(f.pixels);
    auto prev = last_hash_.find(f.camera);
    const bool frozen = prev != last_hash_.end() && prev->second == hash;
    last_hash_[f.camera] = hash;
    auto prev_seq = last_seq_.find(f.camera);
    if (prev_seq != last_seq_.end() && f.sequence > prev_seq->second + 1) stats_.dropped_frames += f.sequence - prev_seq->second - 1;
    last_seq_[f.camera] = f.sequence;
    if (frozen) {
      ++stats_.frozen_frames;
      continue;
    }
    if (latest_[cam]) ++stats_.unpaired_frames;  // superseded before it found a partner
    latest_[cam] = std::move(f);
  }
  if (latest_[0] && latest_[1]) {
    const int64_t skew = std::abs(latest_[0]->timestamp_ns - latest_[1]->timestamp_ns);
    if (static_cast<double>(skew) * 1e-9 <= options_.stereo_max_skew_s) {
      const int64_t exposure = (latest_[0]->timestamp_ns + latest_[1]->timestamp_ns) / 2;
      if (exposure > std::max(t, collected_ns) + kFutureToleranceNs) {
        // Stamped ahead of the clock (a device clock's glitch): not used, and not let to hold back the
        // pairs that follow it (they must be newer than the last pair perceived).
        ++stats_.pairs_from_the_future;
      } else if (running && exposure > last_pair_exposure_ns_) {
        PerceivePair(*latest_[0], *latest_[1], &rec);
        last_pair_exposure_ns_ = (latest_[0]->timestamp_ns + latest_[1]->timestamp_ns) / 2;
      }
      latest_[0].reset();
      latest_[1].reset();
    } else {
      // The older one will never find its partner.
      ++stats_.unpaired_frames;
      latest_[latest_[0]->timestamp_ns < latest_[1]->timestamp_ns ? 0 : 1].reset();
    }
  }
  if (rec.perceived) stats_.frame_to_command_ms.Add(static_cast<double>(t - rec.perception_exposure_ns) * 1e-6);

  track_.UpdateProgress(odom);
  PlanOutput plan;
  Decision d = Decide(t, &plan, odom);
  double v = 0.0, w = 0.0;
  if (d == Decision::kDrive && !plan.stopped()) {
    const Status s = driver_->SetCommand({plan.speed_mps, plan.yaw_rate_rps, last_perception_ns_});
    if (s.ok()) {
      v = plan.speed_mps;
      w = plan.yaw_rate_rps;
    } else {
      d = Decision::kPerceptionStale;  // the driver refuses data older than its own limit
      driver_->CommandZero();
    }
  } else {
    driver_->CommandZero();
  }
  planner_.CommandSent(t, v, w);
  IDI_RETURN_IF_ERROR(driver_->RunUntil(t));
  rec.decision = d;
  rec.plan = plan;
  rec.speed_mps = v;
  rec.yaw_rate_rps = w;

  ++stats_.ticks;
  ++stats_.decisions[DecisionName(d)];
  if (v == 0.0 && w == 0.0) ++stats_.zero_ticks; else ++stats_.drive_ticks;
  if (first_tick_ || d != last_decision_) {
    std::string text = std::string(DecisionName(d));
    if (d == Decision::kDrive) text += std::string(" (") + PlanStateName(plan.state) + ")";
    if (d == Decision::kRmpNotRunning) text += std::string(" (") + RmpDriverStateName(driver_->health().state) + ")";
    if (d == Decision::kPerceptionStale && last_perception_ns_ >= 0) {
      text += " (last perception " + FormatNumber(static_cast<double>(t - last_perception_ns_) * 1e-9) + " s ago)";
    }
    if (d == Decision::kStopRequested) text += " (" + stop_reason_ + ")";
    spdlog::info("t={:.3f} s: {}", static_cast<double>(t - start_ns_) * 1e-9, text);
    if (sink_) sink_(t, text);
  }
  spdlog::debug("t={:.3f} {} {} v={:.3f} w={:.3f} e={:.4f} corner r={:.3f}{}", static_cast<double>(t - start_ns_) * 1e-9,
                DecisionName(d), PlanStateName(plan.state), v, w, plan.lateral_error_m, plan.corner_radius_m,
                plan.corner_in_view ? "" : " (not in view)");
  last_decision_ = d;
  first_tick_ = false;
  if (log_ != nullptr) {
    IDI_RETURN_IF_ERROR(log_->AddTick({t, rec.left_seq, rec.right_seq, v, w, DecisionName(d), PlanStateName(plan.state)}));
  }
  // Done: stopped at the track's known end for finish_hold_s.
  if (d == Decision::kAtEnd) {
    if (at_end_since_ns_ < 0) at_end_since_ns_ = t;
    if (stats_.finished_ns < 0 && static_cast<double>(t - at_end_since_ns_) * 1e-9 >= options_.finish_hold_s) stats_.finished_ns = t;
  } else {
    at_end_since_ns_ = -1;
  }
  PingWatchdog();
  return rec;
}

}  // namespace idi::rmp
