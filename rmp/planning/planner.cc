#include "rmp/planning/planner.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include "shared/util/units.h"

namespace idi::rmp {
namespace {

// Length of the polyline `pts` lying inside `polygon`, sampled every `step` metres.
double LengthInside(const std::vector<Vec2d>& pts, const std::vector<Vec2d>& polygon, double step) {
  double inside = 0.0;
  for (std::size_t i = 1; i < pts.size(); ++i) {
    const Vec2d a = pts[i - 1], d = pts[i] - pts[i - 1];
    const double len = d.norm();
    const int n = std::max(1, static_cast<int>(std::ceil(len / step)));
    for (int k = 0; k < n; ++k) {
      const Vec2d p = a + d * ((k + 0.5) / n);
      if (PointInPolygon(polygon, p)) inside += len / n;
    }
  }
  return inside;
}

// The polyline from arc length s0 over `length` metres.
std::vector<Vec2d> PolylineSpan(const std::vector<Vec2d>& pts, double s0, double length) {
  std::vector<Vec2d> out;
  double s = 0.0;
  for (std::size_t i = 1; i < pts.size(); ++i) {
    const double seg = (pts[i] - pts[i - 1]).norm();
    const double a = std::max(s0, s), b = std::min(s0 + length, s + seg);
    if (b > a && seg > 1e-12) {
      const Vec2d pa = pts[i - 1] + (pts[i] - pts[i - 1]) * ((a - s) / seg);
      const Vec2d pb = pts[i - 1] + (pts[i] - pts[i - 1]) * ((b - s) / seg);
      if (out.empty()) out.push_back(pa);
      out.push_back(pb);
    }
    s += seg;
  }
  return out;
}

// Arc length of the point of a polyline closest to p.
double ProjectOnPolyline(const std::vector<Vec2d>& pts, const Vec2d& p) {
  double best = std::numeric_limits<double>::infinity(), best_s = 0.0, s = 0.0;
  for (std::size_t i = 1; i < pts.size(); ++i) {
    const Vec2d a = pts[i - 1], d = pts[i] - a;
    const double l2 = d.squaredNorm();
    const double t = l2 < 1e-18 ? 0.0 : std::clamp((p - a).dot(d) / l2, 0.0, 1.0);
    const double dist = (a + t * d - p).norm();
    if (dist < best) {
      best = dist;
      best_s = s + t * std::sqrt(l2);
    }
    s += std::sqrt(l2);
  }
  return best_s;
}

}  // namespace

const char* PlanStateName(PlanState state) {
  switch (state) {
    case PlanState::kFollow: return "follow";
    case PlanState::kCorner: return "corner";
    case PlanState::kUncertain: return "uncertain";
    case PlanState::kApproachEnd: return "approach-end";
    case PlanState::kAtEnd: return "at-end";
    case PlanState::kPivot: return "pivot";
    case PlanState::kCornerApproach: return "corner-approach";
    case PlanState::kCornerPivot: return "corner-pivot";
    case PlanState::kNoTrack: return "no-track";
    case PlanState::kOffTrack: return "off-track";
  }
  return "?";
}

Status PlannerOptions::Check() const {
  auto positive = [](double v) { return std::isfinite(v) && v > 0; };
  if (!(cruise_speed_mps >= 0 && cruise_speed_mps <= max_speed_mps)) {
    return InvalidArgument("planner: cruise_speed_mps must be in [0, max_speed_mps]");
  }
  if (!positive(max_speed_mps)) return InvalidArgument("planner: max_speed_mps must be positive");
  if (!positive(max_accel_mps2)) return InvalidArgument("planner: max_accel_mps2 must be positive");
  if (!positive(max_decel_mps2)) return InvalidArgument("planner: max_decel_mps2 must be positive");
  if (!positive(max_yaw_rate_rps)) return InvalidArgument("planner: max_yaw_rate_rps must be positive");
  if (!positive(max_yaw_accel_rps2)) return InvalidArgument("planner: max_yaw_accel_rps2 must be positive");
  if (!positive(max_lateral_accel_mps2)) return InvalidArgument("planner: max_lateral_accel_mps2 must be positive");
  if (!positive(corner_cut_m)) return InvalidArgument("planner: corner_cut_m must be positive");
  if (!(corner_leg_min_m >= 0 && corner_leg_min_m < pivot_min_leg_m)) {
    return InvalidArgument("planner: corner_leg_min_m must be in [0, pivot_min_leg_m)");
  }
  // Upper bounds: the corner search grows the cut by 40 % a step up to this (1e300 took 2000 steps a
  // corner, every tick).
  if (!(max_corner_cut_m >= corner_cut_m && max_corner_cut_m <= 1.0)) {
    return InvalidArgument("planner: max_corner_cut_m must be in [corner_cut_m, 1] m");
  }
  if (!(min_corner_turn_deg >= 0 && min_corner_turn_deg < pivot_corner_min_turn_deg)) {
    return InvalidArgument("planner: min_corner_turn_deg must be in [0, pivot_corner_min_turn_deg)");
  }
  if (min_support < 1) return InvalidArgument("planner: min_support must be at least 1");
  if (!positive(simplify_tolerance_m)) return InvalidArgument("planner: simplify_tolerance_m must be positive");
  if (!positive(visibility_check_m) || !(visibility_min_m >= 0)) {
    return InvalidArgument("planner: visibility_check_m must be positive and visibility_min_m >= 0");
  }
  // At most 1 s each: the prediction steps through latency + 4 time constants every tick (3600 s, a unit
  // slip, hung the loop; 50 s predicted so far ahead that every tick was "off track").
  if (!(command_latency_s >= 0 && command_latency_s <= 1) ||
      !(response_time_constant_s >= 0 && response_time_constant_s <= 1)) {
    return InvalidArgument("planner: command_latency_s and response_time_constant_s must be in [0, 1] s");
  }
  if (!positive(control_period_s)) return InvalidArgument("planner: control_period_s must be positive");
  if (!positive(tracking_min_length_m) || !(tracking_time_s >= 0)) {
    return InvalidArgument("planner: tracking_min_length_m must be positive, tracking_time_s >= 0");
  }
  if (!(preview_time_s >= 0)) return InvalidArgument("planner: preview_time_s must be >= 0");
  if (!(pivot_heading_error_deg > 0 && pivot_heading_error_deg < 180)) {
    return InvalidArgument("planner: pivot_heading_error_deg must be in (0, 180)");
  }
  if (!positive(max_lateral_error_m)) return InvalidArgument("planner: max_lateral_error_m must be positive");
  if (!(uncertain_speed_fraction > 0 && uncertain_speed_fraction <= 1)) {
    return InvalidArgument("planner: uncertain_speed_fraction must be in (0, 1]");
  }
  if (!(stop_margin_m >= 0)) return InvalidArgument("planner: stop_margin_m must be >= 0");
  if (!(pivot_corner_min_turn_deg > 0 && pivot_corner_min_turn_deg < 180)) {
    return InvalidArgument("planner: pivot_corner_min_turn_deg must be in (0, 180)");
  }
  if (!positive(pivot_commit_m)) return InvalidArgument("planner: pivot_commit_m must be positive");
  if (!positive(pivot_rate_rps) || pivot_rate_rps > max_yaw_rate_rps) {
    return InvalidArgument("planner: pivot_rate_rps must be in (0, max_yaw_rate_rps]");
  }
  if (!positive(pivot_timeout_s)) return InvalidArgument("planner: pivot_timeout_s must be positive");
  if (!positive(pivot_min_leg_m)) return InvalidArgument("planner: pivot_min_leg_m must be positive");
  if (!(pivot_extra_deg >= 0 && pivot_extra_deg <= 90)) return InvalidArgument("planner: pivot_extra_deg must be in [0, 90]");
  if (!(pivot_done_deg > 0 && pivot_done_deg < 45)) return InvalidArgument("planner: pivot_done_deg must be in (0, 45)");
  return Status::Ok();
}

Planner::Planner(const PlannerOptions& options) : options_(options) {}

void Planner::Reset() {
  sent_.clear();
  path_ = SmoothPath();
  radius_cache_.clear();
  corner_turn_ = CornerTurn();
  corner_turn_failure_.clear();
  corners_turned_.clear();
  corners_failed_.clear();
}

void Planner::FailCornerTurn(const std::string& why) {
  // Not retried at this vertex; from here the ordinary rules apply (the control loop stops the vehicle
  // while the track stays unseen for longer than its track-lost limit).
  corners_failed_.push_back(corner_turn_.vertex);
  if (corners_failed_.size() > 8) corners_failed_.erase(corners_failed_.begin());
  corner_turn_failure_ = why;
  corner_turn_ = CornerTurn();
}

double Planner::TurnedCornerEnd() const {
  double s_min = -1e300;
  const auto& spans = path_.corner_spans();
  for (std::size_t c = 0; c < spans.size() && c + 1 < path_.vertices().size(); ++c) {
    for (const Vec2d& v : corners_turned_) {
      // Just past the corner's end: its sharp vertex ends the leg before at the same point.
      if ((path_.vertices()[c + 1] - v).norm() < 0.2) s_min = std::max(s_min, spans[c].second + 1e-6);
    }
  }
  return s_min;
}

bool Planner::BlindCorner(const PlannerInput& input, const Pose2& predicted, const PathProjection& proj, double v_pred, double* s_stop, double* v_cmd,
                          double* w_cmd, PlanOutput* out) {
  if (!options_.pivot_at_blind_corners) return false;
  const std::vector<Vec2d>& verts = path_.vertices();
  const auto& spans = path_.corner_spans();
  // The legs of corner c (vertex verts[c + 1]): from the last vertex before it and to the first after it
  // that lie at least corner_leg_min_m away. Nearer vertices are blips of the model at the vertex, not
  // legs: while the vehicle pivots there the cameras see the tape's outer corner, and fusion once made a
  // 4 cm stub beyond the vertex; taken as the next leg it turned the corner into a slight left bend, the
  // pivot reversed and the manoeuvre failed (2 of 40 noise seeds of the closed-loop acute corner).
  auto legs = [&](std::size_t c) {
    const Vec2d& v = verts[c + 1];
    std::size_t a = c, b = c + 2;
    while (a > 0 && (v - verts[a]).norm() < options_.corner_leg_min_m) --a;
    while (b + 1 < verts.size() && (verts[b] - v).norm() < options_.corner_leg_min_m) ++b;
    return std::pair<Vec2d, Vec2d>((v - verts[a]).normalized(), (verts[b] - v).normalized());
  };
  auto turn_at = [&](std::size_t c) {
    const auto [d0, d1] = legs(c);
    return std::atan2(d0.x() * d1.y() - d0.y() * d1.x(), d0.dot(d1));
  };
  auto failed_before = [&](const Vec2d& v) {
    for (const Vec2d& t : corners_failed_) {
      if ((t - v).norm() < 0.2) return true;
    }
    return false;
  };
  auto turned_before = [&](const Vec2d& v) {
    for (const auto* list : {&corners_turned_, &corners_failed_}) {
      for (const Vec2d& t : *list) {
        if ((t - v).norm() < 0.2) return true;
      }
    }
    return false;
  };
  // The track's points after the vertex in travel order (from the point nearest it): on a very sharp
  // corner the incoming leg also lies within the next leg's band near the vertex (at 160 deg, points of
  // leg 1 10-15 cm back passed for leg 2), so only later points are evidence of the next leg.
  auto after_vertex = [&](const Vec2d& vertex) {
    std::size_t best = 0;
    double best_d = std::numeric_limits<double>::infinity();
    for (std::size_t i = 0; i < input.track.points.size(); ++i) {
      const double d = (input.track.points[i] - vertex).squaredNorm();
      if (d < best_d) {
        best_d = d;
        best = i;
      }
    }
    return best + 1;
  };
  // How far beyond the vertex the next leg is known from repeated sightings (support >= min_support).
  auto leg_known_m = [&](const Vec2d& vertex, const Vec2d& d2) {
    double known = 0.0;
    for (std::size_t i = after_vertex(vertex); i < input.track.points.size() && i < input.track.support.size(); ++i) {
      const Vec2d r = input.track.points[i] - vertex;
      const double along = r.dot(d2), across = std::abs(d2.x() * r.y() - d2.y() * r.x());
      if (along > 0 && across < 0.05 && input.track.support[i] >= options_.min_support) known = std::max(known, along);
    }
    return known;
  };
  const std::size_t n_corners = std::min(spans.size(), verts.size() >= 2 ? verts.size() - 2 : 0);
  std::size_t c = n_corners;
  if (corner_turn_.committed) {
    // The committed corner: the vertex nearest the one remembered (new observations move it a little).
    double best = 0.15;
    for (std::size_t k = 0; k < n_corners; ++k) {
      const double d = (verts[k + 1] - corner_turn_.vertex).norm();
      if (d < best) {
        best = d;
        c = k;
      }
    }
    if (c == n_corners) {
      FailCornerTurn("the committed corner's vertex is no longer in the track model");
      *v_cmd = *w_cmd = 0.0;
      out->state = PlanState::kNoTrack;
      return true;
    }
  } else {
    // The next real corner ahead; only an acute one is turned on the spot.
    for (std::size_t k = 0; k < n_corners; ++k) {
      if (spans[k].second < proj.s) continue;
      const double turn = turn_at(k);
      if (std::abs(turn) < DegToRad(options_.min_corner_turn_deg)) continue;
      if (std::abs(turn) >= DegToRad(options_.pivot_corner_min_turn_deg)) {
        if (!turned_before(verts[k + 1]) && leg_known_m(verts[k + 1], legs(k).second) >= options_.pivot_min_leg_m) {
          c = k;
        } else if (!failed_before(verts[k + 1])) {
          // An acute corner not (yet) turned on the spot, its next leg not known well enough, ends the
          // known track at its vertex: its arc has radius 0 and no speed limit, and driving on would
          // reach the vertex at speed and leave the track. (Where the manoeuvre failed, the vehicle
          // already stands at the vertex, and the ordinary rules of 5.d apply.)
          *s_stop = std::min(*s_stop, spans[k].first);
        }
      }
      break;
    }
    if (c == n_corners) return false;
    // Brake to a stop at the vertex; commit once close to it.
    *s_stop = std::min(*s_stop, spans[c].first);
    if (spans[c].first - proj.s > options_.pivot_commit_m) return false;
    corner_turn_ = CornerTurn();
    corner_turn_.committed = true;
    corner_turn_.commit_ns = input.now_ns;
  }
  corner_turn_.vertex = verts[c + 1];
  corner_turn_.turn_rad = turn_at(c);
  auto fail = [&](const std::string& why) {
    FailCornerTurn(why);
    *v_cmd = *w_cmd = 0.0;
    out->state = PlanState::kNoTrack;
    return true;
  };
  if (static_cast<double>(input.now_ns - corner_turn_.commit_ns) * 1e-9 > options_.pivot_timeout_s) {
    return fail("blind corner: not turned and re-acquired within pivot_timeout_s");
  }
  const double to_vertex = spans[c].first - proj.s;
  if (!corner_turn_.pivoting) {
    *s_stop = std::min(*s_stop, spans[c].first);
    if (to_vertex > 0.03 || (to_vertex > 0.005 && std::abs(v_pred) > 0.05)) return false;  // still approaching
    corner_turn_.pivoting = true;
    corner_turn_.pivot_ns = input.now_ns;
    corner_turn_.last_yaw = input.odom_from_vehicle.yaw;
    corner_turn_.turned_rad = 0.0;
  }
  // Turning on the spot: the angle turned so far (in the corner's direction), the heading error to the
  // remembered next leg, and whether an observation since the pivot began has seen that leg.
  const double sign = corner_turn_.turn_rad >= 0 ? 1.0 : -1.0;
  corner_turn_.turned_rad += sign * WrapAngle(input.odom_from_vehicle.yaw - corner_turn_.last_yaw);
  corner_turn_.last_yaw = input.odom_from_vehicle.yaw;
  const Vec2d d2 = legs(c).second;
  const double th = WrapAngle(predicted.yaw - std::atan2(d2.y(), d2.x()));
  bool reacquired = false;
  for (std::size_t i = after_vertex(corner_turn_.vertex);
       i < input.track.points.size() && i < input.track.seen_ns.size();
       ++i) {
    const Vec2d r = input.track.points[i] - corner_turn_.vertex;
    const double along = r.dot(d2), across = std::abs(d2.x() * r.y() - d2.y() * r.x());
    if (along > 0.1 && across < 0.05 && input.track.seen_ns[i] >= corner_turn_.pivot_ns) {
      reacquired = true;
      break;
    }
  }
  if (std::abs(th) <= DegToRad(options_.pivot_done_deg)) {
    if (!reacquired) return fail("blind corner: facing the remembered leg without seeing it again");
    corners_turned_.push_back(corner_turn_.vertex);
    if (corners_turned_.size() > 8) corners_turned_.erase(corners_turned_.begin());
    corner_turn_ = CornerTurn();
    return false;  // follow the new leg
  }
  if (corner_turn_.turned_rad > std::abs(corner_turn_.turn_rad) + DegToRad(options_.pivot_extra_deg)) {
    return fail("blind corner: turned beyond the corner's angle without facing the next leg");
  }
  // Towards the leg the way the corner turns (the short way once within 90 deg of it), slowing down
  // on the last few degrees.
  const double dir = std::abs(th) > 0.5 * kPi ? sign : -std::copysign(1.0, th);
  *v_cmd = 0.0;
  *w_cmd = dir * std::min(options_.pivot_rate_rps, std::max(0.15, 2.0 * std::abs(th)));
  out->state = PlanState::kCornerPivot;
  out->heading_error_rad = th;
  return true;
}

void Planner::CommandSent(int64_t t_ns, double speed_mps, double yaw_rate_rps) {
  sent_.push_back({t_ns, speed_mps, yaw_rate_rps});
  // Keep what can still be in flight, plus one older command (the one in effect before them).
  const double horizon_s = options_.command_latency_s + 4.0 * options_.response_time_constant_s + 0.1;
  const int64_t keep_ns = static_cast<int64_t>(horizon_s * 1e9);
  while (sent_.size() > 2 && sent_[1].t_ns < t_ns - keep_ns) sent_.pop_front();
}

Pose2 Planner::PredictPose(const PlannerInput& input, double* speed, double* yaw_rate) const {
  Pose2 pose = input.odom_from_vehicle;
  double v = input.speed_mps, w = input.yaw_rate_rps;
  const double horizon = options_.command_latency_s + options_.response_time_constant_s;
  const int64_t latency_ns = static_cast<int64_t>(options_.command_latency_s * 1e9);
  const double dt = 0.005;
  const double tau = options_.response_time_constant_s;
  for (double t = 0.0; t < horizon - 1e-9; t += dt) {
    const int64_t when = input.now_ns + static_cast<int64_t>(t * 1e9) - latency_ns;
    // The command in effect: the last one sent at or before `when`.
    double vc = v, wc = w;
    for (auto it = sent_.rbegin(); it != sent_.rend(); ++it) {  // none yet: it keeps what it does
      if (it->t_ns <= when) {
        vc = it->speed;
        wc = it->yaw_rate;
        break;
      }
    }
    const double step = std::min(dt, horizon - t);
    const double k = tau > 1e-6 ? 1.0 - std::exp(-step / tau) : 1.0;
    const double v_next = v + (vc - v) * k, w_next = w + (wc - w) * k;
    pose = IntegrateUnicycle(pose, 0.5 * (v + v_next), 0.5 * (w + w_next), step);
    v = v_next;
    w = w_next;
  }
  *speed = v;
  *yaw_rate = w;
  return pose;
}

bool Planner::TurnKeepsTrackInView(const std::vector<Vec2d>& vertices, std::size_t corner, double radius,
                                   const std::vector<std::vector<Vec2d>>& footprints) const {
  if (footprints.empty()) return true;
  // The turn alone: its two legs (at most 1 m each) and the arc.
  const Vec2d v = vertices[corner];
  const Vec2d a = vertices[corner - 1], b = vertices[corner + 1];
  const Vec2d in = v + (a - v).normalized() * std::min((a - v).norm(), 1.0);
  const Vec2d out = v + (b - v).normalized() * std::min((b - v).norm(), 1.0);
  const SmoothPath turn = SmoothPath::Build({in, v, out}, {radius});
  if (turn.empty() || turn.corner_spans().empty()) return true;
  const auto [arc0, arc1] = turn.corner_spans().front();
  for (double s = std::max(0.0, arc0 - 0.3); s <= arc1 + 1e-9; s += 0.03) {
    const PathPoint p = turn.At(s);
    const Pose2 odom_from_vehicle{p.xy.x(), p.xy.y(), p.heading};
    const Pose2 vehicle_from_odom = odom_from_vehicle.Inverse();
    const double s_track = ProjectOnPolyline(vertices, p.xy);
    std::vector<Vec2d> coming = PolylineSpan(vertices, s_track, options_.visibility_check_m);
    const double span = PolylineLength(coming);
    for (Vec2d& q : coming) q = vehicle_from_odom * q;
    const double need = std::min(options_.visibility_min_m, 0.8 * span);
    for (const auto& fp : footprints) {
      if (fp.size() >= 3 && LengthInside(coming, fp, 0.02) < need) return false;
    }
  }
  return true;
}

namespace {
// A corner within this of one already decided is the same corner (the vertex moves by millimetres as
// views are fused; corners of a real track are decimetres apart).
constexpr double kCornerCacheTolerance_m = 0.05;
constexpr double kCornerCacheTurnTolerance_deg = 8.0;
}  // namespace

std::vector<double> Planner::CornerRadii(const std::vector<Vec2d>& vertices, const Pose2& /*odom_from_vehicle*/,
                                         const std::vector<std::vector<Vec2d>>& footprints,
                                         std::vector<bool>* in_view) {
  std::vector<double> radii;
  in_view->clear();
  if (radius_cache_.size() > 2000) radius_cache_.clear();
  for (std::size_t i = 1; i + 1 < vertices.size(); ++i) {
    const Vec2d d0 = (vertices[i] - vertices[i - 1]).normalized(), d1 = (vertices[i + 1] - vertices[i]).normalized();
    const double turn = std::atan2(d0.x() * d1.y() - d0.y() * d1.x(), d0.dot(d1));
    if (std::abs(turn) < DegToRad(options_.min_corner_turn_deg)) {
      // A gentle bend: a radius that cuts it by a fraction of the tolerance the polyline was
      // simplified with.
      radii.push_back(RadiusForCut(0.5 * options_.simplify_tolerance_m, turn));
      in_view->push_back(true);
      continue;
    }
    // A turn that keeps the track in view is kept; a corner decided as not in view is decided again
    // each time (the view of it may improve, or it may turn out not to be a corner at all).
    CachedCorner* cached = nullptr;
    double nearest = kCornerCacheTolerance_m;
    for (CachedCorner& c : radius_cache_) {
      const double d = (c.vertex - vertices[i]).norm();
      if (d < nearest && std::abs(c.turn_rad - turn) < DegToRad(kCornerCacheTurnTolerance_deg)) {
        nearest = d;
        cached = &c;
      }
    }
    if (cached != nullptr && cached->visible) {
      radii.push_back(cached->radius_m);
      in_view->push_back(true);
      continue;
    }
    double chosen = RadiusForCut(options_.corner_cut_m, turn);
    bool visible = true;
    if (options_.keep_track_in_view && !footprints.empty()) {
      visible = false;
      for (double cut = options_.corner_cut_m; cut <= options_.max_corner_cut_m * 1.0001; cut *= 1.4) {
        const double r = RadiusForCut(cut, turn);
        if (TurnKeepsTrackInView(vertices, i, r, footprints)) {
          chosen = r;
          visible = true;
          break;
        }
      }
    }
    // Corners seen only near the horizon are not cached: the track beyond them may still grow.
    const bool complete = (vertices.back() - vertices[i]).norm() > options_.visibility_check_m + 0.2;
    if (complete) {
      if (cached != nullptr) {
        *cached = {vertices[i], turn, chosen, visible};
      } else {
        radius_cache_.push_back({vertices[i], turn, chosen, visible});
      }
    }
    radii.push_back(chosen);
    in_view->push_back(visible);
  }
  return radii;
}

double Planner::SpeedLimitAt(double s, const TrackAhead& track, double /*s_stop*/) const {
  double v = options_.cruise_speed_mps;
  const double k = std::abs(path_.At(s).curvature);
  if (k > 1e-6) {
    v = std::min(v, 0.8 * options_.max_yaw_rate_rps / k);
    v = std::min(v, std::sqrt(options_.max_lateral_accel_mps2 / k));
    v = std::min(v, std::sqrt(0.5 * options_.max_yaw_accel_rps2) / k);
  }
  // Where the curvature changes (into, out of and between arcs) the yaw rate must ramp at the yaw
  // acceleration limit; keep the ramp within `ramp` metres: v^2 |dk| / alpha <= ramp.
  const double ramp = 0.12;
  double k_lo = 1e9, k_hi = -1e9;
  for (double ds = -0.1; ds <= 0.1 + 1e-9; ds += 0.02) {
    const double kk = path_.At(s + ds).curvature;
    k_lo = std::min(k_lo, kk);
    k_hi = std::max(k_hi, kk);
  }
  if (k_hi - k_lo > 1e-6) v = std::min(v, std::sqrt(options_.max_yaw_accel_rps2 * ramp / (k_hi - k_lo)));
  // Track seen fewer than min_support times here: uncertain.
  double acc = 0.0;
  for (std::size_t i = 0; i < track.points.size(); ++i) {
    if (i > 0) acc += (track.points[i] - track.points[i - 1]).norm();
    if (acc + 1e-9 >= s) {
      if (track.support[i] < options_.min_support) v = std::min(v, options_.uncertain_speed_fraction * options_.cruise_speed_mps);
      break;
    }
  }
  return v;
}

PlanOutput Planner::Plan(const PlannerInput& input) {
  PlanOutput out;
  const double dt = options_.control_period_s;
  const double last_v = sent_.empty() ? 0.0 : sent_.back().speed;
  const double last_w = sent_.empty() ? 0.0 : sent_.back().yaw_rate;
  auto stop = [&](PlanState state) {
    out.state = state;
    out.speed_mps = 0.0;
    out.yaw_rate_rps = 0.0;
    return out;
  };
  if (!input.track.valid() || !input.odom_from_vehicle.IsFinite() || !std::isfinite(input.speed_mps) ||
      !std::isfinite(input.yaw_rate_rps)) {
    path_ = SmoothPath();
    return stop(PlanState::kNoTrack);
  }
  double v_pred = 0.0, w_pred = 0.0;
  const Pose2 predicted = PredictPose(input, &v_pred, &w_pred);
  // Corners turned (or failed) are remembered while the vehicle is near them: a turned one so that the
  // path continues on its far side, a failed one so that it is not retried. Once the vehicle is more
  // than kForgetCornerM away (the vertex has left the model ahead, which reaches 0.3 m behind the
  // vehicle), the same vertex met again - the next lap of a closed track - is a new corner; kept
  // for ever, it cut the path there and stopped the vehicle off track.
  constexpr double kForgetCornerM = 1.0;
  for (auto* list : {&corners_turned_, &corners_failed_}) {
    list->erase(std::remove_if(list->begin(),
                               list->end(),
                               [&](const Vec2d& v) {
                                 return (v - input.odom_from_vehicle.translation()).norm() > kForgetCornerM;
                               }),
                list->end());
  }

  const std::vector<Vec2d> vertices = SimplifyPolyline(input.track.points, options_.simplify_tolerance_m);
  std::vector<bool> corner_in_view;
  std::vector<double> radii = CornerRadii(vertices, input.odom_from_vehicle, input.footprints_m, &corner_in_view);
  if (options_.pivot_at_blind_corners) {
    // Acute corners are turned on the spot at their vertex (5. in the header): no arc.
    for (std::size_t i = 1; i + 1 < vertices.size() && i - 1 < radii.size(); ++i) {
      const Vec2d d0 = (vertices[i] - vertices[i - 1]).normalized(), d1 = (vertices[i + 1] - vertices[i]).normalized();
      if (std::abs(std::atan2(d0.x() * d1.y() - d0.y() * d1.x(), d0.dot(d1))) >= DegToRad(options_.pivot_corner_min_turn_deg)) {
        radii[i - 1] = 0.0;
      }
    }
  }
  path_ = SmoothPath::Build(vertices, radii);
  if (path_.empty() || path_.length() < 1e-3) return stop(PlanState::kNoTrack);

  PathProjection proj = path_.Project(predicted.translation(), predicted.yaw, TurnedCornerEnd());
  out.lateral_error_m = proj.lateral_m;
  out.heading_error_rad = proj.heading_error;
  if (proj.distance_m > options_.max_lateral_error_m) return stop(PlanState::kOffTrack);

  // The next corner ahead of the vehicle.
  for (std::size_t c = 0; c < path_.corner_spans().size(); ++c) {
    if (path_.corner_spans()[c].second >= proj.s && c < corner_in_view.size() &&
        std::abs(path_.radii()[c]) > 0 && path_.corner_spans()[c].second > path_.corner_spans()[c].first &&
        RadiusForCut(options_.corner_cut_m, DegToRad(options_.min_corner_turn_deg)) > path_.radii()[c]) {
      out.corner_radius_m = path_.radii()[c];
      out.corner_in_view = corner_in_view[c];
      break;
    }
  }

  double s_stop = std::max(0.0, path_.length() - (input.track.end_known ? options_.stop_margin_m : 0.0));
  double v_cmd = 0.0, w_cmd = 0.0;
  const std::size_t turned_before = corners_turned_.size();
  const bool corner_decided = BlindCorner(input, predicted, proj, v_pred, &s_stop, &v_cmd, &w_cmd, &out);
  if (corner_decided && out.state == PlanState::kNoTrack) return stop(PlanState::kNoTrack);
  if (corners_turned_.size() != turned_before) {
    // A corner was just turned: from here the path continues on its far side.
    proj = path_.Project(predicted.translation(), predicted.yaw, TurnedCornerEnd());
    out.lateral_error_m = proj.lateral_m;
    out.heading_error_rad = proj.heading_error;
  }
  const double to_stop = s_stop - proj.s;
  out.distance_to_stop_m = std::max(0.0, to_stop);
  if (corner_decided) {
    out.distance_to_stop_m = 0.0;
  } else if (to_stop <= 0.005) {
    return stop(input.track.end_known ? PlanState::kAtEnd : PlanState::kUncertain);
  } else {
    // Speed profile: backward pass from the stop point (v = 0) to the vehicle.
    const double ds = 0.02;
    double v_profile = 0.0;
    for (double s = s_stop; s >= proj.s - 1e-9; s -= ds) {
      const double lim = SpeedLimitAt(s, input.track, s_stop);
      v_profile = std::min(lim, std::sqrt(v_profile * v_profile + 2.0 * options_.max_decel_mps2 * std::min(ds, s_stop - s + ds)));
    }
    double v_target = std::min(v_profile, std::sqrt(2.0 * options_.max_decel_mps2 * std::max(0.0, to_stop)));
    v_target = std::min(v_target, SpeedLimitAt(proj.s, input.track, s_stop));

    // Tracking law at the predicted pose.
    const double v_ref = std::max(std::max(v_target, v_pred), 0.02);
    const double length = std::max(options_.tracking_min_length_m, v_ref * options_.tracking_time_s);
    const double k_lat = 1.0 / (length * length), k_head = 2.0 / length;
    const double s_prev = proj.s + v_ref * options_.preview_time_s;
    const double kappa = path_.MeanCurvature(proj.s, std::max(s_prev, proj.s + 0.005));
    const double e = proj.lateral_m, th = proj.heading_error;
    v_cmd = v_target;
    if (std::abs(th) > DegToRad(options_.pivot_heading_error_deg)) {
      // Facing away from the path: turn on the spot towards it first.
      v_cmd = 0.0;
      w_cmd = -std::copysign(std::min(options_.max_yaw_rate_rps, 2.0 * std::abs(th)), th);
      out.state = PlanState::kPivot;
    } else {
      v_cmd *= std::max(0.0, std::cos(th));
      const double denom = std::max(0.5, 1.0 - kappa * e);
      w_cmd = v_cmd * (kappa * std::cos(th) / denom - k_lat * e - k_head * std::sin(th));
      // At very low speed the feedback fades with v; keep a small heading correction.
      if (v_cmd < 0.02) w_cmd += -0.5 * std::sin(th);
      out.state = PlanState::kFollow;
      if (out.corner_radius_m > 0 && path_.At(proj.s + v_ref * 0.5).curvature != 0.0) out.state = PlanState::kCorner;
      if (SpeedLimitAt(proj.s, input.track, s_stop) < options_.cruise_speed_mps &&
          std::abs(path_.At(proj.s).curvature) < 1e-6) {
        out.state = PlanState::kUncertain;
      }
      if (input.track.end_known && to_stop < 1.0) out.state = PlanState::kApproachEnd;
    }
    if (corner_turn_.committed) out.state = PlanState::kCornerApproach;
  }

  // Limits.
  v_cmd = std::clamp(v_cmd, 0.0, options_.max_speed_mps);
  v_cmd = std::clamp(v_cmd, last_v - 2.0 * options_.max_decel_mps2 * dt, last_v + options_.max_accel_mps2 * dt);
  v_cmd = std::max(v_cmd, 0.0);
  w_cmd = std::clamp(w_cmd, -options_.max_yaw_rate_rps, options_.max_yaw_rate_rps);
  w_cmd = std::clamp(w_cmd, last_w - options_.max_yaw_accel_rps2 * dt, last_w + options_.max_yaw_accel_rps2 * dt);
  out.speed_mps = v_cmd;
  out.yaw_rate_rps = w_cmd;
  return out;
}

}  // namespace idi::rmp
