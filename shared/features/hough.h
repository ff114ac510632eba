// Hough transform in (r, theta) with votes restricted by the gradient direction (§7.7.1, the
// O'Gorman-Clowes variant), peaks taken strongest first, segments extracted along each peak.
#pragma once

#include <opencv2/core.hpp>
#include <vector>

#include "shared/features/gradient.h"
#include "shared/features/pixel_geometry.h"

namespace idi {

// A straight segment in fit coordinates: normal·x = offset, extending over [t0, t1] along
// Direction() = (-normal.y, normal.x) measured from the foot normal*offset.
struct HoughSegment {
  Vec2d normal = Vec2d::UnitY();
  double offset = 0;
  double t0 = 0, t1 = 0;
  int support = 0;  // edge pixels on the segment
};

inline Vec2d LineDirection(const Vec2d& normal) { return Vec2d(-normal.y(), normal.x()); }

class HoughLineFinder {
 public:
  // Finds segments; the edge pixels a segment claims are marked 2 in `edges->mask` and their
  // votes withdrawn, so the next peak cannot take them again (this is the non-maximum suppression
  // between overlapping peaks).
  std::vector<HoughSegment> Find(const GradientImages& g, EdgeMap* edges, const PixelGeometry& geometry,
                                 const HoughOptions& options);

 private:
  struct Hit {
    double t;
    int index;  // edge pixel index
  };
  void Vote(int index, int delta);
  void Walk(const GradientImages& g, const EdgeMap& edges, const PixelGeometry& geometry, const Vec2d& normal,
            double offset, double t_min, double t_max, std::vector<Hit>* hits);

  HoughOptions options_;
  int n_theta_ = 0, n_r_ = 0, window_bins_ = 0;
  double r_max_ = 0;
  Vec2d centre_ = Vec2d::Zero();
  std::vector<float> cos_, sin_;
  std::vector<std::uint16_t> acc_;
  // Per edge pixel: centred fit coordinates and gradient angle bin.
  std::vector<float> ex_, ey_;
  std::vector<int> bin_;
  cv::Mat index_;  // CV_32S: edge index of each pixel, -1 elsewhere
  cv::Mat visit_;  // CV_32S: last walk that looked at the pixel (walks of distorted lines only; made by the first)
  // Which 8 x 8 blocks of the image hold an edge pixel: a walk steps over the stretches of its line
  // whose band crosses only empty blocks.
  static constexpr int kBlockShift = 3;
  std::vector<std::uint8_t> blocks_;
  int block_cols_ = 0, block_rows_ = 0;
  bool AnyEdgeBlock(int x0, int y0, int x1, int y1) const;
  int walk_id_ = 0;
  double cos_tol_ = 0;
};

// Total least squares line through points (weights optional): returns normal and offset; false if
// degenerate.
bool FitLineTls(const std::vector<Vec2d>& points, const std::vector<double>* weights, Vec2d* normal, double* offset);

}  // namespace idi
