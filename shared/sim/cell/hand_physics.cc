#include "shared/sim/cell/hand_physics.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

#include "shared/util/units.h"

namespace idi::sim {
namespace {

// The part of the segment a + t (b - a), t in [0, 1], inside the part grown by `grow` along every face
// normal (a slightly square-cornered Minkowski sum with a ball). nullopt when they do not meet.
std::optional<std::pair<double, double>> ClipSegmentToPart(const ConvexPart& part, const Vec3d& a, const Vec3d& b,
                                                           double grow) {
  double lo = 0, hi = 1;
  const Vec3d d = b - a;
  for (std::size_t k = 0; k < part.normals.size(); ++k) {
    const double na = part.normals[k].dot(a) - part.offsets[k] - grow;
    const double nd = part.normals[k].dot(d);
    if (std::abs(nd) < 1e-15) {
      if (na > 0) return std::nullopt;
      continue;
    }
    const double t = -na / nd;
    if (nd > 0) {
      hi = std::min(hi, t);
    } else {
      lo = std::max(lo, t);
    }
    if (lo > hi) return std::nullopt;
  }
  return std::make_pair(lo, hi);
}

// Lawson-Hanson non-negative least squares: min |A x - b| with x >= 0. Returns the residual norm.
double HandNnlsResidual(const Eigen::MatrixXd& a, const Eigen::VectorXd& b) {
  const Eigen::Index n = a.cols();
  Eigen::VectorXd x = Eigen::VectorXd::Zero(n);
  std::vector<char> passive(static_cast<std::size_t>(n), 0);
  for (int outer = 0; outer < 3 * n + 10; ++outer) {
    const Eigen::VectorXd w = a.transpose() * (b - a * x);
    Eigen::Index best = -1;
    double best_w = 1e-10 * (1.0 + b.norm());
    for (Eigen::Index j = 0; j < n; ++j) {
      if (!passive[static_cast<std::size_t>(j)] && w(j) > best_w) {
        best_w = w(j);
        best = j;
      }
    }
    if (best < 0) break;
    passive[static_cast<std::size_t>(best)] = 1;
    for (int inner = 0; inner < 3 * n + 10; ++inner) {
      std::vector<Eigen::Index> idx;
      for (Eigen::Index j = 0; j < n; ++j) {
        if (passive[static_cast<std::size_t>(j)]) idx.push_back(j);
      }
      Eigen::MatrixXd ap(a.rows(), static_cast<Eigen::Index>(idx.size()));
      for (std::size_t k = 0; k < idx.size(); ++k) ap.col(static_cast<Eigen::Index>(k)) = a.col(idx[k]);
      const Eigen::VectorXd z = ap.completeOrthogonalDecomposition().solve(b);
      bool feasible = true;
      for (Eigen::Index k = 0; k < z.size(); ++k) feasible = feasible && z(k) > 0;
      if (feasible) {
        x.setZero();
        for (std::size_t k = 0; k < idx.size(); ++k) x(idx[k]) = z(static_cast<Eigen::Index>(k));
        break;
      }
      // Step towards z until a passive variable hits zero; drop it.
      double alpha = 1;
      for (std::size_t k = 0; k < idx.size(); ++k) {
        const double zk = z(static_cast<Eigen::Index>(k));
        if (zk <= 0) alpha = std::min(alpha, x(idx[k]) / (x(idx[k]) - zk));
      }
      for (std::size_t k = 0; k < idx.size(); ++k) {
        x(idx[k]) += alpha * (z(static_cast<Eigen::Index>(k)) - x(idx[k]));
        if (x(idx[k]) <= 1e-14) {
          x(idx[k]) = 0;
          passive[static_cast<std::size_t>(idx[k])] = 0;
        }
      }
    }
  }
  return (a * x - b).norm();
}

struct LinkHit {
  int segment = 0;                // 0 proximal link, 1 distal link
  Vec3d on_link = Vec3d::Zero();  // the link's axis point nearest the obstacle (obstacle frame)
  Vec3d closest = Vec3d::Zero();  // the obstacle's surface point nearest it (obstacle frame)
  double distance = 0;
};

// Whether the finger (its two links as capsules of `radius` about their axes, sampled across the
// finger's width) comes within `radius` of one of the obstacle's parts, and where. The distance from a
// point moving along a line to a convex set is convex in the line parameter, so a ternary search over
// the part of the segment inside the grown planes (a superset of the capsule's reach) finds the nearest
// point exactly.
std::optional<LinkHit> FingerHits(const HandTruth& hand, const std::array<Vec3d, 3>& points, const Vec3d& hinge,
                                  const Obstacle& o, double radius) {
  const Rigid3d obstacle_from_palm = o.palm_from_obstacle.Inverse();
  const double side = std::max(0.0, hand.finger_width_mm / 2 - hand.fingers.pad_radius_mm);
  std::optional<LinkHit> best;
  for (int seg = 0; seg < 2; ++seg) {
    for (const double s : {0.0, -side, side}) {
      const Vec3d a = obstacle_from_palm * (points[static_cast<std::size_t>(seg)] + s * hinge);
      const Vec3d b = obstacle_from_palm * (points[static_cast<std::size_t>(seg) + 1] + s * hinge);
      for (const ConvexPart& part : o.parts) {
        const auto clip = ClipSegmentToPart(part, a, b, radius);
        if (!clip) continue;
        double lo = clip->first, hi = clip->second;
        auto dist = [&](double t) { return part.Distance(a + t * (b - a)); };
        for (int it = 0; it < 60 && hi - lo > 1e-9; ++it) {
          const double m1 = lo + (hi - lo) / 3, m2 = hi - (hi - lo) / 3;
          if (dist(m1) <= dist(m2)) {
            hi = m2;
          } else {
            lo = m1;
          }
        }
        const double t = 0.5 * (lo + hi);
        LinkHit h;
        h.segment = seg;
        h.on_link = a + t * (b - a);
        h.distance = part.Distance(h.on_link, &h.closest);
        if (h.distance <= radius && (!best || h.distance < best->distance)) best = h;
      }
    }
  }
  return best;
}

}  // namespace

Status HandTruth::Check() const {
  if (!fingers.Valid() || !(finger_width_mm >= 2 * fingers.pad_radius_mm) || !(palm_half_size_mm > 0) ||
      !(palm_depth_mm > 0) || !(friction > 0) || !flange_from_palm.translation.allFinite()) {
    return InvalidArgument("hand: lengths, range and friction must be positive (finger width >= its thickness)");
  }
  return Status::Ok();
}

std::optional<FingerContact> SweepFinger(const HandTruth& hand, int finger, double spread, double start,
                                         const std::vector<Obstacle>& obstacles) {
  const BarrettFingerFrame g = BarrettFingerAt(hand.fingers, finger, spread);
  const double closed = DegToRad(hand.fingers.closed_deg);
  const double radius = hand.fingers.pad_radius_mm;
  auto hit_at = [&](double reading, int* which) {
    const auto points = BarrettFingerPoints(hand.fingers, finger, spread, reading);
    for (std::size_t k = 0; k < obstacles.size(); ++k) {
      if (FingerHits(hand, points, g.hinge, obstacles[k], radius)) {
        if (which != nullptr) *which = static_cast<int>(k);
        return true;
      }
    }
    return false;
  };
  // A NaN start never reached the closed end of the sweep below (a loop without end), nor did one so
  // far from it that a step no longer changes it; a finger's reading is an angle within a turn.
  if (!(std::abs(start) <= 2 * M_PI) || !std::isfinite(spread) || finger < 0 || finger > 2) return std::nullopt;
  // Already touching: the finger cannot move (it stalls where it is).
  double free_at = start;
  double hit = -1;
  if (hit_at(start, nullptr)) {
    hit = start;
  } else {
    const double step = DegToRad(0.25);
    for (double r = start + step;; r += step) {
      const double rr = std::min(r, closed);
      if (hit_at(rr, nullptr)) {
        hit = rr;
        break;
      }
      free_at = rr;
      if (rr >= closed) return std::nullopt;
    }
    while (hit - free_at > 1e-6) {
      const double mid = 0.5 * (hit + free_at);
      if (hit_at(mid, nullptr)) {
        hit = mid;
      } else {
        free_at = mid;
      }
    }
  }
  int which = -1;
  IDI_CHECK(hit_at(hit, &which), "finger sweep lost its contact");
  const Obstacle& o = obstacles[static_cast<std::size_t>(which)];
  const auto points = BarrettFingerPoints(hand.fingers, finger, spread, hit);
  const LinkHit h = *FingerHits(hand, points, g.hinge, o, radius);
  Vec3d n_obj = h.on_link - h.closest;
  if (n_obj.norm() > 1e-9) {
    n_obj.normalize();
  } else {
    // The axis itself touches (a finger already inside): take the face the point is least deep behind.
    int face = 0;
    for (const ConvexPart& part : o.parts) {
      if (part.MaxSeparation(h.on_link, &face) <= 0) {
        n_obj = part.normals[static_cast<std::size_t>(face)];
        break;
      }
    }
  }
  FingerContact c;
  c.finger = finger;
  c.obstacle = o.id;
  c.reading_rad = hit;
  c.point = o.palm_from_obstacle * h.closest;
  c.normal = o.palm_from_obstacle.RotateVector(n_obj);
  // The velocity of the finger's point nearest the contact per unit reading: the proximal link turns
  // about the knuckle, the distal link also turns about the joint between the links.
  const Vec3d p = o.palm_from_obstacle * h.on_link;
  Vec3d v = g.hinge.cross(p - points[0]);
  if (h.segment == 1) v += hand.fingers.distal_ratio * g.hinge.cross(p - points[1]);
  c.push = v.normalized();
  return c;
}

bool ForceClosure(const std::vector<Vec3d>& points, const std::vector<Vec3d>& inward, double friction,
                  const Vec3d& reference, double length_scale_mm) {
  constexpr int kEdges = 8;
  const auto m = static_cast<Eigen::Index>(points.size());
  if (m < 2 || inward.size() != points.size()) return false;
  Eigen::MatrixXd w(6, kEdges * m);
  for (Eigen::Index i = 0; i < m; ++i) {
    const Vec3d n = inward[static_cast<std::size_t>(i)].normalized();
    const Vec3d t1 = (std::abs(n.z()) < 0.9 ? n.cross(Vec3d::UnitZ()) : n.cross(Vec3d::UnitX())).normalized();
    const Vec3d t2 = n.cross(t1);
    const Vec3d r = (points[static_cast<std::size_t>(i)] - reference) / length_scale_mm;
    for (int j = 0; j < kEdges; ++j) {
      const double a = 2 * kPi * j / kEdges;
      const Vec3d f = (n + friction * (std::cos(a) * t1 + std::sin(a) * t2)).normalized();
      w.col(kEdges * i + j) << f, r.cross(f);
    }
  }
  // The wrenches positively span R^6 iff every +-unit wrench is a non-negative combination of them.
  for (int k = 0; k < 6; ++k) {
    for (const double s : {1.0, -1.0}) {
      Eigen::VectorXd target = Eigen::VectorXd::Zero(6);
      target(k) = s;
      if (HandNnlsResidual(w, target) > 1e-7) return false;
    }
  }
  return true;
}

GraspJudgement JudgeGrasp(const HandTruth& hand, const std::vector<FingerContact>& contacts, const Vec3d& com) {
  GraspJudgement j;
  j.contacts = contacts;
  if (contacts.empty()) {
    j.reason = "no finger touched anything: the fingers closed on air";
    return j;
  }
  for (const FingerContact& c : contacts) {
    if (c.obstacle == kTableId) {
      j.reason = "finger " + std::to_string(c.finger + 1) + " stalled on the table";
      return j;
    }
    if (j.object >= 0 && c.obstacle != j.object) {
      j.reason = "the fingers are on two different objects";
      return j;
    }
    j.object = c.obstacle;
  }
  if (contacts.size() < 2) {
    j.reason = "only finger " + std::to_string(contacts.front().finger + 1) + " touched the object";
    return j;
  }
  const double cone = std::atan(hand.friction);
  double worst = 0;
  int worst_finger = -1;
  std::vector<Vec3d> points, inward;
  for (const FingerContact& c : contacts) {
    const double angle = std::acos(std::clamp(c.push.dot(-c.normal), -1.0, 1.0));
    if (angle > worst) {
      worst = angle;
      worst_finger = c.finger;
    }
    points.push_back(c.point);
    inward.push_back(-c.normal);
  }
  j.worst_cone_margin_deg = RadToDeg(cone - worst);
  if (worst > cone) {
    j.reason = "finger " + std::to_string(worst_finger + 1) + " pushes " + FormatNumber(RadToDeg(worst)) +
               " deg off the contact normal, outside the friction cone (" + FormatNumber(RadToDeg(cone)) +
               " deg): it slips";
    return j;
  }
  if (!ForceClosure(points, inward, hand.friction, com, 50.0)) {
    j.reason = "the contacts are not force closure";
    return j;
  }
  j.holds = true;
  j.reason = std::to_string(contacts.size()) + " fingers on the object, force closure, friction margin " +
             FormatNumber(j.worst_cone_margin_deg) + " deg";
  return j;
}

std::optional<HandCollision> FindHandCollision(const HandTruth& hand, double spread,
                                               const std::array<double, 3>& readings,
                                               const std::vector<Obstacle>& obstacles, double tolerance_mm) {
  const double h = hand.palm_half_size_mm, depth = hand.palm_depth_mm;
  std::vector<Vec3d> palm_points;
  for (int i = 0; i <= 4; ++i) {
    for (int k = 0; k <= 4; ++k) {
      const double u = -h + 2 * h * i / 4, v = -h + 2 * h * k / 4, w = -depth * k / 4;
      palm_points.emplace_back(u, v, 0.0);     // the palm
      palm_points.emplace_back(u, h, w);       // the sides
      palm_points.emplace_back(u, -h, w);
      palm_points.emplace_back(h, u, w);
      palm_points.emplace_back(-h, u, w);
    }
  }
  for (const Obstacle& o : obstacles) {
    const Rigid3d obstacle_from_palm = o.palm_from_obstacle.Inverse();
    for (const ConvexPart& part : o.parts) {
      for (const Vec3d& p : palm_points) {
        if (part.MaxSeparation(obstacle_from_palm * p) < -tolerance_mm) return HandCollision{o.id, "palm"};
      }
      for (const Vec3d& v : part.vertices) {
        const Vec3d p = o.palm_from_obstacle * v;
        if (std::abs(p.x()) < h - tolerance_mm && std::abs(p.y()) < h - tolerance_mm && p.z() < -tolerance_mm &&
            p.z() > -depth + tolerance_mm) {
          return HandCollision{o.id, "palm"};
        }
      }
    }
    for (int f = 0; f < 3; ++f) {
      const auto points = BarrettFingerPoints(hand.fingers, f, spread, readings[static_cast<std::size_t>(f)]);
      const Vec3d hinge = BarrettFingerAt(hand.fingers, f, spread).hinge;
      if (FingerHits(hand, points, hinge, o, std::max(0.0, hand.fingers.pad_radius_mm - tolerance_mm))) {
        return HandCollision{o.id, "finger " + std::to_string(f + 1)};
      }
    }
  }
  return std::nullopt;
}

}  // namespace idi::sim
