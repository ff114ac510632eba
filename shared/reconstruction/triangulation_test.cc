#include "shared/reconstruction/triangulation.h"

#include <gtest/gtest.h>

#include <random>

#include "tests/support/wireframe_views.h"

namespace idi {
namespace {


class TriangulationTest : public ::testing::Test {
 protected:
  void SetUp() override {
    camera_.params = {1240, 1240, 319.5, 239.5, -0.1, 0.02, 0, 0, 0};
    for (const Vec3d& c : {Vec3d(1000, 0, 500), Vec3d(700, 700, 600), Vec3d(0, 1000, 400), Vec3d(-700, 700, 700)}) {
      poses_.push_back(test::LookAt(c, Vec3d(0, 0, 50)));
    }
  }
  CameraModel camera_;
  std::vector<Rigid3d> poses_;
};

TEST_F(TriangulationTest, ExactPointFromTwoAndFourViews) {
  const Vec3d x(30, -20, 80);
  std::vector<PointObservation> obs;
  for (const Rigid3d& pose : poses_) {
    obs.push_back({&camera_, pose, *Project(camera_, pose * x)});
  }
  const auto two = TriangulatePoint({obs[0], obs[1]});
  ASSERT_TRUE(two.has_value());
  EXPECT_LT((two->xyz - x).norm(), 1e-8);
  const auto four = TriangulatePoint(obs);
  ASSERT_TRUE(four.has_value());
  EXPECT_LT((four->xyz - x).norm(), 1e-8);
  EXPECT_LT(four->reprojection_rms_px, 1e-8);
}

TEST_F(TriangulationTest, NoisyPixelsGiveSubMillimetreAtOneMetre) {
  std::mt19937 rng(11);
  std::normal_distribution<double> noise(0.0, 0.1);
  double sum2 = 0;
  const int n = 200;
  for (int i = 0; i < n; ++i) {
    const Vec3d x(std::uniform_real_distribution<double>(-50, 50)(rng), 0.0, 60.0);
    std::vector<PointObservation> obs;
    for (const Rigid3d& pose : poses_) {
      obs.push_back({&camera_, pose, *Project(camera_, pose * x) + Vec2d(noise(rng), noise(rng))});
    }
    const auto t = TriangulatePoint(obs);
    ASSERT_TRUE(t.has_value());
    sum2 += (t->xyz - x).squaredNorm();
  }
  // 0.1 px at ~1.1 m with f = 1240 px is ~0.09 mm per ray; four well-spread rays: well under 0.2 mm.
  EXPECT_LT(std::sqrt(sum2 / n), 0.2);
}

// With sigmas each view counts by its precision: a precise view's ray is followed, imprecise ones give
// way, and chi2 is the sum of the squared residuals in sigmas.
TEST_F(TriangulationTest, WeightsEachViewByItsSigma) {
  const Vec3d x(30, -20, 80);
  std::vector<PointObservation> obs;
  for (std::size_t v = 0; v < poses_.size(); ++v) {
    const Vec2d exact = *Project(camera_, poses_[v] * x);
    obs.push_back({&camera_, poses_[v], v == 0 ? exact : Vec2d(exact + Vec2d(1.0, -1.0)), v == 0 ? 0.02 : 1.0});
  }
  auto error_in_view0 = [&](const TriangulatedPoint& t) {
    return (*Project(camera_, poses_[0] * t.xyz) - obs[0].pixel).norm();
  };
  const auto weighted = TriangulatePoint(obs);
  ASSERT_TRUE(weighted.has_value());
  EXPECT_LT(error_in_view0(*weighted), 0.01);
  double chi2 = 0;
  for (const PointObservation& o : obs)
    chi2 += ((*Project(camera_, o.cam_from_world * weighted->xyz) - o.pixel) / o.sigma_px).squaredNorm();
  EXPECT_NEAR(weighted->chi2, chi2, 1e-3 * chi2);
  for (PointObservation& o : obs) o.sigma_px = 0;
  const auto plain = TriangulatePoint(obs);
  ASSERT_TRUE(plain.has_value());
  EXPECT_GT(error_in_view0(*plain), 0.5);
  obs[1].sigma_px = -1;
  EXPECT_FALSE(TriangulatePoint(obs).has_value());
}

TEST_F(TriangulationTest, RefusesDegenerateInput) {
  const Vec3d x(0, 0, 50);
  const PointObservation o{&camera_, poses_[0], *Project(camera_, poses_[0] * x)};
  EXPECT_FALSE(TriangulatePoint({o}).has_value());
  EXPECT_FALSE(TriangulatePoint({o, o}).has_value());  // parallel rays
  PointObservation bad = o;
  bad.pixel = Vec2d(NAN, 3);
  EXPECT_FALSE(TriangulatePoint({o, bad}).has_value());
}

TEST_F(TriangulationTest, LineFromPlanes) {
  const Vec3d a(-40, 10, 20), b(60, -30, 90);
  std::vector<LineObservation> obs;
  CameraModel pin = camera_;
  pin.params[kK1] = pin.params[kK2] = 0;
  for (const Rigid3d& pose : poses_) {
    const Vec2d pa = *Project(pin, pose * a), pb = *Project(pin, pose * b);
    obs.push_back({MakeProjection(pin.K(), pose), Line2Through(pa, pb)});
  }
  for (std::size_t n : {2u, 4u}) {
    const auto line = TriangulateLine(std::vector<LineObservation>(obs.begin(), obs.begin() + static_cast<long>(n)));
    ASSERT_TRUE(line.has_value());
    EXPECT_LT(DistancePointToLine(*line, a), 1e-6);
    EXPECT_LT(DistancePointToLine(*line, b), 1e-6);
  }
  EXPECT_FALSE(TriangulateLine({obs[0], obs[0]}).has_value());
}

}  // namespace
}  // namespace idi
