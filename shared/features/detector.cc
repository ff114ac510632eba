// FeatureDetector: the pipeline of features.h, options checks and the bounds.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <optional>
#include <set>
#include <string>
#include <utility>

#include "shared/features/active_contour.h"
#include "shared/features/empl.h"
#include "shared/features/features.h"
#include "shared/features/gradient.h"
#include "shared/features/hough.h"
#include "shared/features/idi_points.h"
#include "shared/features/pixel_geometry.h"

namespace idi {
namespace {

constexpr double kDetPi = 3.14159265358979323846;

Status Positive(double v, const char* name) {
  if (!(v > 0) || !std::isfinite(v)) {
    return InvalidArgument(std::string(name) + " must be positive and finite, got " + FormatNumber(v));
  }
  return Status::Ok();
}

Status NonNegative(double v, const char* name) {
  if (!(v >= 0) || !std::isfinite(v)) {
    return InvalidArgument(std::string(name) + " must be >= 0 and finite, got " + FormatNumber(v));
  }
  return Status::Ok();
}

Status InRange(double v, double lo, double hi, const char* name) {
  if (!(v >= lo && v <= hi)) {
    return InvalidArgument(std::string(name) + " must be in [" + FormatNumber(lo) + ", " + FormatNumber(hi) +
                           "], got " + FormatNumber(v));
  }
  return Status::Ok();
}

double Ms(std::chrono::steady_clock::time_point a, std::chrono::steady_clock::time_point b) {
  return std::chrono::duration<double, std::milli>(b - a).count();
}

}  // namespace

Status EdgeOptions::Check() const {
  IDI_RETURN_IF_ERROR(InRange(smoothing_sigma_px, 0.3, 5.0, "edges.smoothing_sigma_px"));
  IDI_RETURN_IF_ERROR(Positive(low_threshold_sigmas, "edges.low_threshold_sigmas"));
  IDI_RETURN_IF_ERROR(Positive(high_threshold_sigmas, "edges.high_threshold_sigmas"));
  IDI_RETURN_IF_ERROR(NonNegative(min_low_threshold, "edges.min_low_threshold"));
  IDI_RETURN_IF_ERROR(NonNegative(min_high_threshold, "edges.min_high_threshold"));
  if (high_threshold_sigmas < low_threshold_sigmas) {
    return InvalidArgument("edges.high_threshold_sigmas must be >= edges.low_threshold_sigmas");
  }
  return Status::Ok();
}

Status HoughOptions::Check() const {
  IDI_RETURN_IF_ERROR(InRange(angle_step_deg, 0.1, 10.0, "hough.angle_step_deg"));
  IDI_RETURN_IF_ERROR(InRange(offset_step_px, 0.25, 10.0, "hough.offset_step_px"));
  IDI_RETURN_IF_ERROR(InRange(vote_window_deg, 0.0, 45.0, "hough.vote_window_deg"));
  IDI_RETURN_IF_ERROR(InRange(band_px, 0.5, 5.0, "hough.band_px"));
  IDI_RETURN_IF_ERROR(InRange(max_angle_error_deg, 1.0, 89.0, "hough.max_angle_error_deg"));
  // Bounded: the EMPL scan walks the gap on both sides of every segment, one pixel at a time.
  IDI_RETURN_IF_ERROR(InRange(max_gap_px, 0.0, 200.0, "hough.max_gap_px"));
  IDI_RETURN_IF_ERROR(InRange(min_length_px, 4.0, 1e5, "hough.min_length_px"));
  IDI_RETURN_IF_ERROR(InRange(min_fill, 0.05, 1.0, "hough.min_fill"));
  if (max_lines < 1) {
    return InvalidArgument("hough.max_lines must be >= 1");
  }
  return Status::Ok();
}

Status EmplOptions::Check() const {
  IDI_RETURN_IF_ERROR(InRange(band_halfwidth_px, 1.0, 20.0, "empl.band_halfwidth_px"));
  IDI_RETURN_IF_ERROR(NonNegative(threshold_alpha, "empl.threshold_alpha"));
  IDI_RETURN_IF_ERROR(Positive(threshold_window_px, "empl.threshold_window_px"));
  IDI_RETURN_IF_ERROR(InRange(max_angle_error_deg, 1.0, 89.0, "empl.max_angle_error_deg"));
  if (max_iterations < 1) {
    return InvalidArgument("empl.max_iterations must be >= 1");
  }
  IDI_RETURN_IF_ERROR(Positive(outlier_sigmas, "empl.outlier_sigmas"));
  IDI_RETURN_IF_ERROR(NonNegative(max_fit_rms_px, "empl.max_fit_rms_px"));
  IDI_RETURN_IF_ERROR(InRange(chunk_length_px, 4.0, 1e5, "empl.chunk_length_px"));
  IDI_RETURN_IF_ERROR(NonNegative(end_margin_px, "empl.end_margin_px"));
  IDI_RETURN_IF_ERROR(NonNegative(merge_angle_deg, "empl.merge_angle_deg"));
  IDI_RETURN_IF_ERROR(NonNegative(merge_offset_px, "empl.merge_offset_px"));
  IDI_RETURN_IF_ERROR(Positive(split_angle_deg, "empl.split_angle_deg"));
  IDI_RETURN_IF_ERROR(Positive(curve_max_radius_px, "empl.curve_max_radius_px"));
  IDI_RETURN_IF_ERROR(NonNegative(curve_min_sagitta_px, "empl.curve_min_sagitta_px"));
  IDI_RETURN_IF_ERROR(NonNegative(curve_min_sagitta_short_px, "empl.curve_min_sagitta_short_px"));
  IDI_RETURN_IF_ERROR(NonNegative(curve_end_trim_px, "empl.curve_end_trim_px"));
  IDI_RETURN_IF_ERROR(NonNegative(peak_proximity_sigma_px, "empl.peak_proximity_sigma_px"));
  IDI_RETURN_IF_ERROR(NonNegative(flat_band_max_texture_ratio, "empl.flat_band_max_texture_ratio"));
  IDI_RETURN_IF_ERROR(NonNegative(extension_fraction, "empl.extension_fraction"));
  IDI_RETURN_IF_ERROR(NonNegative(min_extension_px, "empl.min_extension_px"));
  IDI_RETURN_IF_ERROR(NonNegative(min_extension_blur_sigmas, "empl.min_extension_blur_sigmas"));
  if (!(max_extension_px >= min_extension_px)) {
    return InvalidArgument("empl.max_extension_px must be >= empl.min_extension_px");
  }
  IDI_RETURN_IF_ERROR(InRange(junction_refit_angle_deg, 0.0, 90.0, "empl.junction_refit_angle_deg"));
  return Status::Ok();
}

Status IdiOptions::Check() const {
  IDI_RETURN_IF_ERROR(InRange(min_angle_deg, 0.1, 89.0, "idi.min_angle_deg"));
  IDI_RETURN_IF_ERROR(NonNegative(merge_radius_px, "idi.merge_radius_px"));
  IDI_RETURN_IF_ERROR(NonNegative(max_point_sigma_px, "idi.max_point_sigma_px"));
  IDI_RETURN_IF_ERROR(NonNegative(image_margin_px, "idi.image_margin_px"));
  IDI_RETURN_IF_ERROR(InRange(max_gap_px, 0.0, 100.0, "idi.max_gap_px"));
  IDI_RETURN_IF_ERROR(InRange(gap_min_strength, 0.0, 1.0, "idi.gap_min_strength"));
  IDI_RETURN_IF_ERROR(NonNegative(gap_max_contrast, "idi.gap_max_contrast"));
  return Status::Ok();
}

Status CurveOptions::Check() const {
  IDI_RETURN_IF_ERROR(InRange(min_length_px, 5.0, 1e5, "curves.min_length_px"));
  IDI_RETURN_IF_ERROR(InRange(point_spacing_px, 1.0, 50.0, "curves.point_spacing_px"));
  IDI_RETURN_IF_ERROR(NonNegative(alpha, "curves.alpha"));
  IDI_RETURN_IF_ERROR(NonNegative(beta, "curves.beta"));
  IDI_RETURN_IF_ERROR(NonNegative(gamma, "curves.gamma"));
  if (max_iterations < 0) {
    return InvalidArgument("curves.max_iterations must be >= 0");
  }
  IDI_RETURN_IF_ERROR(Positive(straight_rms_px, "curves.straight_rms_px"));
  return Status::Ok();
}

Status FeatureOptions::Check() const {
  IDI_RETURN_IF_ERROR(edges.Check());
  IDI_RETURN_IF_ERROR(hough.Check());
  IDI_RETURN_IF_ERROR(empl.Check());
  IDI_RETURN_IF_ERROR(idi.Check());
  IDI_RETURN_IF_ERROR(curves.Check());
  return Status::Ok();
}

double EmplLine::Angle() const { return std::atan2(normal.y(), normal.x()); }

Eigen::Vector2d EmplLine::Direction() const {
  const Eigen::Vector2d d = p2 - p1;
  const double n = d.norm();
  return n > 0 ? Eigen::Vector2d(d / n) : Eigen::Vector2d(-normal.y(), normal.x());
}

double OffsetBoundPx(double contrast, double noise_sigma, double blur_sigma_px, double length_px) {
  const double sigma_e = std::sqrt(blur_sigma_px * blur_sigma_px + 1.0 / 12.0);
  return noise_sigma / contrast * std::sqrt(2.0 * std::sqrt(kDetPi) * sigma_e / length_px);
}

double AngleBoundRad(double contrast, double noise_sigma, double blur_sigma_px, double length_px) {
  const double sigma_e = std::sqrt(blur_sigma_px * blur_sigma_px + 1.0 / 12.0);
  return noise_sigma / contrast * std::sqrt(24.0 * std::sqrt(kDetPi) * sigma_e / (length_px * length_px * length_px));
}

namespace {

// Whether the stretch a-b lies on line l (within tolerance_px of it) and inside its extent (2 px slack).
bool Covers(const EmplLine& l, const Vec2d& a, const Vec2d& b, double tolerance_px = 1.5) {
  if (std::fabs(l.SignedDistance(a)) >= tolerance_px || std::fabs(l.SignedDistance(b)) >= tolerance_px) {
    return false;
  }
  const Vec2d u = l.Direction();
  const double ta = u.dot(a - l.p1), tb = u.dot(b - l.p1);
  return std::min(ta, tb) >= -2.0 && std::max(ta, tb) <= l.length_px + 2.0;
}

}  // namespace

struct FeatureDetector::Impl {
  FeatureOptions options;
  std::optional<CameraModel> camera;
  PixelGeometry geometry;
  GradientImages gradients;
  EdgeMap edges;
  HoughLineFinder hough;
  cv::Mat curve_mask;
  std::vector<EmplPixel> empl_scratch;

  // Merges collinear pieces (§8.8.2): same line to within the tolerances, gap no larger than the
  // Hough gap (or overlapping, i.e. two peaks of one edge).
  //
  // What is not refitted (the refit would only repeat a decision already made):
  //  - two pieces one fit split apart (`origin`: the fit each line came from): that fit found them
  //    to be different lines from the same pixels - a curve of short straight pieces, a corner;
  //  - a pair whose refit was refused before: after a merge the scan starts again, and the refit
  //    depends only on the two lines and the image. Lines carry serial numbers for that; a merged
  //    line gets a new one (and a new origin).
  // Without both, a curve of many short pieces (tens of lines, almost none mergeable) cost tens of
  // refits per image.
  void MergeCollinear(const EmplFitter& fitter, std::vector<EmplFitResult>* fits, std::vector<uint32_t> origin) const {
    const EmplOptions& eo = options.empl;
    std::vector<uint32_t> serial(fits->size());
    for (std::size_t k = 0; k < serial.size(); ++k) serial[k] = static_cast<uint32_t>(k);
    uint32_t next_serial = static_cast<uint32_t>(serial.size());
    uint32_t next_origin = origin.empty() ? 0 : *std::max_element(origin.begin(), origin.end()) + 1;
    std::set<std::pair<uint32_t, uint32_t>> refused;
    for (std::size_t pass = 0; pass <= fits->size() + 1; ++pass) {
      bool merged = false;
      for (std::size_t i = 0; i < fits->size() && !merged; ++i) {
        for (std::size_t j = i + 1; j < fits->size() && !merged; ++j) {
          if (origin[i] == origin[j] || refused.count({serial[i], serial[j]}) != 0) {
            continue;
          }
          const EmplLine& a = (*fits)[i].line;
          const EmplLine& b = (*fits)[j].line;
          const double dang = std::asin(std::min(1.0, std::fabs(a.normal.x() * b.normal.y() - a.normal.y() * b.normal.x())));
          const double sig = std::sqrt(std::max(0.0, a.covariance(0, 0)) + std::max(0.0, b.covariance(0, 0)));
          if (dang > std::max(eo.merge_angle_deg * kDetPi / 180.0, 4.0 * sig)) {
            continue;
          }
          if (std::fabs(a.SignedDistance(b.p1)) > eo.merge_offset_px ||
              std::fabs(a.SignedDistance(b.p2)) > eo.merge_offset_px ||
              std::fabs(b.SignedDistance(a.p1)) > eo.merge_offset_px ||
              std::fabs(b.SignedDistance(a.p2)) > eo.merge_offset_px) {
            continue;
          }
          const EmplLine& longer = a.length_px >= b.length_px ? a : b;
          const Vec2d foot = longer.normal * longer.offset, dir = LineDirection(longer.normal);
          double ta0 = dir.dot(a.p1 - foot), ta1 = dir.dot(a.p2 - foot);
          double tb0 = dir.dot(b.p1 - foot), tb1 = dir.dot(b.p2 - foot);
          if (ta0 > ta1) std::swap(ta0, ta1);
          if (tb0 > tb1) std::swap(tb0, tb1);
          const double gap = std::max(tb0 - ta1, ta0 - tb1);
          if (gap > options.hough.max_gap_px + 1.0) {
            continue;
          }
          EmplRequest req;
          req.segment.normal = longer.normal;
          req.segment.offset = longer.offset;
          req.segment.t0 = std::min(ta0, tb0);
          req.segment.t1 = std::max(ta1, tb1);
          // Each piece has already grown to where its edge ends: the refit asks only whether the
          // stretch they span together is one line (growing further would refit the rest of a curve).
          req.t_limit_lo = req.segment.t0 - 2.0;
          req.t_limit_hi = req.segment.t1 + 2.0;
          std::vector<EmplFitResult> refit = fitter.Fit(req);
          if (refit.size() == 1 && refit[0].line.length_px >= 0.9 * std::max(a.length_px, b.length_px)) {
            (*fits)[i] = std::move(refit[0]);
            fits->erase(fits->begin() + static_cast<std::ptrdiff_t>(j));
            serial[i] = next_serial++;
            serial.erase(serial.begin() + static_cast<std::ptrdiff_t>(j));
            origin[i] = next_origin++;
            origin.erase(origin.begin() + static_cast<std::ptrdiff_t>(j));
            merged = true;
          } else {
            refused.insert({serial[i], serial[j]});
          }
        }
      }
      if (!merged) {
        break;
      }
    }
  }

  // How far another edge's blur reaches into a line's fit: the photometric band (2 sigma + 1.5 px) and the
  // other edge's own profile (2 sigma).
  static double Clearance(const EmplLine& l) { return 3.0 + 4.0 * (l.blur_sigma_px > 0 ? l.blur_sigma_px : 1.5); }

  // Refits the lines of shallow junctions clear of each other's edge (EmplOptions::junction_refit_angle_deg).
  // A junction is a pair of lines meeting within both lines' unconfirmed extensions (plus the clearance),
  // as for an IDI point. Every refit keeps clear of the lines as they were, so the order does not matter; a
  // refit that fails or loses a tenth of the line keeps the first fit.

  void RefitShallowJunctions(const EmplFitter& fitter, std::vector<EmplFitResult>* fits) const {
    const EmplOptions& eo = options.empl;
    if (eo.junction_refit_angle_deg <= options.idi.min_angle_deg) {
      return;
    }
    const double min_sin = std::sin(options.idi.min_angle_deg * kDetPi / 180.0);
    const double max_sin = std::sin(eo.junction_refit_angle_deg * kDetPi / 180.0);
    const std::size_t n = fits->size();
    std::vector<std::vector<std::size_t>> near(n);
    for (std::size_t i = 0; i < n; ++i) {
      for (std::size_t j = i + 1; j < n; ++j) {
        const EmplLine& a = (*fits)[i].line;
        const EmplLine& b = (*fits)[j].line;
        const double det = a.normal.x() * b.normal.y() - a.normal.y() * b.normal.x();
        if (std::fabs(det) < min_sin || std::fabs(det) > max_sin) {
          continue;
        }
        const Vec2d x((a.offset * b.normal.y() - b.offset * a.normal.y()) / det,
                      (a.normal.x() * b.offset - b.normal.x() * a.offset) / det);
        if (DistanceBeyondSegment(a, x) > (a.extension1 - a.p1).norm() + Clearance(a) ||
            DistanceBeyondSegment(b, x) > (b.extension1 - b.p1).norm() + Clearance(b)) {
          continue;
        }
        // A wedge, not a bend: both lines run away from the junction on the same side, so their edges
        // run side by side (at an obtuse bend they part at once).
        if ((0.5 * (a.p1 + a.p2) - x).dot(0.5 * (b.p1 + b.p2) - x) <= 0) {
          continue;
        }
        near[i].push_back(j);
        near[j].push_back(i);
      }
    }
    std::vector<std::optional<EmplFitResult>> refits(n);
    for (std::size_t i = 0; i < n; ++i) {
      if (near[i].empty()) {
        continue;
      }
      const EmplLine& l = (*fits)[i].line;
      EmplRequest req;
      req.segment.normal = l.normal;
      req.segment.offset = l.offset;
      const Vec2d foot = l.normal * l.offset, dir = LineDirection(l.normal);
      req.segment.t0 = std::min(dir.dot(l.p1 - foot), dir.dot(l.p2 - foot));
      req.segment.t1 = std::max(dir.dot(l.p1 - foot), dir.dot(l.p2 - foot));
      req.t_limit_lo = req.segment.t0 - 2.0;
      req.t_limit_hi = req.segment.t1 + 2.0;
      req.split_depth = 2;  // the first fit already decided whether this is one line
      req.avoid_clearance_px = Clearance(l);
      for (const std::size_t j : near[i]) {
        req.avoid.emplace_back((*fits)[j].line.extension1, (*fits)[j].line.extension2);
      }
      std::vector<EmplFitResult> r = fitter.Fit(req);
      if (r.size() == 1 && r[0].line.length_px >= 0.9 * l.length_px) {
        refits[i] = std::move(r[0]);
      }
    }
    for (std::size_t i = 0; i < n; ++i) {
      if (refits[i]) {
        (*fits)[i] = std::move(*refits[i]);
      }
    }
  }
};

FeatureDetector::FeatureDetector(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
FeatureDetector::FeatureDetector(FeatureDetector&&) noexcept = default;
FeatureDetector& FeatureDetector::operator=(FeatureDetector&&) noexcept = default;
FeatureDetector::~FeatureDetector() = default;

const FeatureOptions& FeatureDetector::options() const { return impl_->options; }

Result<FeatureDetector> FeatureDetector::Create(const FeatureOptions& options, const std::optional<CameraModel>& camera) {
  IDI_RETURN_IF_ERROR(options.Check());
  auto impl = std::make_unique<Impl>();
  impl->options = options;
  if (camera) {
    if (camera->width < 16 || camera->height < 16) {
      return InvalidArgument("camera image size " + std::to_string(camera->width) + " x " +
                             std::to_string(camera->height) + " is too small");
    }
    for (double p : camera->params) {
      if (!std::isfinite(p)) {
        return InvalidArgument("camera parameters must be finite");
      }
    }
    if (!(camera->fx() > 0 && camera->fy() > 0)) {
      return InvalidArgument("camera focal lengths must be positive");
    }
    impl->camera = camera;
    impl->geometry = PixelGeometry(*camera);
    if (!impl->geometry.valid()) {
      return InvalidArgument("camera distortion cannot be inverted over the whole image (k1..k3, p1, p2 out of range)");
    }
  }
  return FeatureDetector(std::move(impl));
}

Result<FeatureResult> FeatureDetector::Detect(const cv::Mat& image) {
  Impl& m = *impl_;
  const auto t_start = std::chrono::steady_clock::now();
  FeatureResult result;
  IDI_RETURN_IF_ERROR(ComputeGradients(image, m.options.edges.smoothing_sigma_px, &m.gradients));
  if (m.camera && (image.cols != m.camera->width || image.rows != m.camera->height)) {
    return InvalidArgument("image is " + std::to_string(image.cols) + " x " + std::to_string(image.rows) +
                           " px but the camera model is " + std::to_string(m.camera->width) + " x " +
                           std::to_string(m.camera->height));
  }
  result.width = image.cols;
  result.height = image.rows;
  result.noise_sigma = m.gradients.noise_sigma;
  const auto t_grad = std::chrono::steady_clock::now();
  DetectEdges(m.gradients, m.options.edges, &m.edges);
  result.edge_pixels = static_cast<int>(m.edges.pixels.size());
  const auto t_edges = std::chrono::steady_clock::now();
  const std::vector<HoughSegment> segments = m.hough.Find(m.gradients, &m.edges, m.geometry, m.options.hough);
  const auto t_hough = std::chrono::steady_clock::now();

  EmplFitter fitter(m.gradients, m.geometry, m.edges, m.options, &m.empl_scratch);
  std::vector<EmplFitResult> fits;
  std::vector<uint32_t> origin;  // the fit (Hough segment) each line came from
  for (const HoughSegment& seg : segments) {
    // A weaker peak on an edge that EMPL lines already explain (the EMPL fit grows a segment to the
    // edge's full length, beyond the pixels its Hough peak claimed; on a curve, the straight pieces
    // an earlier fit split it into) adds nothing: only the longest stretch of it that no line
    // explains is fitted, and a peak with none is skipped.
    const Vec2d foot = seg.normal * seg.offset, dir = LineDirection(seg.normal);
    const auto explained = [&fits](const Vec2d& from, const Vec2d& to, double tolerance_px = 1.5) {
      return std::any_of(fits.begin(), fits.end(),
                         [&](const EmplFitResult& f) { return Covers(f.line, from, to, tolerance_px); });
    };
    const int stretches = std::max(1, static_cast<int>(std::ceil((seg.t1 - seg.t0) / 8.0)));
    const double step = (seg.t1 - seg.t0) / stretches;
    std::vector<char> covered(static_cast<std::size_t>(stretches));
    for (int k = 0; k < stretches; ++k) {
      covered[static_cast<std::size_t>(k)] = explained(foot + (seg.t0 + k * step) * dir, foot + (seg.t0 + (k + 1) * step) * dir);
    }
    // The longest run of stretches nothing explains yet.
    int run_lo = 0, run_hi = 0;
    for (int k = 0; k < stretches;) {
      if (covered[static_cast<std::size_t>(k)]) {
        ++k;
        continue;
      }
      int e = k;
      while (e < stretches && !covered[static_cast<std::size_t>(e)]) ++e;
      if (e - k > run_hi - run_lo) {
        run_lo = k;
        run_hi = e;
      }
      k = e;
    }
    if (run_hi == run_lo) {
      continue;
    }
    EmplRequest req;
    req.segment = seg;
    // Fit only that run and let it grow away from the explained stretches, not back over them (on a
    // curve the explained side is the pieces an earlier fit already cut; refitting them repeats it).
    req.segment.t0 = seg.t0 + run_lo * step;
    req.segment.t1 = seg.t0 + run_hi * step;
    if (run_lo > 0) req.t_limit_lo = req.segment.t0 - step;
    if (run_hi < stretches) req.t_limit_hi = req.segment.t1 + step;
    // Beyond the peak's ends the fit grows while edge pixels stay in its band: it stops growing
    // where the band reaches an explained stretch.
    const double band = m.options.empl.band_halfwidth_px;
    for (int side = 0; side < 2; ++side) {
      if ((side == 0 && run_lo > 0) || (side == 1 && run_hi < stretches)) continue;
      for (int k = 0; k < 32; ++k) {
        const double t_near = side == 0 ? seg.t0 - k * 8.0 : seg.t1 + k * 8.0;
        const double t_far = side == 0 ? t_near - 8.0 : t_near + 8.0;
        if (explained(foot + t_near * dir, foot + t_far * dir, band)) {
          (side == 0 ? req.t_limit_lo : req.t_limit_hi) = t_near;
          break;
        }
      }
    }
    for (EmplFitResult& f : fitter.Fit(req)) {
      // A fit grows along the whole edge and splits a curve into straight pieces: the peaks of one
      // curved edge each return the same pieces. A piece an earlier line already covers is that line.
      if (explained(f.line.p1, f.line.p2)) {
        continue;
      }
      fits.push_back(std::move(f));
      origin.push_back(static_cast<uint32_t>(&seg - segments.data()));
    }
  }
  m.MergeCollinear(fitter, &fits, std::move(origin));
  m.RefitShallowJunctions(fitter, &fits);
  // Longest first: stable ids that favour the best-supported lines.
  std::sort(fits.begin(), fits.end(),
            [](const EmplFitResult& a, const EmplFitResult& b) { return a.line.length_px > b.line.length_px; });
  for (EmplFitResult& f : fits) {
    f.line.id = static_cast<int>(result.lines.size());
    result.lines.push_back(std::move(f.line));
  }
  const auto t_empl = std::chrono::steady_clock::now();
  GapTest gap;
  if (m.options.idi.max_gap_px > 0) {
    gap = [&m](const EmplLine& line, const Vec2d& end, const Vec2d& x) {
      if (!(line.contrast <= m.options.idi.gap_max_contrast * m.gradients.level_scale)) return false;
      // The extension bridges the corner's blur: the gap is checked up to where it begins.
      return EdgeContinues(
          m.gradients, m.geometry, line, end, x, (line.extension1 - line.p1).norm(), m.options.idi.gap_min_strength);
    };
  }
  result.points = FindIdiPoints(&result.lines, m.options.idi, image.cols, image.rows, gap);
  const auto t_points = std::chrono::steady_clock::now();
  if (m.options.curves.enabled) {
    result.curves = FindCurves(m.gradients, m.edges, m.geometry, result.lines, m.options.curves, &m.curve_mask);
    AddCurveLinePoints(m.options.idi, &result.curves, &result.lines, &result.points);
  }
  const auto t_end = std::chrono::steady_clock::now();
  result.timing.gradient_ms = Ms(t_start, t_grad);
  result.timing.edges_ms = Ms(t_grad, t_edges);
  result.timing.hough_ms = Ms(t_edges, t_hough);
  result.timing.empl_ms = Ms(t_hough, t_empl);
  result.timing.points_ms = Ms(t_empl, t_points);
  result.timing.curves_ms = Ms(t_points, t_end);
  result.timing.total_ms = Ms(t_start, t_end);
  return result;
}

Result<FeatureResult> DetectFeatures(const cv::Mat& image, const FeatureOptions& options,
                                     const std::optional<CameraModel>& camera) {
  IDI_ASSIGN_OR_RETURN(FeatureDetector detector, FeatureDetector::Create(options, camera));
  return detector.Detect(image);
}

}  // namespace idi
