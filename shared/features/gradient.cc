#include "shared/features/gradient.h"

#include <algorithm>
#include <cmath>
#include <opencv2/core/hal/intrin.hpp>
#include <opencv2/imgproc.hpp>
#include <string>

namespace idi {
namespace {

constexpr double kMaxFloatLevel = 1e6;  // the largest |grey level| a float image may hold
constexpr int kMaxSidePx = 16384;

// Gaussian kernel exactly as cv::GaussianBlur builds it for this sigma (size 2*ceil(3 sigma)+1).
std::vector<double> GaussianKernelFor(double sigma) {
  const int radius = std::max(1, static_cast<int>(std::ceil(3.0 * sigma)));
  std::vector<double> k(static_cast<std::size_t>(2 * radius + 1));
  double sum = 0;
  for (int i = -radius; i <= radius; ++i) {
    const double v = std::exp(-0.5 * i * i / (sigma * sigma));
    k[static_cast<std::size_t>(i + radius)] = v;
    sum += v;
  }
  for (double& v : k) {
    v /= sum;
  }
  return k;
}

}  // namespace

double GradientNoiseGain(double sigma_px) {
  const std::vector<double> g = GaussianKernelFor(sigma_px);
  const int n = static_cast<int>(g.size());
  // x kernel of gx: 0.5 * (g[i+1] - g[i-1]) in correlation form; y kernel: g.
  double sx = 0, sy = 0;
  for (int i = -1; i <= n; ++i) {
    const double a = (i + 1 >= 0 && i + 1 < n) ? g[static_cast<std::size_t>(i + 1)] : 0.0;
    const double b = (i - 1 >= 0 && i - 1 < n) ? g[static_cast<std::size_t>(i - 1)] : 0.0;
    sx += 0.25 * (a - b) * (a - b);
  }
  for (double v : g) {
    sy += v * v;
  }
  return std::sqrt(sx * sy);
}

Status ComputeGradients(const cv::Mat& image, double smoothing_sigma_px, GradientImages* out) {
  if (image.empty()) {
    return InvalidArgument("image is empty");
  }
  if (image.channels() != 1) {
    return InvalidArgument("expected a single-channel (grey) image, got " + std::to_string(image.channels()) +
                           " channels; convert it to grey first");
  }
  const int depth = image.depth();
  if (depth != CV_8U && depth != CV_16U && depth != CV_32F) {
    return InvalidArgument("unsupported pixel type (depth " + std::to_string(depth) +
                           "); expected 8-bit, 16-bit or float grey");
  }
  if (image.cols < 16 || image.rows < 16) {
    return InvalidArgument("image of " + std::to_string(image.cols) + " x " + std::to_string(image.rows) +
                           " px is smaller than the minimum 16 x 16 px");
  }
  // The Hough accumulator counts votes in 16 bits: a line's length (at most the diagonal, 23170 px
  // here) must stay below 65535.
  if (image.cols > kMaxSidePx || image.rows > kMaxSidePx) {
    return InvalidArgument("image of " + std::to_string(image.cols) + " x " + std::to_string(image.rows) +
                           " px is larger than the maximum " + std::to_string(kMaxSidePx) + " px a side");
  }
  if (depth == CV_32F) {
    if (!cv::checkRange(image)) {
      return InvalidArgument("float image contains NaN or infinite values");
    }
    // Grey levels (the twin's float images are 0..255 DN): far larger values (a no-data marker of 1e30)
    // would overflow the gradient's square.
    double lo = 0, hi = 0;
    cv::minMaxLoc(image, &lo, &hi);
    if (lo < -kMaxFloatLevel || hi > kMaxFloatLevel) {
      return InvalidArgument("float image has values up to " + FormatNumber(std::max(-lo, hi)) +
                             "; grey levels beyond +-1e6 are not an image");
    }
  }
  out->level_scale = depth == CV_16U ? 257.0 : 1.0;
  out->smoothing_sigma_px = smoothing_sigma_px;
  image.convertTo(out->raw, CV_32F);
  // The float Gaussian of cv::GaussianBlur (its kernel, separable, replicated border), applied to the
  // image as it comes: an 8-bit image is read a byte a pixel instead of through its float copy (this
  // function took 0.38 instead of 0.43 ms on the 640 x 480 object scene of features_bench E). The result
  // is the same to the bit from 7 taps on (sigma >= 0.67); with 5 it differs in float rounding (5e-5
  // grey levels).
  const int radius = std::max(1, static_cast<int>(std::ceil(3.0 * smoothing_sigma_px)));
  const cv::Mat kernel = cv::getGaussianKernel(2 * radius + 1, smoothing_sigma_px, CV_32F);
  cv::sepFilter2D(image, out->smooth, CV_32F, kernel, kernel, cv::Point(-1, -1), 0, cv::BORDER_REPLICATE);

  const int w = image.cols, h = image.rows;
  out->gx.create(h, w, CV_32F);
  out->gy.create(h, w, CV_32F);
  out->mag2.create(h, w, CV_32F);
  // Histogram of the gradient magnitude on every other pixel for the noise estimate. Four partial
  // histograms taken in turn: on a flat image most samples fall in a few bins, and one histogram made
  // each count wait on the store of the one before.
  constexpr int kBins = 2048;
  const double bin_width = 0.01 * out->level_scale;
  const float inv_bin_width = static_cast<float>(1.0 / bin_width);
  std::vector<int> hists(4 * kBins, 0);
  int samples = 0;
  for (int y = 0; y < h; ++y) {
    const float* s = out->smooth.ptr<float>(y);
    const float* su = out->smooth.ptr<float>(std::max(0, y - 1));
    const float* sd = out->smooth.ptr<float>(std::min(h - 1, y + 1));
    float* gxr = out->gx.ptr<float>(y);
    float* gyr = out->gy.ptr<float>(y);
    float* m2 = out->mag2.ptr<float>(y);
    gxr[0] = 0.5f * (s[1] - s[0]);
    gxr[w - 1] = 0.5f * (s[w - 1] - s[w - 2]);
    gyr[0] = 0.5f * (sd[0] - su[0]);
    m2[0] = gxr[0] * gxr[0] + gyr[0] * gyr[0];
    int x = 1;
#if CV_SIMD128
    const cv::v_float32x4 half = cv::v_setall_f32(0.5f);
    for (; x + 4 <= w - 1; x += 4) {
      const cv::v_float32x4 gxv = half * (cv::v_load(s + x + 1) - cv::v_load(s + x - 1));
      const cv::v_float32x4 gyv = half * (cv::v_load(sd + x) - cv::v_load(su + x));
      cv::v_store(gxr + x, gxv);
      cv::v_store(gyr + x, gyv);
      cv::v_store(m2 + x, gxv * gxv + gyv * gyv);
    }
#endif
    for (; x < w; ++x) {
      if (x < w - 1) {
        gxr[x] = 0.5f * (s[x + 1] - s[x - 1]);
      }
      gyr[x] = 0.5f * (sd[x] - su[x]);
      m2[x] = gxr[x] * gxr[x] + gyr[x] * gyr[x];
    }
    if ((y & 1) == 0 && y > 0 && y < h - 1) {
      // Clamped as a float: the cast of a value beyond int's range is undefined.
      const auto bin = [&](float v) {
        return static_cast<int>(std::min(std::sqrt(v) * inv_bin_width, static_cast<float>(kBins - 1)));
      };
      int xs = 2;
#if CV_SIMD128
      // Pixels xs, xs + 2, xs + 4, xs + 6: the same bins (the vector square root is correctly
      // rounded, as std::sqrt is).
      const cv::v_float32x4 vinv = cv::v_setall_f32(inv_bin_width);
      const cv::v_float32x4 vlast = cv::v_setall_f32(static_cast<float>(kBins - 1));
      for (; xs + 8 <= w - 1; xs += 8) {
        cv::v_float32x4 even, odd;
        cv::v_load_deinterleave(m2 + xs, even, odd);
        int b[4];
        cv::v_store(b, cv::v_trunc(cv::v_min(cv::v_sqrt(even) * vinv, vlast)));
        for (int i = 0; i < 4; ++i) ++hists[static_cast<std::size_t>(i * kBins + b[i])];
        samples += 4;
      }
#endif
      for (int i = 0; xs < w - 1; xs += 2, i = (i + 1) & 3) {
        ++hists[static_cast<std::size_t>(i * kBins + bin(m2[xs]))];
        ++samples;
      }
    }
  }
  std::vector<int> hist(kBins, 0);
  for (int b = 0; b < kBins; ++b) {
    for (int i = 0; i < 4; ++i) hist[static_cast<std::size_t>(b)] += hists[static_cast<std::size_t>(i * kBins + b)];
  }
  // Median of a Rayleigh distribution = sigma * sqrt(2 ln 2).
  int acc = 0, median_bin = 0;
  for (int b = 0; b < kBins; ++b) {
    acc += hist[static_cast<std::size_t>(b)];
    if (2 * acc >= samples) {
      median_bin = b;
      break;
    }
  }
  const double median = (median_bin + 0.5) * bin_width;
  out->gradient_noise = median / std::sqrt(2.0 * std::log(2.0));
  out->noise_sigma = out->gradient_noise / GradientNoiseGain(smoothing_sigma_px);
  return Status::Ok();
}

namespace {

// The mask bytes of four pixels from their candidate and strong bits (strong implies candidate).
struct MaskBytes {
  std::uint8_t b[16][16][4] = {};
  constexpr MaskBytes() {
    for (int c = 0; c < 16; ++c) {
      for (int st = 0; st < 16; ++st) {
        for (int i = 0; i < 4; ++i) {
          b[c][st][i] = static_cast<std::uint8_t>((c & (1 << i)) == 0 ? 0 : (st & (1 << i)) != 0 ? 1 : 2);
        }
      }
    }
  }
};
constexpr MaskBytes kMaskTable;

}  // namespace

void DetectEdges(const GradientImages& g, const EdgeOptions& options, EdgeMap* edges) {
  const auto& kMaskBytes = kMaskTable.b;
  const int w = g.width(), h = g.height();
  const double low = std::max(options.low_threshold_sigmas * g.gradient_noise, options.min_low_threshold * g.level_scale);
  const double high =
      std::max({options.high_threshold_sigmas * g.gradient_noise, options.min_high_threshold * g.level_scale, low});
  edges->low_threshold = low;
  edges->high_threshold = high;
  const float low2 = static_cast<float>(low * low), high2 = static_cast<float>(high * high);
  edges->mask.create(h, w, CV_8U);
  edges->mask.setTo(0);
  edges->pixels.clear();
  // tan(22.5°) for the four-sector non-maximum suppression.
  constexpr float kTan22 = 0.41421356f;
  std::vector<cv::Point> stack;
  // One pixel: 0 (suppressed), 1 (strong edge) or 2 (candidate for the hysteresis).
  auto classify = [&](float v, float gxv, float gyv, const float* m, const float* mu, const float* md, int x) {
    if (v < low2) {
      return 0;
    }
    const float ax = std::fabs(gxv), ay = std::fabs(gyv);
    float n1, n2;
    if (ay <= kTan22 * ax) {  // gradient along x: compare left/right
      n1 = m[x - 1];
      n2 = m[x + 1];
    } else if (ax <= kTan22 * ay) {  // along y
      n1 = mu[x];
      n2 = md[x];
    } else if ((gxv > 0) == (gyv > 0)) {  // diagonal down-right
      n1 = mu[x - 1];
      n2 = md[x + 1];
    } else {
      n1 = mu[x + 1];
      n2 = md[x - 1];
    }
    // Ties broken towards one side so a plateau of two equal pixels keeps one.
    if (v > n1 && v >= n2) {
      return v >= high2 ? 1 : 2;
    }
    return 0;
  };
  for (int y = 1; y < h - 1; ++y) {
    const float* m = g.mag2.ptr<float>(y);
    const float* mu = g.mag2.ptr<float>(y - 1);
    const float* md = g.mag2.ptr<float>(y + 1);
    const float* gxr = g.gx.ptr<float>(y);
    const float* gyr = g.gy.ptr<float>(y);
    std::uint8_t* out = edges->mask.ptr<std::uint8_t>(y);
    int x = 1;
#if CV_SIMD128
    // Four pixels at a time, the same decisions as `classify` without its branches (on a textured
    // floor the sector of a pixel above the low threshold is unpredictable).
    const cv::v_float32x4 vlow = cv::v_setall_f32(low2), vhigh = cv::v_setall_f32(high2);
    const cv::v_float32x4 vtan = cv::v_setall_f32(kTan22), vzero = cv::v_setzero_f32();
    for (; x + 4 <= w - 1; x += 4) {
      const cv::v_float32x4 v = cv::v_load(m + x);
      const cv::v_float32x4 above_low = v >= vlow;
      if (!cv::v_check_any(above_low)) {
        continue;  // the mask is already 0 there
      }
      const cv::v_float32x4 gxv = cv::v_load(gxr + x), gyv = cv::v_load(gyr + x);
      const cv::v_float32x4 ax = cv::v_abs(gxv), ay = cv::v_abs(gyv);
      const cv::v_float32x4 along_x = ay <= vtan * ax, along_y = ax <= vtan * ay;
      const cv::v_float32x4 down_right = ~((gxv > vzero) ^ (gyv > vzero));
      const cv::v_float32x4 n1 =
          cv::v_select(along_x, cv::v_load(m + x - 1),
                       cv::v_select(along_y, cv::v_load(mu + x),
                                    cv::v_select(down_right, cv::v_load(mu + x - 1), cv::v_load(mu + x + 1))));
      const cv::v_float32x4 n2 =
          cv::v_select(along_x, cv::v_load(m + x + 1),
                       cv::v_select(along_y, cv::v_load(md + x),
                                    cv::v_select(down_right, cv::v_load(md + x + 1), cv::v_load(md + x - 1))));
      const cv::v_float32x4 candidate = above_low & (v > n1) & (v >= n2);
      const int cand_bits = cv::v_signmask(candidate);
      if (cand_bits == 0) {
        continue;
      }
      const int strong_bits = cv::v_signmask(candidate & (v >= vhigh));
      // The four mask bytes at once (0, 1 strong, 2 candidate), then the strong pixels in x order.
      out[x] = kMaskBytes[cand_bits][strong_bits][0];
      out[x + 1] = kMaskBytes[cand_bits][strong_bits][1];
      out[x + 2] = kMaskBytes[cand_bits][strong_bits][2];
      out[x + 3] = kMaskBytes[cand_bits][strong_bits][3];
      for (int bits = strong_bits; bits != 0; bits &= bits - 1)
        stack.emplace_back(x + __builtin_ctz(static_cast<unsigned>(bits)), y);
    }
#endif
    for (; x < w - 1; ++x) {
      const int c = classify(m[x], gxr[x], gyr[x], m, mu, md, x);
      out[x] = static_cast<std::uint8_t>(c);
      if (c == 1) {
        stack.emplace_back(x, y);
      }
    }
  }
  // Hysteresis: grow from strong pixels through connected candidates.
  for (std::size_t i = 0; i < stack.size(); ++i) {
    edges->pixels.push_back(stack[i]);
  }
  while (!stack.empty()) {
    const cv::Point p = stack.back();
    stack.pop_back();
    for (int dy = -1; dy <= 1; ++dy) {
      std::uint8_t* row = edges->mask.ptr<std::uint8_t>(p.y + dy);
      for (int dx = -1; dx <= 1; ++dx) {
        if (row[p.x + dx] == 2) {
          row[p.x + dx] = 1;
          stack.emplace_back(p.x + dx, p.y + dy);
          edges->pixels.emplace_back(p.x + dx, p.y + dy);
        }
      }
    }
  }
  // Drop the unconnected candidates.
  cv::compare(edges->mask, 1, edges->mask, cv::CMP_EQ);  // 255 where connected, in place
  cv::bitwise_and(edges->mask, 1, edges->mask);
}

}  // namespace idi
