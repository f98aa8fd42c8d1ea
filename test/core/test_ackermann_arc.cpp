#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <stdexcept>

#include "vwe_vo/trajectory/ackermann_arc.h"
#include "vwe_vo/trajectory/dead_reckoning.h"

using namespace vwe_vo;

namespace {

struct Unicycle {
  double x, y, th;
};

// RK4 of x' = v cos th, y' = v sin th, th' = omega over dt_s (may be negative).
Unicycle integrateUnicycle(Unicycle s, double omega, double v, double dt_s, int steps) {
  const double h = dt_s / steps;
  auto f = [&](const Unicycle& q) {
    return Unicycle{v * std::cos(q.th), v * std::sin(q.th), omega};
  };
  auto add = [](const Unicycle& a, const Unicycle& b, double k) {
    return Unicycle{a.x + k * b.x, a.y + k * b.y, a.th + k * b.th};
  };
  for (int i = 0; i < steps; ++i) {
    const Unicycle k1 = f(s), k2 = f(add(s, k1, h / 2)), k3 = f(add(s, k2, h / 2)),
                   k4 = f(add(s, k3, h));
    s.x += h / 6 * (k1.x + 2 * k2.x + 2 * k3.x + k4.x);
    s.y += h / 6 * (k1.y + 2 * k2.y + 2 * k3.y + k4.y);
    s.th += h / 6 * (k1.th + 2 * k2.th + 2 * k3.th + k4.th);
  }
  return s;
}

Pose3 testExtrinsics() {
  return makePose(R_base_opticalFrame(), Vec3(0.1, 0.02, 0.3));
}

// Central differences of (R, p) of f(x) at x.
void centralDiff(const std::function<Pose3(double)>& f, double x, double h, Mat3* dR, Vec3* dp) {
  const Pose3 a = f(x + h), b = f(x - h);
  *dR = (a.linear() - b.linear()) / (2 * h);
  *dp = (a.translation() - b.translation()) / (2 * h);
}

const double kOmegas[] = {1.3, -0.7, 3.0, -2.5, 0.15, -0.19, 0.21, 1e-3, -1e-5, 1e-7, -1e-9, 0.0};

}  // namespace

TEST(AckermannArc, MatchesUnicycleIntegration) {
  for (double omega : kOmegas) {
    for (double v : {2.0, -0.8}) {
      for (double dt : {1.0, -0.6}) {
        const Unicycle s = integrateUnicycle({0, 0, 0}, omega, v, dt, 4000);
        const Pose3 T = arcT_Vr_Vt(omega, v, dt);
        EXPECT_NEAR(T.translation().x(), s.x, 1e-9) << omega << " " << v << " " << dt;
        EXPECT_NEAR(T.translation().y(), s.y, 1e-9) << omega << " " << v << " " << dt;
        EXPECT_EQ(T.translation().z(), 0.0);
        EXPECT_NEAR(yawOf(T.linear()), wrapAngle(s.th), 1e-12) << omega;
      }
    }
  }
}

TEST(AckermannArc, IsAOneParameterGroup) {
  // Constant (omega, v): T(d1 + d2) = T(d1) * T(d2), and T(-d) = T(d)^-1.
  for (double omega : kOmegas) {
    const Pose3 a = arcT_Vr_Vt(omega, 1.7, 0.4), b = arcT_Vr_Vt(omega, 1.7, 0.35);
    const Pose3 ab = arcT_Vr_Vt(omega, 1.7, 0.75);
    EXPECT_TRUE((a * b).matrix().isApprox(ab.matrix(), 1e-13)) << omega;
    const Pose3 inv = arcT_Vr_Vt(omega, 1.7, -0.4);
    EXPECT_TRUE((a * inv).matrix().isApprox(Eigen::Matrix4d::Identity(), 1e-13)) << omega;
  }
}

TEST(AckermannArc, ContinuousThroughZeroOmega) {
  const double v = 1.5, dt = 0.8;
  ArcJacobian j0;
  const Pose3 T0 = arcT_Vr_Vt(0.0, v, dt, &j0);
  EXPECT_TRUE(T0.translation().isApprox(Vec3(v * dt, 0, 0), 1e-15));
  for (double omega : {1e-9, -1e-9, 1e-6, -1e-6}) {
    ArcJacobian j;
    const Pose3 T = arcT_Vr_Vt(omega, v, dt, &j);
    // First-order agreement: the remainder is O(omega^2) ~ 1e-12.
    const Vec3 lin = T0.translation() + omega * j0.dp_domega;
    EXPECT_LT((T.translation() - lin).norm(), 1e-11) << omega;
    EXPECT_LT((T.linear() - (T0.linear() + omega * j0.dR_domega)).norm(), 1e-11) << omega;
    EXPECT_LT((j.dp_domega - j0.dp_domega).norm(), 1e-5) << omega;
    EXPECT_LT((j.dp_dv - j0.dp_dv).norm(), 1e-6) << omega;
  }
}

TEST(AckermannArc, AccurateOnBothSidesOfTheSeriesSwitch) {
  // Reference: closed forms in long double, 1 - cos x as 2 sin^2(x/2); the remaining
  // cancellation in x cos x - sin x costs ~1e-19 / x^2 <= 1e-13 relative for |x| >= 1e-3.
  const double v = 2.0, dt = 1.0;
  for (double mag = 1e-3; mag < 0.6; mag *= 1.07) {
    for (double psi : {mag, -mag}) {
      const long double x = psi;
      const long double s = std::sin(x), c = std::cos(x), h = std::sin(x / 2);
      const long double omc = 2 * h * h;
      const Vec3 p_ref(double(s / x), double(omc / x), 0.0);
      const Vec3 dp_domega_ref(double((x * c - s) / (x * x)), double((x * s - omc) / (x * x)), 0.0);
      ArcJacobian j;
      const Pose3 T = arcT_Vr_Vt(psi, v, dt, &j);
      EXPECT_LT((T.translation() / v - p_ref).norm(), 1e-14 * p_ref.norm()) << psi;
      EXPECT_LT((j.dp_dv - p_ref).norm(), 1e-14 * p_ref.norm()) << psi;
      EXPECT_NEAR(j.dp_domega.x() / v, dp_domega_ref.x(), 1e-12 * std::abs(dp_domega_ref.x()))
          << psi;
      EXPECT_NEAR(j.dp_domega.y() / v, dp_domega_ref.y(), 1e-13 * std::abs(dp_domega_ref.y()))
          << psi;
    }
  }
}

TEST(AckermannArc, VehicleDerivativesMatchFiniteDifferences) {
  for (double omega : kOmegas) {
    for (double dt : {0.9, -0.3}) {
      const double v = 1.2;
      ArcJacobian j;
      arcT_Vr_Vt(omega, v, dt, &j);
      Mat3 dR;
      Vec3 dp;
      centralDiff([&](double w) { return arcT_Vr_Vt(w, v, dt); }, omega, 1e-6, &dR, &dp);
      EXPECT_LT((j.dR_domega - dR).norm(), 1e-8) << omega;
      EXPECT_LT((j.dp_domega - dp).norm(), 1e-8) << omega;
      centralDiff([&](double s) { return arcT_Vr_Vt(omega, s, dt); }, v, 1e-6, &dR, &dp);
      EXPECT_LT(dR.norm(), 1e-12);
      EXPECT_LT((j.dp_dv - dp).norm(), 1e-8) << omega;
    }
  }
}

TEST(AckermannArc, CameraDerivativesMatchFiniteDifferences) {
  const Pose3 T_bc = testExtrinsics();
  for (double omega : kOmegas) {
    const double v = 1.2, dt = 0.7;
    ArcJacobian j;
    const Pose3 T = arcT_Cr_Ct(omega, v, dt, T_bc, &j);
    EXPECT_TRUE(T.matrix().isApprox(
        (T_bc.inverse(Eigen::Isometry) * arcT_Vr_Vt(omega, v, dt) * T_bc).matrix(), 1e-14));
    Mat3 dR;
    Vec3 dp;
    centralDiff([&](double w) { return arcT_Cr_Ct(w, v, dt, T_bc); }, omega, 1e-6, &dR, &dp);
    EXPECT_LT((j.dR_domega - dR).norm(), 1e-8) << omega;
    EXPECT_LT((j.dp_domega - dp).norm(), 1e-8) << omega;
    centralDiff([&](double s) { return arcT_Cr_Ct(omega, s, dt, T_bc); }, v, 1e-6, &dR, &dp);
    EXPECT_LT((j.dp_dv - dp).norm(), 1e-8) << omega;
    // Moving forward moves the camera along its optical axis.
    if (omega == 0.0) {
      EXPECT_TRUE(T.translation().isApprox(Vec3(0, 0, v * dt), 1e-12));
    }
  }
}

TEST(AckermannArc, ModelJacobianMatchesFiniteDifferences) {
  const Pose3 T_bc = testExtrinsics();
  const int64_t t_ref = 5 * kNsPerSec;
  AckermannArcModel model(0.4, 1.1, t_ref, T_bc, t_ref - kNsPerSec, t_ref + kNsPerSec);
  EXPECT_EQ(model.numParams(), 2);
  EXPECT_EQ(model.referenceTime(), t_ref);
  EXPECT_TRUE(model.covers(t_ref + kNsPerSec));
  EXPECT_FALSE(model.covers(t_ref + kNsPerSec + 1));
  EXPECT_FALSE(model.covers(t_ref - kNsPerSec - 1));
  EXPECT_TRUE(model.T_Cr_Ct(t_ref).matrix().isApprox(Eigen::Matrix4d::Identity(), 1e-15));

  for (int64_t t : {t_ref + 300000000LL, t_ref - 450000000LL}) {
    PoseJacobian jac;
    model.T_Cr_Ct(t, &jac);
    ASSERT_EQ(jac.param_index.size(), 2u);
    for (size_t k = 0; k < 2; ++k) {
      const int idx = jac.param_index[k];
      const double h = 1e-6;
      AckermannArcModel plus = model, minus = model;
      if (idx == AckermannArcModel::kOmega) {
        plus.setOmega(model.omega() + h);
        minus.setOmega(model.omega() - h);
      } else {
        ASSERT_EQ(idx, AckermannArcModel::kV);
        plus.setV(model.v() + h);
        minus.setV(model.v() - h);
      }
      const Pose3 a = plus.T_Cr_Ct(t), b = minus.T_Cr_Ct(t);
      EXPECT_LT((jac.dR[k] - (a.linear() - b.linear()) / (2 * h)).norm(), 1e-8) << idx;
      EXPECT_LT((jac.dt[k] - (a.translation() - b.translation()) / (2 * h)).norm(), 1e-8) << idx;
    }
  }
  AckermannArcModel unbounded(0.1, 1.0, 0, T_bc);
  EXPECT_TRUE(unbounded.covers(std::numeric_limits<int64_t>::min()));
  EXPECT_TRUE(unbounded.covers(std::numeric_limits<int64_t>::max()));
  EXPECT_THROW(unbounded.setValidInterval(10, 5), std::invalid_argument);
}

TEST(AckermannArc, ChainMatchesPiecewiseIntegration) {
  const Pose3 start = planarPose(1.0, -2.0, 0.3);
  ArcChain chain(start, 0);
  const double cmds[][3] = {{0.5, 1.0, 0.4}, {-0.8, 1.5, 0.7}, {0.0, 0.9, 0.5}, {1e-8, 2.0, 0.3}};
  int64_t t = 0;
  Unicycle s{1.0, -2.0, 0.3};
  for (const auto& c : cmds) {
    const int64_t t_end = t + secToNs(c[2]);
    chain.append(c[0], c[1], t_end);
    // Mid-segment and end-of-segment poses against RK4 from the segment start.
    for (double frac : {0.5, 1.0}) {
      const Unicycle q = integrateUnicycle(s, c[0], c[1], frac * c[2], 4000);
      const Pose3 T = chain.T_odom_base(t + secToNs(frac * c[2]));
      EXPECT_NEAR(T.translation().x(), q.x, 1e-9);
      EXPECT_NEAR(T.translation().y(), q.y, 1e-9);
      EXPECT_NEAR(yawOf(T.linear()), wrapAngle(q.th), 1e-12);
    }
    s = integrateUnicycle(s, c[0], c[1], c[2], 4000);
    t = t_end;
  }
  EXPECT_EQ(chain.numArcs(), 4u);
  EXPECT_EQ(chain.endTime(), t);
  EXPECT_TRUE(chain.T_odom_base(0).isApprox(start, 1e-15));
  EXPECT_THROW(chain.append(0.0, 1.0, t - 1), std::invalid_argument);
  // arcPropagate is the single-arc case.
  const Pose3 T = arcPropagate(start, 7, 0.5, 1.0, 7 + 400000000LL);
  EXPECT_TRUE(T.isApprox(chain.T_odom_base(400000000LL), 1e-14));
}

// A roll rate p turns the body about base_link's x axis after the arc: at omega = v = 0 the
// camera (mounted at p_bc) has rolled by p dt about x through the base origin, so it moved by
// Rx(p dt) p_bc - p_bc; with omega and v the pose is the arc's composed with that roll.
TEST(AckermannArc, RollRateTurnsTheBodyAboutItsForwardAxis) {
  const Pose3 T_bc = testExtrinsics();
  const int64_t t_ref = 5 * kNsPerSec, t = t_ref + 400000000LL;  // dt = 0.4 s
  const double p = 0.05, dt = 0.4;
  AckermannArcModel still(0.0, 0.0, t_ref, T_bc);
  still.setRollRate(p);
  EXPECT_DOUBLE_EQ(still.rollRate(), p);
  const Pose3 T_C = still.T_Cr_Ct(t);
  const Pose3 T_V = T_bc * T_C * T_bc.inverse();  // the body's motion, back in base_link
  const double a = p * dt;
  EXPECT_NEAR(T_V.linear()(1, 1), std::cos(a), 1e-12);
  EXPECT_NEAR(T_V.linear()(2, 1), std::sin(a), 1e-12);
  EXPECT_NEAR(T_V.linear()(0, 0), 1.0, 1e-12);
  EXPECT_LT(T_V.translation().norm(), 1e-12);  // about the base origin: base_link stays put
  const Vec3 cam_moved = T_C.translation();    // the camera's centre, in the reference camera
  const Vec3 expected =
      T_bc.linear().transpose() *
      (Eigen::AngleAxisd(a, Vec3::UnitX()) * T_bc.translation() - T_bc.translation());
  EXPECT_LT((cam_moved - expected).norm(), 1e-12);

  AckermannArcModel moving(0.3, 1.2, t_ref, T_bc);
  const Pose3 flat = moving.T_Cr_Ct(t);
  moving.setRollRate(p);
  const Pose3 rolled = moving.T_Cr_Ct(t);
  const Pose3 expected_V =
      arcT_Vr_Vt(0.3, 1.2, dt) *
      makePose(Eigen::AngleAxisd(a, Vec3::UnitX()).toRotationMatrix(), Vec3::Zero());
  EXPECT_TRUE(rolled.matrix().isApprox(vehicleToCamera(expected_V, T_bc).matrix(), 1e-12));
  EXPECT_FALSE(rolled.matrix().isApprox(flat.matrix(), 1e-6));
  PoseJacobian jac;
  EXPECT_THROW(moving.T_Cr_Ct(t, &jac), std::logic_error);  // no Jacobian with a roll rate
  moving.setRollRate(0.0);
  EXPECT_TRUE(moving.T_Cr_Ct(t, &jac).matrix().isApprox(flat.matrix(), 1e-15));
}
