// The one interface through which the VWE, the front-end, the back-end and the mapper see a
// continuous-time trajectory: the camera pose at any time t relative to the camera at a
// reference time, T_Cr_Ct(t | theta), and its derivatives w.r.t. the parameters theta.
#pragma once

#include <cstdint>
#include <stdexcept>
#include <vector>

#include "vwe_vo/common/math.h"

namespace vwe_vo {

/// Sparse derivative of T_Cr_Ct w.r.t. the model parameters: for each parameter that moves
/// the pose at this t, its index in theta and dR/dtheta_k, dt/dtheta_k.
struct PoseJacobian {
  std::vector<int> param_index;
  std::vector<Mat3> dR;
  std::vector<Vec3> dt;
  void clear() {
    param_index.clear();
    dR.clear();
    dt.clear();
  }
  void add(int k, const Mat3& dR_k, const Vec3& dt_k) {
    param_index.push_back(k);
    dR.push_back(dR_k);
    dt.push_back(dt_k);
  }
};

/// Derivatives of T_Cr_Ct w.r.t. the planar motion of the vehicle between the reference time and
/// t, for models with T_Cr_Ct = T_base_cam^-1 * T_Vr_Vt * T_base_cam and T_Vr_Vt a planar pose
/// (heading psi, position x, y in the reference vehicle frame). Moving x or y does not rotate.
struct PlanarLocalJacobian {
  Mat3 dR_dpsi;
  Vec3 dt_dpsi, dt_dx, dt_dy;
};

class TrajectoryModel {
 public:
  virtual ~TrajectoryModel() = default;
  /// Number of parameters theta (the size of a full gradient).
  virtual int numParams() const = 0;
  /// Reference time: T_Cr_Ct(t_ref) = identity.
  virtual int64_t referenceTime() const = 0;
  /// False if the model cannot give a pose at t (outside its valid interval).
  virtual bool covers(int64_t t_ns) const = 0;
  /// Camera at t seen from the camera at the reference time. If jac is not null it is cleared
  /// and filled with the derivatives w.r.t. every parameter that influences this pose.
  virtual Pose3 T_Cr_Ct(int64_t t_ns, PoseJacobian* jac = nullptr) const = 0;

  /// Optional factored Jacobian of planar models with many parameters (the back-end's spline):
  /// the objective differentiates each ray w.r.t. only the three planar coordinates of T_Vr_Vt
  /// (T_Cr_CtPlanar) and hands the model dVar/d(psi, x, y) per ray (addPlanarGradient), which
  /// chains it to the parameters. Same gradient as through PoseJacobian, much less work per event.
  virtual bool hasPlanarJacobian() const { return false; }
  /// T_Cr_Ct(t) and its derivatives w.r.t. the planar coordinates of T_Vr_Vt(t).
  virtual Pose3 T_Cr_CtPlanar(int64_t /*t_ns*/, PlanarLocalJacobian* /*jac*/) const {
    throw std::logic_error("TrajectoryModel: this model has no planar Jacobian");
  }
  /// gradient (size numParams()) += sum_i g_i . d(psi, x, y)(t_i) / dtheta, with g_i the
  /// derivative of a scalar w.r.t. the planar coordinates of T_Vr_Vt(t_ns[i]).
  virtual void addPlanarGradient(const std::vector<int64_t>& /*t_ns*/,
                                 const std::vector<Vec3>& /*g*/,
                                 Eigen::VectorXd* /*gradient*/) const {
    throw std::logic_error("TrajectoryModel: this model has no planar Jacobian");
  }
};

}  // namespace vwe_vo
