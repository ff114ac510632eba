// Nonlinear least squares (Levenberg-Marquardt) behind a Ceres-free interface.
//
// shared/optim is the only module that includes Ceres (DESIGN.md §3). Callers describe a problem with
// parameter blocks (memory they own) and residual functions with analytic derivatives (the contract of
// ceres::CostFunction, without the header); SolveLevenbergMarquardt runs Ceres on it. EvaluateDense
// gives the full Jacobian at the current values for covariance and identifiability (covariance.h).
#pragma once

#include <Eigen/Core>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "shared/util/status.h"

namespace idi::optim {

// A block of residuals depending on some parameter blocks.
class ResidualFunction {
 public:
  ResidualFunction(int num_residuals, std::vector<int> block_sizes)
      : num_residuals_(num_residuals), block_sizes_(std::move(block_sizes)) {}
  virtual ~ResidualFunction() = default;

  int num_residuals() const { return num_residuals_; }
  const std::vector<int>& block_sizes() const { return block_sizes_; }

  // residuals: num_residuals values. jacobians: null, or one pointer per block (each may be null) to a
  // row-major num_residuals x block_size array. Returns false if the residual cannot be evaluated
  // (e.g. the point is behind the laser); the solver then rejects the step.
  virtual bool Evaluate(const double* const* parameters, double* residuals, double** jacobians) const = 0;

 private:
  int num_residuals_;
  std::vector<int> block_sizes_;
};

enum class LossKind { kTrivial, kHuber, kCauchy };
struct Loss {
  LossKind kind = LossKind::kTrivial;
  double scale = 1.0;  // residual norm where the robust loss starts to bend
};

class Problem {
 public:
  // Registers a block of `size` values; the memory must outlive every solve. Re-adding is a no-op.
  void AddParameterBlock(double* values, int size);
  void SetConstant(const double* values, bool constant = true);
  bool IsConstant(const double* values) const;
  // Adds a residual; every block in `blocks` must be registered, with the sizes the function expects.
  void AddResidual(std::shared_ptr<const ResidualFunction> function, std::vector<double*> blocks, Loss loss = {});

  struct Block {
    double* values = nullptr;
    int size = 0;
    bool constant = false;
  };
  struct Residual {
    std::shared_ptr<const ResidualFunction> function;
    std::vector<double*> blocks;
    Loss loss;
  };
  const std::vector<Block>& blocks() const { return blocks_; }
  const std::vector<Residual>& residuals() const { return residuals_; }
  int num_residuals() const { return num_residuals_; }
  // Sum of the sizes of the non-constant blocks: the columns of EvaluateDense's Jacobian.
  int num_free_parameters() const;
  // Column of the first value of `values` in EvaluateDense's Jacobian, -1 if constant or unknown.
  int ColumnOf(const double* values) const;

 private:
  const Block* Find(const double* values) const;
  std::vector<Block> blocks_;
  std::vector<Residual> residuals_;
  int num_residuals_ = 0;
};

struct SolverOptions {
  int max_iterations = 100;
  double function_tolerance = 1e-13;   // relative change of the cost
  double gradient_tolerance = 1e-16;
  double parameter_tolerance = 1e-13;  // relative step size
  int num_threads = 1;
  // Called after every iteration with its number and cost (for progress on long solves).
  std::function<void(int iteration, double cost)> on_iteration;
  Status Check() const;
};

struct SolverSummary {
  bool converged = false;  // a tolerance was met
  bool usable = false;     // the parameters hold a valid (possibly not converged) solution
  std::string termination; // "convergence", "no_convergence", "failure"
  std::string message;
  int iterations = 0;
  double initial_cost = 0;  // 1/2 sum of squared (loss-transformed) residuals
  double final_cost = 0;
  std::vector<double> cost_per_iteration;  // [0] = initial cost
  double time_ms = 0;
  std::string BriefReport() const;
};

// Minimises 1/2 sum_i loss(|r_i|^2) over the non-constant blocks, updating them in place. Fails
// (NotConverged / Internal) only when Ceres reports the solution unusable.
Result<SolverSummary> SolveLevenbergMarquardt(Problem& problem, const SolverOptions& options = {});

struct DenseEvaluation {
  Eigen::VectorXd residuals;  // loss not applied
  Eigen::MatrixXd jacobian;   // rows: residuals in order of AddResidual; columns: free parameters
};
// Residuals and Jacobian at the current values. Fails if a residual cannot be evaluated or is not finite.
Result<DenseEvaluation> EvaluateDense(const Problem& problem);

}  // namespace idi::optim
