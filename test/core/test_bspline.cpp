#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <random>
#include <stdexcept>
#include <string>

#include "vwe_vo/trajectory/bspline.h"

using namespace vwe_vo;

namespace {

const int64_t kEpoch = 10 * kNsPerSec;

// A non-uniform clamped cubic on [0, 4] s that moves forward while weaving.
BSpline knownSpline(int degree = 3) {
  std::vector<double> interior = {0.7, 1.5, 1.6, 2.8, 3.3};
  std::vector<double> knots;
  for (int i = 0; i <= degree; ++i) knots.push_back(0.0);
  knots.insert(knots.end(), interior.begin(), interior.end());
  for (int i = 0; i <= degree; ++i) knots.push_back(4.0);
  const int ncp = static_cast<int>(knots.size()) - degree - 1;
  std::vector<Vec2> P;
  for (int i = 0; i < ncp; ++i)
    P.emplace_back(1.1 * i + 0.2 * std::cos(i), 0.8 * std::sin(1.3 * i));
  return BSpline(degree, knots, P, kEpoch);
}

// Cox-de Boor recursion, straight from the definition (independent of Piegl & Tiller A2.2).
double coxDeBoor(const std::vector<double>& U, int i, int p, double u) {
  if (p == 0) return (U[i] <= u && u < U[i + 1]) ? 1.0 : 0.0;
  double a = 0.0, b = 0.0;
  if (U[i + p] > U[i]) a = (u - U[i]) / (U[i + p] - U[i]) * coxDeBoor(U, i, p - 1, u);
  if (U[i + p + 1] > U[i + 1]) {
    b = (U[i + p + 1] - u) / (U[i + p + 1] - U[i + 1]) * coxDeBoor(U, i + 1, p - 1, u);
  }
  return a + b;
}

Pose3 testExtrinsics() {
  return makePose(R_base_opticalFrame(), Vec3(0.1, 0.02, 0.3));
}

bool isFinitePose(const Pose3& T) {
  return T.matrix().allFinite();
}

// Error of one analytic Jacobian column (dR, dt) against central differences of f.
double jacobianColumnError(const PoseJacobian& jac, int param,
                           const std::function<Pose3(double)>& f_of_delta, double h,
                           double* fd_norm) {
  Mat3 dR = Mat3::Zero();
  Vec3 dt = Vec3::Zero();
  int found = 0;
  for (size_t k = 0; k < jac.param_index.size(); ++k) {
    if (jac.param_index[k] == param) {
      dR += jac.dR[k];
      dt += jac.dt[k];
      ++found;
    }
  }
  EXPECT_LE(found, 1) << "parameter " << param << " listed twice";
  const Pose3 a = f_of_delta(h), b = f_of_delta(-h);
  const Mat3 dR_fd = (a.linear() - b.linear()) / (2 * h);
  const Vec3 dt_fd = (a.translation() - b.translation()) / (2 * h);
  *fd_norm = std::sqrt(dR_fd.squaredNorm() + dt_fd.squaredNorm());
  return std::sqrt((dR - dR_fd).squaredNorm() + (dt - dt_fd).squaredNorm());
}

}  // namespace

TEST(BSpline, BasisIsAPartitionOfUnityAndMatchesCoxDeBoor) {
  for (int degree = 1; degree <= 5; ++degree) {
    const BSpline s = knownSpline(degree);
    const int n = s.numControlPoints() - 1;
    for (double u = s.validFrom(); u <= s.validTo(); u += 0.0137) {
      const BasisDerivatives b = s.basis(u, 2);
      ASSERT_EQ(b.values.rows(), 3);
      ASSERT_EQ(b.values.cols(), degree + 1);
      ASSERT_GE(b.first, 0);
      ASSERT_LE(b.first + degree, n);
      EXPECT_NEAR(b.values.row(0).sum(), 1.0, 1e-14) << degree << " " << u;
      EXPECT_NEAR(b.values.row(1).sum(), 0.0, 1e-10) << degree << " " << u;
      EXPECT_NEAR(b.values.row(2).sum(), 0.0, 1e-9) << degree << " " << u;
      EXPECT_GE(b.values.row(0).minCoeff(), -1e-15);
      for (int j = 0; j <= degree; ++j) {
        EXPECT_NEAR(b.values(0, j), coxDeBoor(s.knots(), b.first + j, degree, u), 1e-13);
      }
    }
    // The end of the domain belongs to the last span.
    const BasisDerivatives end = s.basis(s.validTo(), 0);
    EXPECT_EQ(end.first, n - degree);
    EXPECT_NEAR(end.values(0, degree), 1.0, 1e-14);
    EXPECT_TRUE(s.position(s.validTo()).isApprox(s.controlPoints().back(), 1e-14));
    EXPECT_TRUE(s.position(s.validFrom()).isApprox(s.controlPoints().front(), 1e-14));
  }
}

TEST(BSpline, FindSpan) {
  const BSpline s = knownSpline();  // knots 0 0 0 0 .7 1.5 1.6 2.8 3.3 4 4 4 4
  EXPECT_EQ(s.findSpan(0.0), 3);
  EXPECT_EQ(s.findSpan(0.69), 3);
  EXPECT_EQ(s.findSpan(0.7), 4);
  EXPECT_EQ(s.findSpan(1.55), 5);
  EXPECT_EQ(s.findSpan(3.9), 8);
  EXPECT_EQ(s.findSpan(4.0), 8);
  EXPECT_EQ(s.findSpan(7.0), 8);
  EXPECT_EQ(s.findSpan(-1.0), 3);
}

TEST(BSpline, BasisDerivativesMatchFiniteDifferences) {
  const double h = 1e-6;
  for (int degree = 2; degree <= 4; ++degree) {
    const BSpline s = knownSpline(degree);
    for (double u : {0.1, 0.55, 1.2, 1.58, 2.0, 3.0, 3.9}) {
      const BasisDerivatives b = s.basis(u, 2), bp = s.basis(u + h, 2), bm = s.basis(u - h, 2);
      ASSERT_EQ(bp.first, b.first);
      ASSERT_EQ(bm.first, b.first);
      for (int j = 0; j <= degree; ++j) {
        const double d1 = (bp.values(0, j) - bm.values(0, j)) / (2 * h);
        const double d2 = (bp.values(1, j) - bm.values(1, j)) / (2 * h);
        EXPECT_NEAR(b.values(1, j), d1, 1e-7 * std::max(1.0, std::abs(d1))) << degree << " " << u;
        EXPECT_NEAR(b.values(2, j), d2, 1e-6 * std::max(1.0, std::abs(d2))) << degree << " " << u;
      }
    }
  }
}

TEST(BSpline, CurveDerivativesMatchFiniteDifferences) {
  const BSpline s = knownSpline();
  const double h = 1e-6;
  for (double u = 0.05; u < 4.0; u += 0.1) {
    const Vec2 d1 = (s.position(u + h) - s.position(u - h)) / (2 * h);
    const Vec2 d2 = (s.velocity(u + h) - s.velocity(u - h)) / (2 * h);
    EXPECT_LT((s.velocity(u) - d1).norm(), 1e-7 * std::max(1.0, d1.norm())) << u;
    EXPECT_LT((s.acceleration(u) - d2).norm(), 1e-6 * std::max(1.0, d2.norm())) << u;
  }
  EXPECT_EQ(s.derivative(1.0, 4), Vec2::Zero());
}

TEST(BSpline, FitRecoversAKnownSpline) {
  const BSpline truth = knownSpline();
  std::vector<int64_t> t;
  std::vector<Vec2> p;
  for (int k = 0; k <= 400; ++k) {
    t.push_back(kEpoch + k * 10000000LL);  // 4 s at 100 Hz, ends on the domain ends
    p.push_back(truth.position(truth.toSplineTime(t.back())));
  }
  const BSpline fit = fitBSplineWithKnots(t, p, 3, truth.knots(), kEpoch);
  ASSERT_EQ(fit.numControlPoints(), truth.numControlPoints());
  for (int i = 0; i < fit.numControlPoints(); ++i) {
    EXPECT_LT((fit.controlPoints()[i] - truth.controlPoints()[i]).norm(), 1e-9) << i;
  }
}

TEST(BSpline, PieglTillerKnotsAreClampedSortedAndCounted) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> gap(0.001, 0.1);
  std::vector<double> u = {2.0};
  for (int k = 0; k < 57; ++k) u.push_back(u.back() + gap(rng));
  for (int degree : {1, 2, 3, 5}) {
    for (int ncp : {degree + 1, degree + 4, 20, 58}) {
      const std::vector<double> U = pieglTillerKnots(u, degree, ncp);
      ASSERT_EQ(static_cast<int>(U.size()), ncp + degree + 1);
      for (int i = 0; i <= degree; ++i) {
        EXPECT_EQ(U[i], u.front());
        EXPECT_EQ(U[U.size() - 1 - i], u.back());
      }
      for (size_t i = degree + 1; i + degree + 1 < U.size(); ++i) {
        EXPECT_GT(U[i], U[i - 1]) << degree << " " << ncp << " " << i;  // interior strictly
      }
      EXPECT_LT(U[U.size() - degree - 2], u.back());
      // A valid spline can be built on them.
      EXPECT_NO_THROW(BSpline(degree, U, std::vector<Vec2>(ncp, Vec2::Zero()), 0));
    }
  }
  EXPECT_THROW(pieglTillerKnots(u, 3, 59), std::invalid_argument);
}

TEST(BSpline, FitApproximatesAnArcWithEitherKnotPlacement) {
  // A circle of radius 5 m at 2 m/s, sampled irregularly; a cubic fit with 0.5 s knots is
  // accurate to well under a millimetre.
  std::mt19937 rng(3);
  std::uniform_int_distribution<int64_t> jitter(-3000000, 3000000);
  std::vector<int64_t> t;
  std::vector<Vec2> p;
  auto circle = [](double s) { return Vec2(5 * std::sin(0.4 * s), 5 * (1 - std::cos(0.4 * s))); };
  for (int k = 0; k <= 300; ++k) {
    t.push_back(1000 * kNsPerSec + k * 20000000LL + (k > 0 && k < 300 ? jitter(rng) : 0));
    p.push_back(circle(dtSec(t.back(), t.front())));
  }
  for (auto placement : {BSplineFitOptions::KnotPlacement::kPieglTiller,
                         BSplineFitOptions::KnotPlacement::kUniform}) {
    BSplineFitOptions opt;
    opt.knot_placement = placement;
    const BSpline s = fitBSpline(t, p, opt);
    EXPECT_EQ(s.numControlPoints(), 12 + 3);  // 6 s / 0.5 s spans + degree
    EXPECT_EQ(s.epochNs(), t.front());
    EXPECT_TRUE(s.covers(t.front()));
    EXPECT_TRUE(s.covers(t.back()));
    EXPECT_FALSE(s.covers(t.back() + 1000));
    EXPECT_TRUE(s.position(0.0).isApprox(p.front(), 1e-12));  // fixed end points
    EXPECT_LT((s.position(s.validTo()) - p.back()).norm(), 1e-12);
    for (double u = 0.0; u <= 6.0; u += 0.01) {
      EXPECT_LT((s.position(u) - circle(u)).norm(), 1e-4) << u;
      EXPECT_NEAR(wrapAngle(s.heading(u) - 0.4 * u), 0.0, 1e-3) << u;
    }
  }
}

TEST(BSpline, HeadingIsTangentToTheCurve) {
  const BSpline s = knownSpline();
  const double h = 1e-5;
  for (double u = 0.01; u < 4.0; u += 0.05) {
    const Vec2 dir = s.position(u + h) - s.position(u - h);
    EXPECT_NEAR(wrapAngle(s.heading(u) - std::atan2(dir.y(), dir.x())), 0.0, 1e-8) << u;
    const Pose3 T = s.T_odom_base(u);
    EXPECT_NEAR(wrapAngle(yawOf(T.linear()) - s.heading(u)), 0.0, 1e-14);
    EXPECT_TRUE(T.translation().isApprox(Vec3(s.position(u).x(), s.position(u).y(), 0), 1e-14));
    const Pose3 T_odom_cam = s.T_odom_cam(u, testExtrinsics());
    EXPECT_TRUE(T_odom_cam.isApprox(T * testExtrinsics(), 1e-14));
  }
}

TEST(BSpline, StandstillsGiveFinitePosesAndHeldHeadings) {
  // Control points 3..6 coincide: the curve is exactly still on [1.6, 2.0], where only they
  // are active.
  std::vector<double> knots = {0, 0, 0, 0, 0.5, 1.0, 1.6, 2.0, 2.6, 3.0, 3.5, 3.5, 3.5, 3.5};
  std::vector<Vec2> P = {{0, 0},     {0.5, 0.1}, {1.0, 0.3}, {1.5, 0.6}, {1.5, 0.6},
                         {1.5, 0.6}, {1.5, 0.6}, {2.0, 1.2}, {2.4, 1.9}, {2.6, 2.8}};
  BSpline s(3, knots, P, 0);
  for (double u = 1.6; u <= 2.0; u += 0.05) EXPECT_LT(s.velocity(u).norm(), 1e-15) << u;

  auto checkAllFinite = [](const BSpline& sp) {
    for (double u = sp.validFrom() - 0.2; u <= sp.validTo() + 0.2; u += 0.001) {
      PoseJacobian jac;
      const Pose3 T = sp.T_odom_base(u, &jac);
      ASSERT_TRUE(isFinitePose(T)) << u;
      ASSERT_TRUE(std::isfinite(sp.heading(u))) << u;
      for (size_t k = 0; k < jac.param_index.size(); ++k) {
        ASSERT_TRUE(jac.dR[k].allFinite() && jac.dt[k].allFinite()) << u;
      }
    }
    for (double u : {1.6, 1.8, 2.0}) ASSERT_TRUE(isFinitePose(sp.T_odom_base(u))) << u;
  };
  // Without declared standstills: the look-back heading keeps the poses finite and the heading
  // of the approach.
  checkAllFinite(s);
  const double approach = s.heading(1.55);
  EXPECT_NEAR(wrapAngle(s.heading(1.8) - approach), 0.0, 0.05);

  // Declared standstill [1.5, 2.2]: position and heading held at their values at 1.5.
  s.setStandstills({{1.5, 2.2}});
  checkAllFinite(s);
  const Pose3 held = s.T_odom_base(1.5);
  for (double u = 1.5; u <= 2.2; u += 0.01) {
    EXPECT_TRUE(s.T_odom_base(u).isApprox(held, 1e-15)) << u;
  }
  EXPECT_NEAR(wrapAngle(s.heading(1.5) - std::atan2(s.velocity(1.5).y(), s.velocity(1.5).x())), 0,
              1e-14);

  // A standstill at the start takes its heading from the motion that follows.
  std::vector<Vec2> P2 = {{0, 0}, {0, 0}, {0, 0}, {0, 0}, {0, 1},
                          {0, 2}, {0, 3}, {0, 4}, {0, 5}, {0, 6}};
  BSpline start(3, knots, P2, 0);
  checkAllFinite(start);
  EXPECT_NEAR(start.heading(0.0), kPi / 2, 1e-9);
  start.setStandstills({{0.0, 1.0}});
  checkAllFinite(start);
  EXPECT_NEAR(start.heading(0.3), kPi / 2, 1e-9);
  EXPECT_TRUE(start.T_odom_base(0.7).translation().isApprox(Vec3::Zero()));

  // No usable tangent anywhere: the default heading.
  BSpline still(3, knots, std::vector<Vec2>(10, Vec2(3, 4)), 0);
  still.setDefaultHeading(0.25);
  checkAllFinite(still);
  EXPECT_EQ(still.heading(1.0), 0.25);

  EXPECT_THROW(s.setStandstills({{2.0, 1.0}}), std::invalid_argument);
  EXPECT_THROW(s.setStandstills({{1.0, 2.0}, {1.5, 2.5}}), std::invalid_argument);
  EXPECT_THROW(s.setMinSpeed(0.0), std::invalid_argument);
}

TEST(BSpline, PoseJacobiansMatchFiniteDifferences) {
  BSpline base = knownSpline();
  base.setStandstills({{2.9, 3.1}});  // also exercise held poses
  const Pose3 T_bc = testExtrinsics();
  const double h = 1e-6;
  for (double u : {0.0, 0.3, 1.55, 2.2, 3.0, 3.95}) {
    PoseJacobian jac_base, jac_cam;
    base.T_odom_base(u, &jac_base);
    base.T_odom_cam(u, T_bc, &jac_cam);
    for (int k = 0; k < 2 * base.numControlPoints(); ++k) {
      auto perturbed = [&](double delta) {
        BSpline s = base;
        Vec2 P = s.controlPoints()[k / 2];
        P(k % 2) += delta;
        s.setControlPoint(k / 2, P);
        return s;
      };
      double fd_norm = 0.0;
      const double e_base = jacobianColumnError(
          jac_base, k, [&](double d) { return perturbed(d).T_odom_base(u); }, h, &fd_norm);
      EXPECT_LE(e_base, 1e-5 * fd_norm + 1e-9) << "u " << u << " param " << k;
      const double e_cam = jacobianColumnError(
          jac_cam, k, [&](double d) { return perturbed(d).T_odom_cam(u, T_bc); }, h, &fd_norm);
      EXPECT_LE(e_cam, 1e-5 * fd_norm + 1e-9) << "u " << u << " param " << k;
    }
  }
}

/// A body tilt that varies with time: pitch 1.5 deg and roll 1 deg, swinging.
static Mat3 swingingTilt(int64_t t_ns) {
  const double t = nsToSec(t_ns - kEpoch);
  return (Eigen::AngleAxisd(0.026 * std::sin(2.0 * t), Vec3::UnitY()) *
          Eigen::AngleAxisd(0.017 * std::cos(3.0 * t), Vec3::UnitX()))
      .toRotationMatrix();
}

class BSplineCameraModelTilt : public ::testing::TestWithParam<bool> {};

TEST_P(BSplineCameraModelTilt, JacobianMatchesFiniteDifferences) {
  // Planar, and with the body tilted about base_link (setTilt): the camera at
  // T_odom_base(t) tilt(t) T_base_cam.
  const bool tilted = GetParam();
  const Pose3 T_bc = testExtrinsics();
  const BSpline base = knownSpline();
  const int64_t t_ref = kEpoch + 1200000000LL;
  auto spline = std::make_shared<BSpline>(base);
  BSplineCameraModel model(spline, T_bc, t_ref);
  if (tilted) model.setTilt(swingingTilt);
  auto mount = [&](int64_t t) {
    Pose3 T = T_bc;
    if (tilted)
      T.linear() = swingingTilt(t) * T_bc.linear(),
      T.translation() = swingingTilt(t) * T_bc.translation();
    return T;
  };
  EXPECT_EQ(model.numParams(), 2 * base.numControlPoints());
  EXPECT_EQ(model.referenceTime(), t_ref);
  EXPECT_TRUE(model.covers(kEpoch));
  EXPECT_FALSE(model.covers(kEpoch - 1));
  EXPECT_TRUE(model.T_Cr_Ct(t_ref).matrix().isApprox(Eigen::Matrix4d::Identity(), 1e-14));

  const double h = 1e-6;
  for (int64_t t : std::vector<int64_t>{t_ref, t_ref + 150000000LL, t_ref - 900000000LL,
                                        kEpoch + 3800000000LL}) {
    PoseJacobian jac;
    const Pose3 T = model.T_Cr_Ct(t, &jac);
    // The value is the relative camera pose.
    const Pose3 expected =
        base.T_odom_cam(base.toSplineTime(t_ref), mount(t_ref)).inverse(Eigen::Isometry) *
        base.T_odom_cam(base.toSplineTime(t), mount(t));
    EXPECT_TRUE(T.isApprox(expected, 1e-12));
    // The planar path gives the same pose.
    PlanarLocalJacobian lj;
    EXPECT_TRUE(model.T_Cr_CtPlanar(t, &lj).isApprox(expected, 1e-12));
    for (int idx : jac.param_index) {
      EXPECT_GE(idx, 0);
      EXPECT_LT(idx, model.numParams());
    }
    int nonzero_columns = 0;
    for (int k = 0; k < model.numParams(); ++k) {
      auto pose_with = [&](double delta) {
        BSpline s = base;
        Vec2 P = s.controlPoints()[k / 2];
        P(k % 2) += delta;
        s.setControlPoint(k / 2, P);
        *spline = s;  // the model sees the shared spline change
        const Pose3 out = model.T_Cr_Ct(t);
        *spline = base;
        return out;
      };
      double fd_norm = 0.0;
      const double err = jacobianColumnError(jac, k, pose_with, h, &fd_norm);
      EXPECT_LE(err, 1e-5 * fd_norm + 1e-9) << "t " << t << " param " << k;
      if (fd_norm > 1e-6) ++nonzero_columns;
    }
    if (t != t_ref) {
      EXPECT_GT(nonzero_columns, 4);
    }
  }
}

INSTANTIATE_TEST_SUITE_P(PlanarAndTilted, BSplineCameraModelTilt, ::testing::Bool());

TEST(BSpline, OptionsAndInputsAreValidated) {
  auto expectThrowNaming = [](const BSplineFitOptions& o, const std::string& field) {
    try {
      o.validate();
      ADD_FAILURE() << "no throw for " << field;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
    }
  };
  BSplineFitOptions ok;
  EXPECT_NO_THROW(ok.validate());
  BSplineFitOptions o = ok;
  o.degree = 0;
  expectThrowNaming(o, "degree");
  o.degree = kBSplineMaxDegree + 1;
  expectThrowNaming(o, "degree");
  o = ok;
  o.num_control_points = 3;
  expectThrowNaming(o, "num_control_points");
  o = ok;
  o.knot_spacing_s = 0.0;
  expectThrowNaming(o, "knot_spacing_s");
  o = ok;
  o.knot_spacing_s = std::nan("");
  expectThrowNaming(o, "knot_spacing_s");

  // Too few samples: the message carries the counts.
  std::vector<int64_t> t = {0, 100000000, 200000000, 300000000, 400000000};
  std::vector<Vec2> p(5, Vec2::Zero());
  BSplineFitOptions many;
  many.num_control_points = 8;
  try {
    fitBSpline(t, p, many);
    ADD_FAILURE() << "no throw";
  } catch (const std::invalid_argument& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("5 samples"), std::string::npos) << msg;
    EXPECT_NE(msg.find("8 control points"), std::string::npos) << msg;
  }
  EXPECT_THROW(fitBSpline({0, 2, 1}, std::vector<Vec2>(3, Vec2::Zero())), std::invalid_argument);
  EXPECT_THROW(fitBSpline({0, 1}, std::vector<Vec2>(3, Vec2::Zero())), std::invalid_argument);
  // Knot vectors: wrong size, decreasing.
  EXPECT_THROW(BSpline(3, {0, 0, 0, 0, 1, 1, 1}, std::vector<Vec2>(4, Vec2::Zero()), 0),
               std::invalid_argument);
  EXPECT_THROW(BSpline(3, {0, 0, 0, 0, 1, 0.5, 1, 1, 1}, std::vector<Vec2>(5, Vec2::Zero()), 0),
               std::invalid_argument);
  BSpline s = knownSpline();
  EXPECT_THROW(s.setControlPoints({Vec2::Zero()}), std::invalid_argument);
  EXPECT_THROW(s.setControlPoint(s.numControlPoints(), Vec2::Zero()), std::invalid_argument);
}
