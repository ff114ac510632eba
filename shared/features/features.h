// The vision front end (dissertation chapter 7): EMPL lines and IDI points from one grey image.
//
// Pipeline (FeatureDetector::Detect):
//   1. gradients by derivative of Gaussian and Canny edges (§7.5-7.6.4);
//   2. Hough transform in (r, theta) whose votes are restricted to the gradient direction (§7.7.1),
//      peaks taken strongest first, segments extracted along each peak with a gap tolerance;
//   3. EMPL refinement (§7.11, eqs. 7.26-7.30): sub-pixel edge points from the gradient profile of
//      the pixels in a band around the segment that pass an adaptive local threshold and agree with
//      the line's direction, weighted by gradient magnitude, fitted by minimising positional and
//      orientational error; then a photometric refinement of the same line on the raw pixels (a
//      blurred-step model, the estimator whose variance is the Cramér-Rao bound), which also gives
//      the line's covariance; confirmed segment ends kept apart from unconfirmed extensions (§8.8.2);
//      collinear pieces merged, kinked ones split;
//   4. IDI points (§7.10): intersections of pairs of lines near their segments, three or more lines
//      meeting near one place giving one point (§8.8.2 "non unique point"), with the topology and the
//      covariance propagated from the line fits;
//   5. curves (§7.9.1): active contours on the edges no line explains, and IDI points where a curve
//      meets a line.
//
// Conventions: pixel coordinates with integer values at pixel centres, x right, y down
// (shared/camera/pinhole.h). Lines are undirected: a line is the set of x with normal·x = offset,
// unit normal, angle = atan2(normal.y, normal.x) in [0, pi). When a camera with distortion is given,
// all geometry (lines, points, segment ends) is in undistorted pixel coordinates (same K).
#pragma once

#include <Eigen/Core>
#include <memory>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "shared/camera/pinhole.h"
#include "shared/util/status.h"

namespace idi {

// Derivative-of-Gaussian gradients and Canny edges (§7.5-7.6.4).
struct EdgeOptions {
  // Standard deviation of the Gaussian smoothing before differentiation (px).
  double smoothing_sigma_px = 1.0;
  // Hysteresis thresholds in multiples of the gradient noise estimated from the image (the median
  // gradient magnitude of a Rayleigh-distributed noise field), with absolute floors in grey levels
  // per pixel of an 8-bit image (scaled for 16-bit and float images).
  double low_threshold_sigmas = 2.5;
  double high_threshold_sigmas = 5.0;
  double min_low_threshold = 0.8;
  double min_high_threshold = 1.6;

  Status Check() const;
};

// Hough transform with gradient-restricted votes and segment extraction (§7.7.1).
struct HoughOptions {
  double angle_step_deg = 1.0;
  double offset_step_px = 1.0;
  // Each edge pixel votes only for angles within this window of its gradient direction (the
  // dissertation uses up to ±25°; the derivative-of-Gaussian direction is much better than that).
  double vote_window_deg = 4.0;
  // Segments along a peak: edge pixels within this distance of the peak line whose gradient agrees
  // to within max_angle_error_deg, gaps up to max_gap_px, at least min_length_px long.
  double band_px = 1.5;
  double max_angle_error_deg = 20.0;
  double max_gap_px = 6.0;
  double min_length_px = 15.0;
  // A run must have edge pixels on at least this fraction of its length.
  double min_fill = 0.6;
  int max_lines = 400;

  Status Check() const;
};

// EMPL refinement of one line (§7.11, eqs. 7.26-7.30) and its segment bookkeeping (§8.8.2).
struct EmplOptions {
  // Half width delta of the band around the line searched for edge evidence (px).
  double band_halfwidth_px = 3.0;
  // Across the band, the edge is the gradient profile's peak (direction within max_angle_error_deg)
  // with the largest strength x exp(-d^2 / 2 sigma^2), d its distance from the line: the peak nearest
  // the line unless a much stronger one is near too. A stronger edge 2-3 px away (a bracket's face
  // seen edge-on, a shallow junction) took the stations of a weaker one, which then stopped short of
  // its corner. On the object scenes (features_bench D, with the noise floor of EmplFitter::Fit) it
  // found 238 -> 241 of 261, 226 -> 227 of 255, 207 -> 208 of 234 and 221 -> 224 of 256 corners,
  // spurious points 4, 6 -> 7, 6, 1 -> 2; line offsets and sections A-C unchanged within noise.
  // 0 = the strongest peak in the band.
  double peak_proximity_sigma_px = 1.5;
  // Adaptive local threshold, eq. 7.29: a pixel counts when its gradient magnitude exceeds alpha
  // times the mean magnitude over +-epsilon px along the line and +-delta px across it. (A clean
  // step's peak is (2 delta + 1) / (sqrt(2 pi) sigma) times that mean: 1.9 for sigma 1.5.)
  double threshold_alpha = 0.75;
  double threshold_window_px = 10.0;
  // The local level of eq. 7.29 is the mean of the stations' band means within +-epsilon, lowered to
  // their median where that is lower, but not below half the mean. Where a weak edge runs on from a
  // strong collinear one (a plate's end continued by the faint edge between two faces below it), the
  // strong stretch raised the mean for epsilon px into the weak edge, whose segment then stopped that
  // far short of its junction (EmplTest.AWeakEdgeRunningOnFromAStrongOneReachesTheJunction). On the
  // twin's object scenes (features_bench D, with max_fit_rms_px) it found 245 -> 246 of 261, 228 -> 233
  // of 255, 208 -> 209 of 234 and 225 of 256 corners, spurious points 4 -> 6, 7 -> 6, 6 -> 7 and 3; the
  // long lines' offsets unchanged. Sections A and B moved by at most 0.01 in RMS / bound, C not at all.
  // Only stations between alpha x half the mean and alpha x the mean need the median: no measurable time.
  bool threshold_median = true;
  // T_theta of eq. 7.26: largest angle between a pixel's gradient and the line normal (deg).
  double max_angle_error_deg = 20.0;
  int max_iterations = 4;
  // Edge points further than this many robust sigmas from the fit are dropped (outliers).
  double outlier_sigmas = 3.5;
  // A line whose edge points scatter about its fit by more than this RMS (px) is not one edge but noise
  // peaks or pieces of several (peaks spread evenly over the +-3 px band have an RMS of 1.7 px): with the
  // median threshold such a "line", 60 px long with an RMS of 3.1 px, made two spurious points on an
  // object scene. On features_bench D the limit removed 2, 1, 0 and 0 spurious points, no corner, and the
  // sigma_b 2 row's point RMS went 0.461 -> 0.450 px. 0 = no limit.
  double max_fit_rms_px = 1.0;
  // Photometric refinement: a blurred step with its own contrast/background per chunk of the line
  // (so alternating contrast along a chessboard line is fine) fitted to the raw pixels.
  bool photometric_refinement = true;
  double chunk_length_px = 24.0;
  // The photometric band goes on over the flat image beside the edge (up to 2 half-widths + 2 px each
  // side, stopping short of any gradient above Canny's low threshold): the chunk's background and
  // contrast are then fixed by pixels the edge does not move, and on clean edges of 40 px and more the
  // offset's error falls from 1.2-2.1 to 0.9-1.9 times the Cramer-Rao bound (features_bench section A),
  // IDI points' from 1.3-2.1 to 1.1-1.8 (section B). On textured faces the flat image is not flat:
  // flat_band_max_texture_ratio leaves such a side's flat band out. Off by default because it costs
  // time where lines are long: the photometric stage took 18.4 instead of 10.1 ms on the 9 x 7
  // chessboard (5.0 instead of 4.9 ms on an object scene; section E).
  bool photometric_flat_band = false;
  // With the flat band, each side of a line keeps it only where the variation of the smoothed gradient
  // there has at most this many times the energy the noise alone would give (the noise taken from the
  // high-pass energy of the same pixels, which smooth texture and the blur tails of other edges hardly
  // raise; a uniform slope is the ramp's, not texture). Without the test, texture dragged the lines:
  // on the twin's textured object scenes (features_bench D, flat band and ramp) the line offsets'
  // median / 90th percentile were 0.0235 / 0.091 px at sigma_b 1 and 0.047 / 0.226 px at sigma_b 2;
  // with it 0.0155 / 0.070 and 0.026 / 0.161 px, as without the flat band (0.0136 / 0.070 and
  // 0.026 / 0.153 px; EmplTest.FlatBandLeavesOutATexturedSide). The test also drops some sides by
  // chance: section A at 40 px and more moved by at most 0.06 x the bound except at contrast 20 and
  // sigma_b 2, 40 px (1.49 -> 1.86) and 80 px (1.35 -> 1.44). 0 = no test.
  double flat_band_max_texture_ratio = 1.3;
  // Each chunk's background may slope across the edge: a third linear parameter per chunk, times the
  // distance from the starting line. Odd about the edge, so it costs the offset almost no information
  // (section A). With the flat band, a shaded face beside an edge biases the offset wherever the band is
  // lopsided (cut short on one side by another edge): +0.04 px at 1 grey level per px, and none with the
  // ramp (EmplTest.PhotometricRampKeepsAnEdgeOnAShadedFaceUnbiased). Off by default with the flat band.
  bool photometric_ramp = false;
  // The photometric window (+-half, the flat band aside) of a station stops short of an edge of the
  // opposite sign inside it: two pixels in a row whose gradient along the normal passes Canny's low
  // threshold against the station's own sign, less ceil(sigma) + 1 px for that edge's blur, but at
  // least ceil(sigma) px. Without it the far side of a thin face seen edge-on (a bracket's plate) entered
  // the one-step model and pulled both edges towards the middle (0.49 px for a 5 px strip at sigma_b 1.5,
  // 0.09 px with it: EmplTest.ThinStripKeepsItsTwoEdgesApart), and a shallow wedge's point moved out
  // of the wedge (0.075 px at 24 deg, 0.005 px with it: DetectorTest.ShallowCornerIsNotPulledOutOfTheWedge).
  // On the twin's object scenes (features_bench D) it found 241 -> 245 of 261, 227 -> 228 of 255, 208
  // of 234 and 224 -> 225 of 256 corners (spurious 4, 7, 6, 2 -> 3); the long lines' offset error
  // (median / 90th percentile) went 0.0169 / 0.0416 -> 0.0147 / 0.0378 px, 0.0136 / 0.0701 -> 0.0135 /
  // 0.0638 and 0.0261 / 0.1530 -> 0.0231 / 0.1443. Sections A and B moved by at most 0.04 in RMS / bound.
  bool photometric_stop_at_other_edge = true;
  // Stations within this distance of a confirmed end are left out of the photometric fit (corners).
  double end_margin_px = 2.0;
  // Collinear pieces are merged when the angle differs by less than merge_angle_deg (or 4 sigma),
  // each end lies within merge_offset_px of the other line, and the gap is below the Hough gap.
  double merge_angle_deg = 1.0;
  double merge_offset_px = 1.0;
  // A line is split where a two-piece fit changes the direction by more than split_angle_deg and
  // explains the points significantly better (a false merge of two edges that nearly line up).
  double split_angle_deg = 1.5;
  // A segment whose edge points bend with a radius below curve_max_radius_px and a sagitta above
  // curve_min_sagitta_px (and 5 sigma) is a curve, not a line: it is left to the active contours. A run
  // long enough to be split in two (2 x HoughOptions::min_length_px points) is first tested as a kink
  // (two lines fitting at least as well as the quadratic), and split. A shorter run cannot be split and
  // is a curve above curve_min_sagitta_short_px. On the twin's object scenes 1.5 px instead of 0.6 for
  // long runs found 5 more of 196 corners and 6 fewer spurious points (with the kink test): the last
  // pixels of a straight edge before a junction are pulled towards the other edge.
  double curve_max_radius_px = 250.0;
  double curve_min_sagitta_px = 1.5;
  double curve_min_sagitta_short_px = 0.6;
  // The curve test is repeated without the points this close to the run's ends, and a run is a curve
  // only when both tests say so: a straight edge between two junctions bends at both ends, and a short
  // run (too short to split) was taken for an arc and dropped. On the twin's object scenes (features_bench
  // section D) 3 px found 235 -> 236 of 261 corners without clutter, 222 -> 226 of 255 with it, 202 -> 207
  // of 234 with distortion, 218 -> 221 of 256 at sigma_b 2; spurious points 2 -> 4 of 261 without
  // clutter and 5 -> 6 with distortion, the same elsewhere. 0 = test the whole run only.
  double curve_end_trim_px = 3.0;
  // Unconfirmed extension beyond each confirmed end (§8.8.2): fraction of the length, clamped.
  double extension_fraction = 0.1;
  // 5 px rather than 4: a segment that stops 4.1 px short of its corner (the last stations fail the
  // threshold) missed it. On the object scenes 4 -> 5 px found 231 -> 236 of 261, 222 -> 226 of 255 and
  // 207 -> 207 of 234 corners at sigma_b 1, with the same spurious points (4, 6, 6).
  double min_extension_px = 5.0;
  // ... and at least this many times the edge's blur (the photometric fit's, else the gradient
  // profile's): where an edge ends at a junction its last stations fail the threshold over a few blur
  // widths. On the twin's cluttered object scenes at sigma_b 2 (features_bench D) it found 221 instead of
  // 213 of 256 corners, spurious points 1 either way; at sigma_b 1 (blur ~1.04 px, so min_extension_px
  // rules) nothing changes.
  double min_extension_blur_sigmas = 3.0;
  double max_extension_px = 25.0;
  // Two lines that form a wedge (both run away from their intersection on the same side) at less than
  // this angle, and more than IdiOptions::min_angle_deg, are refitted without the stations where the
  // other line's edge is within reach of their band (3 px plus four blur sigmas): near a shallow apex the
  // two blurred edges overlap and pull both fits apart, which moves the IDI point out of the wedge
  // (0.075 px at 24 deg and A/sigma_n = 30; more at lower angles and contrast). Off (0) by default: at
  // 40 deg it changed the vehicle's view of a tape corner enough to lose the track there
  // (ClosedLoopTest.TurnsAnAcuteCornerOnTheSpot), which is not understood yet.
  double junction_refit_angle_deg = 0.0;

  Status Check() const;
};

// IDI points (§7.10, §8.8.2).
struct IdiOptions {
  // Lines meeting at less than this angle do not make a point (their intersection is ill-posed).
  double min_angle_deg = 10.0;
  // Intersections closer than this (px) are one point made by all their lines.
  double merge_radius_px = 2.5;
  // Margin outside the image within which a point is still kept (px).
  double image_margin_px = 2.0;
  // A line takes part only in the first point beyond each end of its confirmed segment (and in any
  // along the segment): its extension bridges the blur where its edge ends, not the way to a corner
  // beyond that one.
  bool first_point_beyond_end = true;
  // A point whose position standard deviation, sqrt(trace) of the covariance its lines' (or curve's)
  // fits give it, exceeds this (px) is not reported: its lines are too weak or too short to place it,
  // and on the twin's object scenes such points are mostly where faint texture or noise lines cross:
  // with it, features_bench D's spurious points went 6, 6, 7, 3 -> 3, 2, 3, 2 and its corners found
  // 913 -> 911 of 1006 (the two lost: 13 DN edges, and a 16 px line), on one noise draw (draw 0 of
  // --draws; over 3 draws the spurious points are 16, 10, 9 and 12). Sections B and C are unchanged.
  // 0 keeps all.
  double max_point_sigma_px = 1.0;
  // An intersection beyond a line's unconfirmed extension, but no more than this (px) beyond its
  // confirmed segment, still counts when the image between the segment's end and the intersection
  // carries the line's edge (see EdgeContinues): near a junction with a stronger edge the adaptive
  // threshold stops a faint edge's segment short although its gradient goes on. 0 = extensions only.
  double max_gap_px = 15.0;
  // ... the edge carried there: in every stretch of the gap, the gradient along the line's normal, with
  // its direction within 30 deg of it, is at least this fraction of its strength along the segment's end.
  double gap_min_strength = 0.9;
  // ... and only for lines of at most this contrast (8-bit grey levels): a strong edge's segment ends
  // where its edge does.
  double gap_max_contrast = 30.0;

  Status Check() const;
};

// Active contours (§7.9.1) on edge chains that no line explains.
struct CurveOptions {
  bool enabled = true;
  double min_length_px = 30.0;
  double point_spacing_px = 4.0;
  // Energy weights of the greedy snake: continuity, curvature, image (gradient magnitude).
  double alpha = 0.5;
  double beta = 0.5;
  double gamma = 1.0;
  int max_iterations = 30;
  // A chain fitted by one line to within this RMS (px) is straight, not a curve.
  double straight_rms_px = 0.6;

  Status Check() const;
};

struct FeatureOptions {
  EdgeOptions edges;
  HoughOptions hough;
  EmplOptions empl;
  IdiOptions idi;
  CurveOptions curves;

  Status Check() const;
};

// An EMPL line: the fitted line, its confirmed segment and unconfirmed extensions.
struct EmplLine {
  int id = -1;
  Eigen::Vector2d normal = Eigen::Vector2d::UnitY();  // unit, angle in [0, pi)
  double offset = 0;                                  // normal·x = offset (px)
  Eigen::Vector2d p1 = Eigen::Vector2d::Zero();       // confirmed segment ends on the line
  Eigen::Vector2d p2 = Eigen::Vector2d::Zero();
  Eigen::Vector2d extension1 = Eigen::Vector2d::Zero();  // end of the unconfirmed extension beyond p1
  Eigen::Vector2d extension2 = Eigen::Vector2d::Zero();  // ... and beyond p2
  double length_px = 0;                                  // |p2 - p1|
  double fit_rms_px = 0;                                 // RMS distance of the edge points from the line
  // Covariance of (angle_rad, offset_px) from the fit.
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Zero();
  double contrast = 0;           // mean |step| across the edge (grey levels)
  double blur_sigma_px = 0;      // fitted edge width (PSF and pixel integration), 0 if not fitted
  bool alternating = false;      // the contrast changes sign along the line (chessboard)
  int support = 0;               // edge points used
  std::vector<int> point_ids;    // IDI points on this line, ordered along p1 -> p2

  double Angle() const;                       // atan2(normal.y, normal.x)
  Eigen::Vector2d Direction() const;          // unit, from p1 towards p2
  double SignedDistance(const Eigen::Vector2d& x) const { return normal.dot(x) - offset; }
};

// A curve found by an active contour: a polyline through the edge.
struct Curve {
  int id = -1;
  std::vector<Eigen::Vector2d> points;
  double fit_rms_px = 0;
  std::vector<int> point_ids;
};

enum class IdiPointKind { kLines, kCurveLine };

// An IDI point: the intersection of two or more EMPL lines (or of a curve and a line).
struct IdiPoint {
  int id = -1;
  Eigen::Vector2d xy = Eigen::Vector2d::Zero();
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Zero();  // px^2
  std::vector<int> line_ids;   // sorted
  std::vector<int> curve_ids;  // for kCurveLine
  IdiPointKind kind = IdiPointKind::kLines;
};

struct FeatureTimings {
  double gradient_ms = 0, edges_ms = 0, hough_ms = 0, empl_ms = 0, points_ms = 0, curves_ms = 0, total_ms = 0;
};

struct FeatureResult {
  int width = 0;
  int height = 0;
  double noise_sigma = 0;  // estimated image noise (grey levels)
  int edge_pixels = 0;
  std::vector<EmplLine> lines;
  std::vector<IdiPoint> points;
  std::vector<Curve> curves;
  FeatureTimings timing;
};

// Detects EMPL lines and IDI points. Keeps its buffers between calls, so reuse one detector per
// camera stream. Not thread safe; use one per thread.
class FeatureDetector {
 public:
  // InvalidArgument when the options fail Check(). With a camera that has distortion, geometry is
  // fitted in undistorted pixel coordinates; the camera's width/height must match the images.
  static Result<FeatureDetector> Create(const FeatureOptions& options,
                                        const std::optional<CameraModel>& camera = std::nullopt);
  FeatureDetector(FeatureDetector&&) noexcept;
  FeatureDetector& operator=(FeatureDetector&&) noexcept;
  ~FeatureDetector();

  // Accepts single-channel 8-bit, 16-bit or float images of at least 16 x 16 px. Colour, empty or
  // smaller images give InvalidArgument naming what was wrong; an image without lines gives an
  // empty result.
  Result<FeatureResult> Detect(const cv::Mat& image);

  const FeatureOptions& options() const;

 private:
  struct Impl;
  explicit FeatureDetector(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

// One-shot convenience: creates a detector and runs it once.
Result<FeatureResult> DetectFeatures(const cv::Mat& image, const FeatureOptions& options = {},
                                     const std::optional<CameraModel>& camera = std::nullopt);

// The covariance of the intersection of two lines, each given with the covariance of its
// (angle, offset); nullopt when they are parallel. Used for IDI points and by reconstruction.
struct LineIntersection {
  Eigen::Vector2d xy;
  Eigen::Matrix2d covariance;
};
std::optional<LineIntersection> IntersectWithCovariance(const EmplLine& a, const EmplLine& b);

// Cramér-Rao bounds for a straight blurred step edge of contrast A (grey levels) with Gaussian PSF
// sigma_b and white noise sigma_n, fitted over L px (the formula, sigma_e^2 = sigma_b^2 + 1/12):
// offset at the segment centre and angle (rad).
double OffsetBoundPx(double contrast, double noise_sigma, double blur_sigma_px, double length_px);
double AngleBoundRad(double contrast, double noise_sigma, double blur_sigma_px, double length_px);

}  // namespace idi
