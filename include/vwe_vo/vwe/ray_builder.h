// Events become the rays of a ProjectiveVolume in one place, for the VWE objective (front-end,
// back-end) and the EMVS disparity-space image (mapping): which pose an event uses (the middle of
// its pose slice, VolumeOptions::pose_slice_s) and the VolumeRay of its bearing seen from that
// pose in the reference camera frame.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <limits>

#include "vwe_vo/vwe/projective_volume.h"

namespace vwe_vo {

/// The time whose pose the event at t_ns uses: the middle of its slice on a fixed grid of
/// absolute times, [k slice_ns, (k + 1) slice_ns), so the events sharing a pose do not depend on
/// how they are batched; t_ns itself for slice_ns <= 1. Where the trajectory does not cover the
/// middle (it ends inside the slice) the event uses the pose at t_ns.
inline int64_t poseSliceTime(int64_t t_ns, int64_t slice_ns) {
  if (slice_ns <= 1) return t_ns;
  return t_ns - ((t_ns % slice_ns) + slice_ns) % slice_ns + slice_ns / 2;
}

/// A camera pose in the reference camera frame as rays need it: the ray of bearing f is
/// o + lambda R f; it votes where rho = 1 / z < rho_max, in front of the camera by at least
/// min_depth along the reference view's axis (z > o_z + min_depth; 0: in front of it).
template <typename S>
struct RayPose {
  using Vec3S = Eigen::Matrix<S, 3, 1>;
  using Mat3S = Eigen::Matrix<S, 3, 3>;
  RayPose() = default;
  RayPose(const Mat3S& R_ref_cam, const Vec3S& t_ref_cam, S min_depth = S(0))
      : R(R_ref_cam),
        o(t_ref_cam),
        // lambda = (z - o_z) / d_z > 0  <=>  z > o_z  <=>  rho < 1 / o_z (when o_z > 0)
        rho_max(o.z() + min_depth > 0 ? float(S(1) / (o.z() + min_depth))
                                      : std::numeric_limits<float>::infinity()) {}
  Mat3S R = Mat3S::Identity();
  Vec3S o = Vec3S::Zero();
  float rho_max = std::numeric_limits<float>::infinity();
};

/// The VolumeRay of bearings seen from a RayPose, for the virtual pinhole of a volume: the ray
/// o + lambda d meets the plane z = 1 / rho at (u0 + rho du, v0 + rho dv) with
/// u0 = fx d_x / d_z + cx, du = fx (o_x - o_z d_x / d_z) (v likewise). S = double for the VWE
/// (its Jacobians), float for the EMVS DSI (millions of rays per keyframe).
template <typename S>
class VolumeRayBuilder {
 public:
  using Vec3S = Eigen::Matrix<S, 3, 1>;
  explicit VolumeRayBuilder(const ProjectiveVolume& volume)
      : VolumeRayBuilder(S(volume.fx()), S(volume.fy()), S(volume.cx()), S(volume.cy())) {}
  VolumeRayBuilder(S fx, S fy, S cx, S cy) : fx_(fx), fy_(fy), cx_(cx), cy_(cy) {}

  /// The ray of bearing f (camera frame) from `pose`; its direction R f in *d if d is not null.
  /// False if the direction does not point in front of the reference view (d_z <= 1e-9).
  bool operator()(const RayPose<S>& pose, const Vec3S& f, VolumeRay* ray,
                  Vec3S* d = nullptr) const {
    const Vec3S dir = pose.R * f;
    if (d) *d = dir;
    if (!(dir.z() > S(1e-9))) return false;
    const S ax = dir.x() / dir.z(), ay = dir.y() / dir.z();
    const Vec3S& o = pose.o;
    ray->u0 = float(fx_ * ax + cx_);
    ray->v0 = float(fy_ * ay + cy_);
    ray->du = float(fx_ * (o.x() - o.z() * ax));
    ray->dv = float(fy_ * (o.y() - o.z() * ay));
    ray->rho_max = pose.rho_max;
    return true;
  }

 private:
  S fx_, fy_, cx_, cy_;
};

}  // namespace vwe_vo
