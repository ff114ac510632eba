#include "shared/optim/least_squares.h"

#include <ceres/ceres.h>

#include <chrono>
#include <cmath>
#include <sstream>

namespace idi::optim {
namespace {

// Forwards Ceres' CostFunction calls to a ResidualFunction.
class CeresCostAdapter final : public ceres::CostFunction {
 public:
  explicit CeresCostAdapter(const ResidualFunction* f) : f_(f) {
    set_num_residuals(f->num_residuals());
    *mutable_parameter_block_sizes() = f->block_sizes();
  }
  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override {
    return f_->Evaluate(parameters, residuals, jacobians);
  }

 private:
  const ResidualFunction* f_;
};

class ProgressCallback final : public ceres::IterationCallback {
 public:
  explicit ProgressCallback(const std::function<void(int, double)>* f) : f_(f) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& s) override {
    (*f_)(s.iteration, s.cost);
    return ceres::SOLVER_CONTINUE;
  }

 private:
  const std::function<void(int, double)>* f_;
};

ceres::LossFunction* MakeLoss(const Loss& loss) {
  switch (loss.kind) {
    case LossKind::kTrivial: return nullptr;
    case LossKind::kHuber: return new ceres::HuberLoss(loss.scale);
    case LossKind::kCauchy: return new ceres::CauchyLoss(loss.scale);
  }
  return nullptr;
}

}  // namespace

void Problem::AddParameterBlock(double* values, int size) {
  IDI_CHECK(values != nullptr && size > 0, "Problem::AddParameterBlock: empty block");
  if (const Block* b = Find(values)) {
    IDI_CHECK(b->size == size, "Problem::AddParameterBlock: block re-added with another size");
    return;
  }
  blocks_.push_back({values, size, false});
}

const Problem::Block* Problem::Find(const double* values) const {
  for (const Block& b : blocks_) {
    if (b.values == values) return &b;
  }
  return nullptr;
}

void Problem::SetConstant(const double* values, bool constant) {
  for (Block& b : blocks_) {
    if (b.values == values) {
      b.constant = constant;
      return;
    }
  }
  IDI_CHECK(false, "Problem::SetConstant: unknown parameter block");
}

bool Problem::IsConstant(const double* values) const {
  const Block* b = Find(values);
  IDI_CHECK(b != nullptr, "Problem::IsConstant: unknown parameter block");
  return b->constant;
}

void Problem::AddResidual(std::shared_ptr<const ResidualFunction> function, std::vector<double*> blocks, Loss loss) {
  IDI_CHECK(function != nullptr, "Problem::AddResidual: null function");
  IDI_CHECK(function->block_sizes().size() == blocks.size(), "Problem::AddResidual: wrong number of blocks");
  for (std::size_t i = 0; i < blocks.size(); ++i) {
    const Block* b = Find(blocks[i]);
    IDI_CHECK(b != nullptr, "Problem::AddResidual: parameter block not registered");
    IDI_CHECK(b->size == function->block_sizes()[i], "Problem::AddResidual: block size mismatch");
  }
  num_residuals_ += function->num_residuals();
  residuals_.push_back({std::move(function), std::move(blocks), loss});
}

int Problem::num_free_parameters() const {
  int n = 0;
  for (const Block& b : blocks_) {
    if (!b.constant) n += b.size;
  }
  return n;
}

int Problem::ColumnOf(const double* values) const {
  int col = 0;
  for (const Block& b : blocks_) {
    if (b.values == values) return b.constant ? -1 : col;
    if (!b.constant) col += b.size;
  }
  return -1;
}

Status SolverOptions::Check() const {
  if (max_iterations <= 0 || num_threads <= 0 || !(function_tolerance >= 0) || !(gradient_tolerance >= 0) ||
      !(parameter_tolerance >= 0)) {
    return InvalidArgument("SolverOptions: max_iterations and num_threads must be positive, tolerances >= 0");
  }
  return Status::Ok();
}

std::string SolverSummary::BriefReport() const {
  std::ostringstream s;
  s << termination << " after " << iterations << " iterations, cost " << initial_cost << " -> " << final_cost << " ("
    << time_ms << " ms)";
  if (!message.empty()) s << ": " << message;
  return s.str();
}

Result<SolverSummary> SolveLevenbergMarquardt(Problem& problem, const SolverOptions& options) {
  IDI_RETURN_IF_ERROR(options.Check());
  if (problem.residuals().empty()) {
    return InvalidArgument("least squares: the problem has no residuals");
  }
  const auto t0 = std::chrono::steady_clock::now();
  ceres::Problem::Options po;
  po.cost_function_ownership = ceres::TAKE_OWNERSHIP;  // the adapters, not the ResidualFunctions
  po.loss_function_ownership = ceres::TAKE_OWNERSHIP;
  ceres::Problem cp(po);
  for (const Problem::Block& b : problem.blocks()) {
    cp.AddParameterBlock(b.values, b.size);
    if (b.constant) cp.SetParameterBlockConstant(b.values);
  }
  for (const Problem::Residual& r : problem.residuals()) {
    cp.AddResidualBlock(new CeresCostAdapter(r.function.get()), MakeLoss(r.loss), r.blocks);
  }
  ceres::Solver::Options so;
  so.minimizer_type = ceres::TRUST_REGION;
  so.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  // Dense QR: the problems are small (tens of parameters) and QR keeps the accuracy that the normal
  // equations would square away on precise data.
  so.linear_solver_type = ceres::DENSE_QR;
  so.max_num_iterations = options.max_iterations;
  so.function_tolerance = options.function_tolerance;
  so.gradient_tolerance = options.gradient_tolerance;
  so.parameter_tolerance = options.parameter_tolerance;
  so.num_threads = options.num_threads;
  so.logging_type = ceres::SILENT;
  so.minimizer_progress_to_stdout = false;
  ProgressCallback callback(&options.on_iteration);
  if (options.on_iteration) so.callbacks.push_back(&callback);
  ceres::Solver::Summary cs;
  ceres::Solve(so, &cp, &cs);

  SolverSummary s;
  s.converged = cs.termination_type == ceres::CONVERGENCE;
  s.usable = cs.IsSolutionUsable();
  s.termination = cs.termination_type == ceres::CONVERGENCE      ? "convergence"
                  : cs.termination_type == ceres::NO_CONVERGENCE ? "no_convergence"
                                                                 : "failure";
  s.message = cs.message;
  s.initial_cost = cs.initial_cost;
  s.final_cost = cs.final_cost;
  s.iterations = static_cast<int>(cs.iterations.size()) - 1;
  for (const ceres::IterationSummary& it : cs.iterations) {
    s.cost_per_iteration.push_back(it.cost);
  }
  s.time_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  if (!s.usable) {
    return NotConverged("least squares: " + cs.message);
  }
  return s;
}

Result<DenseEvaluation> EvaluateDense(const Problem& problem) {
  DenseEvaluation out;
  const int n = problem.num_free_parameters();
  out.residuals.resize(problem.num_residuals());
  out.jacobian = Eigen::MatrixXd::Zero(problem.num_residuals(), n);
  std::vector<int> col_of(problem.blocks().size());
  Eigen::Index row = 0;
  std::vector<const double*> params;
  std::vector<double*> jac_ptrs;
  std::vector<std::vector<double>> jac_storage;
  for (std::size_t ri = 0; ri < problem.residuals().size(); ++ri) {
    const Problem::Residual& r = problem.residuals()[ri];
    const int m = r.function->num_residuals();
    params.assign(r.blocks.begin(), r.blocks.end());
    jac_storage.resize(r.blocks.size());
    jac_ptrs.resize(r.blocks.size());
    for (std::size_t b = 0; b < r.blocks.size(); ++b) {
      jac_storage[b].assign(static_cast<std::size_t>(m * r.function->block_sizes()[b]), 0.0);
      jac_ptrs[b] = problem.ColumnOf(r.blocks[b]) >= 0 ? jac_storage[b].data() : nullptr;
    }
    if (!r.function->Evaluate(params.data(), out.residuals.data() + row, jac_ptrs.data())) {
      return Internal("least squares: residual block " + std::to_string(ri) + " cannot be evaluated");
    }
    for (std::size_t b = 0; b < r.blocks.size(); ++b) {
      const int col = problem.ColumnOf(r.blocks[b]);
      if (col < 0) continue;
      const int size = r.function->block_sizes()[b];
      for (int i = 0; i < m; ++i) {
        for (int j = 0; j < size; ++j) {
          out.jacobian(row + i, col + j) += jac_storage[b][static_cast<std::size_t>(i * size + j)];
        }
      }
    }
    row += m;
  }
  if (!out.residuals.allFinite() || !out.jacobian.allFinite()) {
    return Internal("least squares: residuals or Jacobian not finite");
  }
  return out;
}

}  // namespace idi::optim
