#include "shared/optim/covariance.h"

#include <gtest/gtest.h>

#include <random>

namespace idi::optim {
namespace {

Eigen::MatrixXd RandomMatrix(int rows, int cols, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n;
  Eigen::MatrixXd m(rows, cols);
  for (int i = 0; i < rows; ++i)
    for (int j = 0; j < cols; ++j) m(i, j) = n(rng);
  return m;
}

TEST(CovarianceTest, FullRankGivesTheInverseInformation) {
  Eigen::MatrixXd j = RandomMatrix(50, 4, 1);
  j.col(2) *= 1000.0;  // different units must not matter
  const auto r = AnalyzeJacobian(j, 2.0);
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->rank, 4);
  EXPECT_TRUE(r->undetermined.empty());
  const Eigen::MatrixXd expected = 2.0 * (j.transpose() * j).inverse();
  EXPECT_TRUE(r->covariance.isApprox(expected, 1e-9));
  EXPECT_NEAR(r->stddev(2), std::sqrt(expected(2, 2)), 1e-12);
  EXPECT_LT(r->condition_number, 10.0);  // scaled: random columns are well conditioned
  EXPECT_GT(r->condition_number_unscaled, 100.0);
}

TEST(CovarianceTest, NamesUndeterminedAndCorrelatedParameters) {
  Eigen::MatrixXd j = RandomMatrix(60, 5, 2);
  j.col(3) = 2.0 * j.col(1);                       // 1 and 3 cannot be separated
  j.col(4) = j.col(0) + 0.05 * RandomMatrix(60, 1, 3).col(0);  // 0 and 4 nearly the same
  const auto r = AnalyzeJacobian(j, 1.0);
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->rank, 4);
  EXPECT_EQ(r->undetermined, (std::vector<int>{1, 3}));
  EXPECT_TRUE(std::isinf(r->stddev(1)));
  EXPECT_TRUE(std::isinf(r->condition_number));
  bool found = false;
  for (const CorrelatedPair& p : r->correlated) found |= (p.i == 0 && p.j == 4 && std::abs(p.correlation) > 0.95);
  EXPECT_TRUE(found);
  EXPECT_NE(DescribeCorrelations(*r, {"a", "b", "c", "d", "e"}).find("a / e"), std::string::npos);
}

// A null direction spread over 60 parameters (every component about 1/sqrt(60) = 0.13, under the 0.2
// that names a parameter): the rank is 59, so at least one parameter is named undetermined, with an
// infinite std (before, none was, and every std came out finite).
TEST(CovarianceTest, ASpreadOutNullDirectionStillNamesAParameter) {
  const Eigen::MatrixXd random = RandomMatrix(200, 60, 5);
  const Eigen::VectorXd c = Eigen::VectorXd::Ones(60) / std::sqrt(60.0);
  const Eigen::MatrixXd j = random - (random * c) * c.transpose();  // j c = 0; columns of similar norms
  const auto r = AnalyzeJacobian(j, 1.0);
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->rank, 59);
  ASSERT_FALSE(r->undetermined.empty());
  for (const int i : r->undetermined) EXPECT_TRUE(std::isinf(r->stddev(i)));
}

TEST(CovarianceTest, VarianceFactorAndBadInput) {
  Eigen::VectorXd r(12);
  r.setConstant(2.0);
  EXPECT_DOUBLE_EQ(VarianceFactor(r, 2), 48.0 / 10.0);
  EXPECT_FALSE(AnalyzeJacobian(Eigen::MatrixXd::Zero(2, 3), 1.0).ok());
  Eigen::MatrixXd nan = RandomMatrix(10, 2, 4);
  nan(3, 1) = std::nan("");
  EXPECT_EQ(AnalyzeJacobian(nan, 1.0).status().code(), StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace idi::optim
