// Small PNG plots for reports (calibration residuals per iteration, spreads, histograms), drawn with
// OpenCV: line plots, scatter plots, histograms, linear or logarithmic axes, a legend.
//
//   plot::Figure f;
//   f.SetTitle("cost per iteration");
//   f.y_axis().log = true;
//   f.AddLine(iterations, costs, "robot 1", plot::kBlue);
//   IDI_RETURN_IF_ERROR(f.SavePng("cost.png"));
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "shared/util/status.h"

namespace idi::plot {

struct Color {
  std::uint8_t r = 0, g = 0, b = 0;
};
inline constexpr Color kBlue{31, 119, 180};
inline constexpr Color kRed{214, 39, 40};
inline constexpr Color kGreen{44, 160, 44};
inline constexpr Color kOrange{255, 127, 14};
inline constexpr Color kPurple{148, 103, 189};
inline constexpr Color kGray{127, 127, 127};

enum class Marker { kNone, kCircle, kCross };

struct Axis {
  std::string label;
  bool log = false;                // base-10 logarithmic; every value must be > 0
  std::optional<double> min, max;  // fixed range; default: the data's, padded
};

struct HistogramBins {
  std::vector<double> edges;  // bins + 1 edges
  std::vector<int> counts;
};
// Equal-width bins over [lo, hi] (default: the data's range); non-finite values are an error.
Result<HistogramBins> Histogram(const std::vector<double>& values, int bins, std::optional<double> lo = std::nullopt,
                                std::optional<double> hi = std::nullopt);

class Figure {
 public:
  explicit Figure(int width_px = 800, int height_px = 600) : width_(width_px), height_(height_px) {}

  void SetTitle(std::string title) { title_ = std::move(title); }
  Axis& x_axis() { return x_; }
  Axis& y_axis() { return y_; }
  // Same mm per pixel on both axes (spread plots).
  void SetEqualAspect(bool equal) { equal_aspect_ = equal; }

  void AddLine(std::vector<double> x, std::vector<double> y, std::string label, Color color,
               Marker marker = Marker::kNone);
  void AddScatter(std::vector<double> x, std::vector<double> y, std::string label, Color color,
                  Marker marker = Marker::kCircle);
  // Bars of the counts of `values` in `bins` equal bins.
  Status AddHistogram(const std::vector<double>& values, int bins, std::string label, Color color);
  // A circle of `radius` about (cx, cy) in data units (e.g. a spread radius).
  void AddCircle(double cx, double cy, double radius, std::string label, Color color);

  // PNG bytes of the figure. Fails on empty figures, mismatched or non-finite data, and values <= 0
  // on a log axis, naming the series.
  Result<std::vector<std::uint8_t>> EncodePng() const;
  // Writes the PNG atomically.
  Status SavePng(const std::string& path) const;

 private:
  struct Series {
    std::string label;
    std::vector<double> x, y;
    Color color;
    bool line = true;
    Marker marker = Marker::kNone;
    bool bars = false;
    double bar_width = 0;
  };
  int width_, height_;
  std::string title_;
  Axis x_, y_;
  bool equal_aspect_ = false;
  std::vector<Series> series_;
};

}  // namespace idi::plot
