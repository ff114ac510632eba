#include "shared/optim/covariance.h"

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

namespace idi::optim {

Status IdentifiabilityOptions::Check() const {
  if (!(rank_tolerance > 0 && rank_tolerance < 1) || !(correlation_threshold > 0 && correlation_threshold <= 1) ||
      !(null_component_threshold > 0 && null_component_threshold < 1)) {
    return InvalidArgument("IdentifiabilityOptions: tolerances must lie in (0, 1)");
  }
  return Status::Ok();
}

Result<CovarianceReport> AnalyzeJacobian(const Eigen::MatrixXd& jacobian, double variance_factor,
                                         const IdentifiabilityOptions& options) {
  IDI_RETURN_IF_ERROR(options.Check());
  const Eigen::Index m = jacobian.rows(), n = jacobian.cols();
  if (n == 0 || m < n) {
    return InvalidArgument("covariance: need at least as many residuals (" + std::to_string(m) + ") as parameters (" +
                           std::to_string(n) + ")");
  }
  if (!jacobian.allFinite() || !(variance_factor >= 0) || !std::isfinite(variance_factor)) {
    return InvalidArgument("covariance: Jacobian or variance factor not finite");
  }
  CovarianceReport r;
  r.variance_factor = variance_factor;
  // Column scaling: parameter i in units of 1 / |J_i|.
  Eigen::VectorXd scale(n);
  for (Eigen::Index j = 0; j < n; ++j) {
    const double norm = jacobian.col(j).norm();
    scale(j) = norm > 0 ? 1.0 / norm : 1.0;
  }
  const Eigen::MatrixXd js = jacobian * scale.asDiagonal();
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(js, Eigen::ComputeThinV);
  r.singular_values = svd.singularValues();
  const double s_max = r.singular_values(0);
  const double s_tol = options.rank_tolerance * s_max;
  r.rank = 0;
  for (Eigen::Index i = 0; i < n; ++i) {
    if (r.singular_values(i) > s_tol) ++r.rank;
  }
  const double s_min = r.singular_values(n - 1);
  r.condition_number = s_min > s_tol ? s_max / s_min : std::numeric_limits<double>::infinity();
  {
    Eigen::JacobiSVD<Eigen::MatrixXd> raw(jacobian);
    const auto& sv = raw.singularValues();
    r.condition_number_unscaled = sv(n - 1) > 0 ? sv(0) / sv(n - 1) : std::numeric_limits<double>::infinity();
  }
  const Eigen::MatrixXd& v = svd.matrixV();
  std::vector<bool> undetermined(static_cast<std::size_t>(n), false);
  for (Eigen::Index k = r.rank; k < n; ++k) {
    for (Eigen::Index i = 0; i < n; ++i) {
      if (std::abs(v(i, k)) > options.null_component_threshold) undetermined[static_cast<std::size_t>(i)] = true;
    }
    // A null direction spread thinly over many parameters (every |v_i| under the threshold) still names
    // its largest component: a rank-deficient Jacobian never comes out with nothing undetermined.
    Eigen::Index largest = 0;
    v.col(k).cwiseAbs().maxCoeff(&largest);
    undetermined[static_cast<std::size_t>(largest)] = true;
  }
  for (Eigen::Index i = 0; i < n; ++i) {
    if (undetermined[static_cast<std::size_t>(i)] || jacobian.col(i).norm() == 0) r.undetermined.push_back(static_cast<int>(i));
  }
  // Pseudo-inverse of J^T J in scaled units over the determined directions, then unscale.
  Eigen::VectorXd inv_s2 = Eigen::VectorXd::Zero(n);
  for (Eigen::Index k = 0; k < r.rank; ++k) inv_s2(k) = 1.0 / (r.singular_values(k) * r.singular_values(k));
  const Eigen::MatrixXd cov_scaled = v * inv_s2.asDiagonal() * v.transpose();
  r.covariance = variance_factor * (scale.asDiagonal() * cov_scaled * scale.asDiagonal());
  r.stddev = r.covariance.diagonal().cwiseMax(0.0).cwiseSqrt();
  for (int i : r.undetermined) r.stddev(i) = std::numeric_limits<double>::infinity();
  r.correlation = Eigen::MatrixXd::Identity(n, n);
  for (Eigen::Index i = 0; i < n; ++i) {
    for (Eigen::Index j = i + 1; j < n; ++j) {
      const double d = std::sqrt(cov_scaled(i, i) * cov_scaled(j, j));
      const double rho = d > 0 ? cov_scaled(i, j) / d : 0.0;
      r.correlation(i, j) = r.correlation(j, i) = rho;
      if (std::abs(rho) > options.correlation_threshold) {
        r.correlated.push_back({static_cast<int>(i), static_cast<int>(j), rho});
      }
    }
  }
  std::sort(r.correlated.begin(), r.correlated.end(),
            [](const CorrelatedPair& a, const CorrelatedPair& b) { return std::abs(a.correlation) > std::abs(b.correlation); });
  return r;
}

double VarianceFactor(const Eigen::VectorXd& whitened_residuals, int num_parameters) {
  const Eigen::Index dof = whitened_residuals.size() - num_parameters;
  if (dof <= 0) return std::numeric_limits<double>::quiet_NaN();
  return whitened_residuals.squaredNorm() / static_cast<double>(dof);
}

std::string DescribeCorrelations(const CovarianceReport& report, const std::vector<std::string>& names) {
  std::ostringstream s;
  for (std::size_t k = 0; k < report.correlated.size(); ++k) {
    const CorrelatedPair& p = report.correlated[k];
    auto name = [&](int i) {
      return i >= 0 && static_cast<std::size_t>(i) < names.size() ? names[static_cast<std::size_t>(i)] : std::to_string(i);
    };
    if (k > 0) s << ", ";
    s << name(p.i) << " / " << name(p.j) << " (" << p.correlation << ")";
  }
  return s.str();
}

}  // namespace idi::optim
