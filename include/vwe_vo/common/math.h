// Rotations, poses, time and interpolation shared by every vwe_vo component.
// The one place for these formulas: other modules call these instead of writing their own.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>

namespace vwe_vo {

using Vec2 = Eigen::Vector2d;
using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;
using Quat = Eigen::Quaterniond;
/// Rigid transform. Names carry frames: T_A_B maps points from frame B to frame A.
using Pose3 = Eigen::Isometry3d;

constexpr double kPi = 3.14159265358979323846;
constexpr double kDegPerRad = 180.0 / kPi;
constexpr double kRadPerDeg = kPi / 180.0;
constexpr int64_t kNsPerSec = 1000000000LL;

/// Time: the core keeps int64 nanoseconds; seconds (double) only for differences.
inline double nsToSec(int64_t t_ns) {
  return static_cast<double>(t_ns) * 1e-9;
}
inline int64_t secToNs(double t_s) {
  return static_cast<int64_t>(t_s * 1e9 + (t_s >= 0 ? 0.5 : -0.5));
}
/// (t_ns - ref_ns) in seconds, exact for differences up to ~100 days.
inline double dtSec(int64_t t_ns, int64_t ref_ns) {
  return nsToSec(t_ns - ref_ns);
}

/// Rotation about +z by yaw [rad] (counter-clockwise seen from above).
Mat3 rotZ(double yaw);
/// Rotation about +x by roll [rad].
Mat3 rotX(double roll);
/// Yaw of the x axis of R projected on the xy-plane [rad], in (-pi, pi].
double yawOf(const Mat3& R);
/// Wraps an angle to (-pi, pi].
double wrapAngle(double a);
/// Angle of the rotation R [rad], in [0, pi]; numerically safe near 0 and pi.
double rotationAngle(const Mat3& R);
/// Angle between two vectors [rad], in [0, pi]; 0 if either is zero.
double angleBetween(const Vec3& a, const Vec3& b);

/// Planar pose of base_link in odom: position (x, y, 0), rotation Rz(yaw).
Pose3 planarPose(double x, double y, double yaw);
Pose3 makePose(const Mat3& R, const Vec3& t);
Pose3 makePose(const Quat& q, const Vec3& t);

/// Interpolates a -> b with alpha in [0, 1]: slerp of rotation, lerp of translation.
Pose3 interpolatePose(const Pose3& a, const Pose3& b, double alpha);

/// Skew-symmetric matrix [v]_x such that [v]_x w = v x w.
Mat3 skew(const Vec3& v);

/// The default forward-facing camera optical frame (z forward, x right, y down) expressed in a
/// vehicle frame (x forward, y left, z up): R_base_cam with columns = camera axes in base.
Mat3 R_base_opticalFrame();

}  // namespace vwe_vo
