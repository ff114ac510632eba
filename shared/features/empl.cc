#include "shared/features/empl.h"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <numeric>
#include <tuple>

#include "shared/util/statistics.h"

namespace idi {
namespace {

constexpr double kEmplPi = 3.14159265358979323846;

// Normal CDF Phi(z) and density phi(z) by table with linear interpolation (error < 2e-6): the
// photometric fit evaluates them for every pixel of every band several times per frame.
class NormalTable {
 public:
  static constexpr double kRange = 8.0;
  static constexpr int kPerUnit = 128;
  static constexpr int kSize = static_cast<int>(2 * kRange * kPerUnit) + 2;

  NormalTable() {
    for (int i = 0; i < kSize; ++i) {
      const double z = -kRange + static_cast<double>(i) / kPerUnit;
      entry_[static_cast<std::size_t>(i)] = {0.5 * std::erfc(-z / std::sqrt(2.0)),
                                             std::exp(-0.5 * z * z) / std::sqrt(2.0 * kEmplPi)};
    }
  }
  void Eval(double z, double* cdf, double* pdf) const {
    if (z <= -kRange) {
      *cdf = 0;
      *pdf = 0;
      return;
    }
    if (z >= kRange) {
      *cdf = 1;
      *pdf = 0;
      return;
    }
    const double f = (z + kRange) * kPerUnit;
    const int i = static_cast<int>(f);
    const double a = f - i;
    const Entry& lo = entry_[static_cast<std::size_t>(i)];
    const Entry& hi = entry_[static_cast<std::size_t>(i) + 1];
    *cdf = lo.cdf + a * (hi.cdf - lo.cdf);
    *pdf = lo.pdf + a * (hi.pdf - lo.pdf);
  }

 private:
  // Phi and phi side by side: one interpolation reads 32 consecutive bytes.
  struct Entry {
    double cdf, pdf;
  };
  std::array<Entry, kSize> entry_{};
};

const NormalTable& Normal() {
  static const NormalTable table;
  return table;
}

// The photometric fit of one line's pixels (see EmplFitter::PhotometricRefine): a blurred step
// b_k + a_k Phi((n . u - e) / sigma) [+ m_k d] per chunk k, with d the distance from the starting line
// (N = 3: the background's slope across the edge) or without it (N = 2).
struct PhotometricSolution {
  double theta = 0, e = 0, sigma = 0;
  std::vector<double> contrast;  // a_k
  Eigen::Matrix3d information;   // of (theta, e, sigma), the chunks' linear parameters eliminated
  double rss = 0;
};

// A pixel's linear regressors (Phi, 1[, d]); x^T l as x0 l0 + x1 l1 [+ x2 l2], the order of the Eigen
// expression it replaced.
template <int N>
struct Regressors {
  double v[N];
  double Dot(const double* l) const {
    double d = v[0] * l[0] + v[1] * l[1];
    if constexpr (N == 3) d += v[2] * l[2];
    return d;
  }
};

template <int N>
bool SolvePhotometric(
    std::vector<EmplPixel>& px, int n_chunks, double theta, double e, double sigma, PhotometricSolution* out) {
  using VecN = Eigen::Matrix<double, N, 1>;
  using MatN = Eigen::Matrix<double, N, N>;
  using MatN3 = Eigen::Matrix<double, N, 3>;
  const std::size_t nc = static_cast<std::size_t>(n_chunks);
  const NormalTable& normal = Normal();
  const double c0 = std::cos(theta), s0 = std::sin(theta), e0 = e;
  // The linear regressors of a pixel: (Phi, 1[, d]).
  auto regressors = [&](const EmplPixel& p, double cdf) {
    Regressors<N> x;
    x.v[0] = cdf;
    x.v[1] = 1.0;
    if constexpr (N == 3) {
      x.v[2] = c0 * p.ux + s0 * p.uy - e0;
    }
    return x;
  };
  std::vector<VecN> lin(nc, VecN::Zero());  // (a_k, b_k[, m_k])
  // The band's pixels come chunk by chunk (PhotometricRefine numbers the chunks in order): chunk k is
  // px[first[k], first[k + 1]).
  std::vector<std::size_t> first(nc + 1, px.size());
  for (std::size_t i = px.size(); i-- > 0;) {
    first[static_cast<std::size_t>(px[i].chunk)] = i;
  }
  for (std::size_t k = nc; k-- > 0;) {
    first[k] = std::min(first[k], first[k + 1]);
  }
  constexpr double kFlatZ = 4.5;  // Phi(4.5) = 1 - 3.4e-6
  // The step's profile at a pixel: Phi(z) and phi(z). The flat image beside the edge (most of a wide
  // band) tells only the chunk's linear parameters: the step's slope there is below 4e-5 of its peak,
  // and its Jacobian is left 0.
  const auto profile = [&normal](double z, double* cdf, double* pdf) {
    if (std::fabs(z) > kFlatZ) {
      *cdf = z > 0 ? 1.0 : 0.0;
      *pdf = 0;
    } else {
      normal.Eval(z, cdf, pdf);
    }
  };
  // The starting geometry's profile, kept for the first Gauss-Newton pass (which evaluates the model at
  // the same geometry).
  thread_local std::vector<double> start_z, start_cdf, start_pdf;
  start_z.resize(px.size());
  start_cdf.resize(px.size());
  start_pdf.resize(px.size());
  // The chunks' linear parameters for the starting geometry: N x N linear least squares each, its sums
  // in locals over the chunk's pixels.
  const double inv_sigma0 = 1.0 / sigma;
  for (std::size_t k = 0; k < nc; ++k) {
    MatN hh = MatN::Zero();
    VecN hb = VecN::Zero();
    double h[N][N] = {}, b[N] = {};
    for (std::size_t i = first[k]; i < first[k + 1]; ++i) {
      const EmplPixel& p = px[i];
      const double z = (c0 * p.ux + s0 * p.uy - e) * inv_sigma0;
      double cdf, pdf;
      profile(z, &cdf, &pdf);
      start_z[i] = z;
      start_cdf[i] = cdf;
      start_pdf[i] = pdf;
      const Regressors<N> x = regressors(p, cdf);
      const double r = static_cast<double>(p.value);
#pragma GCC unroll 3
      for (int j = 0; j < N; ++j) {
#pragma GCC unroll 3
        for (int q = 0; q < N; ++q) h[q][j] += x.v[q] * x.v[j];
        b[j] += x.v[j] * r;
      }
    }
    for (int j = 0; j < N; ++j) {
      for (int q = 0; q < N; ++q) hh(q, j) = h[q][j];
      hb(j) = b[j];
    }
    if (!(hh.determinant() > 1e-9 * (hh.diagonal().prod() + 1e-30))) {
      return false;
    }
    lin[k] = hh.inverse() * hb;
  }
  // Gauss-Newton on (theta, e, sigma) with each chunk's linear parameters eliminated by the Schur
  // complement. Each pass accumulates the normal equations at the current estimate; a pass that finds a
  // larger residual than the previous one reverts to it and stops (the start is already close).
  struct ChunkAcc {
    MatN hcc = MatN::Zero();    // x^T x
    MatN3 hcg = MatN3::Zero();  // x^T J
    VecN bc = VecN::Zero();     // x^T r
  };
  std::vector<ChunkAcc> chunks(nc);
  std::vector<MatN> hcc_inv(nc);
  Eigen::Matrix3d s_mat = Eigen::Matrix3d::Identity();
  double rss = 0;
  // The estimate before the last step, to go back to when the step raised the residual.
  struct Saved {
    double theta, e, sigma, rss;
    std::vector<VecN> lin;
    Eigen::Matrix3d s;
  } prev{theta, e, sigma, std::numeric_limits<double>::infinity(), lin, s_mat};
  double outlier_cut = std::numeric_limits<double>::infinity();
  // Each pass first evaluates the model at every pixel it keeps (its regressors, residual and
  // Jacobian, in columns), then forms the sums column by column with a few accumulators at a time:
  // summed in one loop, the 21 running sums did not fit the registers and each pixel's additions
  // waited on the stores of the one before. Every sum still adds its terms in pixel order.
  thread_local std::vector<double> col_x0, col_x2, col_r, col_j0, col_j1, col_j2;
  for (std::vector<double>* v : {&col_x0, &col_x2, &col_r, &col_j0, &col_j1, &col_j2}) {
    v->resize(px.size());
  }
  std::vector<std::size_t> kept_end(nc);
  for (int iter = 0; iter < 6; ++iter) {
    const double c = std::cos(theta), s = std::sin(theta), inv_sigma = 1.0 / sigma;
    std::size_t n = 0;
    for (std::size_t k = 0; k < nc; ++k) {
      const double* l = lin[k].data();
      for (std::size_t i = first[k]; i < first[k + 1]; ++i) {
        EmplPixel& p = px[i];
        if (p.weight == 0.0f) {
          continue;
        }
        double z, cdf, pdf;
        if (iter == 0) {
          z = start_z[i];
          cdf = start_cdf[i];
          pdf = start_pdf[i];
        } else {
          z = (c * p.ux + s * p.uy - e) * inv_sigma;
          profile(z, &cdf, &pdf);
        }
        const Regressors<N> x = regressors(p, cdf);
        const double r = p.value - x.Dot(l);
        if (std::fabs(r) > outlier_cut) {
          p.weight = 0.0f;  // specks and clutter far off the model
          continue;
        }
        const double ap = l[0] * pdf * inv_sigma;
        // d model / d(theta, e, sigma); d model / d(linear parameters) = x.
        col_x0[n] = cdf;
        if constexpr (N == 3) col_x2[n] = x.v[2];
        col_r[n] = r;
        col_j0[n] = ap * (-s * p.ux + c * p.uy);
        col_j1[n] = -ap;
        col_j2[n] = -ap * z;
        ++n;
      }
      kept_end[k] = n;
    }
    // The chunks' sums: x^T x and x^T r, then x^T J (x = (Phi, 1[, d]); a product with its 1 is exact).
    for (std::size_t k = 0, lo = 0; k < nc; lo = kept_end[k], ++k) {
      const std::size_t hi = kept_end[k];
      ChunkAcc& ck = chunks[k];
      double h00 = 0, h01 = 0, h11 = 0, h02 = 0, h12 = 0, h22 = 0, b0 = 0, b1 = 0, b2 = 0;
      for (std::size_t i = lo; i < hi; ++i) {
        const double x0 = col_x0[i], r = col_r[i];
        h00 += x0 * x0;
        h01 += x0;
        h11 += 1.0;
        b0 += x0 * r;
        b1 += r;
        if constexpr (N == 3) {
          const double x2 = col_x2[i];
          h02 += x0 * x2;
          h12 += x2;
          h22 += x2 * x2;
          b2 += x2 * r;
        }
      }
      ck.hcc(0, 0) = h00;
      ck.hcc(0, 1) = ck.hcc(1, 0) = h01;
      ck.hcc(1, 1) = h11;
      ck.bc(0) = b0;
      ck.bc(1) = b1;
      if constexpr (N == 3) {
        ck.hcc(0, 2) = ck.hcc(2, 0) = h02;
        ck.hcc(1, 2) = ck.hcc(2, 1) = h12;
        ck.hcc(2, 2) = h22;
        ck.bc(2) = b2;
      }
      double g00 = 0, g01 = 0, g02 = 0, g10 = 0, g11 = 0, g12 = 0, g20 = 0, g21 = 0, g22 = 0;
      for (std::size_t i = lo; i < hi; ++i) {
        const double x0 = col_x0[i], j0 = col_j0[i], j1 = col_j1[i], j2 = col_j2[i];
        g00 += x0 * j0;
        g01 += x0 * j1;
        g02 += x0 * j2;
        g10 += j0;
        g11 += j1;
        g12 += j2;
        if constexpr (N == 3) {
          const double x2 = col_x2[i];
          g20 += x2 * j0;
          g21 += x2 * j1;
          g22 += x2 * j2;
        }
      }
      ck.hcg(0, 0) = g00;
      ck.hcg(0, 1) = g01;
      ck.hcg(0, 2) = g02;
      ck.hcg(1, 0) = g10;
      ck.hcg(1, 1) = g11;
      ck.hcg(1, 2) = g12;
      if constexpr (N == 3) {
        ck.hcg(2, 0) = g20;
        ck.hcg(2, 1) = g21;
        ck.hcg(2, 2) = g22;
      }
    }
    // The geometry's sums J^T J and J^T r, and the residual, over all pixels in order.
    double q00 = 0, q01 = 0, q02 = 0, q11 = 0, q12 = 0, q22 = 0, r0 = 0, r1 = 0, r2 = 0, rr = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const double r = col_r[i], j0 = col_j0[i], j1 = col_j1[i], j2 = col_j2[i];
      rr += r * r;
      q00 += j0 * j0;
      q01 += j0 * j1;
      q02 += j0 * j2;
      q11 += j1 * j1;
      q12 += j1 * j2;
      q22 += j2 * j2;
      r0 += r * j0;
      r1 += r * j1;
      r2 += r * j2;
    }
    rss = rr;
    Eigen::Matrix3d hgg;
    hgg << q00, q01, q02, q01, q11, q12, q02, q12, q22;
    const Eigen::Vector3d gg(r0, r1, r2);
    if (rss > prev.rss * (1.0 + 1e-9)) {
      std::tie(theta, e, sigma, rss, lin, s_mat) = std::tie(prev.theta, prev.e, prev.sigma, prev.rss, prev.lin, prev.s);
      break;
    }
    Eigen::Matrix3d schur = hgg;
    Eigen::Vector3d rhs = gg;
    for (std::size_t k = 0; k < nc; ++k) {
      const ChunkAcc& ck = chunks[k];
      const double det = ck.hcc.determinant();
      if (!(det > 1e-12 * (ck.hcc.diagonal().prod() + 1e-30))) {
        return false;
      }
      hcc_inv[k] = ck.hcc.inverse();
      schur -= ck.hcg.transpose() * hcc_inv[k] * ck.hcg;
      rhs -= ck.hcg.transpose() * hcc_inv[k] * ck.bc;
    }
    s_mat = schur;
    const Eigen::Vector3d dg = schur.ldlt().solve(rhs);
    if (!dg.allFinite()) {
      return false;
    }
    prev = {theta, e, sigma, rss, lin, schur};
    for (std::size_t k = 0; k < nc; ++k) {
      lin[k] += hcc_inv[k] * (chunks[k].bc - chunks[k].hcg * dg);
    }
    theta += dg(0);
    e += dg(1);
    sigma = std::clamp(sigma + dg(2), 0.15, 12.0);
    if (iter == 0) {
      outlier_cut = 5.0 * std::sqrt(rss / static_cast<double>(px.size()));
      prev.rss = std::numeric_limits<double>::infinity();  // the cut changes the residual set
    }
    // Converged when the last step is far below the noise (the step itself is applied): below fixed
    // steps, or below a tenth of each parameter's own standard deviation (the information of this pass
    // with the residual variance), where what is left of the step adds at most 1 % to the variance. On
    // a short or weak line the fixed steps are far finer than its precision: with the relative test the
    // passes on the object scene of features_bench E went from 3.96 to 3.17 a line on average (EMPL
    // 1.40 -> 1.34 ms). Sections B-D moved in the third significant digit at most, A as well but for one
    // row at the detection limit (contrast 20, A/sigma_n 5, 20 px, flat band and ramp: found 0.65 -> 0.62).
    if (iter >= 1 && std::fabs(dg(1)) < 1e-3 && std::fabs(dg(0)) < 1e-5 && std::fabs(dg(2)) < 1e-2) {
      break;
    }
    if (iter >= 1) {
      const double dof = static_cast<double>(n) - 3.0 - static_cast<double>(N * n_chunks);
      const Eigen::Matrix3d cov = schur.inverse() * (rss / std::max(1.0, dof));
      if (cov.diagonal().allFinite() && (dg.array().abs() < 0.1 * cov.diagonal().array().max(0.0).sqrt()).all()) {
        break;
      }
    }
  }
  out->theta = theta;
  out->e = e;
  out->sigma = sigma;
  out->contrast.resize(nc);
  for (std::size_t k = 0; k < nc; ++k) {
    out->contrast[k] = lin[k](0);
  }
  out->information = s_mat;
  out->rss = rss;
  return true;
}

// Angle difference wrapped to (-pi/2, pi/2] (lines are undirected).
double WrapHalfPi(double a) {
  a = std::fmod(a, kEmplPi);
  if (a > 0.5 * kEmplPi) {
    a -= kEmplPi;
  } else if (a <= -0.5 * kEmplPi) {
    a += kEmplPi;
  }
  return a;
}

}  // namespace

struct EmplFitter::Station {
  double t = 0;
  int major = 0;
  int minor_base = 0;  // rounded line position on the minor axis (pixel)
  bool horizontal = true;
  bool has_peak = false;
  bool valid = false;
  bool outlier = false;
  Vec2d point = Vec2d::Zero();  // sub-pixel edge point, fit coordinates
  double strength = 0;          // |gradient along the normal| at the peak
  double band_mean = 0;         // mean gradient magnitude over the band (eq. 7.29)
  double grad_angle = 0;        // undirected gradient angle at the peak, [0, pi)
  int sign = 0;                 // contrast sign relative to the normal
  double width2 = 0;            // squared width of the gradient profile (Gaussian fit), 0 if unknown
  double tangential = 0;        // largest gradient component along the line within the band
  bool avoided = false;         // near an edge the request keeps clear of: confirms the extent, not fitted
};

namespace {

// Whether `p` lies within the request's clearance of one of the segments it avoids.
bool NearAvoided(const EmplRequest& request, const Vec2d& p) {
  const double c2 = request.avoid_clearance_px * request.avoid_clearance_px;
  for (const auto& [a, b] : request.avoid) {
    const Vec2d d = b - a;
    const double len2 = d.squaredNorm();
    const double t = len2 > 0 ? std::clamp(d.dot(p - a) / len2, 0.0, 1.0) : 0.0;
    if ((a + t * d - p).squaredNorm() < c2) {
      return true;
    }
  }
  return false;
}

}  // namespace

double ExtensionLength(const EmplOptions& o, double length_px, double blur_sigma_px) {
  const double least = std::max(o.min_extension_px, o.min_extension_blur_sigmas * std::max(0.0, blur_sigma_px));
  return std::clamp(o.extension_fraction * length_px, std::min(least, o.max_extension_px), o.max_extension_px);
}

void SetLineGeometry(double theta,
                     double e,
                     const Vec2d& centre,
                     const Eigen::Matrix2d& cov_theta_e,
                     double blur_sigma_px,
                     const EmplOptions& options,
                     EmplFitResult* result) {
  EmplLine& line = result->line;
  Vec2d n(std::cos(theta), std::sin(theta));
  double d = n.dot(centre) + e;
  Eigen::Matrix2d j;
  j << 1, 0, Vec2d(-std::sin(theta), std::cos(theta)).dot(centre), 1;
  Eigen::Matrix2d cov = j * cov_theta_e * j.transpose();
  // Normalise the angle to [0, pi).
  double angle = std::atan2(n.y(), n.x());
  if (angle < 0 || angle >= kEmplPi) {
    n = -n;
    d = -d;
    cov(0, 1) = -cov(0, 1);
    cov(1, 0) = -cov(1, 0);
  }
  line.normal = n;
  line.offset = d;
  line.covariance = cov;
  // Ends: the confirmed extent projected onto the final line.
  const Vec2d foot = n * d, dir = LineDirection(n);
  const Vec2d a = foot + dir * dir.dot(line.p1 - foot);
  const Vec2d b = foot + dir * dir.dot(line.p2 - foot);
  line.p1 = a;
  line.p2 = b;
  line.length_px = (b - a).norm();
  const Vec2d u = line.length_px > 0 ? Vec2d((b - a) / line.length_px) : dir;
  const double ext = ExtensionLength(options, line.length_px, blur_sigma_px);
  line.extension1 = a - ext * u;
  line.extension2 = b + ext * u;
  result->t0 = dir.dot(a - foot);
  result->t1 = dir.dot(b - foot);
  if (result->t0 > result->t1) {
    std::swap(result->t0, result->t1);
  }
}

EmplFitter::EmplFitter(const GradientImages& g,
                       const PixelGeometry& geometry,
                       const EdgeMap& edges,
                       const FeatureOptions& options,
                       std::vector<EmplPixel>* scratch)
    : g_(g),
      geometry_(geometry),
      edges_(edges),
      options_(options),
      scratch_(scratch),
      cos_tol_(std::cos(options.empl.max_angle_error_deg * kEmplPi / 180.0)),
      noise_gain_(GradientNoiseGain(g.smoothing_sigma_px)),
      proximity_(options.empl.peak_proximity_sigma_px > 0
                     ? 1.0 / (options.empl.peak_proximity_sigma_px * options.empl.peak_proximity_sigma_px)
                     : 0.0) {}

void EmplFitter::Scan(const Vec2d& normal, double offset, double t_lo, double t_hi, std::vector<Station>* out) const {
  out->clear();
  const int w = g_.width(), h = g_.height();
  const int delta = std::max(1, static_cast<int>(std::ceil(options_.empl.band_halfwidth_px)));
  const Vec2d dir = LineDirection(normal);
  const Vec2d foot = normal * offset;
  const bool ident = geometry_.identity();
  // Without distortion the major coordinate advances by max(|dir.x|, |dir.y|) >= 0.707 per unit t:
  // stepping by the inverse visits every column (or row) once.
  const double step = ident ? 1.0 / std::max(std::fabs(dir.x()), std::fabs(dir.y())) - 1e-9 : 0.35;
  int last_major = std::numeric_limits<int>::min();
  bool last_horizontal = true;
  std::array<double, 64> gn{}, gm{};
  for (double t = t_lo; t <= t_hi; t += step) {
    const Vec2d q = geometry_.ToPixel(foot + t * dir);
    Vec2d dir_px = dir;
    if (!ident) {
      dir_px = (geometry_.ToPixel(foot + (t + 0.5) * dir) - geometry_.ToPixel(foot + (t - 0.5) * dir)).normalized();
    }
    const bool horizontal = std::fabs(dir_px.x()) >= std::fabs(dir_px.y());
    const double qmaj = horizontal ? q.x() : q.y();
    const int major = RoundToInt(qmaj);
    if (major == last_major && horizontal == last_horizontal) {
      continue;
    }
    last_major = major;
    last_horizontal = horizontal;
    const double dmaj = horizontal ? dir_px.x() : dir_px.y();
    const double dmin = horizontal ? dir_px.y() : dir_px.x();
    const double minor = (horizontal ? q.y() : q.x()) + (major - qmaj) * dmin / dmaj;
    const int base = RoundToInt(minor);
    const int major_size = horizontal ? w : h, minor_size = horizontal ? h : w;
    if (major < 0 || major >= major_size || base - delta - 1 < 0 || base + delta + 1 >= minor_size) {
      continue;
    }
    Station s;
    s.t = t + (major - qmaj) / dmaj;
    s.major = major;
    s.minor_base = base;
    s.horizontal = horizontal;
    const Vec2d n_px(dir_px.y(), -dir_px.x());
    double best = 0, mean = 0, tang = 0;
    int best_k = 0;
    for (int k = -delta - 1; k <= delta + 1; ++k) {
      const int px = horizontal ? major : base + k;
      const int py = horizontal ? base + k : major;
      const float gxv = g_.gx.at<float>(py, px), gyv = g_.gy.at<float>(py, px);
      const double v = gxv * n_px.x() + gyv * n_px.y();
      // gx^2 + gy^2 in float as the gradient stage forms mag2 (the same value where neither is fused
      // into a multiply-add, as on x86-64; on arm64 the last bit may differ), from the two loads already
      // made: a third image's column was a third of the scan's cache misses.
      const float m2 = gxv * gxv + gyv * gyv;
      const double m = std::sqrt(static_cast<double>(m2));
      const std::size_t i = static_cast<std::size_t>(k + delta + 1);
      gn[i] = v;
      gm[i] = m;
      if (k >= -delta && k <= delta) {
        mean += m;
        tang = std::max(tang, std::fabs(gxv * dir_px.x() + gyv * dir_px.y()));
      }
    }
    if (proximity_ > 0) {
      // The edge is the profile's peak nearest the line, not the strongest in the band: a stronger
      // edge a few pixels away (a thin face seen edge-on, a shallow junction) must not take its place.
      const double k_line = minor - base;
      double best_score = 0;
      for (int k = -delta; k <= delta; ++k) {
        const std::size_t i = static_cast<std::size_t>(k + delta + 1);
        const double a = std::fabs(gn[i]);
        if (!(a >= cos_tol_ * gm[i]) || a == 0) continue;
        const double sg = gn[i] > 0 ? 1.0 : -1.0;
        if (sg * gn[i - 1] > a || sg * gn[i + 1] > a) continue;
        const double dk = k - k_line;
        const double score = a * std::exp(-0.5 * dk * dk * proximity_);
        if (score > best_score) {
          best_score = score;
          best = a;
          best_k = k;
        }
      }
    } else {
      for (int k = -delta; k <= delta; ++k) {
        const std::size_t i = static_cast<std::size_t>(k + delta + 1);
        if (std::fabs(gn[i]) > best && std::fabs(gn[i]) >= cos_tol_ * gm[i]) {
          best = std::fabs(gn[i]);
          best_k = k;
        }
      }
    }
    // Per unit of perpendicular band width: a column crosses an oblique edge over a longer stretch.
    s.band_mean = mean / (2 * delta + 1) * std::fabs(horizontal ? n_px.y() : n_px.x());
    s.tangential = tang;
    if (best > 0) {
      const std::size_t i = static_cast<std::size_t>(best_k + delta + 1);
      const int sign = gn[i] > 0 ? 1 : -1;
      const double vm = sign * gn[i - 1], v0 = sign * gn[i], vp = sign * gn[i + 1];
      if (v0 >= vm && v0 >= vp) {
        // Sub-pixel peak of the gradient profile: Gaussian (log-parabola) fit, exact for a Gaussian
        // profile; a parabola where a neighbour is not positive.
        double off = 0, width2 = 0;
        if (vm > 0 && vp > 0) {
          const double a = std::log(vm), b = std::log(v0), c = std::log(vp);
          const double den = a - 2 * b + c;
          if (den < 0) {
            off = 0.5 * (a - c) / den;
            width2 = -1.0 / den;
          }
        } else {
          const double den = vm - 2 * v0 + vp;
          if (den < 0) {
            off = 0.5 * (vm - vp) / den;
          }
        }
        off = std::clamp(off, -0.5, 0.5);
        const double minor_px = base + best_k + off;
        const Vec2d p_px = horizontal ? Vec2d(major, minor_px) : Vec2d(minor_px, major);
        s.point = geometry_.ToFit(p_px);
        s.has_peak = true;
        s.strength = v0;
        s.sign = sign;
        s.width2 = width2;
        const int px = horizontal ? major : base + best_k;
        const int py = horizontal ? base + best_k : major;
        double ang = FastAtan2(g_.gy.at<float>(py, px), g_.gx.at<float>(py, px));
        if (ang < 0) {
          ang += kEmplPi;
        }
        if (ang >= kEmplPi) {
          ang -= kEmplPi;
        }
        s.grad_angle = ang;
      }
    }
    out->push_back(s);
  }
}

namespace {

// Weighted fit of eq. 7.26 about `centre`: minimises sum w ((n(theta)·(p-c) - e)^2 + lambda
// (theta - alpha)^2) by Gauss-Newton from the total least squares solution; lambda balances the
// orientational against the positional error by their observed variances.
struct GradientFit {
  double theta = 0, e = 0;
  Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
  double rms = 0;
};

bool FitEq726(const std::vector<Vec2d>& p, const std::vector<double>& w, const std::vector<double>& alpha,
              const Vec2d& centre, double theta_hint, GradientFit* fit) {
  const std::size_t n = p.size();
  if (n < 3) {
    return false;
  }
  Vec2d normal;
  double offset;
  if (!FitLineTls(p, &w, &normal, &offset)) {
    return false;
  }
  double theta = std::atan2(normal.y(), normal.x());
  // Keep the orientation close to the hint so that the sign of e stays meaningful.
  if (std::cos(theta - theta_hint) < 0) {
    theta += kEmplPi;
    normal = -normal;
    offset = -offset;
  }
  double e = offset - normal.dot(centre);
  // Variances for lambda.
  double sw = 0, sp = 0, sa = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const Vec2d nn(std::cos(theta), std::sin(theta));
    const double r = nn.dot(p[i] - centre) - e;
    const double ra = WrapHalfPi(theta - alpha[i]);
    sw += w[i];
    sp += w[i] * r * r;
    sa += w[i] * ra * ra;
  }
  const double lambda = sa > 0 ? std::min(1e4, sp / sa) : 0.0;
  Eigen::Matrix2d hess;
  double rss = 0;
  for (int iter = 0; iter < 3; ++iter) {
    hess.setZero();
    Eigen::Vector2d grad = Eigen::Vector2d::Zero();
    const Vec2d nn(std::cos(theta), std::sin(theta)), nd(-std::sin(theta), std::cos(theta));
    rss = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const Vec2d q = p[i] - centre;
      const double r = nn.dot(q) - e;
      const Eigen::Vector2d j(nd.dot(q), -1.0);
      const double ra = WrapHalfPi(theta - alpha[i]);
      hess += w[i] * (j * j.transpose());
      hess(0, 0) += w[i] * lambda;
      grad += w[i] * (j * r);
      grad(0) += w[i] * lambda * ra;
      rss += w[i] * (r * r + lambda * ra * ra);
    }
    const Eigen::Vector2d step = hess.ldlt().solve(-grad);
    if (!step.allFinite()) {
      return false;
    }
    theta += step(0);
    e += step(1);
    if (step.norm() < 1e-9) {
      break;
    }
  }
  double sr = 0;
  const Vec2d nn(std::cos(theta), std::sin(theta));
  for (std::size_t i = 0; i < n; ++i) {
    const double r = nn.dot(p[i] - centre) - e;
    sr += r * r;
  }
  fit->theta = theta;
  fit->e = e;
  fit->rms = std::sqrt(sr / static_cast<double>(n));
  fit->cov = hess.inverse() * (rss / std::max(1.0, static_cast<double>(n) - 2.0));
  (void)sw;
  return fit->cov.allFinite();
}

}  // namespace

std::vector<EmplFitResult> EmplFitter::Fit(const EmplRequest& request) const {
  const EmplOptions& eo = options_.empl;
  const HoughOptions& ho = options_.hough;
  Vec2d normal = request.segment.normal;
  double offset = request.segment.offset;
  double ta = std::max(request.segment.t0, request.t_limit_lo);
  double tb = std::min(request.segment.t1, request.t_limit_hi);
  if (tb - ta < 2) {
    return {};
  }
  const double gap = ho.max_gap_px + 1.0;
  std::vector<Station> st, extra;
  std::vector<double> prefix, band;
  std::vector<Vec2d> pts;
  std::vector<double> wts, alphas;
  std::vector<std::size_t> idx;
  // A station's peak must stand out of the gradient noise (Canny's low threshold, a multiple of the
  // noise estimated from the image), not be a fraction of the line's typical strength: where the
  // lighting makes two faces' contrast fade along their edge, its faint end is still edge (0.3 of
  // the median strength cut one segment 9 px short of its corner on the object scenes).
  const double floor = edges_.low_threshold;
  GradientFit fit;
  Vec2d centre = Vec2d::Zero();
  std::size_t run_begin = 0, run_end = 0;
  const int window = std::max(1, static_cast<int>(std::lround(eo.threshold_window_px)));
  // A curved silhouette is not a line (§7.9.1): a significant quadratic in the residuals along the
  // run. Tested on every iteration's fit: a run that is curved stays curved when the line is
  // refined (growing only adds to the bend), so it is given up at once instead of refitted.
  bool kinked = false;   // the run bends at one point: it must split (or it is not a line)
  double curve_rss = 0;  // the quadratic's weighted residual sum of squares, from the last curved()
  // Whether a quadratic in the residuals along the run is significant, fitted to the points at least
  // `trim` px from the run's ends; its weighted residual sum of squares over those points in *rss.
  const auto bends = [&](double trim, double* rss_out) {
    const Vec2d nn(std::cos(fit.theta), std::sin(fit.theta)), dd(-nn.y(), nn.x());
    double t_first = 1e18, t_last = -1e18;
    for (const Vec2d& p : pts) {
      t_first = std::min(t_first, dd.dot(p - centre));
      t_last = std::max(t_last, dd.dot(p - centre));
    }
    const double lo = t_first + trim, hi = t_last - trim;
    double m[5] = {0, 0, 0, 0, 0}, b[3] = {0, 0, 0};  // sums of w t^k and of w r t^k
    double tmin = 1e18, tmax = -1e18;
    std::size_t used = 0;
    for (std::size_t i = 0; i < pts.size(); ++i) {
      const double t = dd.dot(pts[i] - centre), r = nn.dot(pts[i] - centre) - fit.e;
      if (t < lo || t > hi) continue;
      const double w = wts[i], t2 = t * t;
      m[0] += w;
      m[1] += w * t;
      m[2] += w * t2;
      m[3] += w * t2 * t;
      m[4] += w * t2 * t2;
      b[0] += w * r;
      b[1] += w * r * t;
      b[2] += w * r * t2;
      tmin = std::min(tmin, t);
      tmax = std::max(tmax, t);
      ++used;
    }
    if (trim > 0 && used < 5) return false;  // too little left without the ends to tell
    Eigen::Matrix3d ata;
    ata << m[0], m[1], m[2], m[1], m[2], m[3], m[2], m[3], m[4];
    const Eigen::Vector3d q = ata.ldlt().solve(Eigen::Vector3d(b[0], b[1], b[2]));
    double rss = 0;
    for (std::size_t i = 0; i < pts.size(); ++i) {
      const double t = dd.dot(pts[i] - centre), r = nn.dot(pts[i] - centre) - fit.e;
      if (t < lo || t > hi) continue;
      const double res = r - (q(0) + q(1) * t + q(2) * t * t);
      rss += wts[i] * res * res;
    }
    *rss_out = rss;
    const double var = rss / std::max(1.0, static_cast<double>(used) - 3.0);
    const Eigen::Matrix3d inv = ata.inverse();
    const double sigma_c = std::sqrt(std::max(0.0, inv(2, 2) * var));
    const double half = 0.5 * (tmax - tmin);
    const double sagitta = std::fabs(q(2)) * half * half;
    const double radius = std::fabs(q(2)) > 0 ? 0.5 / std::fabs(q(2)) : 1e18;
    // A run long enough for the split test below is a curve only when it bends clearly more than the
    // disturbed ends of a straight edge do (see EmplOptions::curve_min_sagitta_px).
    const bool splittable = pts.size() >= 2 * static_cast<std::size_t>(ho.min_length_px);
    const double min_sagitta = splittable ? eo.curve_min_sagitta_px : eo.curve_min_sagitta_short_px;
    return q.allFinite() && radius < eo.curve_max_radius_px && sagitta > min_sagitta && std::fabs(q(2)) > 5.0 * sigma_c;
  };
  // Curved over the whole run and still curved without its ends (EmplOptions::curve_end_trim_px): the
  // last pixels of a straight edge before a junction bend towards the other edge, which a short run
  // cannot tell from an arc.
  const auto curved = [&]() {
    if (!bends(0.0, &curve_rss)) return false;
    double interior_rss = 0;
    return !(eo.curve_end_trim_px > 0) || bends(eo.curve_end_trim_px, &interior_rss);
  };
  // The best two-piece total least squares fit of the current points (a kink: two edges that nearly
  // line up), from prefix sums of the weighted moments; its break index 0 when the run is too short.
  std::vector<std::array<double, 6>> pre;
  struct TwoPiece {
    std::size_t k = 0;   // first point of the second piece
    double rss_all = 0;  // one line
    double rss = 0;      // two lines
    double dangle = 0;   // angle between the pieces (rad)
  };
  // Total least squares of points [a, b): its weighted residual sum of squares, and its direction.
  const auto tls = [&](std::size_t a, std::size_t b, double* angle) {  // angle may be null
    double m[6];
    for (int k = 0; k < 6; ++k) {
      m[k] = pre[b][static_cast<std::size_t>(k)] - pre[a][static_cast<std::size_t>(k)];
    }
    const double mx = m[1] / m[0], my = m[2] / m[0];
    const double cxx = m[3] / m[0] - mx * mx, cxy = m[4] / m[0] - mx * my, cyy = m[5] / m[0] - my * my;
    if (angle) {
      *angle = 0.5 * std::atan2(2 * cxy, cxx - cyy);
    }
    const double tr = cxx + cyy, det = cxx * cyy - cxy * cxy;
    const double lmin = 0.5 * tr - std::sqrt(std::max(0.0, 0.25 * tr * tr - det));
    return std::max(0.0, lmin) * m[0];
  };
  const auto two_piece = [&]() {
    TwoPiece out;
    const std::size_t n = pts.size(), m = static_cast<std::size_t>(ho.min_length_px);
    pre.assign(n + 1, {0, 0, 0, 0, 0, 0});
    for (std::size_t i = 0; i < n; ++i) {
      const Vec2d q = pts[i] - centre;
      const double w = wts[i];
      pre[i + 1] = {pre[i][0] + w,
                    pre[i][1] + w * q.x(),
                    pre[i][2] + w * q.y(),
                    pre[i][3] + w * q.x() * q.x(),
                    pre[i][4] + w * q.x() * q.y(),
                    pre[i][5] + w * q.y() * q.y()};
    }
    if (n < 2 * m || m == 0) {
      return out;
    }
    out.rss_all = tls(0, n, nullptr);
    out.rss = out.rss_all;
    for (std::size_t k = m; k + m <= n; ++k) {
      const double rss = tls(0, k, nullptr) + tls(k, n, nullptr);
      if (rss < out.rss) {
        out.rss = rss;
        out.k = k;
      }
    }
    if (out.k > 0) {
      double a1, a2;
      tls(0, out.k, &a1);
      tls(out.k, n, &a2);
      out.dangle = std::fabs(WrapHalfPi(a1 - a2));
    }
    return out;
  };
  for (int iter = 0; iter < eo.max_iterations; ++iter) {
    double lo = std::max(ta - gap - 2, request.t_limit_lo);
    double hi = std::min(tb + gap + 2, request.t_limit_hi);
    // Scan, growing the range while the edge evidence reaches its ends (only the new stretch is
    // scanned each time).
    Scan(normal, offset, lo, hi, &st);
    for (int grow = 0; grow < 64; ++grow) {
      if (st.empty()) {
        return {};
      }
      // Adaptive local threshold (eq. 7.29): alpha times the band's gradient level within +-epsilon,
      // that level being the mean of the stations' band means there; with EmplOptions::threshold_median,
      // lowered to their median where that is lower (a short strong stretch raises the mean, not the
      // median), but not below half the mean. Only a station between the two thresholds needs the median.
      const std::size_t ns = st.size();
      prefix.assign(ns + 1, 0.0);
      for (std::size_t i = 0; i < ns; ++i) {
        prefix[i + 1] = prefix[i] + st[i].band_mean;
      }
      for (std::size_t i = 0; i < ns; ++i) {
        const std::size_t a = i >= static_cast<std::size_t>(window) ? i - static_cast<std::size_t>(window) : 0;
        const std::size_t b = std::min(ns, i + static_cast<std::size_t>(window) + 1);
        const double local_mean = (prefix[b] - prefix[a]) / static_cast<double>(b - a);
        Station& x = st[i];
        x.valid = x.has_peak && x.strength >= floor && x.strength >= eo.threshold_alpha * local_mean;
        if (!x.valid && eo.threshold_median && x.has_peak && x.strength >= floor &&
            x.strength >= 0.5 * eo.threshold_alpha * local_mean) {
          band.clear();
          for (std::size_t k = a; k < b; ++k) {
            band.push_back(st[k].band_mean);
          }
          x.valid = x.strength >= eo.threshold_alpha * Median(band);
        }
      }
      // Grow when valid stations come within a gap of a scan end that is not a hard limit.
      bool grew = false;
      const auto first_valid = std::find_if(st.begin(), st.end(), [](const Station& x) { return x.valid; });
      const auto last_valid = std::find_if(st.rbegin(), st.rend(), [](const Station& x) { return x.valid; });
      if (first_valid == st.end()) {
        return {};
      }
      const bool grow_lo = first_valid->t - st.front().t < gap && lo > request.t_limit_lo && st.front().t - lo < 2;
      const bool grow_hi = st.back().t - last_valid->t < gap && hi < request.t_limit_hi && hi - st.back().t < 2;
      if (grow_lo) {
        const double new_lo = std::max(lo - 64, request.t_limit_lo);
        Scan(normal, offset, new_lo, lo - 0.25, &extra);
        const Station front = st.front();
        std::erase_if(extra, [&](const Station& x) {
          return x.t >= front.t || (x.major == front.major && x.horizontal == front.horizontal);
        });
        st.insert(st.begin(), extra.begin(), extra.end());
        lo = new_lo;
        grew = true;
      }
      if (grow_hi) {
        const double new_hi = std::min(hi + 64, request.t_limit_hi);
        Scan(normal, offset, hi + 0.25, new_hi, &extra);
        const Station back = st.back();
        std::erase_if(extra, [&](const Station& x) {
          return x.t <= back.t || (x.major == back.major && x.horizontal == back.horizontal);
        });
        st.insert(st.end(), extra.begin(), extra.end());
        hi = new_hi;
        grew = true;
      }
      if (!grew) {
        break;
      }
    }
    // Runs of valid stations; keep the one overlapping the requested stretch most.
    std::size_t best_b = 0, best_e = 0;
    double best_overlap = -1e18;
    for (std::size_t i = 0; i < st.size();) {
      if (!st[i].valid) {
        ++i;
        continue;
      }
      std::size_t j = i, last = i;
      while (j < st.size() && (!st[j].valid || st[j].t - st[last].t <= gap)) {
        if (st[j].valid) {
          last = j;
        }
        ++j;
      }
      const double overlap = std::min(tb, st[last].t) - std::max(ta, st[i].t);
      if (overlap > best_overlap) {
        best_overlap = overlap;
        best_b = i;
        best_e = last + 1;
      }
      i = last + 1;
    }
    if (best_e <= best_b || st[best_e - 1].t - st[best_b].t + 1 < ho.min_length_px) {
      return {};
    }
    run_begin = best_b;
    run_end = best_e;
    for (std::size_t i = run_begin; i < run_end; ++i) {
      st[i].avoided = NearAvoided(request, st[i].point);
    }
    // Fit eq. 7.26 with outlier rejection.
    for (int pass = 0; pass < 2; ++pass) {
      pts.clear();
      wts.clear();
      alphas.clear();
      idx.clear();
      for (std::size_t i = run_begin; i < run_end; ++i) {
        if (st[i].valid && !st[i].outlier && !st[i].avoided) {
          pts.push_back(st[i].point);
          wts.push_back(st[i].strength);
          alphas.push_back(st[i].grad_angle);
          idx.push_back(i);
        }
      }
      if (pts.size() < 3) {
        return {};
      }
      double sw = 0;
      centre.setZero();
      for (std::size_t i = 0; i < pts.size(); ++i) {
        centre += wts[i] * pts[i];
        sw += wts[i];
      }
      centre /= sw;
      if (!FitEq726(pts, wts, alphas, centre, std::atan2(normal.y(), normal.x()), &fit)) {
        return {};
      }
      const Vec2d nn(std::cos(fit.theta), std::sin(fit.theta));
      std::vector<double> absr;
      for (const Vec2d& q : pts) {
        absr.push_back(std::fabs(nn.dot(q - centre) - fit.e));
      }
      const double robust = std::max(0.05, 1.4826 * Median(absr));
      bool dropped = false;
      for (std::size_t k = 0; k < pts.size(); ++k) {
        if (absr[k] > eo.outlier_sigmas * robust) {
          st[idx[k]].outlier = true;
          dropped = true;
        }
      }
      if (!dropped) {
        break;
      }
    }
    if (curved()) {
      // Two edges meeting at a shallow angle (a prism's ridge seen nearly end-on) bend the run as
      // much as an arc does; the kink is told apart by two lines fitting at least as well as the
      // quadratic. It goes on to the split below; a true curve is left to the active contours.
      const TwoPiece kink = two_piece();
      if (request.split_depth >= 2 || kink.k == 0 || kink.rss > curve_rss) {
        return {};
      }
      kinked = true;
      break;
    }
    const Vec2d new_normal(std::cos(fit.theta), std::sin(fit.theta));
    const double new_offset = new_normal.dot(centre) + fit.e;
    const double change = std::fabs(WrapHalfPi(std::atan2(new_normal.y(), new_normal.x()) -
                                               std::atan2(normal.y(), normal.x()))) *
                              100.0 +
                          std::fabs(new_offset - offset * new_normal.dot(normal));
    // Extent in the new parameterisation.
    const Vec2d foot = new_normal * new_offset, dir = LineDirection(new_normal);
    const double sgn = new_normal.dot(normal) >= 0 ? 1.0 : -1.0;
    const Vec2d pa = st[run_begin].point, pb = st[run_end - 1].point;
    const double moved = std::max(std::fabs((new_normal.dot(pa) - new_offset) - sgn * (normal.dot(pa) - offset)),
                                  std::fabs((new_normal.dot(pb) - new_offset) - sgn * (normal.dot(pb) - offset)));
    normal = sgn * new_normal;
    offset = sgn * new_offset;
    const Vec2d dir_kept = LineDirection(normal), foot_kept = normal * offset;
    ta = dir_kept.dot(pa - foot_kept);
    tb = dir_kept.dot(pb - foot_kept);
    if (ta > tb) {
      std::swap(ta, tb);
    }
    (void)foot;
    (void)dir;
    // The stations depend on the line only through the band's placement: rescan only when the
    // line moved noticeably over the segment (it is refitted from the same stations otherwise).
    if ((change < 1e-3 && iter > 0) || moved < 0.3) {
      break;
    }
    for (Station& s : st) {
      s.outlier = false;
    }
  }

  // False merge (§8.8.2 "false augmented EMPL segment"): two edges that nearly line up. Test every
  // breakpoint with a two-piece total least squares fit from prefix sums of the weighted moments.
  if (request.split_depth < 2 && pts.size() >= 2 * static_cast<std::size_t>(ho.min_length_px)) {
    const std::size_t n = pts.size();
    const TwoPiece tp = two_piece();
    const std::size_t best_k = tp.k;
    const double best_rss = tp.rss, rss_all = tp.rss_all, best_dang = tp.dangle;
    const double f = best_rss > 0 ? (rss_all - best_rss) / 2.0 / (best_rss / static_cast<double>(n - 4)) : 0.0;
    if (best_k > 0 && best_dang > eo.split_angle_deg * kEmplPi / 180.0 && f > 50.0) {
      const double t_split = 0.5 * (st[idx[best_k - 1]].t + st[idx[best_k]].t);
      const Vec2d foot_parent = normal * offset, dir_parent = LineDirection(normal);
      std::vector<EmplFitResult> out;
      for (int side = 0; side < 2; ++side) {
        // Each piece starts from its own total least squares line (not the parent's compromise
        // between the two), so its fit starts where it will end up; its stretch and limits are the
        // parent's, carried onto that line.
        const std::size_t a = side == 0 ? 0 : best_k, b = side == 0 ? best_k : n;
        double angle;
        tls(a, b, &angle);
        const double sw_piece = pre[b][0] - pre[a][0];
        const Vec2d piece_centre =
            centre + Vec2d(pre[b][1] - pre[a][1], pre[b][2] - pre[a][2]) / sw_piece;
        Vec2d piece_normal(-std::sin(angle), std::cos(angle));
        if (piece_normal.dot(normal) < 0) {
          piece_normal = -piece_normal;
        }
        const double piece_offset = piece_normal.dot(piece_centre);
        const Vec2d dir_piece = LineDirection(piece_normal), foot_piece = piece_normal * piece_offset;
        const auto carried = [&](double t_parent) {
          return std::isfinite(t_parent) ? dir_piece.dot(foot_parent + t_parent * dir_parent - foot_piece) : t_parent;
        };
        EmplRequest child;
        child.split_depth = request.split_depth + 1;
        child.segment.normal = piece_normal;
        child.segment.offset = piece_offset;
        child.segment.t0 = carried(side == 0 ? st[idx.front()].t : t_split + 1);
        child.segment.t1 = carried(side == 0 ? t_split - 1 : st[idx.back()].t);
        child.t_limit_lo = carried(side == 0 ? request.t_limit_lo : t_split + 0.5);
        child.t_limit_hi = carried(side == 0 ? t_split - 0.5 : request.t_limit_hi);
        child.avoid = request.avoid;
        child.avoid_clearance_px = request.avoid_clearance_px;
        for (EmplFitResult& r : Fit(child)) {
          out.push_back(std::move(r));
        }
      }
      if (!out.empty()) {
        return out;
      }
    }
  }
  if (kinked) {
    return {};  // bent like a curve and no two lines explain it: not a line
  }
  if (eo.max_fit_rms_px > 0 && fit.rms > eo.max_fit_rms_px) {
    return {};  // the points scatter over the band: noise peaks, or several edges, not one
  }

  EmplFitResult result;
  result.line.p1 = st[run_begin].point;
  result.line.p2 = st[run_end - 1].point;
  result.line.fit_rms_px = fit.rms;
  result.line.support = static_cast<int>(pts.size());
  double contrast_sum = 0;
  int pos = 0, neg = 0;
  std::vector<double> widths;
  for (std::size_t i : idx) {
    contrast_sum += st[i].strength;
    (st[i].sign > 0 ? pos : neg) += 1;
    if (st[i].width2 > 0) {
      widths.push_back(st[i].width2);
    }
  }
  // Gradient-peak contrast: the peak of a blurred step's derivative is A / (sqrt(2 pi) sigma).
  const double prof_sigma = widths.empty() ? 1.5 : std::sqrt(Median(widths));
  result.line.contrast = contrast_sum / static_cast<double>(idx.size()) * std::sqrt(2 * kEmplPi) * prof_sigma;
  result.line.alternating = std::min(pos, neg) >= static_cast<int>(ho.min_length_px / 2);
  double theta = fit.theta, e = fit.e;
  Eigen::Matrix2d cov = fit.cov;
  if (eo.photometric_refinement) {
    // Edge width without the smoothing and the central difference (variance 1/3 of the sampled
    // derivative): the starting sigma of the blurred step.
    const double s = g_.smoothing_sigma_px;
    const double sigma_init = std::sqrt(std::max(0.09, prof_sigma * prof_sigma - s * s - 1.0 / 3.0));
    if (PhotometricRefine(st, run_begin, run_end, ta, tb, centre, sigma_init, &theta, &e, &result)) {
      cov = result.line.covariance;
      result.photometric = true;
    } else {
      theta = fit.theta;
      e = fit.e;
    }
  }
  // The edge's blur for the extension: the photometric fit's, or else the gradient profile's.
  const double s_smooth = g_.smoothing_sigma_px;
  const double edge_sigma = result.photometric
                                ? result.line.blur_sigma_px
                                : std::sqrt(std::max(0.09, prof_sigma * prof_sigma - s_smooth * s_smooth - 1.0 / 3.0));
  SetLineGeometry(theta, e, centre, cov, edge_sigma, eo, &result);
  // Station RMS against the final line.
  double sr = 0;
  for (const Vec2d& q : pts) {
    const double r = result.line.SignedDistance(q);
    sr += r * r;
  }
  result.line.fit_rms_px = std::sqrt(sr / static_cast<double>(pts.size()));
  return {result};
}

bool EmplFitter::PhotometricRefine(const std::vector<Station>& st, std::size_t begin, std::size_t end, double t0,
                                   double t1, const Vec2d& centre, double sigma_init, double* theta_io, double* e_io,
                                   EmplFitResult* result) const {
  const EmplOptions& eo = options_.empl;
  double theta = *theta_io, e = *e_io, sigma = std::clamp(sigma_init, 0.3, 6.0);
  const int half = std::clamp(static_cast<int>(std::ceil(2.0 * sigma + 1.5)), 3, 9);
  const int wide = eo.photometric_flat_band ? 2 * half + 2 : half;
  const double flat_g = edges_.low_threshold;
  const float flat_g2 = static_cast<float>(flat_g * flat_g);
  const int flat_margin = static_cast<int>(std::ceil(sigma)) + 1;
  const int w = g_.width(), h = g_.height();
  // photometric_stop_at_other_edge: the window keeps at least this much of the step's own profile.
  const bool stop_at_other_edge = eo.photometric_stop_at_other_edge;
  const int min_reach = std::max(2, static_cast<int>(std::ceil(sigma)));
  const double nrm_x = std::cos(theta), nrm_y = std::sin(theta);
  // Pixels of the clean stations, grouped into chunks with their own contrast and background.
  using Px = EmplPixel;
  std::vector<Px>& px = *scratch_;
  px.clear();
  std::vector<int> chunk_sign;
  int chunk = -1, in_chunk = 0, last_sign = 0;
  double last_t = -1e18;
  const int chunk_len = std::max(4, static_cast<int>(eo.chunk_length_px));
  int stations_used = 0;
  // The flat band's texture test (below): each pixel's side (0 inside +-half, 1 / 2 the outer band
  // before / after the line), and per outer side the sums it needs.
  const bool texture_test = eo.photometric_flat_band && eo.flat_band_max_texture_ratio > 0;
  static thread_local std::vector<std::uint8_t> side_of;
  side_of.clear();
  double high[2] = {0, 0}, smooth[2] = {0, 0}, mean_gx[2] = {0, 0}, mean_gy[2] = {0, 0};
  int counted[2] = {0, 0};
  // Near a confirmed end the edge fades into a corner over a few blur widths.
  const double end_margin = std::max(eo.end_margin_px, 1.5 * sigma);
  for (std::size_t i = begin; i < end; ++i) {
    const Station& s = st[i];
    if (!s.valid || s.outlier || s.avoided || s.t < t0 + end_margin || s.t > t1 - end_margin) {
      continue;
    }
    // Another edge crossing the band (corners, junctions, clutter) breaks the one-step model.
    if (s.tangential > 0.5 * s.strength) {
      continue;
    }
    if (s.minor_base - half < 0 || s.minor_base + half >= (s.horizontal ? h : w)) {
      continue;
    }
    if (chunk < 0 || s.sign != last_sign || in_chunk >= chunk_len || s.t - last_t > 3.0) {
      ++chunk;
      chunk_sign.push_back(s.sign);
      in_chunk = 0;
    }
    ++in_chunk;
    ++stations_used;
    last_sign = s.sign;
    last_t = s.t;
    // With photometric_flat_band, beyond +-half the band goes on over the flat image on each side, up to
    // +-wide: those pixels fix the
    // chunk's background and contrast, with which the edge's position is otherwise confounded (both move
    // the pixels near the edge the same way). With +-4 px alone that costs 40 % of the information on the
    // offset (the fit's error was 1.3 times the Cramer-Rao bound). The band stops short of the first pixel
    // whose gradient passes Canny's low threshold: another edge or texture, whose blur reaches a little
    // way towards this edge.
    const int minor_size = s.horizontal ? h : w;
    int reach[2] = {half, half};
    for (int side = 0; side < 2; ++side) {
      const int dir = side == 0 ? -1 : 1;
      int k = half + 1;
      for (; k <= wide; ++k) {
        const int m = s.minor_base + dir * k;
        if (m < 0 || m >= minor_size) {
          break;
        }
        const float g2 = s.horizontal ? g_.mag2.at<float>(m, s.major) : g_.mag2.at<float>(s.major, m);
        if (g2 > flat_g2) {
          k -= flat_margin;
          break;
        }
      }
      reach[side] = std::max(half, k - 1);
    }
    if (stop_at_other_edge) {
      // An edge of the opposite sign inside the step's own window (the far side of a thin face seen
      // edge-on): the one-step model does not hold there, so the window stops short of that edge's
      // blur. Two pixels in a row beyond Canny's low threshold, so that noise alone seldom stops it.
      auto signed_grad = [&](int k) {
        const int x = s.horizontal ? s.major : s.minor_base + k;
        const int y = s.horizontal ? s.minor_base + k : s.major;
        return g_.gx.at<float>(y, x) * nrm_x + g_.gy.at<float>(y, x) * nrm_y;
      };
      const double own = signed_grad(0);
      const double sg = own > 0 ? 1.0 : -1.0;
      for (int side = 0; side < 2; ++side) {
        const int dir = side == 0 ? -1 : 1;
        for (int k = 1; k <= reach[side]; ++k) {
          if (sg * signed_grad(dir * k) < -flat_g &&
              (k + 1 > reach[side] || sg * signed_grad(dir * (k + 1)) < -flat_g)) {
            reach[side] = std::max(min_reach, k - flat_margin);
            break;
          }
        }
      }
    }
    for (int k = -reach[0]; k <= reach[1]; ++k) {
      const int x = s.horizontal ? s.major : s.minor_base + k;
      const int y = s.horizontal ? s.minor_base + k : s.major;
      const Vec2d u = geometry_.ToFit(x, y) - centre;
      px.push_back({static_cast<float>(u.x()), static_cast<float>(u.y()), g_.raw.at<float>(y, x), chunk, 1.0f});
      if (!texture_test) continue;
      const int side = k < -half ? 1 : k > half ? 2 : 0;
      side_of.push_back(static_cast<std::uint8_t>(side));
      if (side != 0 && x > 0 && y > 0 && x < w - 1 && y < h - 1) {
        const float* a = g_.raw.ptr<float>(y - 1);
        const float* b = g_.raw.ptr<float>(y);
        const float* c = g_.raw.ptr<float>(y + 1);
        const double r =
            (a[x - 1] - 2 * a[x] + a[x + 1]) - 2 * (b[x - 1] - 2 * b[x] + b[x + 1]) + (c[x - 1] - 2 * c[x] + c[x + 1]);
        high[side - 1] += r * r;
        smooth[side - 1] += g_.mag2.at<float>(y, x);
        mean_gx[side - 1] += g_.gx.at<float>(y, x);
        mean_gy[side - 1] += g_.gy.at<float>(y, x);
        counted[side - 1] += 1;
      }
    }
  }
  // The flat band on a side is kept only where the image there is flat but for the noise (and a
  // uniform shading ramp): texture, and the blur tails of other edges, raise the energy of the smoothed
  // gradient's variation there while the high-pass energy of the same pixels (Immerkaer's mask
  // [1 -2 1; -2 4 -2; 1 -2 1], blind to smooth shading) stays that of the noise. For white noise
  // sigma, E[|g - mean g|^2] = 2 (gain sigma)^2 and E[r^2] = 36 sigma^2.
  if (texture_test) {
    bool drop[2] = {false, false};
    for (int sd = 0; sd < 2; ++sd) {
      if (counted[sd] == 0) continue;
      // The side's mean gradient is a shading ramp (the ramp parameter's business), not texture.
      const double nc = counted[sd];
      const double varying = smooth[sd] - (mean_gx[sd] * mean_gx[sd] + mean_gy[sd] * mean_gy[sd]) / nc;
      // The band stops short of gradients above Canny's low threshold T, so the noise's squared gradient
      // there is that of a Rayleigh variable cut at T: 2 s^2 (1 - (1 + t^2/2) e^(-t^2/2)) / (1 - e^(-t^2/2)),
      // t = T / s, s = the gradient noise from the high-pass energy.
      const double s2 = std::max(1e-12, high[sd] / (36.0 * nc) * noise_gain_ * noise_gain_);
      const double half_t2 = 0.5 * static_cast<double>(flat_g2) / s2, eh = std::exp(-std::min(half_t2, 700.0));
      const double cut = half_t2 > 1e-6 ? (1.0 - (1.0 + half_t2) * eh) / (1.0 - eh) : 0.5 * half_t2;
      const double ratio = varying / (2.0 * s2 * std::max(cut, 1e-6) * nc);
      drop[sd] = ratio > eo.flat_band_max_texture_ratio;
    }
    if (drop[0] || drop[1]) {
      std::size_t o = 0;
      for (std::size_t i = 0; i < px.size(); ++i) {
        const int sd = side_of[i];
        if (sd != 0 && drop[sd - 1]) continue;
        px[o++] = px[i];
      }
      px.resize(o);
    }
  }
  const int n_chunks = chunk + 1;
  if (stations_used < std::max(8, static_cast<int>(options_.hough.min_length_px / 2)) || n_chunks < 1) {
    return false;
  }
  PhotometricSolution sol;
  const bool solved = eo.photometric_ramp ? SolvePhotometric<3>(px, n_chunks, theta, e, sigma, &sol)
                                          : SolvePhotometric<2>(px, n_chunks, theta, e, sigma, &sol);
  if (!solved) {
    return false;
  }
  theta = sol.theta;
  e = sol.e;
  sigma = sol.sigma;
  const std::vector<double>& a = sol.contrast;
  const Eigen::Matrix3d& s_mat = sol.information;
  const double rss = sol.rss;
  if (std::fabs(e - *e_io) > 1.5 || std::fabs(WrapHalfPi(theta - *theta_io)) > 0.05) {
    return false;
  }
  double used = 0;
  for (const Px& p : px) {
    used += p.weight > 0 ? 1.0 : 0.0;
  }
  const double dof = std::max(1.0, used - 3.0 - (eo.photometric_ramp ? 3.0 : 2.0) * n_chunks);
  const Eigen::Matrix3d cov3 = s_mat.inverse() * (rss / dof);
  if (!cov3.allFinite() || cov3(0, 0) <= 0 || cov3(1, 1) <= 0) {
    return false;
  }
  *theta_io = theta;
  *e_io = e;
  result->line.covariance = cov3.topLeftCorner<2, 2>();
  result->line.blur_sigma_px = sigma;
  double asum = 0;
  int pos = 0, neg = 0;
  for (std::size_t k = 0; k < a.size(); ++k) {
    asum += std::fabs(a[k]);
    (a[k] > 0 ? pos : neg) += 1;
  }
  result->line.contrast = asum / static_cast<double>(a.size());
  result->line.alternating = pos > 0 && neg > 0;
  return true;
}

}  // namespace idi
