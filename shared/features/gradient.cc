#include "shared/features/gradient.h"

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>
#include <string>

namespace idi {
namespace {

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
  if (depth == CV_32F) {
    if (!cv::checkRange(image)) {
      return InvalidArgument("float image contains NaN or infinite values");
    }
  }
  out->level_scale = depth == CV_16U ? 257.0 : 1.0;
  out->smoothing_sigma_px = smoothing_sigma_px;
  image.convertTo(out->raw, CV_32F);
  const int radius = std::max(1, static_cast<int>(std::ceil(3.0 * smoothing_sigma_px)));
  cv::GaussianBlur(out->raw, out->smooth, cv::Size(2 * radius + 1, 2 * radius + 1), smoothing_sigma_px,
                   smoothing_sigma_px, cv::BORDER_REPLICATE);

  const int w = image.cols, h = image.rows;
  out->gx.create(h, w, CV_32F);
  out->gy.create(h, w, CV_32F);
  out->mag2.create(h, w, CV_32F);
  // Histogram of the gradient magnitude on every other pixel for the noise estimate.
  constexpr int kBins = 2048;
  const double bin_width = 0.01 * out->level_scale;
  std::vector<int> hist(kBins, 0);
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
    for (int x = 1; x < w - 1; ++x) {
      gxr[x] = 0.5f * (s[x + 1] - s[x - 1]);
    }
    for (int x = 0; x < w; ++x) {
      gyr[x] = 0.5f * (sd[x] - su[x]);
      m2[x] = gxr[x] * gxr[x] + gyr[x] * gyr[x];
    }
    if ((y & 1) == 0 && y > 0 && y < h - 1) {
      for (int x = 2; x < w - 1; x += 2) {
        const int b = static_cast<int>(std::sqrt(m2[x]) / bin_width);
        ++hist[static_cast<std::size_t>(std::min(b, kBins - 1))];
        ++samples;
      }
    }
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

void DetectEdges(const GradientImages& g, const EdgeOptions& options, EdgeMap* edges) {
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
  for (int y = 1; y < h - 1; ++y) {
    const float* m = g.mag2.ptr<float>(y);
    const float* mu = g.mag2.ptr<float>(y - 1);
    const float* md = g.mag2.ptr<float>(y + 1);
    const float* gxr = g.gx.ptr<float>(y);
    const float* gyr = g.gy.ptr<float>(y);
    std::uint8_t* out = edges->mask.ptr<std::uint8_t>(y);
    for (int x = 1; x < w - 1; ++x) {
      const float v = m[x];
      if (v < low2) {
        continue;
      }
      const float ax = std::fabs(gxr[x]), ay = std::fabs(gyr[x]);
      float n1, n2;
      if (ay <= kTan22 * ax) {  // gradient along x: compare left/right
        n1 = m[x - 1];
        n2 = m[x + 1];
      } else if (ax <= kTan22 * ay) {  // along y
        n1 = mu[x];
        n2 = md[x];
      } else if ((gxr[x] > 0) == (gyr[x] > 0)) {  // diagonal down-right
        n1 = mu[x - 1];
        n2 = md[x + 1];
      } else {
        n1 = mu[x + 1];
        n2 = md[x - 1];
      }
      // Ties broken towards one side so a plateau of two equal pixels keeps one.
      if (v > n1 && v >= n2) {
        out[x] = 2;  // candidate
        if (v >= high2) {
          out[x] = 1;
          stack.emplace_back(x, y);
        }
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
  for (int y = 0; y < h; ++y) {
    std::uint8_t* row = edges->mask.ptr<std::uint8_t>(y);
    for (int x = 0; x < w; ++x) {
      row[x] = row[x] == 1 ? 1 : 0;
    }
  }
}

}  // namespace idi
