#include "vwe_vo/trajectory/ackermann_arc.h"

#include <cmath>
#include <stdexcept>
#include <string>

namespace vwe_vo {

namespace {

// The arc is p = v*d*[S(psi), C(psi), 0] with S = sin(x)/x, C = (1 - cos x)/x. Below
// kSeriesBelow the closed forms of S' and C' lose ~eps/x^2 to cancellation, so a Taylor series
// is used there; its truncation error (first omitted term x^14/15!) is < 1e-22 at the switch,
// and the closed forms are accurate to ~1e-14 relative above it.
constexpr double kSeriesBelow = 0.2;
constexpr int kSeriesTerms = 7;

struct ArcShape {
  double S, C, dS, dC;  // S(x), C(x) and their derivatives w.r.t. x
};

ArcShape arcShape(double x) {
  ArcShape f{};
  if (std::abs(x) >= kSeriesBelow) {
    const double s = std::sin(x), c = std::cos(x), h = std::sin(0.5 * x);
    const double one_minus_cos = 2.0 * h * h;  // no cancellation, unlike 1 - cos(x)
    f.S = s / x;
    f.C = one_minus_cos / x;
    f.dS = (x * c - s) / (x * x);
    f.dC = (x * s - one_minus_cos) / (x * x);
    return f;
  }
  // S = sum (-1)^k x^2k / (2k+1)!,  C = sum (-1)^k x^(2k+1) / (2k+2)!
  const double x2 = x * x;
  double pw = 1.0;       // x^(2k)
  double pw_prev = 0.0;  // x^(2k-2)
  double fact = 1.0;     // (2k+1)!
  double sign = 1.0;
  for (int k = 0; k < kSeriesTerms; ++k) {
    const double fact_next = fact * (2 * k + 2);  // (2k+2)!
    f.S += sign * pw / fact;
    f.C += sign * pw * x / fact_next;
    f.dC += sign * (2 * k + 1) * pw / fact_next;
    if (k > 0) f.dS += sign * (2 * k) * pw_prev * x / fact;
    pw_prev = pw;
    pw *= x2;
    fact = fact_next * (2 * k + 3);
    sign = -sign;
  }
  return f;
}

}  // namespace

Pose3 arcT_Vr_Vt(double omega, double v, double dt_s, ArcJacobian* jac) {
  const double psi = omega * dt_s;
  const ArcShape f = arcShape(psi);
  const Mat3 R = rotZ(psi);
  const Vec3 p = v * dt_s * Vec3(f.S, f.C, 0.0);
  if (jac) {
    jac->dR_domega = dt_s * skew(Vec3::UnitZ()) * R;
    jac->dp_domega = v * dt_s * dt_s * Vec3(f.dS, f.dC, 0.0);
    jac->dp_dv = dt_s * Vec3(f.S, f.C, 0.0);
  }
  return makePose(R, p);
}

Pose3 vehicleToCamera(const Pose3& T_Vr_Vt, const Pose3& T_base_cam) {
  // R_C = R_bc^T R_V R_bc,  p_C = R_bc^T (R_V p_bc + p_V - p_bc): once per event, so written out
  // rather than as two 4x4 products and an inverse.
  const Mat3& R_bc = T_base_cam.linear();
  const Vec3& p_bc = T_base_cam.translation();
  const Mat3 R_cb = R_bc.transpose();
  return makePose(R_cb * T_Vr_Vt.linear() * R_bc,
                  R_cb * (T_Vr_Vt.linear() * p_bc + T_Vr_Vt.translation() - p_bc));
}

void vehicleToCameraDerivative(const Pose3& T_base_cam, const Mat3& dR_V, const Vec3& dp_V,
                               Mat3* dR_C, Vec3* dp_C) {
  // R_C = R_bc^T R_V R_bc,  p_C = R_bc^T (R_V p_bc + p_V - p_bc)
  const Mat3 R_cb = T_base_cam.linear().transpose();
  *dR_C = R_cb * dR_V * T_base_cam.linear();
  *dp_C = R_cb * (dR_V * T_base_cam.translation() + dp_V);
}

Pose3 arcT_Cr_Ct(double omega, double v, double dt_s, const Pose3& T_base_cam, ArcJacobian* jac) {
  ArcJacobian jac_V;
  const Pose3 T_Vr_Vt = arcT_Vr_Vt(omega, v, dt_s, jac ? &jac_V : nullptr);
  if (jac) {
    vehicleToCameraDerivative(T_base_cam, jac_V.dR_domega, jac_V.dp_domega, &jac->dR_domega,
                              &jac->dp_domega);
    Mat3 dR_dv_C;  // zero: v does not rotate
    vehicleToCameraDerivative(T_base_cam, Mat3::Zero(), jac_V.dp_dv, &dR_dv_C, &jac->dp_dv);
  }
  return vehicleToCamera(T_Vr_Vt, T_base_cam);
}

AckermannArcModel::AckermannArcModel(double omega, double v, int64_t t_ref_ns,
                                     const Pose3& T_base_cam, int64_t valid_from_ns,
                                     int64_t valid_to_ns)
    : omega_(omega), v_(v), t_ref_ns_(t_ref_ns), T_base_cam_(T_base_cam) {
  setValidInterval(valid_from_ns, valid_to_ns);
}

void AckermannArcModel::setValidInterval(int64_t valid_from_ns, int64_t valid_to_ns) {
  if (valid_to_ns < valid_from_ns) {
    throw std::invalid_argument("AckermannArcModel: valid_to_ns " + std::to_string(valid_to_ns) +
                                " < valid_from_ns " + std::to_string(valid_from_ns));
  }
  valid_from_ns_ = valid_from_ns;
  valid_to_ns_ = valid_to_ns;
}

Pose3 AckermannArcModel::T_Cr_Ct(int64_t t_ns, PoseJacobian* jac) const {
  if (roll_rate_ != 0.0) {
    if (jac) throw std::logic_error("AckermannArcModel: no Jacobian with a roll rate");
    const double dt = dtSec(t_ns, t_ref_ns_);
    const Pose3 roll = makePose(rotX(roll_rate_ * dt), Vec3::Zero());
    return vehicleToCamera(arcT_Vr_Vt(omega_, v_, dt) * roll, T_base_cam_);
  }
  ArcJacobian arc_jac;
  const Pose3 T =
      arcT_Cr_Ct(omega_, v_, dtSec(t_ns, t_ref_ns_), T_base_cam_, jac ? &arc_jac : nullptr);
  if (jac) {
    jac->clear();
    jac->add(kOmega, arc_jac.dR_domega, arc_jac.dp_domega);
    jac->add(kV, Mat3::Zero(), arc_jac.dp_dv);
  }
  return T;
}

}  // namespace vwe_vo
