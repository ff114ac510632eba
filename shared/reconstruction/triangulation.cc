#include "shared/reconstruction/triangulation.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

#include "shared/util/statistics.h"

namespace idi {

std::optional<TriangulatedPoint> TriangulatePoint(const std::vector<PointObservation>& observations,
                                                  double min_angle_rad) {
  if (observations.size() < 2) {
    return std::nullopt;
  }
  std::vector<Line3d> rays;
  rays.reserve(observations.size());
  std::vector<double> weight;
  for (const PointObservation& o : observations) {
    if (o.camera == nullptr || !o.pixel.allFinite() || !(o.sigma_px >= 0)) {
      return std::nullopt;
    }
    weight.push_back(o.sigma_px > 0 ? 1.0 / o.sigma_px : 1.0);
    const Rigid3d world_from_cam = o.cam_from_world.Inverse();
    const Vec3d ray = PixelToRay(*o.camera, o.pixel);
    if (!ray.allFinite()) return std::nullopt;  // a pixel the lens model cannot undistort
    rays.push_back({world_from_cam.translation, world_from_cam.RotateVector(ray)});
  }
  double max_angle = 0;
  for (std::size_t i = 0; i < rays.size(); ++i) {
    for (std::size_t j = i + 1; j < rays.size(); ++j) {
      max_angle = std::max(max_angle, std::acos(std::clamp(rays[i].direction.dot(rays[j].direction), -1.0, 1.0)));
    }
  }
  if (max_angle < min_angle_rad) {
    return std::nullopt;
  }
  const auto start = PointClosestToLines(rays);
  if (!start) {
    return std::nullopt;
  }
  Vec3d x = *start;
  // Gauss-Newton on the pixel residuals (forward-difference-free: analytic Jacobian of the pinhole
  // projection, distortion handled by comparing in normalised undistorted coordinates scaled by f).
  auto residuals = [&](const Vec3d& xyz, Eigen::VectorXd* r, Eigen::MatrixXd* jac) {
    const auto n = static_cast<Eigen::Index>(observations.size());
    r->resize(2 * n);
    if (jac) jac->resize(2 * n, 3);
    for (Eigen::Index i = 0; i < n; ++i) {
      const PointObservation& o = observations[static_cast<std::size_t>(i)];
      const Vec3d pc = o.cam_from_world * xyz;
      if (!(pc.z() > 1e-9)) {
        return false;
      }
      const Vec2d measured = PixelToNormalized(*o.camera, o.pixel);
      const double w = weight[static_cast<std::size_t>(i)];
      const double fx = o.camera->fx(), fy = o.camera->fy();
      (*r)(2 * i) = w * fx * (pc.x() / pc.z() - measured.x());
      (*r)(2 * i + 1) = w * fy * (pc.y() / pc.z() - measured.y());
      if (jac) {
        Eigen::Matrix<double, 2, 3> d;
        d << fx / pc.z(), 0, -fx * pc.x() / (pc.z() * pc.z()), 0, fy / pc.z(), -fy * pc.y() / (pc.z() * pc.z());
        jac->block<2, 3>(2 * i, 0) = w * d * o.cam_from_world.rotation;
      }
    }
    return true;
  };
  Eigen::VectorXd r;
  Eigen::MatrixXd j;
  if (!residuals(x, &r, &j)) {
    return std::nullopt;
  }
  for (int iter = 0; iter < 10; ++iter) {
    const Eigen::Vector3d dx = (j.transpose() * j).ldlt().solve(-j.transpose() * r);
    Eigen::VectorXd r_new;
    Eigen::MatrixXd j_new;
    if (!dx.allFinite() || !residuals(x + dx, &r_new, &j_new) || r_new.squaredNorm() > r.squaredNorm()) {
      break;
    }
    x += dx;
    r = r_new;
    j = j_new;
    if (dx.norm() < 1e-12 * (1.0 + x.norm())) {
      break;
    }
  }
  TriangulatedPoint out;
  out.xyz = x;
  out.chi2 = r.squaredNorm();
  double sum_px2 = 0;
  for (std::size_t i = 0; i < observations.size(); ++i) {
    sum_px2 += r.segment<2>(2 * static_cast<Eigen::Index>(i)).squaredNorm() / (weight[i] * weight[i]);
  }
  out.reprojection_rms_px = std::sqrt(sum_px2 / static_cast<double>(observations.size()));
  out.min_ray_angle_rad = max_angle;
  return out;
}

bool ChiSquareConsistent(const TriangulatedPoint& point, std::size_t observations, double z) {
  return point.chi2 <= ChiSquareQuantile(2.0 * static_cast<double>(observations) - 3.0, z);
}

std::optional<LeftOut> LeaveOneOut(const std::vector<PointObservation>& observations, double min_angle_rad) {
  std::optional<LeftOut> best;
  for (std::size_t k = 0; k < observations.size(); ++k) {
    std::vector<PointObservation> rest = observations;
    rest.erase(rest.begin() + static_cast<std::ptrdiff_t>(k));
    const auto t = TriangulatePoint(rest, min_angle_rad);
    if (t && (!best || t->chi2 < best->rest.chi2)) best = LeftOut{k, *t};
  }
  return best;
}

std::optional<Line3d> TriangulateLine(const std::vector<LineObservation>& observations, double min_angle_rad) {
  if (observations.size() < 2) {
    return std::nullopt;
  }
  // Each image line back-projects to the plane pi = P^T B (eq. 8.12-8.13); normalise each plane so
  // every view has the same weight.
  Eigen::MatrixXd planes(static_cast<Eigen::Index>(observations.size()), 4);
  for (std::size_t i = 0; i < observations.size(); ++i) {
    Eigen::Vector4d pi = observations[i].p.transpose() * HomogeneousLine(observations[i].line);
    const double n = pi.head<3>().norm();
    if (!(n > 0) || !pi.allFinite()) {
      return std::nullopt;
    }
    planes.row(static_cast<Eigen::Index>(i)) = (pi / n).transpose();
  }
  // Conditioning: the largest angle between two plane normals.
  double max_angle = 0;
  for (Eigen::Index i = 0; i < planes.rows(); ++i) {
    for (Eigen::Index k = i + 1; k < planes.rows(); ++k) {
      const double c = std::abs(planes.row(i).head<3>().dot(planes.row(k).head<3>()));
      max_angle = std::max(max_angle, std::acos(std::min(1.0, c)));
    }
  }
  if (max_angle < min_angle_rad) {
    return std::nullopt;
  }
  // The line is the pencil of points X with planes X = 0: the two right singular vectors with the
  // smallest singular values span it.
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(planes, Eigen::ComputeFullV);
  const Eigen::Vector4d a = svd.matrixV().col(3);
  const Eigen::Vector4d b = svd.matrixV().col(2);
  // Two finite points on the line: combinations with w = 1 (a and b are homogeneous points).
  // Pick the combination of largest |w| for stability.
  Eigen::Vector4d p1 = std::abs(a.w()) > std::abs(b.w()) ? a : b;
  const Eigen::Vector4d other = std::abs(a.w()) > std::abs(b.w()) ? b : a;
  if (std::abs(p1.w()) < 1e-15) {
    return std::nullopt;  // the line lies at infinity
  }
  p1 /= p1.w();
  // Direction: the finite part of `other` minus its w share of p1.
  const Eigen::Vector3d dir = other.head<3>() - other.w() * p1.head<3>();
  if (dir.norm() < 1e-15) {
    return std::nullopt;
  }
  return Line3d{p1.head<3>(), dir.normalized()};
}

}  // namespace idi
