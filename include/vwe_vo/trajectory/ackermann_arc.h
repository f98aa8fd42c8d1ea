// The Ackermann arc: the front-end's 2-DoF motion model (yaw rate omega, speed v), a planar
// constant-curvature arc of base_link, seen in the vehicle frame or, via the extrinsics, the
// camera.
#pragma once

#include <cstdint>
#include <limits>
#include <vector>

#include "vwe_vo/common/math.h"
#include "vwe_vo/trajectory/trajectory_model.h"

namespace vwe_vo {

/// Derivatives of an arc pose (R, p) w.r.t. omega and v. dR/dv is always zero.
struct ArcJacobian {
  Mat3 dR_domega = Mat3::Zero();
  Vec3 dp_domega = Vec3::Zero();
  Vec3 dp_dv = Vec3::Zero();
};

/// T_Vr_Vt: base_link at r + dt_s seen from base_link at r, for yaw rate omega [rad/s]
/// (> 0: left turn) and speed v [m/s]; dt_s may be negative. Smooth in omega through 0 (a
/// series is used for small |omega * dt_s|). If jac is not null it receives the derivatives.
Pose3 arcT_Vr_Vt(double omega, double v, double dt_s, ArcJacobian* jac = nullptr);

/// T_Cr_Ct = T_base_cam^-1 * T_Vr_Vt * T_base_cam, with derivatives by the chain rule.
Pose3 arcT_Cr_Ct(double omega, double v, double dt_s, const Pose3& T_base_cam,
                 ArcJacobian* jac = nullptr);

/// Conjugation of a vehicle-frame relative pose into the camera frame:
/// T_Cr_Ct = T_base_cam^-1 * T_Vr_Vt * T_base_cam. Shared by every trajectory model.
Pose3 vehicleToCamera(const Pose3& T_Vr_Vt, const Pose3& T_base_cam);
/// The same map applied to a derivative (dR_V, dp_V) of T_Vr_Vt: (dR_C, dp_C) of T_Cr_Ct.
void vehicleToCameraDerivative(const Pose3& T_base_cam, const Mat3& dR_V, const Vec3& dp_V,
                               Mat3* dR_C, Vec3* dp_C);

/// The arc as a TrajectoryModel: theta = [omega, v] (indices 0 and 1).
class AckermannArcModel : public TrajectoryModel {
 public:
  static constexpr int kOmega = 0;
  static constexpr int kV = 1;

  /// covers(t) is true for t in [valid_from_ns, valid_to_ns] (by default: always).
  AckermannArcModel(double omega, double v, int64_t t_ref_ns, const Pose3& T_base_cam,
                    int64_t valid_from_ns = std::numeric_limits<int64_t>::min(),
                    int64_t valid_to_ns = std::numeric_limits<int64_t>::max());

  int numParams() const override { return 2; }
  int64_t referenceTime() const override { return t_ref_ns_; }
  bool covers(int64_t t_ns) const override {
    return t_ns >= valid_from_ns_ && t_ns <= valid_to_ns_;
  }
  Pose3 T_Cr_Ct(int64_t t_ns, PoseJacobian* jac = nullptr) const override;

  double omega() const { return omega_; }
  double v() const { return v_; }
  void setOmega(double omega) { omega_ = omega; }
  void setV(double v) { v_ = v; }
  void setValidInterval(int64_t valid_from_ns, int64_t valid_to_ns);
  const Pose3& T_base_cam() const { return T_base_cam_; }
  /// Roll rate of the body about base_link's x axis [rad/s] (default 0), composed after the arc:
  /// T_Vr_Vt = arc(dt) * Rx(roll_rate * dt). The front-end's nuisance for a body rolling on its
  /// suspension. Poses only: T_Cr_Ct throws if a Jacobian is asked for with a roll rate.
  void setRollRate(double roll_rate) { roll_rate_ = roll_rate; }
  double rollRate() const { return roll_rate_; }

 private:
  double omega_, v_;
  int64_t t_ref_ns_;
  Pose3 T_base_cam_;
  int64_t valid_from_ns_, valid_to_ns_;
  double roll_rate_ = 0.0;
};

}  // namespace vwe_vo
