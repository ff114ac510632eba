#include "rmp/track/track_model.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "rmp/track/polygon.h"
#include "shared/util/units.h"

namespace idi::rmp {
namespace {

bool FinitePoint(const Vec2d& p) { return std::isfinite(p.x()) && std::isfinite(p.y()); }

// A footprint polygon prepared for many questions "inside it (even-odd rule) and at least `margin`
// from its outline?": its bounding box turns away most points outside cheaply, the parity test comes
// before any distance, and an edge whose line lies beyond `margin` needs no clamped distance.
class FootprintTest {
 public:
  explicit FootprintTest(const std::vector<Vec2d>& poly) : poly_(poly) {
    lo_ = Vec2d::Constant(std::numeric_limits<double>::infinity());
    hi_ = -lo_;
    for (std::size_t i = 0, j = poly.size() - 1; i < poly.size(); j = i++) {
      lo_ = lo_.cwiseMin(poly[i]);
      hi_ = hi_.cwiseMax(poly[i]);
      const Vec2d d = poly[j] - poly[i];
      const double l2 = d.squaredNorm();
      edges_.push_back({d, l2 < 1e-18 ? 0.0 : 1.0 / l2, l2 < 1e-18 ? 0.0 : 1.0 / std::sqrt(l2)});
    }
  }
  bool Contains(const Vec2d& p, double margin) const {
    if (!(p.x() >= lo_.x() && p.x() <= hi_.x() && p.y() >= lo_.y() && p.y() <= hi_.y())) return false;
    if (!PointInPolygon(poly_, p)) return false;
    const double margin2 = margin * margin;
    for (std::size_t i = 0; i < poly_.size(); ++i) {
      const Edge& e = edges_[i];
      const Vec2d ap = p - poly_[i];
      // The distance to the edge's line bounds the distance to the edge from below.
      if (e.inv_len > 0 && std::abs(e.d.x() * ap.y() - e.d.y() * ap.x()) * e.inv_len > 1.000001 * margin) continue;
      const double t = std::clamp(ap.dot(e.d) * e.inv_l2, 0.0, 1.0);
      if ((t * e.d - ap).squaredNorm() < margin2) return false;
    }
    return true;
  }

 private:
  struct Edge {
    Vec2d d;
    double inv_l2, inv_len;
  };
  const std::vector<Vec2d>& poly_;
  std::vector<Edge> edges_;
  Vec2d lo_, hi_;
};

// A polyline's segments with what the nearest-point search needs precomputed, so that searching it
// for many points costs a few multiplications per segment.
class PolylineSearch {
 public:
  explicit PolylineSearch(const std::vector<Vec2d>& line) : line_(line) {
    for (std::size_t i = 1; i < line.size(); ++i) {
      const Vec2d d = line[i] - line[i - 1];
      const double l2 = d.squaredNorm();
      seg_.push_back({d, l2 < 1e-18 ? 0.0 : 1.0 / l2});
    }
  }
  // Nearest point on the polyline to p: (point, distance).
  std::pair<Vec2d, double> Nearest(const Vec2d& p) const {
    if (line_.size() == 1) return {line_[0], (line_[0] - p).norm()};
    Vec2d best_q = line_.front();
    double best2 = std::numeric_limits<double>::infinity();
    for (std::size_t i = 0; i < seg_.size(); ++i) {
      const Vec2d& a = line_[i];
      const double t = std::clamp((p - a).dot(seg_[i].d) * seg_[i].inv_l2, 0.0, 1.0);
      const Vec2d q = a + t * seg_[i].d;
      const double dist2 = (q - p).squaredNorm();
      if (dist2 < best2) {
        best2 = dist2;
        best_q = q;
      }
    }
    return {best_q, std::sqrt(best2)};
  }

 private:
  struct Segment {
    Vec2d d;
    double inv_l2;
  };
  const std::vector<Vec2d>& line_;
  std::vector<Segment> seg_;
};

// Unit direction of the polyline near its back end, from the last `span_m` of it.
Vec2d EndDirection(const std::vector<Vec2d>& pts, double span_m) {
  const Vec2d end = pts.back();
  for (std::size_t k = pts.size() - 1; k-- > 0;) {
    if ((end - pts[k]).norm() >= span_m || k == 0) {
      const Vec2d d = end - pts[k];
      return d.norm() > 1e-9 ? Vec2d(d.normalized()) : Vec2d(1, 0);
    }
  }
  return {1, 0};
}

}  // namespace

Status TrackModelOptions::Check() const {
  auto positive = [](double v) { return std::isfinite(v) && v > 0; };
  if (!positive(sample_spacing_m)) return InvalidArgument("track: sample_spacing_m must be positive");
  if (!positive(association_gate_m)) return InvalidArgument("track: association_gate_m must be positive");
  if (!(blend > 0 && blend <= 1)) return InvalidArgument("track: blend must be in (0, 1]");
  if (!positive(join_distance_m)) return InvalidArgument("track: join_distance_m must be positive");
  if (!(max_gap_m >= 0 && std::isfinite(max_gap_m))) return InvalidArgument("track: max_gap_m must be >= 0");
  if (!(max_gap_angle_deg > 0 && max_gap_angle_deg < 90)) return InvalidArgument("track: max_gap_angle_deg must be in (0, 90)");
  if (!positive(end_confirm_m)) return InvalidArgument("track: end_confirm_m must be positive");
  if (!positive(start_search_m)) return InvalidArgument("track: start_search_m must be positive");
  if (!(keep_behind_m >= 0 && std::isfinite(keep_behind_m)))
    return InvalidArgument("track: keep_behind_m must be >= 0");
  if (max_support < 1) return InvalidArgument("track: max_support must be >= 1");
  if (!(footprint_margin_m >= 0 && std::isfinite(footprint_margin_m))) {
    return InvalidArgument("track: footprint_margin_m must be >= 0");
  }
  if (!(evidence_span_m >= 0 && std::isfinite(evidence_span_m))) return InvalidArgument("track: evidence_span_m must be >= 0");
  return Status::Ok();
}

TrackModel::TrackModel(const TrackModelOptions& options) : options_(options) {}

void TrackModel::Reset() {
  samples_.clear();
  progress_ = 0;
  vehicle_offset_m_ = 0.0;
  end_known_ = end_seen_ = false;
  clear_beyond_end_m_ = 0.0;
}

std::vector<Vec2d> TrackModel::Densify(const std::vector<Vec2d>& pts) const {
  std::vector<Vec2d> out;
  if (pts.empty()) return out;
  out.push_back(pts[0]);
  for (std::size_t i = 1; i < pts.size(); ++i) {
    const Vec2d a = pts[i - 1], b = pts[i];
    const double len = (b - a).norm();
    const int n = std::max(1, static_cast<int>(std::ceil(len / options_.sample_spacing_m)));
    for (int k = 1; k <= n; ++k) out.push_back(a + (b - a) * (static_cast<double>(k) / n));
  }
  return out;
}

bool TrackModel::InView(const std::vector<std::vector<Vec2d>>& footprints_odom, const Vec2d& p) const {
  if (footprints_odom.empty()) return false;
  for (const auto& fp : footprints_odom) {
    if (!FootprintTest(fp).Contains(p, options_.footprint_margin_m)) return false;
  }
  return true;
}

std::vector<char> TrackModel::StretchInView(const std::vector<std::vector<Vec2d>>& footprints_odom) const {
  const std::size_t n = samples_.size();
  std::vector<char> stretch(n, 0);
  if (footprints_odom.empty()) return stretch;
  std::vector<char> point(n, 0);
  std::vector<double> s(n, 0.0);
  std::vector<std::size_t> out(n + 1, 0);  // prefix counts of samples out of view
  std::vector<FootprintTest> tests;
  for (const auto& fp : footprints_odom) tests.emplace_back(fp);
  const auto in_view = [&](const Vec2d& p) {
    for (const FootprintTest& t : tests) {
      if (!t.Contains(p, options_.footprint_margin_m)) return false;
    }
    return true;
  };
  for (std::size_t i = 0; i < n; ++i) {
    point[i] = in_view(samples_[i].xy) ? 1 : 0;
    if (i > 0) s[i] = s[i - 1] + (samples_[i].xy - samples_[i - 1].xy).norm();
    out[i + 1] = out[i] + (point[i] ? 0 : 1);
  }
  // A sliding window [lo, hi] of the samples within evidence_span_m of sample i.
  std::size_t lo = 0, hi = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (!point[i]) continue;
    while (s[i] - s[lo] > options_.evidence_span_m) ++lo;
    hi = std::max(hi, i);
    while (hi + 1 < n && s[hi + 1] - s[i] <= options_.evidence_span_m) ++hi;
    stretch[i] = out[hi + 1] == out[lo] ? 1 : 0;
  }
  return stretch;
}

double TrackModel::progress_index_s() const {
  double s = 0.0;
  for (std::size_t i = 1; i <= progress_ && i < samples_.size(); ++i) s += (samples_[i].xy - samples_[i - 1].xy).norm();
  return s;
}

void TrackModel::Initialise(const std::vector<Vec2d>& piece, int64_t seen_ns) {
  samples_.clear();
  for (const Vec2d& p : piece) samples_.push_back({p, 1, false, seen_ns});
  progress_ = 0;
}

Result<TrackUpdateStats> TrackModel::Update(const TrackObservation& observation, const Pose2& odom_from_vehicle) {
  if (!odom_from_vehicle.IsFinite()) return InvalidArgument("track update: non-finite odometry pose");
  // Observations are in the vehicle's frame: a point farther than kMaxObservedRangeM is no camera's view
  // of the ground (a bad triangulation); densified, a point 1e5 m away made ten million samples.
  constexpr double kMaxObservedRangeM = 100.0;
  for (std::size_t i = 0; i < observation.pieces.size(); ++i) {
    for (const Vec2d& p : observation.pieces[i].points_m) {
      if (!FinitePoint(p)) return InvalidArgument("track update: piece " + std::to_string(i) + " has a non-finite point");
      if (p.norm() > kMaxObservedRangeM) {
        return InvalidArgument("track update: piece " + std::to_string(i) + " has a point " + FormatNumber(p.norm()) +
                               " m from the vehicle (more than 100 m)");
      }
    }
  }
  for (std::size_t i = 0; i < observation.footprints_m.size(); ++i) {
    for (const Vec2d& p : observation.footprints_m[i]) {
      // A NaN vertex opened the polygon: ground outside the view counted as seen without tape.
      if (!FinitePoint(p))
        return InvalidArgument("track update: footprint " + std::to_string(i) + " has a non-finite vertex");
    }
  }
  TrackUpdateStats stats;
  stats.pieces = static_cast<int>(observation.pieces.size());

  // Observation in the odometry frame, densified.
  struct Piece {
    std::vector<Vec2d> pts;
    std::array<bool, 2> end_seen{};
    bool used = false;
  };
  std::vector<Piece> pieces;
  for (const CentreLinePiece& cp : observation.pieces) {
    if (cp.points_m.size() < 2) continue;
    std::vector<Vec2d> odom;
    for (const Vec2d& p : cp.points_m) odom.push_back(odom_from_vehicle * p);
    pieces.push_back({Densify(odom), cp.end_seen, false});
  }
  std::vector<std::vector<Vec2d>> footprints;
  for (const auto& fp : observation.footprints_m) {
    std::vector<Vec2d> odom;
    for (const Vec2d& p : fp) odom.push_back(odom_from_vehicle * p);
    footprints.push_back(std::move(odom));
  }
  const Vec2d vehicle = odom_from_vehicle.translation();
  const Vec2d heading(std::cos(odom_from_vehicle.yaw), std::sin(odom_from_vehicle.yaw));

  if (samples_.empty()) {
    // The track starts at the vehicle: the piece passing closest to it, oriented along the heading.
    int best = -1;
    double best_d = options_.start_search_m;
    std::size_t best_k = 0;
    for (std::size_t i = 0; i < pieces.size(); ++i) {
      for (std::size_t k = 0; k < pieces[i].pts.size(); ++k) {
        const double d = (pieces[i].pts[k] - vehicle).norm();
        if (d < best_d) {
          best_d = d;
          best = static_cast<int>(i);
          best_k = k;
        }
      }
    }
    if (best < 0) {
      stats.pieces_ignored = stats.pieces;
      return stats;
    }
    Piece& p = pieces[static_cast<std::size_t>(best)];
    // Direction at the closest point.
    const std::size_t k0 = best_k > 0 ? best_k - 1 : 0, k1 = std::min(best_k + 1, p.pts.size() - 1);
    if ((p.pts[k1] - p.pts[k0]).dot(heading) < 0) {
      std::reverse(p.pts.begin(), p.pts.end());
      std::swap(p.end_seen[0], p.end_seen[1]);
      best_k = p.pts.size() - 1 - best_k;
    }
    std::vector<Vec2d> ahead(p.pts.begin() + static_cast<std::ptrdiff_t>(best_k), p.pts.end());
    if (ahead.size() < 2) {
      stats.pieces_ignored = stats.pieces;
      return stats;
    }
    Initialise(ahead, observation.timestamp_ns);
    end_seen_ = p.end_seen[1];
    p.used = true;
    stats.initialised = true;
    stats.pieces_appended = 1;
    last_associated_ns_ = observation.timestamp_ns;
  }

  // Association and fusion of pieces that overlap the model ahead of (and a little behind) the vehicle.
  const std::size_t first = progress_ > 50 ? progress_ - 50 : 0;
  for (Piece& piece : pieces) {
    if (piece.used) continue;
    // Matched samples: piece samples within the gate of the model.
    std::vector<std::size_t> model_index(piece.pts.size(), std::numeric_limits<std::size_t>::max());
    int matched = 0;
    for (std::size_t k = 0; k < piece.pts.size(); ++k) {
      // Squared distances: the same nearest sample without a square root per pair.
      double best2 = options_.association_gate_m * options_.association_gate_m;
      for (std::size_t i = first; i < samples_.size(); ++i) {
        const double d2 = (samples_[i].xy - piece.pts[k]).squaredNorm();
        if (d2 < best2) {
          best2 = d2;
          model_index[k] = i;
        }
      }
      if (model_index[k] != std::numeric_limits<std::size_t>::max()) ++matched;
    }
    if (matched < 3) continue;
    // Orientation: the piece's direction against the model's where they overlap. The model's direction
    // at its last sample is that of the step into it: a piece that overlaps only the model's end (the
    // first view of tape just past a bridged gap, after the piece seen before was dropped) still gets
    // an orientation. Without it the overlap gave none, and a piece that perception listed from its far
    // end was spliced in backwards: the model ran on to the tape's far end and back, and the vehicle
    // turned round there (seen in 5 of 60 noise seeds of the one-metre gap).
    double agree = 0.0;
    for (std::size_t k = 1; k < piece.pts.size(); ++k) {
      const std::size_t i = model_index[k];
      if (i == std::numeric_limits<std::size_t>::max() || samples_.size() < 2) continue;
      const std::size_t i0 = i + 1 < samples_.size() ? i : i - 1;
      agree += (piece.pts[k] - piece.pts[k - 1]).dot(samples_[i0 + 1].xy - samples_[i0].xy);
    }
    if (agree < 0) {
      std::reverse(piece.pts.begin(), piece.pts.end());
      std::reverse(model_index.begin(), model_index.end());
      std::swap(piece.end_seen[0], piece.end_seen[1]);
    }
    piece.used = true;
    ++stats.pieces_associated;
    std::size_t i_min = samples_.size(), i_max = 0, k_last = 0;
    for (std::size_t k = 0; k < piece.pts.size(); ++k) {
      if (model_index[k] == std::numeric_limits<std::size_t>::max()) continue;
      i_min = std::min(i_min, model_index[k]);
      i_max = std::max(i_max, model_index[k]);
      k_last = k;
    }
    // Fuse: the observed stretch replaces the model's samples in the overlap (keeping the piece's own
    // vertices, so corners stay sharp), each moved back towards the old model by (1 - blend); a piece
    // running on beyond the model's end extends it.
    std::size_t k_first = piece.pts.size();
    for (std::size_t k = 0; k < piece.pts.size(); ++k) {
      if (model_index[k] != std::numeric_limits<std::size_t>::max()) {
        k_first = k;
        break;
      }
    }
    // The piece runs on beyond what matched: it extends the model when nothing lies beyond the match,
    // or replaces what does when that is tape the newest view contradicts (odometry drift moved it
    // out of the gate); a bridged gap beyond is kept.
    bool tail_has_gap = false;
    for (std::size_t i = i_max + 1; i < samples_.size(); ++i) tail_has_gap = tail_has_gap || samples_[i].gap;
    const bool extends = k_last + 3 < piece.pts.size() && !tail_has_gap;
    const std::size_t k_end = extends ? piece.pts.size() - 1 : k_last;
    std::vector<Vec2d> old_section;
    for (std::size_t i = i_min; i <= i_max; ++i) old_section.push_back(samples_[i].xy);
    const PolylineSearch old_search(old_section);
    std::vector<TrackSample> spliced(samples_.begin(), samples_.begin() + static_cast<std::ptrdiff_t>(i_min));
    for (std::size_t k = k_first; k <= k_end; ++k) {
      TrackSample t{piece.pts[k], 1, false, observation.timestamp_ns};
      if (k <= k_last) {
        const auto [q, d] = old_search.Nearest(t.xy);
        if (d < options_.association_gate_m) t.xy += (1.0 - options_.blend) * (q - t.xy);
        const std::size_t i = model_index[k] != std::numeric_limits<std::size_t>::max() ? model_index[k] : i_min;
        t.support = std::min(options_.max_support, samples_[i].support + 1);
      }
      spliced.push_back(t);
    }
    const std::size_t removed = i_max + 1 - i_min;
    if (!extends && i_max + 1 < samples_.size()) {
      // The old model beyond the observed stretch was placed with older odometry: move it across
      // the track by the offset at the seam, so the model does not step there.
      const Vec2d seam_new = spliced.back().xy;
      const Vec2d seam_old = samples_[i_max].xy;
      const Vec2d dir = i_max > 0 ? Vec2d((samples_[i_max].xy - samples_[i_max - 1].xy).normalized()) : Vec2d(1, 0);
      Vec2d delta = seam_new - seam_old;
      if (dir.allFinite()) delta -= delta.dot(dir) * dir;
      for (std::size_t i = i_max + 1; i < samples_.size(); ++i) {
        TrackSample t = samples_[i];
        if (delta.norm() < options_.association_gate_m) t.xy += delta;
        spliced.push_back(t);
      }
    }
    if (progress_ >= i_max + 1) {
      progress_ = progress_ + (k_end + 1 - k_first) - removed;
    } else if (progress_ >= i_min) {
      progress_ = i_min + std::min(progress_ - i_min, k_end - k_first);
    }
    samples_ = std::move(spliced);
    progress_ = std::min(progress_, samples_.size() - 1);
    if (extends) {
      ++stats.pieces_appended;
      if (k_end > k_last) {
        end_known_ = false;
        clear_beyond_end_m_ = 0.0;
      }
      end_seen_ = piece.end_seen[1];
      if (!piece.end_seen[1]) clear_beyond_end_m_ = 0.0;
    } else if (k_last + 3 >= piece.pts.size() && i_max + 3 >= samples_.size() && piece.end_seen[1]) {
      end_seen_ = true;
    }
  }
  if (stats.pieces_associated > 0 || stats.initialised) last_associated_ns_ = observation.timestamp_ns;

  // Pieces that continue the model's far end, directly or across a gap.
  for (bool grew = true; grew && !samples_.empty();) {
    grew = false;
    std::vector<Vec2d> tail;
    for (std::size_t i = samples_.size() > 20 ? samples_.size() - 20 : 0; i < samples_.size(); ++i) tail.push_back(samples_[i].xy);
    const Vec2d end = samples_.back().xy;
    const Vec2d dir = EndDirection(tail, 0.1);
    for (Piece& piece : pieces) {
      if (piece.used) continue;
      const double d_front = (piece.pts.front() - end).norm(), d_back = (piece.pts.back() - end).norm();
      if (d_back < d_front) {
        std::reverse(piece.pts.begin(), piece.pts.end());
        std::swap(piece.end_seen[0], piece.end_seen[1]);
      }
      const Vec2d to_near = piece.pts.front() - end;
      const double dist = to_near.norm();
      const Vec2d piece_dir = (piece.pts[std::min<std::size_t>(piece.pts.size() - 1, 10)] - piece.pts.front()).normalized();
      const bool continues = dist <= options_.join_distance_m && piece_dir.dot(dir) > std::cos(DegToRad(60.0));
      const bool across_gap = !continues && end_seen_ && dist <= options_.max_gap_m &&
                              to_near.normalized().dot(dir) > std::cos(DegToRad(options_.max_gap_angle_deg)) &&
                              piece_dir.dot(dir) > std::cos(DegToRad(45.0));
      if (!continues && !across_gap) continue;
      if (across_gap) {
        // A straight link over the stretch without tape.
        samples_.back().gap = true;
        const int n = std::max(1, static_cast<int>(std::ceil(dist / options_.sample_spacing_m)));
        for (int k = 1; k < n; ++k) {
          samples_.push_back({end + to_near * (static_cast<double>(k) / n), 1, true, observation.timestamp_ns});
        }
      }
      for (const Vec2d& p : piece.pts) samples_.push_back({p, 1, false, observation.timestamp_ns});
      piece.used = true;
      ++stats.pieces_appended;
      end_seen_ = piece.end_seen[1];
      end_known_ = false;
      clear_beyond_end_m_ = 0.0;
      grew = true;
      last_associated_ns_ = observation.timestamp_ns;
      break;
    }
  }
  for (const Piece& piece : pieces) {
    if (!piece.used) ++stats.pieces_ignored;
  }

  // Samples ahead that both cameras should have seen but nothing confirmed lose support; the model's
  // unconfirmed tail is dropped once its support is gone (a false extension, or tape removed).
  const std::vector<char> evidence = StretchInView(footprints);
  for (std::size_t i = progress_; i < samples_.size(); ++i) {
    if (samples_[i].seen_ns == observation.timestamp_ns || samples_[i].gap || !evidence[i]) continue;
    samples_[i].support -= 2;
  }
  // The unconfirmed tail: samples at the far end that this view did not see. If part of it was
  // contradicted (in view, no tape), it ends there.
  std::size_t unconfirmed = samples_.size();
  while (unconfirmed > progress_ + 2 && samples_[unconfirmed - 1].seen_ns != observation.timestamp_ns && !samples_[unconfirmed - 1].gap) --unconfirmed;
  // Only a sample this view contradicts (in view, no tape) ends it: one out of view with no support
  // left was never seen again, which is no evidence (it lies between the vehicle and the footprints,
  // or the view is blank because perception failed on this pair).
  for (std::size_t j = unconfirmed; j < samples_.size(); ++j) {
    if (samples_[j].support <= 0 && !samples_[j].gap && evidence[j]) {
      stats.samples_dropped += static_cast<int>(samples_.size() - j);
      samples_.resize(std::max<std::size_t>(j, progress_ + 2));
      end_seen_ = false;
      end_known_ = false;
      clear_beyond_end_m_ = 0.0;
      break;
    }
  }
  for (TrackSample& s : samples_) s.support = std::max(s.support, 0);

  // Clear ground beyond a visible tape end: once enough of it has been seen, the end is the track's end.
  if (end_seen_ && samples_.size() >= 2 && !end_known_) {
    std::vector<Vec2d> tail;
    for (std::size_t i = samples_.size() > 20 ? samples_.size() - 20 : 0; i < samples_.size(); ++i) tail.push_back(samples_[i].xy);
    const Vec2d end = samples_.back().xy;
    const Vec2d dir = EndDirection(tail, 0.1);
    double clear = 0.0;
    for (double t = 0.05; t <= options_.end_confirm_m + 1e-9; t += 0.05) {
      const Vec2d p = end + t * dir;
      if (!InView(footprints, p)) break;
      // Only tape that could continue the track blocks: a piece running along the end's direction
      // there (the rule that bridges a gap asks the same of a piece). Tape crossing the ray - the
      // start of a loop passing under the end - does not.
      bool tape = false;
      const double gate = std::max(options_.association_gate_m, t * std::tan(DegToRad(options_.max_gap_angle_deg)));
      for (const Piece& piece : pieces) {
        if (piece.used) continue;
        const std::size_t n = piece.pts.size();
        for (std::size_t k = 0; k < n && !tape; ++k) {
          if ((piece.pts[k] - p).norm() >= gate) continue;
          const Vec2d along = piece.pts[std::min(k + 5, n - 1)] - piece.pts[k >= 5 ? k - 5 : 0];
          tape = along.norm() < 1e-9 || std::abs(along.normalized().dot(dir)) > std::cos(DegToRad(45.0));
        }
        if (tape) break;
      }
      if (tape) break;
      clear = t;
    }
    clear_beyond_end_m_ = std::max(clear_beyond_end_m_, clear);
    if (clear_beyond_end_m_ >= options_.end_confirm_m - 1e-9) end_known_ = true;
  }

  UpdateProgress(odom_from_vehicle);
  // Prune what lies well behind the vehicle.
  double behind = 0.0;
  std::size_t cut = 0;
  for (std::size_t i = progress_; i > 0; --i) {
    behind += (samples_[i].xy - samples_[i - 1].xy).norm();
    if (behind > options_.keep_behind_m) {
      cut = i - 1;
      break;
    }
  }
  if (cut > 0) {
    samples_.erase(samples_.begin(), samples_.begin() + static_cast<std::ptrdiff_t>(cut));
    progress_ -= cut;
  }
  return stats;
}

void TrackModel::UpdateProgress(const Pose2& odom_from_vehicle) {
  if (samples_.size() < 2 || !odom_from_vehicle.IsFinite()) return;
  const Vec2d v = odom_from_vehicle.translation();
  const std::size_t lo = progress_ > 30 ? progress_ - 30 : 0;
  const std::size_t hi = std::min(samples_.size() - 1, progress_ + 300);
  std::size_t best = progress_;
  double best_d = std::numeric_limits<double>::infinity();
  for (std::size_t i = lo; i <= hi; ++i) {
    const double d = (samples_[i].xy - v).norm();
    if (d < best_d) {
      best_d = d;
      best = i;
    }
  }
  // Advance the along-track distance.
  if (best > progress_) {
    for (std::size_t i = progress_ + 1; i <= best; ++i) distance_along_m_ += (samples_[i].xy - samples_[i - 1].xy).norm();
  }
  progress_ = best;
  const std::size_t a = std::min(progress_, samples_.size() - 2);
  const Vec2d d = (samples_[a + 1].xy - samples_[a].xy);
  const Vec2d left = d.norm() > 1e-12 ? Vec2d(-d.y(), d.x()) / d.norm() : Vec2d(0, 1);
  vehicle_offset_m_ = (v - samples_[progress_].xy).dot(left);
}

TrackAhead TrackModel::Ahead(double max_length_m, double behind_m) const {
  TrackAhead out;
  if (samples_.size() < 2) return out;
  std::size_t first = progress_;
  double back = 0.0;
  while (first > 0 && back + (samples_[first].xy - samples_[first - 1].xy).norm() <= behind_m) {
    back += (samples_[first].xy - samples_[first - 1].xy).norm();
    --first;
  }
  out.progress_offset_m = back;
  double len = 0.0;
  for (std::size_t i = first; i < samples_.size(); ++i) {
    if (i > first) len += (samples_[i].xy - samples_[i - 1].xy).norm();
    out.points.push_back(samples_[i].xy);
    out.support.push_back(samples_[i].support);
    out.gap.push_back(samples_[i].gap);
    out.seen_ns.push_back(samples_[i].seen_ns);
    if (len - back >= max_length_m) break;
  }
  out.length_m = len;
  out.end_known = end_known_ && out.points.size() == samples_.size() - first;
  return out;
}

}  // namespace idi::rmp
