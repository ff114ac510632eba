// EMPL lines (§7.11, eqs. 7.26-7.30): precise location of one line from the image around a rough
// segment, with confirmed segment ends and unconfirmed extensions (§8.8.2).
#pragma once

#include <limits>
#include <optional>
#include <vector>

#include "shared/features/features.h"
#include "shared/features/gradient.h"
#include "shared/features/hough.h"
#include "shared/features/pixel_geometry.h"

namespace idi {

// A request to fit one line: a rough line and the stretch [t0, t1] along it where edge evidence is
// expected; the confirmed segment may grow beyond it but never past [t_limit_lo, t_limit_hi].
struct EmplRequest {
  HoughSegment segment;
  double t_limit_lo = -std::numeric_limits<double>::infinity();
  double t_limit_hi = std::numeric_limits<double>::infinity();
  int split_depth = 0;
  // Edges of other lines (segments in fit coordinates) the fit keeps clear of: a station within
  // avoid_clearance_px of one still confirms the extent but is left out of the fit. A shallow
  // junction's other edge runs inside this edge's band, and its blur pulls this edge's profile, over
  // many pixels from the junction.
  std::vector<std::pair<Vec2d, Vec2d>> avoid;
  double avoid_clearance_px = 0;
};

// The result of one fit: the line (id unset) and its extent along LineDirection(normal) from the
// foot normal*offset.
struct EmplFitResult {
  EmplLine line;
  double t0 = 0, t1 = 0;
  bool photometric = false;  // the photometric refinement converged and was used
};

// A pixel of the photometric fit: position relative to the line's centre (fit coordinates), value,
// chunk and weight (0 once rejected as an outlier).
struct EmplPixel {
  float ux, uy, value;
  int chunk;
  float weight;
};

class EmplFitter {
 public:
  // `scratch` is kept by the caller between lines and frames (no reallocation per line).
  EmplFitter(const GradientImages& g, const PixelGeometry& geometry, const EdgeMap& edges,
             const FeatureOptions& options, std::vector<EmplPixel>* scratch);

  // Fits the line near `request`; returns no line when there is not enough edge evidence, two when
  // the segment turned out to be two edges that nearly line up (a false merge, §8.8.2).
  std::vector<EmplFitResult> Fit(const EmplRequest& request) const;

 private:
  struct Station;
  void Scan(const Vec2d& normal, double offset, double t_lo, double t_hi, std::vector<Station>* out) const;
  bool PhotometricRefine(const std::vector<Station>& stations, std::size_t begin, std::size_t end, double t0,
                         double t1, const Vec2d& centre, double sigma_init, double* theta, double* e,
                         EmplFitResult* result) const;

  const GradientImages& g_;
  const PixelGeometry& geometry_;
  const EdgeMap& edges_;
  const FeatureOptions& options_;
  std::vector<EmplPixel>* scratch_;
  double cos_tol_;
  double noise_gain_;  // GradientNoiseGain of the smoothing: gradient noise per unit image noise
  double proximity_;  // 1 / peak_proximity_sigma_px^2, 0 for the strongest peak
};

// Unconfirmed extension length for a confirmed segment of `length_px` (§8.8.2) of an edge blurred by
// `blur_sigma_px` (EmplLine::blur_sigma_px; 0 when unknown).
double ExtensionLength(const EmplOptions& options, double length_px, double blur_sigma_px = 0);

// Fills the line's normal/offset/ends from (theta, e) about a centre, with its confirmed ends (line.p1,
// line.p2) projected onto it and its extensions for an edge of blur `blur_sigma_px`; the angle is
// normalised to [0, pi) and the covariance of (theta, e) is carried to (angle, offset).
void SetLineGeometry(double theta,
                     double e,
                     const Vec2d& centre,
                     const Eigen::Matrix2d& cov_theta_e,
                     double blur_sigma_px,
                     const EmplOptions& options,
                     EmplFitResult* result);

}  // namespace idi
