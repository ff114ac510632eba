#include "shared/optim/least_squares.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace idi::optim {
namespace {

// y = a exp(b x) with one residual per sample; blocks: a (1), b (1).
class ExpResidual final : public ResidualFunction {
 public:
  ExpResidual(double x, double y) : ResidualFunction(1, {1, 1}), x_(x), y_(y) {}
  bool Evaluate(const double* const* p, double* r, double** j) const override {
    const double e = std::exp(p[1][0] * x_);
    r[0] = p[0][0] * e - y_;
    if (j) {
      if (j[0]) j[0][0] = e;
      if (j[1]) j[1][0] = p[0][0] * x_ * e;
    }
    return true;
  }

 private:
  double x_, y_;
};

TEST(LeastSquaresTest, FitsAnExponentialAndRecordsTheCostPerIteration) {
  double a = 1.0, b = 0.0;
  Problem problem;
  problem.AddParameterBlock(&a, 1);
  problem.AddParameterBlock(&b, 1);
  for (int i = 0; i < 20; ++i) {
    const double x = 0.1 * i;
    problem.AddResidual(std::make_shared<ExpResidual>(x, 2.5 * std::exp(-0.7 * x)), {&a, &b});
  }
  const auto s = SolveLevenbergMarquardt(problem);
  ASSERT_TRUE(s.ok()) << s.status().ToString();
  EXPECT_TRUE(s->converged) << s->BriefReport();
  EXPECT_NEAR(a, 2.5, 1e-9);
  EXPECT_NEAR(b, -0.7, 1e-9);
  ASSERT_GE(s->cost_per_iteration.size(), 2u);
  EXPECT_GT(s->cost_per_iteration.front(), s->cost_per_iteration.back());
  EXPECT_LT(s->final_cost, 1e-20);
}

TEST(LeastSquaresTest, ConstantBlocksStayAndAreNotColumns) {
  double a = 1.0, b = -0.7;
  Problem problem;
  problem.AddParameterBlock(&a, 1);
  problem.AddParameterBlock(&b, 1);
  problem.SetConstant(&b);
  for (int i = 0; i < 10; ++i) {
    const double x = 0.2 * i;
    problem.AddResidual(std::make_shared<ExpResidual>(x, 3.0 * std::exp(-0.7 * x)), {&a, &b});
  }
  EXPECT_EQ(problem.num_free_parameters(), 1);
  EXPECT_EQ(problem.ColumnOf(&a), 0);
  EXPECT_EQ(problem.ColumnOf(&b), -1);
  ASSERT_TRUE(SolveLevenbergMarquardt(problem).ok());
  EXPECT_NEAR(a, 3.0, 1e-9);
  EXPECT_EQ(b, -0.7);
  const auto dense = EvaluateDense(problem);
  ASSERT_TRUE(dense.ok());
  EXPECT_EQ(dense->jacobian.cols(), 1);
  EXPECT_EQ(dense->jacobian.rows(), 10);
  EXPECT_NEAR(dense->jacobian(3, 0), std::exp(-0.7 * 0.6), 1e-12);
}

TEST(LeastSquaresTest, RobustLossIgnoresAGrossOutlier) {
  double a = 1.0, b = 0.0;
  Problem problem;
  problem.AddParameterBlock(&a, 1);
  problem.AddParameterBlock(&b, 1);
  for (int i = 0; i < 30; ++i) {
    const double x = 0.1 * i;
    const double y = 2.0 * std::exp(-0.5 * x) + (i == 7 ? 5.0 : 0.0);
    problem.AddResidual(std::make_shared<ExpResidual>(x, y), {&a, &b}, {LossKind::kCauchy, 0.01});
  }
  ASSERT_TRUE(SolveLevenbergMarquardt(problem).ok());
  EXPECT_NEAR(a, 2.0, 1e-3);
  EXPECT_NEAR(b, -0.5, 1e-3);
}

TEST(LeastSquaresTest, RejectsEmptyProblemsAndBadOptions) {
  Problem problem;
  EXPECT_EQ(SolveLevenbergMarquardt(problem).status().code(), StatusCode::kInvalidArgument);
  SolverOptions bad;
  bad.max_iterations = 0;
  EXPECT_FALSE(bad.Check().ok());
}

}  // namespace
}  // namespace idi::optim
