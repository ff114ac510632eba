// The digital twin's camera: renders a Scene (scene.h) through the true camera model into the 8-bit
// image a real camera would deliver, and reports the ground truth of what it drew.
//
// Image formation, in order (each step physically motivated, none of them approximated by resampling):
//  1. Exact area integration. Every face is projected into undistorted ("ideal") pixel coordinates,
//     where straight 3D edges stay straight; each pixel's footprint is the quadrilateral its four
//     corners undistort to (the unit square when the lens has no distortion). The visible part of
//     every face inside that footprint is computed exactly by convex clipping against the faces in
//     front of it (depth order may change inside a pixel, e.g. where a box stands on a table), so edge
//     coverage is exact rather than supersampled, and lens distortion bends edges without adding blur.
//     Shading is integrated per visible piece (its centroid; textures are box-filtered over the pixel
//     footprint) and by n x n quadrature near laser spots. Away from edges (more than a tile), smooth
//     shading may be interpolated between exactly shaded pixels 2 px apart, within
//     RenderOptions::shading_tolerance_dn when that is above its default 0.
//  2. Vignetting (irradiance falls off towards the corners), exposure (radiance 1 -> exposure_dn).
//  3. Gaussian point spread function, sigma = psf_sigma_px (a symmetric kernel: it moves no edge).
//  4. Sensor: photon shot noise (Poisson in electrons, gain in DN per electron), Gaussian read noise,
//     black level, rounding to 8 bits with clipping at 0 and 255.
// Gray output is CV_8UC1 (luma of the RGB radiance), colour output CV_8UC3 in OpenCV's BGR order.
//
// Ground truth (GroundTruth) is for tests and reports only; algorithms never see it.
#pragma once

#include <opencv2/core.hpp>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "shared/camera/pinhole.h"
#include "shared/geometry/rigid3.h"
#include "shared/sim/render/scene.h"
#include "shared/util/status.h"

namespace idi::sim {

struct SensorOptions {
  bool noise = true;                  // false: noise-free (still quantized and clipped)
  double gain_dn_per_electron = 0.1;  // shot noise variance = gain * signal (DN^2); 0 = no shot noise
  double read_noise_dn = 0.8;         // Gaussian read noise, standard deviation in DN
  double black_level_dn = 0;          // offset added to every pixel
  Status Check() const;
};

struct RenderOptions {
  double exposure_dn = 200;    // pixel value of radiance 1 (a white surface under unit irradiance)
  double psf_sigma_px = 1.0;   // Gaussian point spread function; 0 = none
  double vignetting = 0;       // relative irradiance loss at the image corners, in [0, 1)
  bool color = false;          // CV_8UC3 (BGR) instead of CV_8UC1
  SensorOptions sensor;
  uint64_t seed = 0;           // noise seed: the same seed gives the same image
  double near_clip = 1e-3;     // scene length units; geometry closer to the camera plane is cut off
  // Ground truth: an edge counts as visible where its two sides differ by at least this much.
  double truth_min_contrast_dn = 1.0;
  // Shading of a tile (8 x 8 pixels) covered by one smoothly shaded surface (value-noise texture,
  // directional light, illumination gradient) is interpolated bilinearly between exactly shaded
  // nodes 2-4 pixels apart when the estimated interpolation error (from the nodes themselves, and only
  // where every texture octave spans at least two node spacings) stays below this many DN. Edges,
  // tiles, grout lines, spotlights and cylinders are always shaded per pixel. 0 (the default) = every
  // pixel exactly: with AVX2 or AVX-512 the exact shading of a covered tile is as fast as the
  // interpolation (it shades 4 or 8 pixels per instruction), so a tolerance pays off only on CPUs
  // without them.
  double shading_tolerance_dn = 0;
  // Threads integrating the pixels (the image is the same for any number); 0 = one per core, at most 4.
  int threads = 0;
  Status Check() const;
};

// A visible piece of a straight 3D edge (a crease or boundary of a solid, a tape edge, or the contour
// of a cylinder).
struct TruthLine {
  int id = 0;
  std::string object;              // solid or cylinder name
  std::string kind;                // "edge" or "silhouette" (view-dependent contour of a cylinder)
  int v1 = -1, v2 = -1;            // the edge's vertex indices in the object's mesh (-1 for silhouettes)
  Vec3d p1_world, p2_world;        // visible part, world frame
  Vec2d p1_px, p2_px;              // its ends in the (distorted) image
  // The projected line in undistorted pixel coordinates (the camera's K without distortion):
  // normal . x = offset, |normal| = 1. Equals the image line when the lens has no distortion.
  Vec2d normal = Vec2d::Zero();
  double offset = 0;
  double contrast_dn = 0;          // radiance step across the edge (noise-free), in DN
  double length_px = 0;
};

// A corner or junction: a projected 3D vertex where visible edges meet (L, Y, arrow, multi,
// tangent where a contour meets a rim), or a T/L junction where an edge disappears behind an
// occluding edge (not a 3D point of either edge's object).
struct TruthJunction {
  int id = 0;
  std::string type;                // "L", "Y", "arrow", "multi", "tangent", "T", "occlusion_L"
  bool is_vertex = true;           // a projected 3D vertex (true) or an occlusion junction (false)
  std::string object;
  int vertex = -1;
  Vec3d point_world = Vec3d::Zero();  // the vertex, or the point on the occluded edge
  Vec2d xy_px = Vec2d::Zero();
  std::vector<int> lines;          // TruthLine ids meeting here
};

struct TruthSpot {
  Vec3d center_world = Vec3d::Zero();
  Vec2d xy_px = Vec2d::Zero();     // projection of the spot centre
  // Centroid of the spot's image: differs from xy_px by the perspective of a tilted surface (e.g.
  // 0.003 px for a 1 px spot on a wall at 50 deg), which a centroid measurement cannot remove.
  Vec2d centroid_px = Vec2d::Zero();
  bool visible = false;            // in the image and not occluded
  double sigma_px = 0;             // approximate image size
};

struct TruthCurve {
  std::string object;
  std::string kind;                // "rim" (a cylinder's circular edge)
  std::vector<Vec2d> points_px;    // visible run, sampled about every 2 px
};

struct GroundTruth {
  int width = 0, height = 0;
  CameraModel camera;
  Rigid3d cam_from_world;
  std::vector<TruthLine> lines;
  std::vector<TruthJunction> junctions;
  std::vector<TruthSpot> spots;
  std::vector<TruthCurve> curves;
};

// Renders one frame: CV_8UC1 or CV_8UC3. Fills `truth` when it is not null. InvalidArgument when the
// scene, camera or options are invalid.
Result<cv::Mat> RenderScene(const Scene& scene, const CameraModel& camera, const Rigid3d& cam_from_world,
                            const RenderOptions& options, GroundTruth* truth = nullptr);

// The same image before the sensor (noise, black level, quantization): CV_32FC1 or CV_32FC3 in DN,
// i.e. after area integration, vignetting, exposure and PSF. For accuracy tests and studies.
Result<cv::Mat> RenderIrradiance(const Scene& scene, const CameraModel& camera, const Rigid3d& cam_from_world,
                                 const RenderOptions& options, GroundTruth* truth = nullptr);

// The sensor alone: irradiance in DN (CV_32FC1 or CV_32FC3) to CV_8UC1/CV_8UC3 with shot and read
// noise, black level, rounding and clipping. Deterministic for a given seed.
cv::Mat ApplySensor(const cv::Mat& irradiance_dn, const SensorOptions& sensor, uint64_t seed);

// Gaussian PSF on a float image in place (separable, normalised, reflecting borders); sigma 0 = none.
void ApplyPsf(cv::Mat* image, double sigma_px);

struct RayHit {
  double distance = 0;             // along the unit direction
  Vec3d point = Vec3d::Zero();
  Vec3d normal = Vec3d::Zero();    // unit, facing the ray's origin
  std::string object;
};
// First surface a ray meets (world frame), e.g. where a laser beam hits the wall; nullopt if none.
// Back faces of closed solids count too, so a ray starting inside a solid hits it from inside.
std::optional<RayHit> CastRay(const Scene& scene, const Vec3d& origin, const Vec3d& direction);

// Ground truth as one JSON object (see truth_json.cc for the layout).
std::string GroundTruthToJson(const GroundTruth& truth);

}  // namespace idi::sim
