// Covariance and identifiability from the Jacobian at a solution.
//
// For whitened residuals (unit variance under the noise model) the covariance of the estimate is
// sigma0^2 (J^T J)^-1, sigma0^2 the a posteriori variance factor (1 when the noise model is right).
// Computed through the SVD of J with its columns scaled to unit norm, so that the singular values and
// the condition number compare parameters of different units fairly; parameters along singular
// vectors whose singular value is below rank_tolerance * s_max are reported as undetermined.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "shared/util/status.h"

namespace idi::optim {

struct IdentifiabilityOptions {
  double rank_tolerance = 1e-9;          // relative singular value below which a direction is undetermined
  double correlation_threshold = 0.95;   // |rho| above this is reported
  double null_component_threshold = 0.2; // |v_i| in an undetermined direction that names parameter i
  Status Check() const;
};

struct CorrelatedPair {
  int i = 0;
  int j = 0;
  double correlation = 0;
};

struct CovarianceReport {
  Eigen::VectorXd singular_values;    // of the column-scaled Jacobian, descending
  double condition_number = 0;        // s_max / s_min of the column-scaled Jacobian (inf if rank deficient)
  double condition_number_unscaled = 0;
  int rank = 0;
  std::vector<int> undetermined;      // parameters the data cannot determine
  double variance_factor = 1;         // sigma0^2 the covariance was scaled with
  Eigen::MatrixXd covariance;         // in the parameters' code units; pseudo-inverse if rank deficient
  Eigen::VectorXd stddev;             // sqrt of the diagonal; inf for undetermined parameters
  Eigen::MatrixXd correlation;
  std::vector<CorrelatedPair> correlated;  // |rho| > threshold, largest first
};

// `jacobian`: whitened residuals x parameters. variance_factor multiplies (J^T J)^-1.
Result<CovarianceReport> AnalyzeJacobian(const Eigen::MatrixXd& jacobian, double variance_factor,
                                         const IdentifiabilityOptions& options = {});

// sigma0^2 = sum r^2 / (m - n), the a posteriori variance factor of whitened residuals.
double VarianceFactor(const Eigen::VectorXd& whitened_residuals, int num_parameters);

// "alpha2_deg / a2_mm (0.97)" style summary of the correlated pairs, using `names`.
std::string DescribeCorrelations(const CovarianceReport& report, const std::vector<std::string>& names);

}  // namespace idi::optim
