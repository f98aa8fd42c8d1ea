// The one interface through which the VWE, the front-end, the back-end and the mapper see a
// continuous-time trajectory: the camera pose at any time t relative to the camera at a
// reference time, T_Cr_Ct(t | theta), and its derivatives w.r.t. the parameters theta.
#pragma once

#include <cstdint>
#include <vector>

#include "vwe_vo/core/math.h"

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
};

}  // namespace vwe_vo
