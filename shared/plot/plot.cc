#include "shared/plot/plot.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <string>
#include <utility>

#include "shared/util/atomic_file.h"

namespace idi::plot {
namespace {

constexpr int kLeft = 90, kRight = 30, kTop = 45, kBottom = 60;
constexpr double kFontScale = 0.45;
const cv::Scalar kInk(40, 40, 40);
const cv::Scalar kGrid(225, 225, 225);

cv::Scalar Bgr(Color c) { return cv::Scalar(c.b, c.g, c.r); }

std::string Format(double v) {
  char buf[32];
  if (v != 0 && (std::abs(v) >= 1e5 || std::abs(v) < 1e-3)) {
    std::snprintf(buf, sizeof(buf), "%.0e", v);
  } else {
    std::snprintf(buf, sizeof(buf), "%g", v);
  }
  return buf;
}

// "Nice" tick positions (1, 2, 5 x 10^k) covering [lo, hi].
std::vector<double> LinearTicks(double lo, double hi) {
  const double span = hi - lo;
  const double raw = span / 6.0;
  const double mag = std::pow(10.0, std::floor(std::log10(raw)));
  double step = mag;
  for (double m : {1.0, 2.0, 5.0, 10.0}) {
    if (m * mag >= raw) {
      step = m * mag;
      break;
    }
  }
  std::vector<double> t;
  // A step lost to rounding (a range of a few units far from zero) would never advance: the two ends.
  if (!(span > 0) || !std::isfinite(span) || !(step > 0) || lo + step == lo || hi + step == hi) return {lo, hi};
  for (double v = std::ceil(lo / step) * step; v <= hi + 1e-9 * span && t.size() < 100; v += step) {
    t.push_back(std::abs(v) < 1e-12 * step ? 0.0 : v);
  }
  return t;
}

struct Range {
  double lo = 0, hi = 1;
};

Range DataRange(const std::vector<double>& v, const Axis& axis, double pad_fraction) {
  double lo = *std::min_element(v.begin(), v.end());
  double hi = *std::max_element(v.begin(), v.end());
  if (axis.log) {
    lo = std::log10(lo);
    hi = std::log10(hi);
  }
  if (hi - lo < 1e-12 * std::max(1.0, std::abs(hi))) {
    // One value: half a unit either side, or more where half a unit is lost to rounding.
    const double pad = std::max(0.5, 1e-9 * std::abs(hi));
    lo -= pad;
    hi += pad;
  } else {
    const double pad = pad_fraction * (hi - lo);
    lo -= pad;
    hi += pad;
  }
  if (axis.min) lo = axis.log ? std::log10(*axis.min) : *axis.min;
  if (axis.max) hi = axis.log ? std::log10(*axis.max) : *axis.max;
  return {lo, hi};
}

void PutText(cv::Mat& img, const std::string& text, cv::Point org, double scale = kFontScale, int thickness = 1) {
  cv::putText(img, text, org, cv::FONT_HERSHEY_SIMPLEX, scale, kInk, thickness, cv::LINE_AA);
}

cv::Size TextSize(const std::string& text, double scale = kFontScale, int thickness = 1) {
  int base = 0;
  return cv::getTextSize(text, cv::FONT_HERSHEY_SIMPLEX, scale, thickness, &base);
}

}  // namespace

Result<HistogramBins> Histogram(const std::vector<double>& values, int bins, std::optional<double> lo,
                                std::optional<double> hi) {
  if (bins <= 0 || bins > 1000000) return InvalidArgument("histogram: bins must be 1 to 1000000");
  if (values.empty()) return InvalidArgument("histogram: no values");
  for (double v : values) {
    if (!std::isfinite(v)) return InvalidArgument("histogram: a value is not finite");
  }
  const double a = lo.value_or(*std::min_element(values.begin(), values.end()));
  double b = hi.value_or(*std::max_element(values.begin(), values.end()));
  if (!(b > a)) b = a + std::max(1.0, 1e-9 * std::abs(a));
  // A range whose width overflows (or a non-finite bound) has no bins: the bin index would be NaN.
  if (!std::isfinite(a) || !std::isfinite(b) || !std::isfinite(b - a)) {
    return InvalidArgument("histogram: the range [" + FormatNumber(a) + ", " + FormatNumber(b) +
                           "] is not finite or too wide");
  }
  HistogramBins h;
  h.counts.assign(static_cast<std::size_t>(bins), 0);
  for (int i = 0; i <= bins; ++i) h.edges.push_back(a + (b - a) * i / bins);
  for (double v : values) {
    if (v < a || v > b) continue;
    const int k = std::min(bins - 1, static_cast<int>((v - a) / (b - a) * bins));
    ++h.counts[static_cast<std::size_t>(k)];
  }
  return h;
}

void Figure::AddLine(std::vector<double> x, std::vector<double> y, std::string label, Color color, Marker marker) {
  series_.push_back({std::move(label), std::move(x), std::move(y), color, true, marker, false, 0});
}

void Figure::AddScatter(std::vector<double> x, std::vector<double> y, std::string label, Color color, Marker marker) {
  series_.push_back({std::move(label), std::move(x), std::move(y), color, false, marker, false, 0});
}

Status Figure::AddHistogram(const std::vector<double>& values, int bins, std::string label, Color color) {
  IDI_ASSIGN_OR_RETURN(const HistogramBins h, Histogram(values, bins));
  Series s{std::move(label), {}, {}, color, false, Marker::kNone, true, h.edges[1] - h.edges[0]};
  for (int i = 0; i < bins; ++i) {
    s.x.push_back(0.5 * (h.edges[static_cast<std::size_t>(i)] + h.edges[static_cast<std::size_t>(i) + 1]));
    s.y.push_back(h.counts[static_cast<std::size_t>(i)]);
  }
  series_.push_back(std::move(s));
  return Status::Ok();
}

void Figure::AddCircle(double cx, double cy, double radius, std::string label, Color color) {
  std::vector<double> x, y;
  for (int i = 0; i <= 120; ++i) {
    const double a = 2.0 * M_PI * i / 120.0;
    x.push_back(cx + radius * std::cos(a));
    y.push_back(cy + radius * std::sin(a));
  }
  AddLine(std::move(x), std::move(y), std::move(label), color);
}

Result<std::vector<std::uint8_t>> Figure::EncodePng() const {
  if (width_ < 200 || height_ < 150) return InvalidArgument("plot: figure smaller than 200 x 150 pixels");
  if (series_.empty()) return InvalidArgument("plot '" + title_ + "': nothing to draw");
  std::vector<double> xs, ys;
  for (const Series& s : series_) {
    if (s.x.size() != s.y.size() || s.x.empty()) {
      return InvalidArgument("plot '" + title_ + "': series '" + s.label + "' has " + std::to_string(s.x.size()) +
                             " x and " + std::to_string(s.y.size()) + " y values");
    }
    for (std::size_t i = 0; i < s.x.size(); ++i) {
      if (!std::isfinite(s.x[i]) || !std::isfinite(s.y[i])) {
        return InvalidArgument("plot '" + title_ + "': series '" + s.label + "' point " + std::to_string(i) + " is not finite");
      }
      if ((x_.log && s.x[i] <= 0) || (y_.log && s.y[i] <= 0 && !s.bars)) {
        return InvalidArgument("plot '" + title_ + "': series '" + s.label + "' has a value <= 0 on a log axis");
      }
      xs.push_back(s.x[i]);
      ys.push_back(s.y[i]);
      if (s.bars) {
        xs.push_back(s.x[i] - 0.5 * s.bar_width);
        xs.push_back(s.x[i] + 0.5 * s.bar_width);
        ys.push_back(0.0);
      }
    }
  }
  for (const auto& [axis, name] : {std::pair<const Axis*, const char*>{&x_, "x"}, {&y_, "y"}}) {
    const double lo = axis->min.value_or(axis->log ? 1.0 : 0.0), hi = axis->max.value_or(lo + 1.0);
    if (!std::isfinite(lo) || !std::isfinite(hi) || (axis->min && axis->max && !(hi > lo)) ||
        (axis->log && (!(lo > 0) || !(hi > 0)))) {
      return InvalidArgument("plot '" + title_ + "': the " + name +
                             " axis' fixed range must be finite with min < max (and > 0 on a log axis)");
    }
  }
  Range rx = DataRange(xs, x_, 0.03), ry = DataRange(ys, y_, 0.05);
  if (!(rx.hi > rx.lo) || !(ry.hi > ry.lo) || !std::isfinite(rx.hi - rx.lo) || !std::isfinite(ry.hi - ry.lo)) {
    return InvalidArgument("plot '" + title_ + "': the data's range is empty or too wide to draw");
  }
  const int pw = width_ - kLeft - kRight, ph = height_ - kTop - kBottom;
  if (equal_aspect_ && !x_.log && !y_.log) {
    const double sx = (rx.hi - rx.lo) / pw, sy = (ry.hi - ry.lo) / ph;
    const double s = std::max(sx, sy);
    const double cx = 0.5 * (rx.lo + rx.hi), cy = 0.5 * (ry.lo + ry.hi);
    rx = {cx - 0.5 * s * pw, cx + 0.5 * s * pw};
    ry = {cy - 0.5 * s * ph, cy + 0.5 * s * ph};
  }
  auto tx = [&](double v) { return x_.log ? std::log10(v) : v; };
  auto ty = [&](double v) { return y_.log ? std::log10(std::max(v, 1e-300)) : v; };
  auto to_px = [&](double x, double y) {
    return cv::Point2d(kLeft + (tx(x) - rx.lo) / (rx.hi - rx.lo) * pw, kTop + (ry.hi - ty(y)) / (ry.hi - ry.lo) * ph);
  };
  cv::Mat img(height_, width_, CV_8UC3, cv::Scalar(255, 255, 255));
  // Grid and ticks.
  auto ticks = [](const Range& r, bool log) {
    if (!log) return LinearTicks(r.lo, r.hi);
    std::vector<double> t;
    for (double e = std::ceil(r.lo); e <= r.hi + 1e-9; e += std::max(1.0, std::floor((r.hi - r.lo) / 8.0))) t.push_back(e);
    return t;
  };
  for (double t : ticks(rx, x_.log)) {
    const int px = static_cast<int>(std::lround(kLeft + (t - rx.lo) / (rx.hi - rx.lo) * pw));
    cv::line(img, {px, kTop}, {px, kTop + ph}, kGrid, 1);
    const std::string s = x_.log ? "1e" + Format(t) : Format(t);
    PutText(img, s, {px - TextSize(s).width / 2, kTop + ph + 18});
  }
  for (double t : ticks(ry, y_.log)) {
    const int py = static_cast<int>(std::lround(kTop + (ry.hi - t) / (ry.hi - ry.lo) * ph));
    cv::line(img, {kLeft, py}, {kLeft + pw, py}, kGrid, 1);
    const std::string s = y_.log ? "1e" + Format(t) : Format(t);
    PutText(img, s, {kLeft - 6 - TextSize(s).width, py + 5});
  }
  cv::rectangle(img, {kLeft, kTop}, {kLeft + pw, kTop + ph}, kInk, 1);
  // Data, clipped to the plot area.
  cv::Mat area = img(cv::Rect(kLeft, kTop, pw + 1, ph + 1));
  const cv::Point2d off(kLeft, kTop);
  auto ip = [&](const cv::Point2d& p) {
    return cv::Point(static_cast<int>(std::lround((p - off).x * 16)), static_cast<int>(std::lround((p - off).y * 16)));
  };
  for (const Series& s : series_) {
    const cv::Scalar c = Bgr(s.color);
    if (s.bars) {
      for (std::size_t i = 0; i < s.x.size(); ++i) {
        const cv::Point2d a = to_px(s.x[i] - 0.5 * s.bar_width, s.y[i]);
        const cv::Point2d b = to_px(s.x[i] + 0.5 * s.bar_width, y_.log ? std::pow(10.0, ry.lo) : 0.0);
        cv::rectangle(area, ip(a), ip(b), c, cv::FILLED, cv::LINE_8, 4);
      }
      continue;
    }
    if (s.line) {
      for (std::size_t i = 1; i < s.x.size(); ++i) {
        cv::line(area, ip(to_px(s.x[i - 1], s.y[i - 1])), ip(to_px(s.x[i], s.y[i])), c, 2, cv::LINE_AA, 4);
      }
    }
    for (std::size_t i = 0; i < s.x.size(); ++i) {
      const cv::Point p = ip(to_px(s.x[i], s.y[i]));
      if (s.marker == Marker::kCircle) cv::circle(area, p, 3 * 16, c, 1, cv::LINE_AA, 4);
      if (s.marker == Marker::kCross) {
        cv::line(area, p + cv::Point(-48, -48), p + cv::Point(48, 48), c, 1, cv::LINE_AA, 4);
        cv::line(area, p + cv::Point(-48, 48), p + cv::Point(48, -48), c, 1, cv::LINE_AA, 4);
      }
    }
  }
  // Title, axis labels (the y label turned), legend.
  PutText(img, title_, {std::max(5, (width_ - TextSize(title_, 0.6).width) / 2), 28}, 0.6);
  PutText(img, x_.label, {kLeft + (pw - TextSize(x_.label).width) / 2, height_ - 15});
  if (!y_.label.empty()) {
    const cv::Size ts = TextSize(y_.label);
    cv::Mat label(ts.height + 8, ts.width + 4, CV_8UC3, cv::Scalar(255, 255, 255));
    PutText(label, y_.label, {2, ts.height + 2});
    cv::Mat turned;
    cv::rotate(label, turned, cv::ROTATE_90_COUNTERCLOCKWISE);
    const int y0 = std::max(0, kTop + (ph - turned.rows) / 2);
    if (y0 + turned.rows <= height_ && turned.cols + 4 <= kLeft) turned.copyTo(img(cv::Rect(4, y0, turned.cols, turned.rows)));
  }
  int ly = kTop + 16;
  for (const Series& s : series_) {
    if (s.label.empty()) continue;
    const int lx = kLeft + pw - TextSize(s.label).width - 40;
    cv::line(img, {lx, ly - 4}, {lx + 24, ly - 4}, Bgr(s.color), 3, cv::LINE_AA);
    PutText(img, s.label, {lx + 30, ly});
    ly += 18;
  }
  std::vector<std::uint8_t> png;
  if (!cv::imencode(".png", img, png)) return Internal("plot '" + title_ + "': PNG encoding failed");
  return png;
}

Status Figure::SavePng(const std::string& path) const {
  IDI_ASSIGN_OR_RETURN(const std::vector<std::uint8_t> png, EncodePng());
  return WriteFileAtomically(path, std::string_view(reinterpret_cast<const char*>(png.data()), png.size()));
}

}  // namespace idi::plot
