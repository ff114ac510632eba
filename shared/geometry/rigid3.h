// Rigid transforms in 3D, templated on the scalar so Ceres Jets flow through.
//
// Naming: a transform `b_from_a` maps coordinates of a point in frame a to frame b
// (p_b = b_from_a * p_a); compose right to left: c_from_a = c_from_b * b_from_a.
// The dissertation writes the same transform as ^bT_a.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <Eigen/LU>
#include <cmath>

namespace idi {

template <typename T>
using Vec2 = Eigen::Matrix<T, 2, 1>;
template <typename T>
using Vec3 = Eigen::Matrix<T, 3, 1>;
template <typename T>
using Mat3 = Eigen::Matrix<T, 3, 3>;
template <typename T>
using Mat4 = Eigen::Matrix<T, 4, 4>;

using Vec2d = Vec2<double>;
using Vec3d = Vec3<double>;
using Mat3d = Mat3<double>;
using Mat4d = Mat4<double>;

template <typename T>
struct Rigid3 {
  Mat3<T> rotation = Mat3<T>::Identity();
  Vec3<T> translation = Vec3<T>::Zero();

  static Rigid3 Identity() { return Rigid3(); }
  static Rigid3 FromMatrix(const Mat4<T>& m) {
    Rigid3 r;
    r.rotation = m.template topLeftCorner<3, 3>();
    r.translation = m.template topRightCorner<3, 1>();
    return r;
  }

  Rigid3 operator*(const Rigid3& rhs) const {
    Rigid3 out;
    out.rotation = rotation * rhs.rotation;
    out.translation = rotation * rhs.translation + translation;
    return out;
  }
  Vec3<T> operator*(const Vec3<T>& p) const { return rotation * p + translation; }
  // Rotates a direction (no translation).
  Vec3<T> RotateVector(const Vec3<T>& v) const { return rotation * v; }

  Rigid3 Inverse() const {
    Rigid3 out;
    out.rotation = rotation.transpose();
    out.translation = -(out.rotation * translation);
    return out;
  }

  Mat4<T> Matrix() const {
    Mat4<T> m = Mat4<T>::Identity();
    m.template topLeftCorner<3, 3>() = rotation;
    m.template topRightCorner<3, 1>() = translation;
    return m;
  }
  // The 3x4 matrix [R | t].
  Eigen::Matrix<T, 3, 4> Matrix3x4() const {
    Eigen::Matrix<T, 3, 4> m;
    m.template leftCols<3>() = rotation;
    m.col(3) = translation;
    return m;
  }

  template <typename U>
  Rigid3<U> Cast() const {
    Rigid3<U> out;
    out.rotation = rotation.template cast<U>();
    out.translation = translation.template cast<U>();
    return out;
  }
};

using Rigid3d = Rigid3<double>;

// Elementary transforms. Rx, Ry, Rz rotate by an angle in radians about the named axis.
template <typename T>
Rigid3<T> RotX(const T& angle) {
  using std::cos;
  using std::sin;
  const T c = cos(angle), s = sin(angle);
  Rigid3<T> r;
  r.rotation << T(1), T(0), T(0), T(0), c, -s, T(0), s, c;
  return r;
}

template <typename T>
Rigid3<T> RotY(const T& angle) {
  using std::cos;
  using std::sin;
  const T c = cos(angle), s = sin(angle);
  Rigid3<T> r;
  r.rotation << c, T(0), s, T(0), T(1), T(0), -s, T(0), c;
  return r;
}

template <typename T>
Rigid3<T> RotZ(const T& angle) {
  using std::cos;
  using std::sin;
  const T c = cos(angle), s = sin(angle);
  Rigid3<T> r;
  r.rotation << c, -s, T(0), s, c, T(0), T(0), T(0), T(1);
  return r;
}

template <typename T>
Rigid3<T> Translation(const T& x, const T& y, const T& z) {
  Rigid3<T> r;
  r.translation << x, y, z;
  return r;
}

template <typename T>
Rigid3<T> Translation(const Vec3<T>& t) {
  Rigid3<T> r;
  r.translation = t;
  return r;
}

// Craig's modified Denavit-Hartenberg link transform, eq. 3.1:
// ^{i-1}T_i = Rx(alpha) Tx(a) Rz(theta) Tz(d), written out in closed form.
template <typename T>
Rigid3<T> DhLink(const T& alpha, const T& a, const T& theta, const T& d) {
  using std::cos;
  using std::sin;
  const T ca = cos(alpha), sa = sin(alpha), ct = cos(theta), st = sin(theta);
  Rigid3<T> r;
  r.rotation << ct, -st, T(0), ca * st, ca * ct, -sa, sa * st, sa * ct, ca;
  r.translation << a, -d * sa, d * ca;
  return r;
}

// Hayati link transform, eq. 3.2, used where consecutive axes are (nearly) parallel and the DH
// parameters become singular: ^{i-1}T_i = Rx(alpha) Tx(a) Ry(beta) Rz(theta).
template <typename T>
Rigid3<T> HayatiLink(const T& alpha, const T& a, const T& beta, const T& theta) {
  using std::cos;
  using std::sin;
  const T ca = cos(alpha), sa = sin(alpha), cb = cos(beta), sb = sin(beta), ct = cos(theta), st = sin(theta);
  Rigid3<T> r;
  r.rotation << cb * ct, -cb * st, sb,                      //
      sa * sb * ct + ca * st, -sa * sb * st + ca * ct, -sa * cb,  //
      -ca * sb * ct + sa * st, ca * sb * st + sa * ct, ca * cb;
  r.translation << a, T(0), T(0);
  return r;
}

// Angle of the rotation part (radians, in [0, pi]); used to compare transforms in tests and checks.
template <typename T>
T RotationAngle(const Mat3<T>& r) {
  using std::acos;
  T c = (r.trace() - T(1)) / T(2);
  if (c > T(1)) c = T(1);
  if (c < T(-1)) c = T(-1);
  return acos(c);
}

}  // namespace idi
