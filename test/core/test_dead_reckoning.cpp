// Dead reckoning against closed forms: constant rates give a circle, ramps integrate to the
// trapezoid of the yaw rate, re-anchoring puts a pose on the spline and keeps relative motion.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "vwe_vo/trajectory/dead_reckoning.h"

using namespace vwe_vo;

namespace {

constexpr int64_t kT0 = 50000000000LL;  // 50 s

// The circle of constant yaw rate w and speed v from the identity: yaw w t, position
// (R sin(w t), R (1 - cos(w t))) with R = v / w.
Pose3 circle(double w, double v, double t) {
  const double R = v / w;
  return planarPose(R * std::sin(w * t), R * (1 - std::cos(w * t)), w * t);
}

double yaw(const Pose3& T) {
  return yawOf(T.linear());
}

}  // namespace

TEST(DeadReckoning, ChainAtConstantRatesIsACircle) {
  const double w = 0.7, v = 1.3;
  ArcChain chain(Pose3::Identity(), kT0);
  // Arcs of unequal lengths at the same rates: the pieces must join into one circle.
  int64_t t = kT0;
  for (int64_t d : {10000000LL, 230000000LL, 70000000LL, 1000000000LL, 490000000LL}) {
    t += d;
    chain.append(w, v, t);
  }
  for (int64_t s = kT0; s <= t + secToNs(0.5); s += 37000000) {  // also beyond the end
    const Pose3 expected = circle(w, v, dtSec(s, kT0));
    const Pose3 T = chain.T_odom_base(s);
    EXPECT_LT((T.translation() - expected.translation()).norm(), 1e-12) << dtSec(s, kT0);
    EXPECT_NEAR(wrapAngle(yaw(T) - yaw(expected)), 0.0, 1e-12) << dtSec(s, kT0);
  }
}

TEST(DeadReckoning, IntegrateRampsAtConstantRatesIsACircleAndRampsGiveTheTrapezoid) {
  const double w = -0.4, v = 2.0;
  std::vector<TimedRates> arcs;
  for (int k = 0; k < 5; ++k)
    arcs.push_back({kT0 + k * 100000000LL,
                    kT0 + k * 100000000LL + 50000000LL,
                    kT0 + (k + 1) * 100000000LL,
                    {w, v}});
  const Trajectory3 traj = integrateRamps(arcs, 10000000LL);
  ASSERT_EQ(traj.size(), 51u);
  EXPECT_EQ(traj.front().t_ns, kT0);
  EXPECT_EQ(traj.back().t_ns, kT0 + 500000000LL);
  for (const StampedPose& p : traj) {
    const Pose3 expected = circle(w, v, dtSec(p.t_ns, kT0));
    EXPECT_LT((p.T.translation() - expected.translation()).norm(), 1e-12);
  }
  // Two arcs of 0.2 s, 0.2 and 1.0 rad/s: the yaw rate is 0.2 up to the first middle, ramps to
  // 1.0 at the second middle and stays there. The midpoint rule is exact on each linear piece.
  std::vector<TimedRates> two = {
      {kT0, kT0 + 100000000LL, kT0 + 200000000LL, {0.2, 1.0}},
      {kT0 + 200000000LL, kT0 + 300000000LL, kT0 + 400000000LL, {1.0, 1.0}}};
  const Trajectory3 ramp = integrateRamps(two, 5000000LL);
  const double expected_yaw = 0.2 * 0.1 + 0.5 * (0.2 + 1.0) * 0.2 + 1.0 * 0.1;
  EXPECT_NEAR(yaw(ramp.back().T), expected_yaw, 1e-12);
  EXPECT_TRUE(integrateRamps({}, 10).empty());
  EXPECT_TRUE(integrateRamps(two, 0).empty());
}

TEST(DeadReckoning, RampedChainReachesEachMiddleWithTheTrapezoidStepsKeepEachArcsTurn) {
  // Arcs of 0.3 s at 0.0, 0.6, -0.3 rad/s (middles 0.15, 0.45, 0.75 s), then a standstill.
  const double w[] = {0.0, 0.6, -0.3};
  for (bool interpolate : {true, false}) {
    ArcDeadReckoning dr(kT0, interpolate);
    for (int k = 0; k < 3; ++k) {
      const int64_t t0 = kT0 + k * 300000000LL;
      dr.append({w[k], 0.5}, false, t0, t0 + 150000000LL, t0 + 300000000LL);
    }
    dr.append({0.0, 0.0}, true, kT0 + 900000000LL, kT0 + 1050000000LL, kT0 + 1200000000LL);
    // Steps: the heading at each window border is the sum of the arcs' turns.
    EXPECT_NEAR(yaw(dr.steps().T_odom_base(kT0 + 600000000LL)), 0.6 * 0.3, 1e-12);
    EXPECT_NEAR(yaw(dr.steps().T_odom_base(kT0 + 900000000LL)), 0.3 * (0.6 - 0.3), 1e-12);
    const Pose3 held = dr.steps().T_odom_base(kT0 + 900000000LL);
    EXPECT_TRUE(dr.steps().T_odom_base(kT0 + 1200000000LL).isApprox(held, 1e-14));
    if (!interpolate) {
      EXPECT_TRUE(dr.ramped()
                      .T_odom_base(kT0 + 450000000LL)
                      .isApprox(dr.steps().T_odom_base(kT0 + 450000000LL), 1e-15));
      continue;
    }
    // Ramped: 0 up to 0.15 s, linear to 0.6 at 0.45 s, linear to -0.3 at 0.75 s; the moving
    // arc before a standstill keeps its rates to its end (0.9 s), then the pose is held.
    const double at045 = 0.5 * 0.6 * 0.3;
    const double at075 = at045 + 0.5 * (0.6 - 0.3) * 0.3;
    const double at090 = at075 - 0.3 * 0.15;
    EXPECT_NEAR(yaw(dr.ramped().T_odom_base(kT0 + 450000000LL)), at045, 1e-12);
    EXPECT_NEAR(yaw(dr.ramped().T_odom_base(kT0 + 750000000LL)), at075, 1e-12);
    EXPECT_NEAR(yaw(dr.ramped().T_odom_base(kT0 + 900000000LL)), at090, 1e-12);
    EXPECT_NEAR(yaw(dr.ramped().T_odom_base(kT0 + 1200000000LL)), at090, 1e-12);
    EXPECT_LT((dr.ramped().T_odom_base(kT0 + 1200000000LL).translation() -
               dr.ramped().T_odom_base(kT0 + 900000000LL).translation())
                  .norm(),
              1e-15);
  }
}

TEST(DeadReckoning, ReanchoringPutsThePoseOnTheSplineAndKeepsTheRelativeMotion) {
  const int p = 3, n = 8;
  std::vector<Vec2> P;
  for (int i = 0; i < n; ++i) P.emplace_back(0.5 * i, 0.1 * i * i);
  const BSpline spline(p, BSpline::clampedUniformKnots(p, n, 0.0, 2.0), P, kT0);
  ArcChain chain(planarPose(3.0, -1.0, 0.4), kT0);
  chain.append(0.3, 0.8, kT0 + secToNs(1.0));
  chain.append(-0.2, 1.1, kT0 + secToNs(2.0));
  const double u = 1.4;
  const Pose3 A = anchorOnSplinePose(spline, u, chain.T_odom_base(kT0 + secToNs(u)));
  EXPECT_TRUE((A * chain.T_odom_base(kT0 + secToNs(u))).isApprox(spline.T_odom_base(u), 1e-12));
  for (double a : {0.2, 1.0, 1.9}) {
    const Pose3 Ta = chain.T_odom_base(kT0 + secToNs(a)),
                Tb = chain.T_odom_base(kT0 + secToNs(a + 0.3));
    const Pose3 rel = Ta.inverse() * Tb, rel_anchored = (A * Ta).inverse() * (A * Tb);
    EXPECT_TRUE(rel_anchored.isApprox(rel, 1e-12)) << a;
  }
}

TEST(DeadReckoning, FittedAnchorRecoversARigidMotionOfTheSplinesPath) {
  // The chain is a circle; the spline interpolates the same circle moved by a known rigid motion.
  const double w = 0.5, v = 1.0;
  ArcChain chain(Pose3::Identity(), kT0);
  chain.append(w, v, kT0 + secToNs(3.0));
  const Pose3 M = planarPose(2.0, -3.0, 0.8);
  // Control points on the moved circle at the Greville abscissae of a fine knot vector: the
  // spline approximates the circle to well below a millimetre.
  const int p = 3, n = 151;
  std::vector<Vec2> P;
  const std::vector<double> U = BSpline::clampedUniformKnots(p, n, 0.0, 3.0);
  for (int i = 0; i < n; ++i) {
    // Greville abscissae of the knots.
    const double g = (U[i + 1] + U[i + 2] + U[i + 3]) / 3.0;
    P.push_back((M * circle(w, v, g)).translation().head<2>());
  }
  const BSpline spline(p, U, P, kT0);
  const Pose3 A = fitAnchorOnSpline(spline, chain, kT0 + secToNs(2.5), 1.0);
  EXPECT_NEAR(wrapAngle(yaw(A) - yaw(M)), 0.0, 2e-3);
  EXPECT_LT((A.translation() - M.translation()).norm(), 5e-3);
  // A chain that did not move: the heading is unknown, the pose at t_end is matched.
  ArcChain still(Pose3::Identity(), kT0);
  still.append(0.0, 0.0, kT0 + secToNs(3.0));
  const int64_t t = kT0 + secToNs(2.5);
  EXPECT_TRUE(fitAnchorOnSpline(spline, still, t, 1.0)
                  .isApprox(anchorOnSplinePose(spline, 2.5, still.T_odom_base(t)), 1e-15));
}

TEST(DeadReckoning, AppendBeforeTheEndThrows) {
  ArcChain chain(Pose3::Identity(), kT0);
  chain.append(0.1, 1.0, kT0 + 100);
  EXPECT_THROW(chain.append(0.1, 1.0, kT0 + 50), std::invalid_argument);
  EXPECT_THROW(appendRamp(&chain, {0, 0}, {1, 1}, kT0 + 200, 0), std::invalid_argument);
}
