// Autodiff (Ceres Jets) through the models agrees with central differences.
#include <ceres/jet.h>
#include <gtest/gtest.h>

#include <functional>
#include <random>

#include "shared/kinematics/biclops.h"
#include "shared/kinematics/rx130.h"

namespace idi {
namespace {

// Compares d f / d x from Jets with central differences, column by column (relative error).
template <int N>
void ExpectJacobiansAgree(const std::vector<double>& x0,
                          const std::function<Eigen::VectorXd(const std::vector<double>&)>& f_double,
                          const std::function<std::vector<ceres::Jet<double, N>>(
                              const std::vector<ceres::Jet<double, N>>&)>& f_jet,
                          const char* what) {
  using J = ceres::Jet<double, N>;
  ASSERT_EQ(static_cast<int>(x0.size()), N);
  std::vector<J> xj(N);
  for (int i = 0; i < N; ++i) {
    xj[static_cast<std::size_t>(i)] = J(x0[static_cast<std::size_t>(i)], i);
  }
  const std::vector<J> yj = f_jet(xj);
  const Eigen::VectorXd y0 = f_double(x0);
  ASSERT_EQ(static_cast<Eigen::Index>(yj.size()), y0.size());
  for (std::size_t k = 0; k < yj.size(); ++k) {
    EXPECT_NEAR(yj[k].a, y0(static_cast<Eigen::Index>(k)), 1e-9 * std::max(1.0, std::abs(y0(static_cast<Eigen::Index>(k)))));
  }
  for (int i = 0; i < N; ++i) {
    // Five-point central difference: truncation error O(h^4), so h can be large enough that
    // rounding (eps |f| / h) stays far below the tolerance.
    const double h = 1e-3 * std::max(1.0, std::abs(x0[static_cast<std::size_t>(i)]));
    auto at = [&](double k) {
      std::vector<double> x = x0;
      x[static_cast<std::size_t>(i)] += k * h;
      return f_double(x);
    };
    const Eigen::VectorXd fd = (at(-2) - 8 * at(-1) + 8 * at(1) - at(2)) / (12 * h);
    Eigen::VectorXd ad(fd.size());
    for (std::size_t k = 0; k < yj.size(); ++k) {
      ad(static_cast<Eigen::Index>(k)) = yj[k].v(i);
    }
    const double scale = std::max(ad.norm(), 1e-3);
    EXPECT_LT((ad - fd).norm() / scale, 1e-6) << what << ": column " << i << "\nautodiff " << ad.transpose()
                                              << "\ncentral  " << fd.transpose();
  }
}

constexpr int kLaserInputs = kRx130ParamCount + kLaserParamCount + kRx130Joints;  // 28

template <typename T>
std::vector<T> LaserLineOutputs(const std::vector<T>& x) {
  const Line3<T> line = LaserLineInBase(x.data(), x.data() + kRx130ParamCount,
                                        x.data() + kRx130ParamCount + kLaserParamCount);
  // A point 3 m along the line and the direction: what the calibration cost differentiates.
  const Vec3<T> far = line.PointAt(T(3000));
  return {line.origin.x(), line.origin.y(), line.origin.z(), far.x(), far.y(), far.z(),
          line.direction.x(), line.direction.y(), line.direction.z()};
}

TEST(JetTest, LaserLineJacobianMatchesCentralDifferences) {
  ParamSet robot = Rx130Nominal();
  ParamSet laser = LaserNominal();
  laser.set_file_value(kLaserThetaX, 0.05);
  laser.set_file_value(kLaserPx, -0.18);
  const Joints q = JointsFromDeg({12, -55, 95, 20, 70, -35});
  std::vector<double> x = robot.values();
  x.insert(x.end(), laser.values().begin(), laser.values().end());
  x.insert(x.end(), q.begin(), q.end());
  ExpectJacobiansAgree<kLaserInputs>(
      x,
      [](const std::vector<double>& v) {
        const auto out = LaserLineOutputs(v);
        return Eigen::Map<const Eigen::VectorXd>(out.data(), static_cast<Eigen::Index>(out.size())).eval();
      },
      [](const std::vector<ceres::Jet<double, kLaserInputs>>& v) { return LaserLineOutputs(v); }, "laser line");
}

constexpr int kBiclopsInputs = kPtuParamCount + kCameraParamCount + 2 + 3;  // 28

template <typename T>
std::vector<T> BiclopsPixel(const std::vector<T>& x) {
  const Rigid3<T> base_from_tcf = BaseFromTcf(T(850.0), T(-150.0), T(1450.0), T(0.25), T(2.9), T(-0.3));
  const T* ptu = x.data();
  const T* intr = x.data() + kPtuParamCount;
  const T pan = x[kPtuParamCount + kCameraParamCount];
  const T tilt = x[kPtuParamCount + kCameraParamCount + 1];
  const Vec3<T> point(x[kBiclopsInputs - 3], x[kBiclopsInputs - 2], x[kBiclopsInputs - 1]);
  Vec2<T> px;
  const bool ok = ProjectThroughBiclops(base_from_tcf, ptu, intr, pan, tilt, point, &px);
  EXPECT_TRUE(ok);
  return {px.x(), px.y()};
}

TEST(JetTest, BiclopsProjectionJacobianMatchesCentralDifferences) {
  const ParamSet ptu(PtuParamSpecs(BiclopsSide::kLeft));
  CameraModel cam = BiclopsNominalCamera(BiclopsSide::kLeft);
  cam.params[kK1] = -0.12;
  cam.params[kK2] = 0.05;
  cam.params[kP1] = 0.001;
  std::vector<double> x = ptu.values();
  x.insert(x.end(), cam.params.begin(), cam.params.end());
  const double pan = 0.1, tilt = -0.2;
  x.push_back(pan);
  x.push_back(tilt);
  // A point 1.2 m in front of the camera.
  const Rigid3d base_from_tcf = BaseFromTcf(850.0, -150.0, 1450.0, 0.25, 2.9, -0.3);
  const Vec3d p = base_from_tcf * TcfFromCamera(ptu.data(), pan, tilt) * Vec3d(60, 40, 1200);
  x.insert(x.end(), {p.x(), p.y(), p.z()});
  ExpectJacobiansAgree<kBiclopsInputs>(
      x,
      [](const std::vector<double>& v) {
        const auto out = BiclopsPixel(v);
        return Eigen::Vector2d(out[0], out[1]).eval();
      },
      [](const std::vector<ceres::Jet<double, kBiclopsInputs>>& v) { return BiclopsPixel(v); }, "biclops pixel");
}

}  // namespace
}  // namespace idi
