#include "shared/optim/ptu/ptu_cost.h"

#include <gtest/gtest.h>

#include <array>
#include <vector>

namespace idi::optim {
namespace {

struct PtuCostFixture {
  std::vector<double> ptu;
  std::vector<double> intr;
  std::array<double, 3> point{};
  Rigid3d base_from_tcf;
  double pan = 0.4, tilt = -0.2;

  PtuCostFixture() {
    ParamSet p(PtuParamSpecs(BiclopsSide::kLeft));
    ptu = p.values();
    const CameraModel cam = BiclopsNominalCamera(BiclopsSide::kLeft);
    intr.assign(cam.params.begin(), cam.params.end());
    intr[kK1] = -0.1;
    intr[kK2] = 0.05;
    intr[kP1] = 1e-3;
    base_from_tcf = BaseFromTcf(300.0, -200.0, 900.0, 0.3, 1.9, -0.4);
    // A point 2 m in front of the camera, slightly off its axis.
    const Rigid3d base_from_cam = base_from_tcf * TcfFromCamera(ptu.data(), pan, tilt);
    const Vec3d x = base_from_cam * Vec3d(150, -90, 2000);
    point = {x.x(), x.y(), x.z()};
  }
};

TEST(PtuSpotResidual, ResidualIsProjectionMinusObservationOverSigma) {
  PtuCostFixture f;
  Vec2d px;
  ASSERT_TRUE(ProjectThroughBiclops(f.base_from_tcf, f.ptu.data(), f.intr.data(), f.pan, f.tilt,
                                    Vec3d(f.point[0], f.point[1], f.point[2]), &px));
  const Vec2d observed = px + Vec2d(0.6, -1.0);
  const PtuSpotResidual r(f.base_from_tcf, f.pan, f.tilt, observed, 0.5);
  ASSERT_EQ(r.block_sizes().size(), static_cast<std::size_t>(kPtuSpotBlockCount));
  const std::vector<double*> blocks = PtuSpotBlocks(f.ptu.data(), f.intr.data(), f.point.data());
  double res[2];
  ASSERT_TRUE(r.Evaluate(blocks.data(), res, nullptr));
  EXPECT_NEAR(res[0], -0.6 / 0.5, 1e-9);
  EXPECT_NEAR(res[1], 1.0 / 0.5, 1e-9);
}

TEST(PtuSpotResidual, JacobianMatchesCentralDifferences) {
  PtuCostFixture f;
  const PtuSpotResidual r(f.base_from_tcf, f.pan, f.tilt, Vec2d(320, 240), 1.0);
  std::vector<double*> blocks = PtuSpotBlocks(f.ptu.data(), f.intr.data(), f.point.data());
  std::vector<std::vector<double>> jac_storage;
  std::vector<double*> jac;
  for (int size : r.block_sizes()) jac_storage.emplace_back(static_cast<std::size_t>(2 * size), 0.0);
  for (auto& s : jac_storage) jac.push_back(s.data());
  double res[2];
  ASSERT_TRUE(r.Evaluate(blocks.data(), res, jac.data()));
  double res_plain[2];
  ASSERT_TRUE(r.Evaluate(blocks.data(), res_plain, nullptr));
  EXPECT_DOUBLE_EQ(res[0], res_plain[0]);
  EXPECT_DOUBLE_EQ(res[1], res_plain[1]);
  for (std::size_t b = 0; b < blocks.size(); ++b) {
    const int size = r.block_sizes()[b];
    for (int k = 0; k < size; ++k) {
      double* v = blocks[b] + k;
      const double saved = *v;
      const double h = 1e-6 * std::max(1.0, std::abs(saved));
      double rp[2], rm[2];
      *v = saved + h;
      ASSERT_TRUE(r.Evaluate(blocks.data(), rp, nullptr));
      *v = saved - h;
      ASSERT_TRUE(r.Evaluate(blocks.data(), rm, nullptr));
      *v = saved;
      for (int row = 0; row < 2; ++row) {
        const double numeric = (rp[row] - rm[row]) / (2 * h);
        const double analytic = jac_storage[b][static_cast<std::size_t>(row * size + k)];
        EXPECT_NEAR(analytic, numeric, 1e-5 * std::max(1.0, std::abs(numeric))) << "block " << b << " k " << k;
      }
    }
  }
}

TEST(PtuSpotResidual, PointBehindTheCameraCannotBeEvaluated) {
  PtuCostFixture f;
  const Rigid3d base_from_cam = f.base_from_tcf * TcfFromCamera(f.ptu.data(), f.pan, f.tilt);
  const Vec3d behind = base_from_cam * Vec3d(0, 0, -1000);
  std::array<double, 3> x = {behind.x(), behind.y(), behind.z()};
  const PtuSpotResidual r(f.base_from_tcf, f.pan, f.tilt, Vec2d(320, 240), 1.0);
  const std::vector<double*> blocks = PtuSpotBlocks(f.ptu.data(), f.intr.data(), x.data());
  double res[2];
  EXPECT_FALSE(r.Evaluate(blocks.data(), res, nullptr));
}

}  // namespace
}  // namespace idi::optim
