// Closed-form test images for the features unit tests: a straight step edge and axis-aligned
// corners/chessboards, each blurred by a Gaussian PSF and integrated over the pixel area exactly.
// These are formulas, not a renderer: scene-level images come from the digital twin (shared/sim).
#pragma once

#include <cmath>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "shared/geometry/rigid3.h"

namespace idi::analytic {

inline double Phi(double z) { return 0.5 * std::erfc(-z / std::sqrt(2.0)); }
inline double PhiPdf(double z) { return std::exp(-0.5 * z * z) / std::sqrt(2.0 * 3.14159265358979323846); }

// First and second antiderivatives of the blurred unit step Phi(u / s).
inline double Psi1(double u, double s) { return u * Phi(u / s) + s * PhiPdf(u / s); }
inline double Psi2(double u, double s) { return 0.5 * (u * u + s * s) * Phi(u / s) + 0.5 * u * s * PhiPdf(u / s); }

// Mean over a pixel of the blurred unit step Phi((n·x - d) / s) (blur s > 0), pixel centred at c:
// the square projects onto the normal as the convolution of boxes of widths |nx| and |ny|.
inline double PixelStep(const Vec2d& n, double d, const Vec2d& c, double s) {
  const double u = n.dot(c) - d;
  const double a = std::fabs(n.x()), b = std::fabs(n.y());
  const double lo = std::min(a, b), hi = std::max(a, b);
  if (lo < 1e-6) {
    return (Psi1(u + 0.5 * hi, s) - Psi1(u - 0.5 * hi, s)) / hi;
  }
  const double h1 = 0.5 * (hi + lo), h0 = 0.5 * (hi - lo);
  return (Psi2(u + h1, s) - Psi2(u + h0, s) - Psi2(u - h0, s) + Psi2(u - h1, s)) / (lo * hi);
}

// Mean over pixel [x-0.5, x+0.5] of the 1D blurred step at x0 (rising).
inline double PixelStep1(double x, double x0, double s) { return Psi1(x + 0.5 - x0, s) - Psi1(x - 0.5 - x0, s); }

// Image of a straight edge: background + contrast * step across normal·x = offset (CV_32F).
inline cv::Mat EdgeImage(int w, int h, const Vec2d& normal, double offset, double background, double contrast,
                         double blur) {
  cv::Mat img(h, w, CV_32F);
  const double s = std::max(blur, 1e-3);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      img.at<float>(y, x) = static_cast<float>(background + contrast * PixelStep(normal, offset, Vec2d(x, y), s));
    }
  }
  return img;
}

// Axis-aligned chessboard (or a single X-junction for squares = 1): squares of `pitch` px starting
// at (x0, y0), `nx` x `ny` squares; outside the board the image is `background`. Exact separable
// blur and area integration: inside, the white indicator is (1 + Sx(x) Sy(y)) / 2 with Sx, Sy square
// waves; every factor is blurred in 1D.
inline cv::Mat ChessboardImage(int w, int h, double x0, double y0, double pitch, int nx, int ny, double dark,
                               double bright, double background, double blur) {
  cv::Mat img(h, w, CV_32F);
  const double s = std::max(blur, 1e-3);
  auto wave = [&](double x, double start, int n) {
    // Sum of alternating steps: +1 on even squares, -1 on odd, 0 outside; and the board mask.
    double v = 0;
    for (int k = 0; k <= n; ++k) {
      const double edge = start + k * pitch;
      const double step = PixelStep1(x, edge, s);
      // +1 up onto square 0, 2(-1)^k between squares, (-1)^n back to 0 after the last one.
      const double sign_k = (k % 2) ? -1.0 : 1.0;
      const double coef = k == 0 ? 1.0 : (k == n ? sign_k : 2.0 * sign_k);
      v += coef * step;
    }
    return v;
  };
  auto inside = [&](double x, double start, int n) {
    return PixelStep1(x, start, s) - PixelStep1(x, start + n * pitch, s);
  };
  for (int y = 0; y < h; ++y) {
    const double sy = wave(y, y0, ny), my = inside(y, y0, ny);
    for (int x = 0; x < w; ++x) {
      const double sx = wave(x, x0, nx), mx = inside(x, x0, nx);
      // Blurred board: mask*(dark + (bright-dark)(1 + Sx Sy)/2) + (1-mask)*background, with the mask
      // and the waves separable (mask = mx*my).
      const double mask = mx * my;
      const double white = 0.5 * (mask + sx * sy);
      img.at<float>(y, x) = static_cast<float>(background * (1 - mask) + dark * (mask - white) + bright * white);
    }
  }
  return img;
}

// Axis-aligned L-corner: the quadrant x > cx, y > cy (both blurred) in `bright` on `dark`.
inline cv::Mat CornerImage(int w, int h, double cx, double cy, double dark, double bright, double blur) {
  cv::Mat img(h, w, CV_32F);
  const double s = std::max(blur, 1e-3);
  for (int y = 0; y < h; ++y) {
    const double fy = PixelStep1(y, cy, s);
    for (int x = 0; x < w; ++x) {
      img.at<float>(y, x) = static_cast<float>(dark + (bright - dark) * PixelStep1(x, cx, s) * fy);
    }
  }
  return img;
}

// The mean of level(q) over each pixel's area (16 x 16 samples q in image coordinates), then a Gaussian
// PSF of sigma `blur` px. Edge positions are good to about 0.005 px, enough for tests at the 0.05 px level.
template <typename Level>
cv::Mat AreaMeanImage(int w, int h, const Level& level, double blur) {
  constexpr int kSub = 16;
  cv::Mat img(h, w, CV_32F);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      double sum = 0;
      for (int j = 0; j < kSub; ++j) {
        for (int i = 0; i < kSub; ++i) {
          sum += level(Vec2d(x - 0.5 + (i + 0.5) / kSub, y - 0.5 + (j + 0.5) / kSub));
        }
      }
      img.at<float>(y, x) = static_cast<float>(sum / (kSub * kSub));
    }
  }
  if (blur > 0) {
    const int k = 2 * static_cast<int>(std::ceil(4 * blur)) + 1;
    cv::GaussianBlur(img, img, cv::Size(k, k), blur, blur, cv::BORDER_REPLICATE);
  }
  return img;
}

// A wedge of opening `angle_rad` with its apex at (ax, ay), opening along the direction `bisector_rad`,
// in `bright` on `dark` (AreaMeanImage).
inline cv::Mat WedgeImage(int w,
                          int h,
                          double ax,
                          double ay,
                          double bisector_rad,
                          double angle_rad,
                          double dark,
                          double bright,
                          double blur) {
  const double a1 = bisector_rad - 0.5 * angle_rad, a2 = bisector_rad + 0.5 * angle_rad;
  // Inside: left of the ray along a1 and right of the ray along a2 (image y down).
  const Vec2d n1(-std::sin(a1), std::cos(a1)), n2(std::sin(a2), -std::cos(a2));
  const Vec2d apex(ax, ay);
  return AreaMeanImage(
      w, h, [&](const Vec2d& q) { return n1.dot(q - apex) > 0 && n2.dot(q - apex) > 0 ? bright : dark; }, blur);
}

// A junction of sectors meeting at (cx, cy): sector k spans the directions [angles_rad[k],
// angles_rad[k + 1]) (the last one wraps to angles_rad[0] + 2 pi; image y down) and has the grey level
// levels[k] (AreaMeanImage).
inline cv::Mat JunctionImage(int w,
                             int h,
                             double cx,
                             double cy,
                             const std::vector<double>& angles_rad,
                             const std::vector<double>& levels,
                             double blur) {
  constexpr double kTwoPi = 2 * 3.14159265358979323846;
  const auto level = [&](const Vec2d& q) {
    double a = std::atan2(q.y() - cy, q.x() - cx) - angles_rad[0];
    a -= kTwoPi * std::floor(a / kTwoPi);
    std::size_t k = 0;
    while (k + 1 < angles_rad.size() && a >= angles_rad[k + 1] - angles_rad[0]) ++k;
    return levels[k];
  };
  return AreaMeanImage(w, h, level, blur);
}

// Adds white Gaussian noise and quantises to 8 bits (deterministic for a seed).
inline cv::Mat Quantize(const cv::Mat& img, double noise_sigma, std::uint64_t seed) {
  cv::Mat noisy = img.clone();
  if (noise_sigma > 0) {
    cv::Mat n(img.size(), CV_32F);
    cv::RNG rng(seed);
    rng.fill(n, cv::RNG::NORMAL, 0.0, noise_sigma);
    noisy += n;
  }
  cv::Mat out;
  noisy.convertTo(out, CV_8U);  // rounds and saturates
  return out;
}

}  // namespace idi::analytic
