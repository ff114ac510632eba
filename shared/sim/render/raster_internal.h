// Internals of the renderer (not an API): the scene prepared for one camera. Faces are cut into convex
// pieces and projected into undistorted ("ideal") pixel coordinates, where 1/z is an affine function
// of the position, so depth order between two planes changes along a straight line and visibility
// inside a pixel can be computed exactly by convex clipping.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "shared/camera/pinhole.h"
#include "shared/sim/render/render.h"
#include "shared/sim/render/scene.h"

namespace idi::sim::internal {

inline constexpr int kMaxPieceVerts = 12;
inline constexpr int kTileSize = 8;       // pixels per tile side
inline constexpr int kSuperTile = 8;      // tiles per super-tile side
inline constexpr double kDepthEps = 1e-9;  // relative: closer than this in 1/z counts as the same depth

// A convex polygon in ideal pixel coordinates with its edges as half-planes a x + b y + c >= 0
// (a^2 + b^2 = 1, inside positive) and its plane's inverse depth 1/z = w.x x + w.y y + w.z.
struct Piece {
  int n = 0;
  std::array<Vec2d, kMaxPieceVerts> v;
  std::array<Vec3d, kMaxPieceVerts> e;
  Vec3d w = Vec3d::Zero();
  int surface = -1;
  int layer = 0;
  int order = 0;  // tie-break between coplanar pieces of the same layer (higher wins)
  // Pieces of one group tile one surface without overlapping (a face cut into convex pieces, or a
  // cylinder's seen facets); their shared edges are seams (bit i of seam_mask: edge i), not edges.
  int group = -1;
  uint32_t seam_mask = 0;
  double xmin = 0, xmax = 0, ymin = 0, ymax = 0;

  double InvDepth(double x, double y) const { return w.x() * x + w.y() * y + w.z(); }
  double InvDepth(const Vec2d& p) const { return InvDepth(p.x(), p.y()); }
  // Smallest signed distance of p to the piece's edges (positive inside).
  double Inside(const Vec2d& p) const;
};

// A texture's constants, computed once per render.
struct TexturePlan {
  const Texture* texture = nullptr;
  int octaves = 0;
  std::array<double, 12> inv_wavelength{}, amplitude{};  // amplitude includes noise_amplitude / sum
  std::array<int64_t, 12> shift_x{}, shift_y{};
  double inv_tile = 0;
  int64_t tile_shift = 0;
};
TexturePlan MakeTexturePlan(const Texture& texture);

// Shading data of one visible face, in the camera frame.
struct Surface {
  Vec3d normal = Vec3d::UnitZ();  // unit, towards the camera side that sees the face
  double d = -1;                  // plane: normal . P = d (negative for a face that is seen)
  double inv_d = -1;              // 1 / d
  Vec3d albedo = Vec3d::Ones();
  const Texture* texture = nullptr;
  int texture_plan = -1;          // index into Prepared::texture_plans
  Vec3d tex_u = Vec3d::Zero(), tex_v = Vec3d::Zero();  // u = tex_u . P + tex_u0
  double tex_u0 = 0, tex_v0 = 0;
  bool cylinder = false;          // smooth normal of a cylinder around axis_point + t * axis_dir
  Vec3d axis_point = Vec3d::Zero(), axis_dir = Vec3d::UnitZ();
  double flat_irradiance = 0;     // ambient + directional for the face normal
  std::vector<int> spots;         // laser spots close enough to this plane to light it
  bool constant = false;          // uniform radiance (no texture, spotlight, gradient, curvature)
  Vec3d radiance = Vec3d::Zero(); // that radiance
  // Radiance varies smoothly over the face (no tiles with grout lines or per-tile steps, no
  // spotlight cone, not a cylinder): a covered tile may interpolate it (see shading_tolerance).
  bool smooth = false;
  int mesh = -1, face = -1;
};

// A solid after tessellation (cylinders become prisms whose silhouette generators are exact), with
// what ground truth needs: per-face visibility and which edges are smooth or curved.
struct Mesh {
  std::string name;
  std::vector<Vec3d> vertices_world;
  std::vector<Vec3d> vertices_cam;
  std::vector<std::vector<int>> faces;
  std::vector<const Material*> face_material;
  std::vector<int> face_surface;  // -1: not seen (back face, edge-on, or behind the camera)
  std::vector<Vec3d> face_normal_cam;
  bool closed = true;
  int layer = 0;
  int cylinder_side_faces = 0;    // for a cylinder: faces [0, n) are the smooth side, the rest caps
};

// Ideal coordinates of the pixel corners of a (possibly distorted) camera, including a margin of
// pixels around the image (the PSF reaches in from outside).
struct PixelGrid {
  int x0 = 0, y0 = 0;        // pixel index of the first raster column/row (negative inside the margin)
  int cols = 0, rows = 0;    // raster size in pixels
  bool distorted = false;
  std::vector<Vec2d> corners;  // (cols + 1) * (rows + 1), row-major; empty when not distorted
  std::vector<Vec2d> centers;  // cols * rows: the centroid of each pixel quad (distorted only)
  std::vector<double> footprints;  // cols * rows: sqrt of each pixel quad's area (distorted only)
  // Corner (i, j) is the top-left corner of raster pixel (i, j), i.e. at pixel (x0 + i - 0.5, y0 + j - 0.5).
  Vec2d Corner(int i, int j) const {
    if (!distorted) return Vec2d(x0 + i - 0.5, y0 + j - 0.5);
    return corners[static_cast<std::size_t>(j) * static_cast<std::size_t>(cols + 1) + static_cast<std::size_t>(i)];
  }
  // Centre (ideal) and footprint size of raster pixel (i, j).
  Vec2d Center(int i, int j) const {
    if (!distorted) return Vec2d(x0 + i, y0 + j);
    return centers[static_cast<std::size_t>(j) * static_cast<std::size_t>(cols) + static_cast<std::size_t>(i)];
  }
  double Footprint(int i, int j) const {
    if (!distorted) return 1.0;
    return footprints[static_cast<std::size_t>(j) * static_cast<std::size_t>(cols) + static_cast<std::size_t>(i)];
  }
};

// Cached per camera (thread-local, a few entries): undistorting every corner is the costly part.
std::shared_ptr<const PixelGrid> GetPixelGrid(const CameraModel& camera, int margin_px);

// Ideal pixel (undistorted, same K) of a distorted pixel, and back. Newton with the analytic Jacobian.
Vec2d IdealFromPixel(const CameraModel& camera, const Vec2d& pixel, const Vec2d* ideal_guess = nullptr);
Vec2d PixelFromIdeal(const CameraModel& camera, const Vec2d& ideal);

// A laser spot as the spot layer draws it. The PSF acts on the continuous image before the pixels
// integrate it, which matters for a spot about a pixel wide: a discrete blur after integration would
// keep the pixel-locking bias of its centroid. So with a PSF the spot layer is the spot's image (a
// Gaussian with the perspective image's exact centroid, covariance and flux, computed by quadrature
// over the surface) convolved analytically with the PSF, integrated over each pixel and added after
// the PSF has blurred everything else. Without a PSF the spot is drawn as emission on its surface.
struct PreparedSpot {
  Vec3d center = Vec3d::Zero();                       // camera frame
  double sigma = 1;                                   // on the surface
  double peak = 0;
  Vec3d color = Vec3d::Ones();
  double reach = 1;                                   // beyond this distance the emission is zero
  bool visible = false;                               // on a seen surface, centre not occluded
  // The perspective image of the spot (lens distortion included): centroid and covariance in pixels,
  // and its flux (radiance x pixel^2).
  Vec2d centroid_px = Vec2d::Zero();
  Eigen::Matrix2d cov_px = Eigen::Matrix2d::Identity();
  double flux = 0;
  // Image layer (PSF > 0): amplitude * exp(-0.5 d' inv_cov_layer d), d = pixel - centroid_px.
  bool image_layer = false;
  Eigen::Matrix2d inv_cov_layer = Eigen::Matrix2d::Identity();
  double amplitude = 0;
};

struct SpotBox {
  int x0, y0, x1, y1;  // raster pixel index range (inclusive) where the spot needs quadrature
  int samples;         // n: n x n Gauss-Legendre nodes per pixel (n x n exact sub-quads at edges)
  int spot = -1;       // index into Prepared::laser_spots
};

struct Prepared {
  CameraModel camera;
  Rigid3d cam_from_world;
  double fx = 1, fy = 1, cx = 0, cy = 0;
  double inv_fx = 1, inv_fy = 1;  // 1 / fx, 1 / fy (shading multiplies instead of dividing)
  double near_clip = 1e-3;
  std::vector<Mesh> meshes;
  std::vector<Surface> surfaces;
  std::vector<TexturePlan> texture_plans;
  std::vector<Piece> pieces;
  // Lighting in the camera frame.
  double ambient = 0;
  std::vector<Vec3d> light_dirs;  // unit, towards the light
  std::vector<double> light_intensity;
  std::vector<SpotLight> spotlights;  // position/direction in the camera frame; cone_half_angle_rad
                                      // holds the cone's cosine here
  IlluminationGradient gradient;      // in the camera frame
  bool has_gradient = false;
  // Laser spots in the camera frame, already convolved with the PSF (see PreparedSpot).
  std::vector<PreparedSpot> laser_spots;
  std::vector<SpotBox> spot_boxes;
  Vec3d background = Vec3d::Zero();
  // Largest error (radiance units) allowed where a tile covered by one smooth surface interpolates
  // its shading between exactly shaded nodes; 0 = shade every pixel (RenderOptions::shading_tolerance_dn).
  double shading_tolerance = 0;

  // Raster and tiles.
  std::shared_ptr<const PixelGrid> grid;
  int tiles_x = 0, tiles_y = 0;
  std::vector<int> tile_start;  // CSR: candidates of tile t are tile_items[tile_start[t] .. tile_start[t+1])
  std::vector<int> tile_items;
  std::vector<double> tile_radius;  // largest pixel-quad circumradius in the tile (ideal pixels)
  std::vector<std::array<double, 4>> tile_box;  // ideal bbox: xmin, ymin, xmax, ymax

  Vec3d Ray(double x, double y) const { return Vec3d((x - cx) / fx, (y - cy) / fy, 1.0); }
  Vec2d IdealFromCam(const Vec3d& p) const { return Vec2d(fx * p.x() / p.z() + cx, fy * p.y() / p.z() + cy); }
  // The tile holding an ideal point (via its distorted pixel); -1 outside the raster.
  int TileOfIdeal(const Vec2d& ideal) const;
};

// Builds everything above. `margin_px` extends the raster beyond the image on every side.
Result<Prepared> Prepare(const Scene& scene, const CameraModel& camera, const Rigid3d& cam_from_world,
                         const RenderOptions& options, int margin_px);

// +1 when a is in front of b at every point, -1 when behind at every point, 0 when the order changes
// among the points. Coplanar pieces are ordered by (layer, order).
int FrontOrder(const Piece& a, const Piece& b, const Vec2d* points, int count);

// Gauss-Legendre rule with m nodes (1..32) on [0, 1]: node i and its weight (weights sum to 1).
double GaussLegendreNode(int m, int i);
double GaussLegendreWeight(int m, int i);

// Radiance (linear RGB, relative) of a surface at an ideal pixel position; `footprint_px` is the size
// of the area being integrated (texture filter width). Laser spots are not included.
Vec3d Shade(const Prepared& prep, const Surface& surface, double x, double y, double footprint_px);
// Shade at n points of one surface: the same values, several points per instruction where the CPU
// and the surface allow (8 with AVX-512, 4 with AVX2; no cylinder, spotlight or tiles), one by one
// otherwise.
void ShadeBatch(const Prepared& prep,
                const Surface& surface,
                const double* x,
                const double* y,
                const double* footprint_px,
                int n,
                Vec3d* out);
// The same, as float Luma() of each radiance (what a gray raster stores).
void ShadeBatchLuma(const Prepared& prep,
                    const Surface& surface,
                    const double* x,
                    const double* y,
                    const double* footprint_px,
                    int n,
                    float* out);
// The finest detail of a surface's shading near an ideal pixel position: the shortest wavelength, in
// pixels, of the texture there (grout width, or the finest noise octave that is not faded out), leaving
// out the finest octaves that together change the radiance by at most `negligible` given the radiance
// there (infinity for an untextured surface).
double ShadingDetailPx(const Prepared& prep, const Surface& surface, double x, double y, double footprint_px,
                       double radiance, double negligible);
// The laser spots' emission (PSF included) at an ideal pixel position on a surface.
Vec3d SpotEmission(const Prepared& prep, const Surface& surface, double x, double y);

// Index of the front-most piece at an ideal point (-1: background), from the tile candidates.
int FrontPieceAt(const Prepared& prep, const Vec2d& ideal);

// Area-integrated radiance image of the raster (margin included): CV_32FC3 (RGB order) or CV_32FC1
// (luma) when !color, computed by `threads` threads (the same image for any number). `out` is
// (re)allocated only when its size or type differs.
void RasterizeRadiance(const Prepared& prep, bool color, int threads, cv::Mat* out);
// The spot layer over the same raster (zero away from spots); false when there is no spot to draw.
bool RasterizeSpots(const Prepared& prep, bool color, cv::Mat* out);

// Ground truth for a prepared scene (lines, junctions, spots, curves).
void ComputeGroundTruth(const Prepared& prep, const RenderOptions& options, GroundTruth* truth);

inline double Luma(const Vec3d& rgb) { return 0.299 * rgb.x() + 0.587 * rgb.y() + 0.114 * rgb.z(); }

}  // namespace idi::sim::internal
