#include "shared/optim/vicki_costs.h"

#include <Eigen/Cholesky>
#include <cmath>

namespace idi::optim {
namespace {

// Writes m into a row-major array (Ceres' Jacobian layout).
template <int R, int C, typename M>
void StoreRowMajor(double* dst, const M& m) {
  Eigen::Map<Eigen::Matrix<double, R, C, Eigen::RowMajor>> map(dst);
  map = m;
}

int Col(int base, int k) { return base < 0 ? -1 : base + k; }

// d t(phi_l, phi_m) / d(phi_l, phi_m) for t = (cos l cos m, sin l cos m, -sin m) (§4.3).
Eigen::Matrix<double, 3, 2> DirectionJacobian(const double* phi) {
  const double cl = std::cos(phi[kPhiL]), sl = std::sin(phi[kPhiL]);
  const double cm = std::cos(phi[kPhiM]), sm = std::sin(phi[kPhiM]);
  Eigen::Matrix<double, 3, 2> j;
  j << -sl * cm, -cl * sm,  //
      cl * cm, -sl * sm,    //
      0.0, -cm;
  return j;
}

}  // namespace

void AppendRx130LaserChain(TwistChain& ch, const double* p, const double* l, const Joints& q, int robot_col,
                           int laser_col, int joint_col) {
  auto r = [&](int k) { return Col(robot_col, k); };
  auto j = [&](int k) { return Col(joint_col, k); };
  ch.RotZ(q[0], j(0));
  // Link 2, DH (eq. 3.1): Rx(alpha) Tx(a) Rz(theta + q) Tz(d).
  ch.RotX(p[kAlpha2], r(kAlpha2));
  ch.TransX(p[kA2], r(kA2));
  ch.RotZ(p[kTheta2] + q[1], r(kTheta2), 1, j(1), 1);
  ch.TransZ(p[kD2], r(kD2));
  // Link 3, Hayati (eq. 3.2): Rx(alpha) Tx(a) Ry(beta) Rz(theta + q).
  ch.RotX(p[kAlpha3], r(kAlpha3));
  ch.TransX(p[kA3], r(kA3));
  ch.RotY(p[kBeta3], r(kBeta3));
  ch.RotZ(p[kTheta3] + q[2], r(kTheta3), 1, j(2), 1);
  ch.RotX(p[kAlpha4], r(kAlpha4));
  ch.TransX(p[kA4], r(kA4));
  ch.RotZ(p[kTheta4] + q[3], r(kTheta4), 1, j(3), 1);
  ch.TransZ(p[kD4], r(kD4));
  ch.RotX(p[kAlpha5], r(kAlpha5));
  ch.TransX(p[kA5], r(kA5));
  ch.RotZ(p[kTheta5] + q[4], r(kTheta5), 1, j(4), 1);
  ch.TransZ(p[kD5], r(kD5));
  ch.RotX(p[kAlpha6], r(kAlpha6));
  ch.TransX(p[kA6], r(kA6));
  ch.RotZ(kRx130Theta6Rad + q[5], j(5));
  ch.TransZ(kRx130D6Mm);
  // Laser tool ^6T_7 (§3.3.3): Rx(theta_x) Ry(theta_y) Tx(px) Ty(py).
  ch.RotX(l[kLaserThetaX], Col(laser_col, kLaserThetaX));
  ch.RotY(l[kLaserThetaY], Col(laser_col, kLaserThetaY));
  ch.TransX(l[kLaserPx], Col(laser_col, kLaserPx));
  ch.TransY(l[kLaserPy], Col(laser_col, kLaserPy));
}

void AppendRailFromBase(TwistChain& ch, const double* phi, double rail_mm, int rail_col, int position_col) {
  // Eq. 3.3: ^R T_B = Tr(D, 0, 0) (Rz(phi_l) Ry(phi_m))^-1 = Tr(D, 0, 0) Ry(-phi_m) Rz(-phi_l).
  ch.TransX(rail_mm, position_col);
  ch.RotY(-phi[kPhiM], Col(rail_col, kPhiM), -1.0);
  ch.RotZ(-phi[kPhiL], Col(rail_col, kPhiL), -1.0);
}

void AppendRail1FromRail2(TwistChain& ch, const double* psi, int psi_col) {
  // Eq. 3.5: Tr(psi_x, psi_y, psi_z) Rx(psi_alpha) Rz(pi).
  ch.TransX(psi[kPsiX], Col(psi_col, kPsiX));
  ch.TransY(psi[kPsiY], Col(psi_col, kPsiY));
  ch.TransZ(psi[kPsiZ], Col(psi_col, kPsiZ));
  ch.RotX(psi[kPsiAlpha], Col(psi_col, kPsiAlpha));
  ch.RotZ(kPi);
}

bool EvaluateAim(const double* robot, const double* laser, const Joints& q, const Vec3d& point, AimEvaluation* out,
                 double min_length_mm) {
  TwistChain ch;
  AppendRx130LaserChain(ch, robot, laser, q, 0, kAimLaserCol, kAimJointCol);
  const Mat3d& r = ch.rotation();
  const Vec3d& o = ch.translation();
  const Vec3d s = point - o;
  const Vec3d p7 = r.transpose() * s;
  const double z = p7.z();
  if (!(z >= min_length_mm)) return false;
  out->laser_axes = r;
  out->length_mm = z;
  out->r << p7.x() / z, p7.y() / z;
  // d p7 = -R^T v(o) + C omega, with the rows of C the cross products (axis x s) (see twist_chain.h).
  Mat3d c;
  c.row(0) = r.col(0).cross(s).transpose();
  c.row(1) = r.col(1).cross(s).transpose();
  c.row(2) = r.col(2).cross(s).transpose();
  const TwistChain::Twists v = ch.PointVelocity(o);
  const Eigen::Matrix<double, 3, 28> dp7 =
      -r.transpose() * v.leftCols<28>() + c * ch.omega().leftCols<28>();
  out->d_chain.row(0) = (dp7.row(0) - out->r.x() * dp7.row(2)) / z;
  out->d_chain.row(1) = (dp7.row(1) - out->r.y() * dp7.row(2)) / z;
  out->d_point.row(0) = (r.col(0) - out->r.x() * r.col(2)).transpose() / z;
  out->d_point.row(1) = (r.col(1) - out->r.y() * r.col(2)).transpose() / z;
  return true;
}

Eigen::Matrix2d AimNoiseCovariance(const AimEvaluation& e, const AimNoiseModel& noise) {
  // Spot error on the observation plane: the beam passes through P + E s, E the plane's in-plane
  // basis, so (x, y) moves by -[X Y]^T E s: covariance sigma^2 [X Y]^T (I - n n^T) [X Y].
  const Eigen::Matrix<double, 3, 2> xy = e.laser_axes.leftCols<2>();
  Eigen::Matrix2d cov = Eigen::Matrix2d::Identity();
  if (noise.plane_normal) {
    const Vec3d n = noise.plane_normal->normalized();
    cov = xy.transpose() * (Mat3d::Identity() - n * n.transpose()) * xy;
  }
  cov *= noise.spot_sigma_mm * noise.spot_sigma_mm / (e.length_mm * e.length_mm);
  const Eigen::Matrix<double, 2, 6> jq = e.d_chain.middleCols<6>(kAimJointCol);
  Eigen::Matrix<double, 6, 1> var;
  for (int i = 0; i < 6; ++i) var(i) = noise.joint_sigma_rad[static_cast<std::size_t>(i)] * noise.joint_sigma_rad[static_cast<std::size_t>(i)];
  cov += jq * var.asDiagonal() * jq.transpose();
  return cov;
}

std::array<double, kRx130Joints> EncoderRoundingSigmaRad() {
  std::array<double, kRx130Joints> s{};
  for (std::size_t i = 0; i < s.size(); ++i) s[i] = DegToRad(1.0 / kRx130CountsPerDeg[i]) / std::sqrt(12.0);
  return s;
}

Vec3d AimedPoint(const Vec3d& point, const double* phi, std::optional<double> offset_mm) {
  if (!offset_mm) return point;
  return point + *offset_mm * RailDirectionInBase(phi[kPhiL], phi[kPhiM]);
}

AimResidual::AimResidual(const Joints& q, std::optional<double> offset_mm, const Eigen::Matrix2d& sqrt_information)
    : ResidualFunction(2, offset_mm ? std::vector<int>{kRx130ParamCount, kLaserParamCount, 3, kRailParamCount}
                                    : std::vector<int>{kRx130ParamCount, kLaserParamCount, 3}),
      q_(q),
      offset_mm_(offset_mm),
      w_(sqrt_information) {}

bool AimResidual::Evaluate(const double* const* parameters, double* residuals, double** jacobians) const {
  const Vec3d p(parameters[2][0], parameters[2][1], parameters[2][2]);
  const Vec3d aimed = AimedPoint(p, offset_mm_ ? parameters[3] : nullptr, offset_mm_);
  AimEvaluation e;
  if (!EvaluateAim(parameters[0], parameters[1], q_, aimed, &e)) return false;
  Eigen::Map<Eigen::Vector2d> residual_map(residuals);
  residual_map = w_ * e.r;
  if (jacobians == nullptr) return true;
  if (jacobians[0]) StoreRowMajor<2, kRx130ParamCount>(jacobians[0], w_ * e.d_chain.leftCols<kRx130ParamCount>());
  if (jacobians[1]) {
    StoreRowMajor<2, kLaserParamCount>(jacobians[1], w_ * e.d_chain.middleCols<kLaserParamCount>(kAimLaserCol));
  }
  if (jacobians[2]) StoreRowMajor<2, 3>(jacobians[2], w_ * e.d_point);
  if (offset_mm_ && jacobians[3]) {
    StoreRowMajor<2, kRailParamCount>(jacobians[3], w_ * e.d_point * (*offset_mm_ * DirectionJacobian(parameters[3])));
  }
  return true;
}

Eigen::Vector2d AimResidual::DerivativeWrtOffset(const double* const* parameters) const {
  if (!offset_mm_) return Eigen::Vector2d::Zero();
  const Vec3d p(parameters[2][0], parameters[2][1], parameters[2][2]);
  AimEvaluation e;
  if (!EvaluateAim(parameters[0], parameters[1], q_, AimedPoint(p, parameters[3], offset_mm_), &e)) {
    return Eigen::Vector2d::Zero();
  }
  return w_ * e.d_point * RailDirectionInBase(parameters[3][kPhiL], parameters[3][kPhiM]);
}

LineJacobian LineFromChain(const TwistChain& ch) {
  LineJacobian l;
  l.origin = ch.translation();
  l.direction = ch.rotation().col(2);
  l.d_origin = ch.PointVelocity(l.origin);
  for (int k = 0; k < TwistChain::kMaxColumns; ++k) l.d_direction.col(k) = ch.omega().col(k).cross(l.direction);
  return l;
}

bool EvaluateLineDistance(const LineJacobian& a, const LineJacobian& b, LineDistance* out) {
  const Vec3d n = a.direction.cross(b.direction);
  const double nn = n.norm();
  if (!(nn > 1e-9)) return false;
  const Vec3d nh = n / nn;
  const Vec3d w = b.origin - a.origin;
  out->distance_mm = w.dot(nh);
  // d e = dw . n^ + w_perp . dn / |n|, w_perp = w - (w . n^) n^; dn = dda x db + da x ddb.
  const Vec3d w_perp = w - out->distance_mm * nh;
  out->d_a = -nh.transpose() * a.d_origin + (b.direction.cross(w_perp) / nn).transpose() * a.d_direction;
  out->d_b = nh.transpose() * b.d_origin + (w_perp.cross(a.direction) / nn).transpose() * b.d_direction;
  const Line3d la{a.origin, a.direction}, lb{b.origin, b.direction};
  const auto st = ClosestPointsBetweenLines(la, lb, 1e-12);
  out->mean_length_mm = st ? 0.5 * (st->first + st->second) : 0.0;
  return true;
}

RailResidual::RailResidual(const Line3d& line1_in_r1, const Line3d& line2_in_r2, double sigma_mm)
    : ResidualFunction(1, {kRobotToRobotParamCount}), a_(line1_in_r1), b_(line2_in_r2), inv_sigma_(1.0 / sigma_mm) {}

bool RailResidual::Evaluate(const double* const* parameters, double* residuals, double** jacobians) const {
  TwistChain ch;
  AppendRail1FromRail2(ch, parameters[0], 0);
  LineJacobian a, b;
  a.origin = a_.origin;
  a.direction = a_.direction;
  b.origin = ch.rotation() * b_.origin + ch.translation();
  b.direction = ch.rotation() * b_.direction;
  b.d_origin = ch.PointVelocity(b.origin);
  for (int k = 0; k < kRobotToRobotParamCount; ++k) b.d_direction.col(k) = ch.omega().col(k).cross(b.direction);
  LineDistance d;
  if (!EvaluateLineDistance(a, b, &d)) return false;
  residuals[0] = d.distance_mm * inv_sigma_;
  if (jacobians && jacobians[0]) {
    for (int k = 0; k < kRobotToRobotParamCount; ++k) jacobians[0][k] = d.d_b(k) * inv_sigma_;
  }
  return true;
}

LineJacobian ArmLineInRail1(const double* robot, const double* laser, const double* phi, double rail_mm,
                            const Joints& q, const double* psi, const ArmChainColumns& cols) {
  TwistChain ch;
  if (psi != nullptr) AppendRail1FromRail2(ch, psi, cols.psi);
  AppendRailFromBase(ch, phi, rail_mm, cols.rail, cols.position);
  AppendRx130LaserChain(ch, robot, laser, q, cols.robot, cols.laser, cols.joints);
  return LineFromChain(ch);
}

RailArmsResidual::RailArmsResidual(const Joints& q1, double rail1_mm, const Joints& q2, double rail2_mm, double sigma_mm)
    : ResidualFunction(1, {kRobotToRobotParamCount, kRx130ParamCount, kLaserParamCount, kRailParamCount,
                           kRx130ParamCount, kLaserParamCount, kRailParamCount}),
      q1_(q1),
      q2_(q2),
      rail1_mm_(rail1_mm),
      rail2_mm_(rail2_mm),
      inv_sigma_(1.0 / sigma_mm) {}

bool RailArmsResidual::Evaluate(const double* const* parameters, double* residuals, double** jacobians) const {
  const LineJacobian a = ArmLineInRail1(parameters[1], parameters[2], parameters[3], rail1_mm_, q1_, nullptr, kArm1Columns);
  const LineJacobian b = ArmLineInRail1(parameters[4], parameters[5], parameters[6], rail2_mm_, q2_, parameters[0], kArm2Columns);
  LineDistance d;
  if (!EvaluateLineDistance(a, b, &d)) return false;
  residuals[0] = d.distance_mm * inv_sigma_;
  if (jacobians == nullptr) return true;
  auto copy = [&](int block, const Eigen::Matrix<double, 1, TwistChain::kMaxColumns>& src, int first, int size) {
    if (jacobians[block] == nullptr) return;
    for (int k = 0; k < size; ++k) jacobians[block][k] = src(first + k) * inv_sigma_;
  };
  copy(0, d.d_b, kArm2Columns.psi, kRobotToRobotParamCount);
  copy(1, d.d_a, kArm1Columns.robot, kRx130ParamCount);
  copy(2, d.d_a, kArm1Columns.laser, kLaserParamCount);
  copy(3, d.d_a, kArm1Columns.rail, kRailParamCount);
  copy(4, d.d_b, kArm2Columns.robot, kRx130ParamCount);
  copy(5, d.d_b, kArm2Columns.laser, kLaserParamCount);
  copy(6, d.d_b, kArm2Columns.rail, kRailParamCount);
  return true;
}

}  // namespace idi::optim
