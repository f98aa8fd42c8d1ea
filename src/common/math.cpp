#include "vwe_vo/common/math.h"

#include <cmath>

namespace vwe_vo {

Mat3 rotZ(double yaw) {
  const double c = std::cos(yaw), s = std::sin(yaw);
  Mat3 R;
  R << c, -s, 0, s, c, 0, 0, 0, 1;
  return R;
}

Mat3 rotX(double roll) {
  const double c = std::cos(roll), s = std::sin(roll);
  Mat3 R;
  R << 1, 0, 0, 0, c, -s, 0, s, c;
  return R;
}

double yawOf(const Mat3& R) {
  return std::atan2(R(1, 0), R(0, 0));
}

double wrapAngle(double a) {
  a = std::fmod(a + kPi, 2.0 * kPi);
  if (a <= 0) a += 2.0 * kPi;
  return a - kPi;
}

double rotationAngle(const Mat3& R) {
  // atan2 of (|axis * sin|, cos) is accurate over the whole range, unlike acos of the trace.
  const Vec3 w(R(2, 1) - R(1, 2), R(0, 2) - R(2, 0), R(1, 0) - R(0, 1));
  const double s = 0.5 * w.norm();
  const double c = 0.5 * (R.trace() - 1.0);
  return std::atan2(s, c);
}

double angleBetween(const Vec3& a, const Vec3& b) {
  const double na = a.norm(), nb = b.norm();
  if (na == 0.0 || nb == 0.0) return 0.0;
  return std::atan2(a.cross(b).norm(), a.dot(b));
}

Pose3 planarPose(double x, double y, double yaw) {
  return makePose(rotZ(yaw), Vec3(x, y, 0.0));
}

Pose3 makePose(const Mat3& R, const Vec3& t) {
  Pose3 T = Pose3::Identity();
  T.linear() = R;
  T.translation() = t;
  return T;
}

Pose3 makePose(const Quat& q, const Vec3& t) {
  return makePose(q.normalized().toRotationMatrix(), t);
}

Pose3 interpolatePose(const Pose3& a, const Pose3& b, double alpha) {
  const Quat qa(a.linear()), qb(b.linear());
  return makePose(qa.slerp(alpha, qb), (1.0 - alpha) * a.translation() + alpha * b.translation());
}

Mat3 skew(const Vec3& v) {
  Mat3 S;
  S << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return S;
}

Mat3 R_base_opticalFrame() {
  Mat3 R;
  // camera x (right) = -y_base, camera y (down) = -z_base, camera z (forward) = +x_base
  R << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  return R;
}

}  // namespace vwe_vo
