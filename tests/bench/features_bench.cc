// Accuracy and speed of the vision front end (issue 4, dissertation §7.13) on images rendered by the
// digital twin (shared/sim/render), with ground truth:
//   A. EMPL line offsets and angles against the Cramér-Rao bound, by method x noise x blur x length
//      (the error-vs-length study of §7.13.1);
//   B. IDI points on L-corners, T- and X-junctions against the bound propagated from the two lines,
//      OpenCV cornerSubPix (11x11) and intersections of OpenCV LSD lines;
//   C. the 640x480 chessboard anchors, and IDI points against Harris corners (§7.13.2): found,
//      missed, spurious, error;
//   D. corners of the twin's object scenes with clutter (and with lens distortion): found/spurious;
//   E. time per 640x480 frame, single thread, against EDLines, LSD and Canny in the same run;
//   F. IDI points against the angle between their lines (shallow junctions), and error / own sigma.
// Usage: features_bench [--quick] [--section A|B|C|D|E|F] [--draws N]. Prints markdown tables.
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <functional>
#include <map>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/ximgproc/edge_drawing.hpp>
#include <random>
#include <string>
#include <vector>

#include "shared/features/features.h"
#include "shared/features/idi_points.h"
#include "shared/geometry/lines.h"
#include "shared/sim/render/render.h"
#include "shared/sim/render/shapes.h"
#include "shared/util/statistics.h"
#include "tests/support/object_scenes.h"

namespace idi {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDepth = 1000.0;  // flat targets at z = 1000 mm, fx = 1000: 1 mm = 1 px

struct Stats {
  std::vector<double> err;
  int trials = 0, found = 0;
  void Add(double e) { err.push_back(e); }
  double Rms() const {
    double s = 0;
    for (double e : err) s += e * e;
    return err.empty() ? NAN : std::sqrt(s / static_cast<double>(err.size()));
  }
  double Mean() const {
    double s = 0;
    for (double e : err) s += e;
    return err.empty() ? NAN : s / static_cast<double>(err.size());
  }
  double Rate() const { return trials ? static_cast<double>(found) / trials : NAN; }
};

CameraModel FlatCamera(int w, int h) {
  CameraModel cam;
  cam.width = w;
  cam.height = h;
  cam.params = {1000, 1000, 0.5 * (w - 1), 0.5 * (h - 1), 0, 0, 0, 0, 0};
  return cam;
}

// A polygon given in pixel coordinates on the flat target.
Vec3d OnTarget(const CameraModel& cam, const Vec2d& px) {
  return Vec3d((px.x() - cam.cx()) * kDepth / cam.fx(), (px.y() - cam.cy()) * kDepth / cam.fy(), kDepth);
}

struct Poly {
  std::vector<Vec2d> px;
  double albedo;
};

sim::Scene FlatScene(const CameraModel& cam, double background_albedo, const std::vector<Poly>& polys) {
  sim::Scene scene;
  scene.lighting.ambient = 1.0;
  scene.lighting.directional.clear();
  scene.solids.push_back(sim::MakeRectangle("target", Vec3d(0, 0, kDepth), Vec3d::UnitX(), Vec3d::UnitY(), 5000, 5000,
                                            sim::Gray(background_albedo)));
  int layer = 1;
  for (const Poly& p : polys) {
    std::vector<Vec3d> v;
    for (const Vec2d& q : p.px) v.push_back(OnTarget(cam, q));
    scene.solids.push_back(sim::MakePolygon("poly" + std::to_string(layer), v, sim::Gray(p.albedo), layer));
    ++layer;
  }
  return scene;
}

// Renders with white Gaussian noise only (no shot noise), so that A / sigma_n is exact.
cv::Mat Render(const sim::Scene& scene, const CameraModel& cam, double blur, double noise, std::uint64_t seed,
               sim::GroundTruth* truth = nullptr) {
  sim::RenderOptions o;
  o.exposure_dn = 200;
  o.psf_sigma_px = blur;
  o.sensor.noise = noise > 0;
  o.sensor.gain_dn_per_electron = 0;
  o.sensor.read_noise_dn = noise;
  o.seed = seed;
  auto img = sim::RenderScene(scene, cam, Rigid3d::Identity(), o, truth);
  if (!img.ok()) {
    std::fprintf(stderr, "render failed: %s\n", img.status().ToString().c_str());
    std::exit(1);
  }
  return *img;
}

double CpuMs(const std::function<void()>& f) {
  timespec a, b;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &a);
  f();
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &b);
  return static_cast<double>(b.tv_sec - a.tv_sec) * 1e3 + static_cast<double>(b.tv_nsec - a.tv_nsec) * 1e-6;
}

double Median(const std::vector<double>& v) { return idi::Median(v, NAN); }

// ---- helpers on lines ----------------------------------------------------------------------------

struct TrueLine {
  Vec2d n;
  double d;
  Vec2d a, b;  // segment ends
};

TrueLine LineThroughPts(const Vec2d& a, const Vec2d& b) {
  const Vec2d dir = (b - a).normalized();
  const Vec2d n(-dir.y(), dir.x());
  return {n, n.dot(a), a, b};
}

// Detected EMPL line matching a true one (angle within 2 deg, within 2 px at the true midpoint).
const EmplLine* MatchLine(const FeatureResult& r, const TrueLine& t) { return test::MatchTruthLine(r, t.n, t.a, t.b); }

// LSD segments as lines: the segments within 2 px and 2 deg of a true line, refitted together
// (total least squares through their end points, weighted by length).
std::optional<Line2d> LsdLineFor(const std::vector<cv::Vec4f>& segs, const TrueLine& t, const Vec2d& lsd_shift) {
  double sw = 0;
  Vec2d m = Vec2d::Zero();
  std::vector<std::pair<Vec2d, double>> pts;
  for (const cv::Vec4f& s : segs) {
    const Vec2d a = Vec2d(s[0], s[1]) - lsd_shift, b = Vec2d(s[2], s[3]) - lsd_shift;
    const double len = (b - a).norm();
    if (len < 5) continue;
    const Vec2d dir = (b - a) / len;
    if (std::fabs(dir.dot(t.n)) > std::sin(2 * kPi / 180)) continue;
    if (std::fabs(t.n.dot(a) - t.d) > 2 || std::fabs(t.n.dot(b) - t.d) > 2) continue;
    // Must overlap the true segment.
    const Vec2d td = (t.b - t.a).normalized();
    const double ta = td.dot(a - t.a), tb = td.dot(b - t.a), tl = (t.b - t.a).norm();
    if (std::max(ta, tb) < -2 || std::min(ta, tb) > tl + 2) continue;
    pts.push_back({a, len});
    pts.push_back({b, len});
    m += len * (a + b);
    sw += 2 * len;
  }
  if (pts.size() < 2) return std::nullopt;
  m /= sw;
  double cxx = 0, cxy = 0, cyy = 0;
  for (const auto& [p, w] : pts) {
    const Vec2d q = p - m;
    cxx += w * q.x() * q.x();
    cxy += w * q.x() * q.y();
    cyy += w * q.y() * q.y();
  }
  const double phi = 0.5 * std::atan2(2 * cxy, cxx - cyy);
  Line2d l;
  l.normal = Vec2d(-std::sin(phi), std::cos(phi));
  l.offset = l.normal.dot(m);
  return l;
}

std::vector<cv::Vec4f> RunLsd(const cv::Mat& img) {
  static cv::Ptr<cv::LineSegmentDetector> lsd = cv::createLineSegmentDetector(cv::LSD_REFINE_STD);
  std::vector<cv::Vec4f> segs;
  lsd->detect(img, segs);
  return segs;
}

// Cramér-Rao covariance of a line of length L in (angle, offset at origin) with its centre at `mid`.
Eigen::Matrix2d BoundCovariance(const Vec2d& n, const Vec2d& mid, double a, double sn, double sb, double len) {
  const double sd = OffsetBoundPx(a, sn, sb, len), st = AngleBoundRad(a, sn, sb, len);
  const Vec2d nd(-n.y(), n.x());
  Eigen::Matrix2d j;
  j << 1, 0, nd.dot(mid), 1;
  return j * Eigen::Vector2d(st * st, sd * sd).asDiagonal() * j.transpose();
}

// ---- A: lines ------------------------------------------------------------------------------------

void SectionA(bool quick) {
  std::printf("\n## A. EMPL line offset at the segment centre vs the Cramér-Rao bound (§7.13.1)\n\n");
  std::printf("Edge of length L (one side of a bright rectangle), random angle and sub-pixel position, 256x256 px.\n");
  std::printf("Offset error = signed distance of the true segment centre from the fitted line.\n\n");
  std::printf("| method | A | A/sigma_n | sigma_b | L px | trials | detected | RMS px | bias px | bound px | RMS/bound | angle RMS mrad | angle bound mrad | predicted sigma px |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  const CameraModel cam = FlatCamera(256, 256);
  auto precise = FeatureDetector::Create(FeatureOptions{});
  FeatureOptions go;
  go.empl.photometric_refinement = false;
  auto gradient_only = FeatureDetector::Create(go);
  FeatureOptions wo;
  wo.empl.photometric_flat_band = true;
  auto flat_band = FeatureDetector::Create(wo);
  wo.empl.photometric_ramp = true;
  auto flat_ramp = FeatureDetector::Create(wo);
  struct Cfg {
    double a, ratio, blur;
  };
  std::vector<Cfg> cfgs = {{150, 30, 1}, {150, 15, 1}, {150, 15, 2}, {20, 15, 2}, {20, 5, 1}};
  std::vector<double> lengths = {20, 40, 80, 160};
  const int trials = quick ? 20 : 80;
  for (const Cfg& c : cfgs) {
    for (double len : lengths) {
      // Methods 0 photometric (the default), 1 gradient only (eq. 7.26), 2 with the flat band, 3 with the
      // flat band and the background's ramp.
      std::array<Stats, 4> s_m, ang_m;
      std::array<double, 4> pred{};
      std::array<int, 4> npred{};
      Stats s_l;
      std::mt19937 rng(static_cast<unsigned>(len * 7 + c.ratio * 3 + c.blur));
      std::uniform_real_distribution<double> u(0, 1);
      const double bg = 0.2, fg = bg + c.a / 200.0;
      for (int t = 0; t < trials; ++t) {
        const double th = u(rng) * kPi;
        const Vec2d dir(std::cos(th), std::sin(th)), nrm(-dir.y(), dir.x());
        const Vec2d centre(128 + u(rng) - 0.5, 128 + u(rng) - 0.5);
        const Vec2d a = centre - 0.5 * len * dir, b = centre + 0.5 * len * dir;
        const Poly rect{{a, b, b + 50 * nrm, a + 50 * nrm}, fg};
        const sim::Scene scene = FlatScene(cam, bg, {rect});
        const cv::Mat img = Render(scene, cam, c.blur, c.a / c.ratio, 1000 + static_cast<std::uint64_t>(t));
        const TrueLine tl = LineThroughPts(a, b);
        for (std::size_t m = 0; m < 4; ++m) {
          auto r = (m == 0 ? *precise : m == 1 ? *gradient_only : m == 2 ? *flat_band : *flat_ramp).Detect(img);
          Stats& s = s_m[m];
          ++s.trials;
          const EmplLine* l = r.ok() ? MatchLine(*r, tl) : nullptr;
          if (!l) continue;
          ++s.found;
          const double sgn = l->normal.dot(tl.n) > 0 ? 1 : -1;
          s.Add(-sgn * l->SignedDistance(centre));
          if (m != 1) {
            ang_m[m].Add(std::remainder(l->Angle() - std::atan2(tl.n.y(), tl.n.x()), kPi));
            const Vec2d nd(-l->normal.y(), l->normal.x());
            const Eigen::Vector2d j(nd.dot(centre), -1.0);
            pred[m] += j.dot(l->covariance * j);
            ++npred[m];
          }
        }
        const auto segs = RunLsd(img);
        ++s_l.trials;
        if (auto ll = LsdLineFor(segs, tl, Vec2d::Zero())) {
          ++s_l.found;
          const double sgn = ll->normal.dot(tl.n) > 0 ? 1 : -1;
          s_l.Add(-sgn * (ll->normal.dot(centre) - ll->offset));
        }
      }
      const double sn = c.a / c.ratio;
      const double bound = OffsetBoundPx(c.a, sn, c.blur, len), abound = AngleBoundRad(c.a, sn, c.blur, len);
      auto row = [&](const char* name, const Stats& s, const Stats* ang, double predicted) {
        std::printf("| %s | %.0f | %.0f | %.0f | %.0f | %d | %.2f | %.4f | %+.4f | %.4f | %.2f | %s | %.3f | %s |\n", name, c.a,
                    c.ratio, c.blur, len, s.trials, s.Rate(), s.Rms(), s.Mean(), bound, s.Rms() / bound,
                    ang ? std::to_string(ang->Rms() * 1e3).substr(0, 6).c_str() : "-", abound * 1e3,
                    predicted > 0 ? std::to_string(predicted).substr(0, 6).c_str() : "-");
      };
      auto predicted = [&](std::size_t m) { return npred[m] ? std::sqrt(pred[m] / npred[m]) : 0.0; };
      row("EMPL (photometric)", s_m[0], &ang_m[0], predicted(0));
      row("EMPL (photometric, flat band)", s_m[2], &ang_m[2], predicted(2));
      row("EMPL (photometric, flat band, ramp)", s_m[3], &ang_m[3], predicted(3));
      row("EMPL (eq. 7.26 only)", s_m[1], nullptr, 0);
      row("OpenCV LSD", s_l, nullptr, 0);
      std::fflush(stdout);
    }
  }
}

// ---- B: junctions --------------------------------------------------------------------------------

struct Junction {
  std::vector<Poly> polys;
  double bg;
  Vec2d truth;
  std::vector<TrueLine> lines;  // the lines meeting there, with their visible extents
};

// The second line's direction is min_deg..max_deg away from the first's (60..120 by default).
Junction MakeJunction(
    const std::string& type, double contrast, std::mt19937& rng, double min_deg = 60, double max_deg = 120) {
  std::uniform_real_distribution<double> u(0, 1);
  const double th = u(rng) * kPi;
  const Vec2d c(96 + u(rng) - 0.5, 96 + u(rng) - 0.5);
  const Vec2d e1(std::cos(th), std::sin(th));
  const double th2 = th + (min_deg + (max_deg - min_deg) * u(rng)) * kPi / 180;
  const Vec2d e2(std::cos(th2), std::sin(th2));
  const double s = 70;  // arm length
  const double bg = 0.2, fg = bg + contrast / 200.0;
  Junction j;
  j.bg = bg;
  j.truth = c;
  if (type == "L") {
    j.polys = {{{c, c + s * e1, c + s * (e1 + e2), c + s * e2}, fg}};
    j.lines = {LineThroughPts(c, c + s * e1), LineThroughPts(c, c + s * e2)};
  } else if (type == "T") {
    // Bar along e1 through c; the stem along e2 on one side: three regions.
    const double mid = bg + 0.5 * contrast / 200.0;
    j.polys = {{{c - s * e1, c + s * e1, c + s * e1 + s * e2, c - s * e1 + s * e2}, mid},
               {{c, c + s * e1, c + s * e1 + s * e2, c + s * e2}, fg}};
    j.lines = {LineThroughPts(c - s * e1, c + s * e1), LineThroughPts(c, c + s * e2)};
  } else {  // X: two opposite quadrants bright
    j.polys = {{{c, c + s * e1, c + s * (e1 + e2), c + s * e2}, fg}, {{c, c - s * e1, c - s * (e1 + e2), c - s * e2}, fg}};
    j.lines = {LineThroughPts(c - s * e1, c + s * e1), LineThroughPts(c - s * e2, c + s * e2)};
  }
  return j;
}

std::optional<Vec2d> Intersect(const Line2d& a, const Line2d& b) { return IntersectLines2(a, b, 1e-6); }

// The IDI point nearest `xy` within `radius` px (its distance in *dist), or null.
const IdiPoint* NearestPoint(const FeatureResult& r, const Vec2d& xy, double radius, double* dist) {
  const IdiPoint* best = nullptr;
  *dist = radius;
  for (const IdiPoint& p : r.points) {
    if ((p.xy - xy).norm() < *dist) {
      *dist = (p.xy - xy).norm();
      best = &p;
    }
  }
  return best;
}

// Trace of the bound covariance of the junction's point: each line's Cramér-Rao offset/angle covariance
// for its visible length and `contrast`, propagated to the intersection (0 when they do not intersect).
double JunctionBoundTrace(const Junction& j, double contrast, double sn, double blur) {
  std::vector<EmplLine> bl(2);
  for (std::size_t k = 0; k < 2; ++k) {
    const TrueLine& tl = j.lines[k];
    bl[k].normal = tl.n;
    bl[k].offset = tl.d;
    bl[k].covariance = BoundCovariance(tl.n, 0.5 * (tl.a + tl.b), contrast, sn, blur, (tl.b - tl.a).norm());
  }
  const auto x = IntersectWithCovariance(bl[0], bl[1]);
  return x ? x->covariance.trace() : 0.0;
}

void SectionB(bool quick) {
  std::printf("\n## B. IDI points on L-corners, T- and X-junctions (192x192 px, arms 70 px, angles 60-120 deg)\n\n");
  std::printf("Bound: each line's Cramér-Rao offset/angle covariance for its visible length, propagated to the intersection.\n");
  std::printf("cornerSubPix: 11x11 window, started 1 px off at random (a pixel-accurate detector); LSD: segments near each\n");
  std::printf("true line refitted together and intersected, with LSD's coordinate shift (measured noise-free) removed.\n\n");
  std::printf("| type | A | A/sigma_n | sigma_b | method | trials | found | RMS px | bias x,y px | bound px | RMS/bound |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|---|\n");
  const CameraModel cam = FlatCamera(192, 192);
  auto det = FeatureDetector::Create(FeatureOptions{});
  FeatureOptions flat_options;
  flat_options.empl.photometric_flat_band = true;
  flat_options.empl.photometric_ramp = true;
  auto det_flat = FeatureDetector::Create(flat_options);
  // LSD's systematic coordinate shift, measured on noise-free L-corners.
  Vec2d lsd_shift = Vec2d::Zero();
  {
    std::mt19937 rng(5);
    int n = 0;
    for (int t = 0; t < 20; ++t) {
      const Junction j = MakeJunction("L", 150, rng);
      const cv::Mat img = Render(FlatScene(cam, j.bg, j.polys), cam, 1.0, 0, 1);
      const auto segs = RunLsd(img);
      auto a = LsdLineFor(segs, j.lines[0], Vec2d::Zero()), b = LsdLineFor(segs, j.lines[1], Vec2d::Zero());
      if (a && b) {
        if (auto x = Intersect(*a, *b)) {
          lsd_shift += *x - j.truth;
          ++n;
        }
      }
    }
    if (n) lsd_shift /= n;
    std::printf("(LSD shift measured: %+.3f, %+.3f px)\n\n", lsd_shift.x(), lsd_shift.y());
  }
  struct Cfg {
    double a, ratio, blur;
  };
  const std::vector<Cfg> cfgs = {{150, 30, 1}, {150, 15, 1}, {150, 15, 2}, {20, 15, 2}};
  const int trials = quick ? 15 : 60;
  for (const std::string type : {"L", "T", "X"}) {
    for (const Cfg& c : cfgs) {
      Stats s_idi, s_flat, s_csp, s_lsd;
      Vec2d b_idi = Vec2d::Zero(), b_flat = Vec2d::Zero(), b_csp = Vec2d::Zero(), b_lsd = Vec2d::Zero();
      double bound2 = 0;
      std::mt19937 rng(static_cast<unsigned>(c.ratio * 11 + c.blur + type[0]));
      std::uniform_real_distribution<double> u(-1, 1);
      const double sn = c.a / c.ratio;
      for (int t = 0; t < trials; ++t) {
        const Junction j = MakeJunction(type, c.a, rng);
        const cv::Mat img = Render(FlatScene(cam, j.bg, j.polys), cam, c.blur, sn, 500 + static_cast<std::uint64_t>(t));
        // Bound: lines of their visible lengths (T: the stem has contrast/2 on one side... use its own).
        bound2 += JunctionBoundTrace(j, (type == "T") ? c.a * 0.5 : c.a, sn, c.blur);
        // IDI, with the default options and with the flat photometric band and its ramp.
        for (const bool flat : {false, true}) {
          Stats& s = flat ? s_flat : s_idi;
          Vec2d& b = flat ? b_flat : b_idi;
          ++s.trials;
          if (auto r = (flat ? *det_flat : *det).Detect(img); r.ok()) {
            double bd = 0;
            if (const IdiPoint* best = NearestPoint(*r, j.truth, 3.0, &bd)) {
              ++s.found;
              s.Add(bd);
              b += best->xy - j.truth;
            }
          }
        }
        // cornerSubPix.
        ++s_csp.trials;
        std::vector<cv::Point2f> pts = {cv::Point2f(static_cast<float>(j.truth.x() + u(rng)), static_cast<float>(j.truth.y() + u(rng)))};
        cv::cornerSubPix(img, pts, cv::Size(5, 5), cv::Size(-1, -1),
                         cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 100, 1e-4));
        const Vec2d pc(pts[0].x, pts[0].y);
        if ((pc - j.truth).norm() < 3) {
          ++s_csp.found;
          s_csp.Add((pc - j.truth).norm());
          b_csp += pc - j.truth;
        }
        // LSD intersections.
        ++s_lsd.trials;
        const auto segs = RunLsd(img);
        auto la = LsdLineFor(segs, j.lines[0], lsd_shift), lb = LsdLineFor(segs, j.lines[1], lsd_shift);
        if (la && lb) {
          if (auto x = Intersect(*la, *lb); x && (*x - j.truth).norm() < 3) {
            ++s_lsd.found;
            s_lsd.Add((*x - j.truth).norm());
            b_lsd += *x - j.truth;
          }
        }
      }
      const double bound = std::sqrt(bound2 / trials);
      auto row = [&](const char* name, const Stats& s, const Vec2d& bias) {
        const double n = std::max(1, s.found);
        std::printf("| %s | %.0f | %.0f | %.0f | %s | %d | %.2f | %.4f | %+.4f,%+.4f | %.4f | %.2f |\n", type.c_str(), c.a,
                    c.ratio, c.blur, name, s.trials, s.Rate(), s.Rms(), bias.x() / n, bias.y() / n, bound, s.Rms() / bound);
      };
      row("IDI point", s_idi, b_idi);
      row("IDI point (flat band, ramp)", s_flat, b_flat);
      row("cornerSubPix 11x11", s_csp, b_csp);
      row("LSD intersection", s_lsd, b_lsd);
      std::fflush(stdout);
    }
  }
}

// ---- F: junction angle ---------------------------------------------------------------------------

// IDI points where the two lines meet at a shallow angle (a box's corner seen obliquely): the error against
// the bound propagated from the two lines, and against the point's own covariance (is it honest?).
void SectionF(bool quick) {
  std::printf("\n## F. IDI points against the angle between their lines (L-corners, 192x192 px, arms 70 px)\n\n");
  std::printf(
      "err/sigma: the error over the point's own predicted RMS (sqrt of its covariance's trace); about 1 when the\n");
  std::printf(
      "covariance is honest. bias: the mean error along the corner's bisector (+ into the corner's wedge).\n\n");
  std::printf(
      "| refit deg | angle deg | A | A/sigma_n | sigma_b | trials | found | RMS px | bias along bisector px | bound px "
      "| "
      "RMS/bound | median err/sigma |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  const CameraModel cam = FlatCamera(192, 192);
  struct Cfg {
    double a, ratio, blur;
  };
  const std::vector<Cfg> cfgs = {{150, 30, 1}, {40, 15, 1.5}};
  const int trials = quick ? 15 : 60;
  // The default detector, and with the refit of shallow wedges (EmplOptions::junction_refit_angle_deg) on.
  for (const double refit : {FeatureOptions{}.empl.junction_refit_angle_deg, 40.0}) {
    FeatureOptions fo;
    fo.empl.junction_refit_angle_deg = refit;
    auto det = FeatureDetector::Create(fo);
    for (const Cfg& c : cfgs) {
      for (const double angle : {12.0, 16.0, 20.0, 30.0, 45.0, 90.0}) {
        Stats s;
        std::vector<double> ratio;
        double bias = 0, bound2 = 0;
        std::mt19937 rng(static_cast<unsigned>(angle * 7 + c.ratio));
        const double sn = c.a / c.ratio;
        for (int t = 0; t < trials; ++t) {
          const Junction j = MakeJunction("L", c.a, rng, angle, angle);
          const cv::Mat img =
              Render(FlatScene(cam, j.bg, j.polys), cam, c.blur, sn, 900 + static_cast<std::uint64_t>(t));
          bound2 += JunctionBoundTrace(j, c.a, sn, c.blur);
          ++s.trials;
          auto r = det->Detect(img);
          if (!r.ok()) continue;
          double bd = 0;
          const IdiPoint* best = NearestPoint(*r, j.truth, 3.0, &bd);
          if (!best) continue;
          ++s.found;
          s.Add(bd);
          ratio.push_back(bd / std::sqrt(std::max(best->covariance.trace(), 1e-18)));
          const Vec2d bisector =
              ((j.lines[0].b - j.lines[0].a).normalized() + (j.lines[1].b - j.lines[1].a).normalized()).normalized();
          bias += bisector.dot(best->xy - j.truth);
        }
        std::sort(ratio.begin(), ratio.end());
        const double bound = std::sqrt(bound2 / trials);
        std::printf("| %.0f | %.0f | %.0f | %.0f | %.1f | %d | %.2f | %.4f | %+.4f | %.4f | %.2f | %.2f |\n",
                    refit,
                    angle,
                    c.a,
                    c.ratio,
                    c.blur,
                    s.trials,
                    s.Rate(),
                    s.Rms(),
                    s.found ? bias / s.found : NAN,
                    bound,
                    s.Rms() / bound,
                    ratio.empty() ? NAN : ratio[ratio.size() / 2]);
        std::fflush(stdout);
      }
    }
  }
}

// ---- C: chessboard, Harris (§7.13.2) -------------------------------------------------------------

struct Board {
  std::vector<Poly> polys;
  std::vector<Vec2d> corners;          // all grid intersections (inner and outer)
  std::vector<TrueLine> rows, cols;    // grid lines
};

Board MakeBoard(std::mt19937& rng, int nx, int ny, double pitch, double a) {
  std::uniform_real_distribution<double> u(0, 1);
  const double th = (u(rng) - 0.5) * 20 * kPi / 180;
  const Vec2d ex(std::cos(th), std::sin(th)), ey(-std::sin(th), std::cos(th));
  const Vec2d origin = Vec2d(319.5, 239.5) - 0.5 * nx * pitch * ex - 0.5 * ny * pitch * ey + Vec2d(u(rng) - 0.5, u(rng) - 0.5);
  Board b;
  const double bg = 0.2, fg = bg + a / 200.0;
  for (int j = 0; j < ny; ++j) {
    for (int i = 0; i < nx; ++i) {
      if ((i + j) % 2) continue;
      const Vec2d p = origin + i * pitch * ex + j * pitch * ey;
      b.polys.push_back({{p, p + pitch * ex, p + pitch * (ex + ey), p + pitch * ey}, fg});
    }
  }
  for (int j = 0; j <= ny; ++j) {
    for (int i = 0; i <= nx; ++i) b.corners.push_back(origin + i * pitch * ex + j * pitch * ey);
  }
  for (int j = 0; j <= ny; ++j) b.rows.push_back(LineThroughPts(origin + j * pitch * ey, origin + j * pitch * ey + nx * pitch * ex));
  for (int i = 0; i <= nx; ++i) b.cols.push_back(LineThroughPts(origin + i * pitch * ex, origin + i * pitch * ex + ny * pitch * ey));
  return b;
}

void SectionC(bool quick) {
  std::printf("\n## C. 640x480 chessboard (9x7 squares of 50 px, +-10 deg), sigma_b = 1, A = 150: the issue's anchors and §7.13.2\n\n");
  std::printf("All %d grid intersections (inner X-junctions and the board's outer corners) are true points.\n\n", 10 * 8);
  std::printf("Inner = the 8 x 6 X-junctions (lines over the whole board); the outer corners are L-corners of 50 px\n");
  double inner_bound[2] = {0, 0};
  {
    std::mt19937 r0(1);
    const Board b0 = MakeBoard(r0, 9, 7, 50, 150);
    for (int k = 0; k < 2; ++k) {
      const double sn = 150.0 / (k == 0 ? 30.0 : 15.0);
      double sum = 0;
      int n = 0;
      for (int j = 1; j < 7; ++j) {
        for (int i = 1; i < 9; ++i) {
          EmplLine a, c;
          const TrueLine& tr = b0.rows[static_cast<std::size_t>(j)];
          const TrueLine& tc = b0.cols[static_cast<std::size_t>(i)];
          a.normal = tr.n;
          a.offset = tr.d;
          a.covariance = BoundCovariance(tr.n, 0.5 * (tr.a + tr.b), 150, sn, 1.0, (tr.b - tr.a).norm());
          c.normal = tc.n;
          c.offset = tc.d;
          c.covariance = BoundCovariance(tc.n, 0.5 * (tc.a + tc.b), 150, sn, 1.0, (tc.b - tc.a).norm());
          if (auto x = IntersectWithCovariance(a, c)) {
            sum += x->covariance.trace();
            ++n;
          }
        }
      }
      inner_bound[k] = std::sqrt(sum / std::max(1, n));
    }
  }
  std::printf("pieces (the dark squares are the background colour). Bound for the inner points: %.4f / %.4f px at A/sigma_n 30 / 15.\n\n",
              inner_bound[0], inner_bound[1]);
  std::printf("| A/sigma_n | method | frames | found | missed | spurious | RMS px | median px | inner RMS px |\n|---|---|---|---|---|---|---|---|---|\n");
  const CameraModel cam = FlatCamera(640, 480);
  auto det = FeatureDetector::Create(FeatureOptions{});
  const int frames = quick ? 3 : 10;
  for (double ratio : {30.0, 15.0}) {
    struct Acc {
      Stats s, inner;
      int missed = 0, spurious = 0;
    };
    std::map<std::string, Acc> acc;
    std::mt19937 rng(static_cast<unsigned>(ratio));
    for (int f = 0; f < frames; ++f) {
      const Board b = MakeBoard(rng, 9, 7, 50, 150);
      const cv::Mat img = Render(FlatScene(cam, 0.2, b.polys), cam, 1.0, 150 / ratio, 77 + static_cast<std::uint64_t>(f));
      auto score = [&](const std::string& name, const std::vector<Vec2d>& found) {
        Acc& a = acc[name];
        std::vector<bool> used(found.size(), false);
        for (std::size_t ti = 0; ti < b.corners.size(); ++ti) {
          const Vec2d& t = b.corners[ti];
          const int gi = static_cast<int>(ti % 10), gj = static_cast<int>(ti / 10);
          const bool inner = gi > 0 && gi < 9 && gj > 0 && gj < 7;
          double bd = 2.0;
          int bi = -1;
          for (std::size_t k = 0; k < found.size(); ++k) {
            const double d = (found[k] - t).norm();
            if (d < bd) {
              bd = d;
              bi = static_cast<int>(k);
            }
          }
          ++a.s.trials;
          if (bi >= 0 && bd > 0.08 && std::getenv("FEATURES_BENCH_VERBOSE") && name == "IDI points") {
            std::printf("  large error %.3f at %.1f,%.1f (board origin %.1f,%.1f)\n", bd, t.x(), t.y(), b.corners[0].x(),
                        b.corners[0].y());
          }
          if (bi >= 0) {
            ++a.s.found;
            a.s.Add(bd);
            if (inner) a.inner.Add(bd);
            used[static_cast<std::size_t>(bi)] = true;
          } else {
            ++a.missed;
          }
        }
        for (bool u : used) a.spurious += u ? 0 : 1;
      };
      // IDI.
      std::vector<Vec2d> idi;
      if (auto r = det->Detect(img); r.ok()) {
        for (const IdiPoint& p : r->points) idi.push_back(p.xy);
      }
      score("IDI points", idi);
      // cornerSubPix started 1 px off the truth.
      std::uniform_real_distribution<double> u(-1, 1);
      std::vector<cv::Point2f> init;
      for (const Vec2d& t : b.corners) init.emplace_back(static_cast<float>(t.x() + u(rng)), static_cast<float>(t.y() + u(rng)));
      cv::cornerSubPix(img, init, cv::Size(5, 5), cv::Size(-1, -1),
                       cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 100, 1e-4));
      std::vector<Vec2d> csp;
      for (const cv::Point2f& p : init) csp.emplace_back(p.x, p.y);
      score("cornerSubPix 11x11 (given truth +-1 px)", csp);
      // LSD lines fitted over whole grid lines, intersected (shift removed as in B: -0.125 each).
      const auto segs = RunLsd(img);
      std::vector<std::optional<Line2d>> rl, cl;
      for (const TrueLine& t : b.rows) rl.push_back(LsdLineFor(segs, t, Vec2d(-0.125, -0.125)));
      for (const TrueLine& t : b.cols) cl.push_back(LsdLineFor(segs, t, Vec2d(-0.125, -0.125)));
      std::vector<Vec2d> lsd;
      for (const auto& r : rl) {
        for (const auto& c : cl) {
          if (r && c) {
            if (auto x = Intersect(*r, *c)) lsd.push_back(*x);
          }
        }
      }
      score("LSD grid-line intersections", lsd);
      // Harris corners (§7.13.2): detector thresholds chosen to find the board's corners, then sub-pixel.
      std::vector<cv::Point2f> harris;
      cv::goodFeaturesToTrack(img, harris, 500, 0.05, 10, cv::noArray(), 3, true, 0.04);
      if (!harris.empty()) {
        cv::cornerSubPix(img, harris, cv::Size(5, 5), cv::Size(-1, -1),
                         cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 100, 1e-4));
      }
      std::vector<Vec2d> hv;
      for (const cv::Point2f& p : harris) hv.emplace_back(p.x, p.y);
      score("Harris + cornerSubPix", hv);
    }
    for (const auto& [name, a] : acc) {
      std::printf("| %.0f | %s | %d | %d | %d | %d | %.4f | %.4f | %.4f |\n", ratio, name.c_str(), frames, a.s.found, a.missed,
                  a.spurious, a.s.Rms(), Median(a.s.err), a.inner.Rms());
    }
    std::fflush(stdout);
  }
}

// Camera at `eye` looking at `target`, image x to the right, y down (world z up).
Rigid3d LookAt(const Vec3d& eye, const Vec3d& target) {
  const Vec3d z = (target - eye).normalized();
  const Vec3d x = z.cross(Vec3d::UnitZ()).normalized();
  const Vec3d y = z.cross(x);
  Rigid3d cam_from_world;
  cam_from_world.rotation.row(0) = x.transpose();
  cam_from_world.rotation.row(1) = y.transpose();
  cam_from_world.rotation.row(2) = z.transpose();
  cam_from_world.translation = -(cam_from_world.rotation * eye);
  return cam_from_world;
}

// ---- D: object scenes ----------------------------------------------------------------------------

// The signed offset error at the middle of each true line of 60 px and more with 20 DN or more contrast
// that the detector found (pixel coordinates: for images without distortion).
std::vector<std::pair<const sim::TruthLine*, double>> LineOffsetsAtMiddle(const sim::GroundTruth& truth,
                                                                          const FeatureResult& r) {
  std::vector<std::pair<const sim::TruthLine*, double>> out;
  for (const sim::TruthLine& tl : truth.lines) {
    if (tl.length_px < 60 || std::fabs(tl.contrast_dn) < 20) continue;
    if (const EmplLine* l = test::MatchTruthLine(r, tl.normal, tl.p1_px, tl.p2_px)) {
      const Vec2d mid = 0.5 * (tl.p1_px + tl.p2_px);
      out.push_back({&tl, l->SignedDistance(mid) * (l->normal.dot(tl.normal) > 0 ? -1 : 1)});
    }
  }
  return out;
}

// FEATURES_BENCH_VERBOSE: each long line's offset error, each missed corner with its lines (found or
// not, and how far the found segment stops from the corner), each spurious point with its lines; under
// the name of the image (written by FEATURES_BENCH_DUMP=DIR) they come from.
void PrintCornerDetails(const sim::GroundTruth& truth,
                        const FeatureResult& r,
                        const std::function<Vec2d(const Vec2d&)>& to_fit,
                        bool line_offsets,
                        double blur_sigma_px) {
  std::map<int, const sim::TruthLine*> lines;
  for (const sim::TruthLine& l : truth.lines) lines[l.id] = &l;
  if (line_offsets) {
    for (const auto& [tl, offset] : LineOffsetsAtMiddle(truth, r)) {
      std::printf("  line %s len %.0f contrast %.0f: offset diff at mid %+.3f px\n",
                  tl->object.c_str(),
                  tl->length_px,
                  tl->contrast_dn,
                  offset);
    }
  }
  std::vector<Vec2d> all_junctions;
  for (const sim::TruthJunction& j : truth.junctions) all_junctions.push_back(to_fit(j.xy_px));
  for (const sim::TruthJunction& j : truth.junctions) {
    if (!j.is_vertex || j.type == "tangent") continue;
    const std::vector<const sim::TruthLine*> counted = test::CountedLines(j, lines);
    if (counted.size() < 2) continue;
    const Vec2d t = to_fit(j.xy_px);
    double bd = 2.0;
    for (const IdiPoint& p : r.points) bd = std::min(bd, (p.xy - t).norm());
    if (bd < 2.0) continue;
    // The widest angle between two of its counted lines (under test::kNearlyCollinearDeg: a slight bend).
    std::printf("  missed %s corner of %s at %.1f,%.1f (lines up to %.1f deg apart); lines:",
                j.type.c_str(),
                j.object.c_str(),
                t.x(),
                t.y(),
                std::acos(std::min(1.0, test::WidestCos(counted))) * 180 / kPi);
    std::vector<const EmplLine*> matched;
    for (int id : j.lines) {
      auto it = lines.find(id);
      if (it == lines.end()) continue;
      const sim::TruthLine& tl = *it->second;
      std::printf(" [%.0f px, %.0f DN%s",
                  tl.length_px,
                  tl.contrast_dn,
                  test::Resolvable(tl, truth.lines, blur_sigma_px) ? "" : ", not resolvable");
      // Which EMPL line explains it, and how far its confirmed segment stops from the corner (negative: it
      // reaches past it), with its extensions.
      if (const EmplLine* l = test::MatchTruthLine(r, tl.normal, to_fit(tl.p1_px), to_fit(tl.p2_px))) {
        matched.push_back(l);
        const double s = l->Direction().dot(t - l->p1), len = l->length_px;
        const double gap = s < 0 ? -s : (s > len ? s - len : -std::min(s, len - s));
        std::printf(": line %d, %.1f px off, segment gap %+.1f, ext %.0f/%.0f",
                    l->id,
                    std::fabs(l->SignedDistance(t)),
                    gap,
                    (l->extension1 - l->p1).norm(),
                    (l->extension2 - l->p2).norm());
      } else {
        const Vec2d a = to_fit(tl.p1_px), b = to_fit(tl.p2_px);
        std::printf(": no line, truth %.1f,%.1f-%.1f,%.1f", a.x(), a.y(), b.x(), b.y());
      }
      std::printf("]");
    }
    // Where the first two found lines meet, and how well they place it (IdiOptions::max_point_sigma_px).
    if (matched.size() >= 2) {
      if (const auto x = IntersectWithCovariance(*matched[0], *matched[1])) {
        std::printf("; lines %d and %d meet %.1f px off, sigma %.2f px",
                    matched[0]->id,
                    matched[1]->id,
                    (x->xy - t).norm(),
                    std::sqrt(x->covariance.trace()));
      }
    }
    std::printf("\n");
  }
  for (const IdiPoint& p : r.points) {
    double bd = 1e9;
    for (const Vec2d& t : all_junctions) bd = std::min(bd, (p.xy - t).norm());
    if (bd <= 3.0) continue;
    std::printf("  spurious point at %.1f,%.1f (sigma %.2f px, %zu lines, nearest junction %.1f px)",
                p.xy.x(),
                p.xy.y(),
                std::sqrt(p.covariance.trace()),
                p.line_ids.size(),
                bd);
    for (int id : p.line_ids) {
      for (const EmplLine& l : r.lines) {
        if (l.id == id) {
          std::printf(" [line %d: %.0f px, %.0f DN, beyond %.1f, rms %.2f]",
                      id,
                      l.length_px,
                      l.contrast,
                      DistanceBeyondSegment(l, p.xy),
                      l.fit_rms_px);
        }
      }
    }
    std::printf("%s\n", p.kind == IdiPointKind::kCurveLine ? " (curve)" : "");
  }
}

void SectionD(bool quick, int draws) {
  std::printf("\n## D. Corners of the twin's object scenes (boxes, prisms, L-brackets on a table before a wall), 640x480\n\n");
  std::printf(
      "True corners: projected 3D vertices (junction types L, Y, arrow, multi) where two of the meeting lines are\n");
  std::printf(
      "visible over >= 20 px with >= 10 DN contrast; found = an IDI point within 2 px. Spurious = IDI points "
      "farther\n");
  std::printf(
      "than 3 px from every true junction of any type (occlusion T-junctions count as real image junctions).\n");
  std::printf("(tests/support/object_scenes.h; FEATURES_BENCH_VERBOSE=1 lists every miss and spurious point.)\n");
  std::printf(
      "Each scene is rendered with %d draw(s) of the sensor noise (seeds 900 + scene + 1000 x draw; draw 0 alone is\n"
      "what this table gave before --draws). One draw is not enough: over 9 draws of the same 12 scenes, the\n"
      "spurious points of a row ranged from 3 to 8 (no clutter) and from 2 to 14 (sigma_b 2).\n\n",
      draws);
  std::printf(
      "| scenes x draws | clutter | distortion | sigma_b | true corners | found | rate | IDI points | spurious | "
      "spurious rate | RMS px |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|---|\n");
  struct Cfg {
    bool clutter, distortion;
    double blur;
  };
  const std::vector<Cfg> cfgs = {{false, false, 1}, {true, false, 1}, {true, true, 1}, {true, false, 2}};
  std::vector<test::CornerScore> scores(cfgs.size());
  // |offset error| at the middle of the long lines, default options and with the flat band and ramp
  // (rows without distortion).
  std::vector<std::array<std::vector<double>, 2>> offsets(cfgs.size());
  FeatureOptions flat_options;
  flat_options.empl.photometric_flat_band = true;
  flat_options.empl.photometric_ramp = true;
  const bool verbose = std::getenv("FEATURES_BENCH_VERBOSE") != nullptr;
  const int scenes = quick ? 3 : 12;
  for (std::size_t ci = 0; ci < cfgs.size(); ++ci) {
    const Cfg& c = cfgs[ci];
    CameraModel cam;
    cam.width = 640;
    cam.height = 480;
    cam.params = {700, 700, 319.5, 239.5, 0, 0, 0, 0, 0};
    if (c.distortion) {
      cam.params[kK1] = -0.18;
      cam.params[kK2] = 0.05;
    }
    auto det = FeatureDetector::Create(FeatureOptions{}, c.distortion ? std::optional<CameraModel>(cam) : std::nullopt);
    auto det_flat = FeatureDetector::Create(flat_options);
    std::mt19937 rng(c.clutter * 10 + c.distortion * 100 + static_cast<unsigned>(c.blur));
    for (int k = 0; k < scenes; ++k) {
      const sim::Scene scene = test::RandomObjectScene(rng, c.clutter);
      // Camera 1.2 m away, looking down at 40 deg.
      const double az = 0.3 * (k % 5) - 0.6;
      const Rigid3d cam_from_world = LookAt(Vec3d(1100 * std::sin(az), -1100 * std::cos(az), 950), Vec3d(0, 0, 60));
      for (int draw = 0; draw < draws; ++draw) {
        sim::RenderOptions o;
        o.psf_sigma_px = c.blur;
        o.seed = 900 + static_cast<std::uint64_t>(k) + 1000 * static_cast<std::uint64_t>(draw);
        sim::GroundTruth truth;
        auto img = sim::RenderScene(scene, cam, cam_from_world, o, &truth);
        if (!img.ok()) {
          std::fprintf(stderr, "render: %s\n", img.status().ToString().c_str());
          continue;
        }
        // d<row>-scene<k>.png, the names the verbose listing gives.
        const std::string image_name = "d" + std::to_string(ci) + "-scene" + std::to_string(k) +
                                       (draw > 0 ? "-draw" + std::to_string(draw) : std::string()) + ".png";
        if (const char* dump = std::getenv("FEATURES_BENCH_DUMP"))
          cv::imwrite(std::string(dump) + "/" + image_name, *img);
        auto r = det->Detect(*img);
        if (!r.ok()) continue;
        if (!c.distortion) {
          for (const auto& [tl, e] : LineOffsetsAtMiddle(truth, *r)) offsets[ci][0].push_back(std::fabs(e));
          if (auto rf = det_flat->Detect(*img); rf.ok()) {
            for (const auto& [tl, e] : LineOffsetsAtMiddle(truth, *rf)) offsets[ci][1].push_back(std::fabs(e));
          }
        }
        // Truth in the coordinates the detector reports (undistorted when distortion is modelled).
        auto to_fit = [&](const Vec2d& px) { return c.distortion ? UndistortPixel(cam, px) : px; };
        scores[ci].Add(test::ScoreCorners(truth, *r, to_fit, c.blur));
        if (verbose) std::printf("  %s (table row %zu, scene %d):\n", image_name.c_str(), ci + 1, k);
        if (verbose) PrintCornerDetails(truth, *r, to_fit, !c.distortion, c.blur);
      }
    }
    const test::CornerScore& sc = scores[ci];
    Stats err;
    for (const double e : sc.errors_px) err.Add(e);
    std::printf("| %d x %d | %s | %s | %.0f | %d | %d | %.3f | %d | %d | %.3f | %.3f |\n",
                scenes,
                draws,
                c.clutter ? "texture" : "none",
                c.distortion ? "k1 -0.18" : "none",
                c.blur,
                sc.total,
                sc.found,
                sc.total ? static_cast<double>(sc.found) / sc.total : NAN,
                sc.points,
                sc.spurious,
                sc.points ? static_cast<double>(sc.spurious) / sc.points : NAN,
                err.Rms());
    std::fflush(stdout);
  }
  std::printf(
      "\nWhy corners were missed: fewer than two of their lines found (a line within 2 deg and 2 px at its middle),\n");
  std::printf(
      "or found but fewer than two confirmed segments reach the corner within their extensions, or neither.\n"
      "Across those causes: corners whose lines all meet at less than %.0f deg (a slight bend, usually fitted\n"
      "as one line; IdiOptions::min_angle_deg makes no point there), and the rate without them.\n\n",
      test::kNearlyCollinearDeg);
  std::printf(
      "| clutter | distortion | sigma_b | missed | line not found | segment stops short | other | nearly collinear: "
      "missed / all | rate without them |\n|---|---|---|---|---|---|---|---|---|\n");
  for (std::size_t k = 0; k < cfgs.size(); ++k) {
    const test::CornerScore& m = scores[k];
    const int rest = m.total - m.nearly_collinear;
    std::printf(
        "| %s | %s | %.0f | %d | %d | %d | %d | %d / %d | %.3f |\n",
        cfgs[k].clutter ? "texture" : "none",
        cfgs[k].distortion ? "k1 -0.18" : "none",
        cfgs[k].blur,
        m.total - m.found,
        m.miss_line_not_found,
        m.miss_segment_short,
        m.miss_other,
        m.nearly_collinear_missed,
        m.nearly_collinear,
        rest > 0 ? static_cast<double>(m.found - (m.nearly_collinear - m.nearly_collinear_missed)) / rest : 0.0);
  }
  std::printf(
      "\nThe same corners counted only where they can be resolved: at least two of their lines have a stretch of\n"
      ">= %.0f px that keeps more than 2 sigma_b + 1 px from every other true line of >= 10 DN (test::Resolvable);\n"
      "closer than that, two blurred edges make one gradient ridge (an L-bracket's plate seen edge-on, the sides\n"
      "of a thin wedge). The last three columns also leave out the nearly collinear ones (under %.0f deg). Shown\n"
      "beside the rates above, not instead of them: the goal is stated for visible corners.\n\n",
      test::kResolvableRunPx,
      test::kNearlyCollinearDeg);
  std::printf(
      "| clutter | distortion | sigma_b | resolvable / all corners | found | rate | and not nearly collinear | found | "
      "rate |\n|---|---|---|---|---|---|---|---|---|\n");
  for (std::size_t k = 0; k < cfgs.size(); ++k) {
    const test::CornerScore& m = scores[k];
    std::printf("| %s | %s | %.0f | %d / %d | %d | %.3f | %d | %d | %.3f |\n",
                cfgs[k].clutter ? "texture" : "none",
                cfgs[k].distortion ? "k1 -0.18" : "none",
                cfgs[k].blur,
                m.resolvable,
                m.total,
                m.resolvable_found,
                m.resolvable > 0 ? static_cast<double>(m.resolvable_found) / m.resolvable : 0.0,
                m.resolvable_angled,
                m.resolvable_angled_found,
                m.resolvable_angled > 0 ? static_cast<double>(m.resolvable_angled_found) / m.resolvable_angled : 0.0);
  }
  std::printf(
      "\nLine offsets: |error| at the middle of every true line of >= 60 px and >= 20 DN that was found (rows\n"
      "without distortion), with the default options and with the photometric fit's flat band and ramp\n"
      "(EmplOptions::photometric_flat_band, photometric_ramp).\n\n");
  std::printf(
      "| clutter | sigma_b | lines | default median px | default 90th px | flat band median px | flat band 90th px "
      "|\n");
  std::printf("|---|---|---|---|---|---|---|\n");
  auto quantile = [](std::vector<double> v, double q) {
    if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
    std::sort(v.begin(), v.end());
    return v[std::min(v.size() - 1, static_cast<std::size_t>(q * static_cast<double>(v.size())))];
  };
  for (std::size_t k = 0; k < cfgs.size(); ++k) {
    if (cfgs[k].distortion) continue;
    const auto& o = offsets[k];
    std::printf("| %s | %.0f | %zu / %zu | %.4f | %.4f | %.4f | %.4f |\n",
                cfgs[k].clutter ? "texture" : "none",
                cfgs[k].blur,
                o[0].size(),
                o[1].size(),
                quantile(o[0], 0.5),
                quantile(o[0], 0.9),
                quantile(o[1], 0.5),
                quantile(o[1], 0.9));
  }
}

// ---- E: timing -----------------------------------------------------------------------------------

void SectionE(bool quick) {
  std::printf("\n## E. Time per 640x480 frame, one thread (cv::setNumThreads(1)), same frames and run\n\n");
  std::printf("CPU time of the calling thread (the machine is shared, so wall time is also given); median of the runs.\n\n");
  std::printf("| frame | method | runs | median CPU ms | median wall ms | output |\n|---|---|---|---|---|---|\n");
  cv::setNumThreads(1);
  std::mt19937 rng(3);
  const CameraModel flat = FlatCamera(640, 480);
  const Board b = MakeBoard(rng, 9, 7, 50, 150);
  CameraModel cam;
  cam.params = {700, 700, 319.5, 239.5, 0, 0, 0, 0, 0};
  std::vector<std::pair<std::string, cv::Mat>> frames = {
      {"chessboard A/sigma 15", Render(FlatScene(flat, 0.2, b.polys), flat, 1.0, 10, 1)}};
  {
    sim::RenderOptions o;
    o.seed = 5;
    auto img =
        sim::RenderScene(test::RandomObjectScene(rng, true), cam, LookAt(Vec3d(0, -1100, 950), Vec3d(0, 0, 60)), o);
    if (img.ok()) frames.push_back({"object scene with clutter", *img});
  }
  const int runs = quick ? 10 : 40;
  auto det = FeatureDetector::Create(FeatureOptions{});
  FeatureOptions fast;
  fast.empl.photometric_refinement = false;
  fast.curves.enabled = false;
  auto det_fast = FeatureDetector::Create(fast);
  FeatureOptions flat_band;
  flat_band.empl.photometric_flat_band = true;
  flat_band.empl.photometric_ramp = true;
  auto det_flat = FeatureDetector::Create(flat_band);
  cv::Ptr<cv::ximgproc::EdgeDrawing> ed = cv::ximgproc::createEdgeDrawing();
  cv::Ptr<cv::LineSegmentDetector> lsd = cv::createLineSegmentDetector(cv::LSD_REFINE_STD);
  if (const char* dump = std::getenv("FEATURES_BENCH_DUMP")) {
    for (std::size_t i = 0; i < frames.size(); ++i) {
      cv::imwrite(std::string(dump) + "/frame" + std::to_string(i) + ".png", frames[i].second);
    }
  }
  for (const auto& [name, img] : frames) {
    auto time = [&](const std::string& method, const std::function<std::string()>& f) {
      std::vector<double> cpu, wall;
      std::string out;
      for (int i = 0; i < runs; ++i) {
        const auto w0 = std::chrono::steady_clock::now();
        cpu.push_back(CpuMs([&] { out = f(); }));
        wall.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - w0).count());
      }
      std::printf("| %s | %s | %d | %.2f | %.2f | %s |\n", name.c_str(), method.c_str(), runs, Median(cpu), Median(wall),
                  out.c_str());
      std::fflush(stdout);
    };
    // The pipeline's own stage times (wall, median over the runs) beside its output.
    const cv::Mat* frame = &img;
    auto pipeline = [frame](FeatureDetector& d) {
      std::vector<FeatureTimings> stages;
      return [&d, frame, stages]() mutable {
        auto r = d.Detect(*frame);
        stages.push_back(r->timing);
        auto med = [&](double FeatureTimings::*m) {
          std::vector<double> v;
          for (const FeatureTimings& t : stages) v.push_back(t.*m);
          return Median(v);
        };
        char buf[256];
        std::snprintf(
            buf,
            sizeof buf,
            "%zu lines, %zu points; stages (median wall ms): gradient %.2f, edges %.2f, Hough %.2f, EMPL %.2f, "
            "points %.2f, curves %.2f",
            r->lines.size(),
            r->points.size(),
            med(&FeatureTimings::gradient_ms),
            med(&FeatureTimings::edges_ms),
            med(&FeatureTimings::hough_ms),
            med(&FeatureTimings::empl_ms),
            med(&FeatureTimings::points_ms),
            med(&FeatureTimings::curves_ms));
        return std::string(buf);
      };
    };
    time("IDI pipeline (image in -> IDI points, photometric EMPL, curves)", pipeline(*det));
    time("IDI pipeline, gradient EMPL only (eq. 7.26), no curves", pipeline(*det_fast));
    time("IDI pipeline, photometric EMPL with the flat band and ramp", pipeline(*det_flat));
    time("EDLines (ximgproc EdgeDrawing)", [&] {
      cv::Mat lines;
      ed->detectEdges(img);
      ed->detectLines(lines);
      return std::to_string(lines.rows) + " segments";
    });
    time("OpenCV LSD", [&] {
      std::vector<cv::Vec4f> segs;
      lsd->detect(img, segs);
      return std::to_string(segs.size()) + " segments";
    });
    time("Canny alone (Sobel 3, 50/150)", [&] {
      cv::Mat e;
      cv::Canny(img, e, 50, 150);
      return std::to_string(cv::countNonZero(e)) + " edge px";
    });
  }
}

}  // namespace
}  // namespace idi

int main(int argc, char** argv) {
  bool quick = false;
  int draws = 3;
  std::string section = "ABCDEF";
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--quick") {
      quick = true;
    } else if (a == "--draws" && i + 1 < argc) {
      draws = std::atoi(argv[++i]);
      if (draws < 1 || draws > 100) {
        std::fprintf(stderr, "features_bench: --draws takes 1 to 100, got '%s'\n", argv[i]);
        return 2;
      }
    } else if (a == "--section" && i + 1 < argc) {
      section = argv[++i];
      if (section.empty() || section.find_first_not_of("ABCDEF") != std::string::npos) {
        std::fprintf(stderr, "features_bench: --section takes letters of ABCDEF, got '%s'\n", section.c_str());
        return 2;
      }
    } else {
      const bool help = a == "--help" || a == "-h";
      std::fprintf(help ? stdout : stderr,
                   "%susage: features_bench [--quick] [--section LETTERS] [--draws N]\n"
                   "  --quick            fewer trials and runs per row\n"
                   "  --draws N          section D: noise draws per scene (default 3)\n"
                   "  --section LETTERS  any of E (time per frame), A (lines vs the bound), B (junctions),\n"
                   "                     C (chessboard anchors, §7.13.2), D (the twin's object scenes),\n"
                   "                     F (L-corners against their angle); default ABCDEF\n"
                   "Markdown tables on stdout. FEATURES_BENCH_VERBOSE=1 lists section D's misses and spurious\n"
                   "points per image; FEATURES_BENCH_DUMP=DIR writes section E's frames and section D's images\n"
                   "(d<row>-scene<k>.png, rows counted from 0) as PNG.\n",
                   help ? "" : ("features_bench: unknown option '" + a + "'\n").c_str());
      return help ? 0 : 2;
    }
  }
  std::printf("# features_bench%s\n", quick ? " (--quick)" : "");
  if (section.find('E') != std::string::npos) idi::SectionE(quick);
  if (section.find('A') != std::string::npos) idi::SectionA(quick);
  if (section.find('B') != std::string::npos) idi::SectionB(quick);
  if (section.find('C') != std::string::npos) idi::SectionC(quick);
  if (section.find('D') != std::string::npos) idi::SectionD(quick, draws);
  if (section.find('F') != std::string::npos) idi::SectionF(quick);
  return 0;
}
