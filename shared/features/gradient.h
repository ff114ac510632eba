// Derivative-of-Gaussian gradients and Canny edges (§7.5-7.6.4), the first stage of the pipeline.
#pragma once

#include <opencv2/core.hpp>
#include <vector>

#include "shared/features/features.h"

namespace idi {

struct GradientImages {
  cv::Mat raw;     // CV_32F copy of the input (grey levels)
  cv::Mat smooth;  // CV_32F, Gaussian of sigma smoothing_sigma_px (eq. 7.4)
  cv::Mat gx, gy;  // CV_32F, central differences of `smooth`: the derivative of Gaussian
  cv::Mat mag2;    // CV_32F, gx^2 + gy^2
  double smoothing_sigma_px = 1.0;
  // Image noise estimated from the median gradient magnitude, and the gradient noise it causes.
  double noise_sigma = 0;
  double gradient_noise = 0;
  // 1 for 8-bit images, 257 for 16-bit: absolute thresholds are given for 8-bit grey levels.
  double level_scale = 1.0;
  int width() const { return raw.cols; }
  int height() const { return raw.rows; }
};

// Ratio of the standard deviation of gx (or gy) to the image's white noise for the derivative of
// Gaussian used here (depends only on sigma).
double GradientNoiseGain(double sigma_px);

// Checks the image (single channel, 8U/16U/32F, at least 16 x 16, finite) and computes the gradients.
Status ComputeGradients(const cv::Mat& image, double smoothing_sigma_px, GradientImages* out);

struct EdgeMap {
  cv::Mat mask;                     // CV_8U: 1 on Canny edge pixels, 0 elsewhere
  std::vector<cv::Point> pixels;    // the edge pixels
  double low_threshold = 0;         // gradient magnitude thresholds used (grey levels / px)
  double high_threshold = 0;
};

// Canny (§7.6.4): non-maximum suppression across the edge, hysteresis with thresholds set from the
// estimated gradient noise.
void DetectEdges(const GradientImages& g, const EdgeOptions& options, EdgeMap* edges);

}  // namespace idi
