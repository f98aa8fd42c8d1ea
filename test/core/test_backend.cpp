// The back-end against independent truths: central finite differences of the multi-volume
// gradient, a known spline trajectory recovered from events starting from biased front-end arcs,
// finite poses through a standstill, and option validation.
#include <gtest/gtest.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>
#include <tuple>

#include "../common/prior_gradient_check.h"
#include "../common/synthetic_events.h"
#include "../common/test_camera.h"
#include "vwe_vo/backend/backend.h"
#include "vwe_vo/io/options_yaml.h"
#include "vwe_vo/pipeline/offline_pipeline.h"
#include "vwe_vo/sensor/subsample.h"

using namespace vwe_vo;

namespace {

constexpr int64_t kEpoch = 100000000000LL;     // 100 s
constexpr double kDuration = 3.2;              // [s]
constexpr double kSpeed = 0.4;                 // [m/s]
constexpr int kFdEvents = 40000;               // events per volume of the gradient check
constexpr double kYawRate = 10.0 * kPi / 180;  // [rad/s]

CameraCalibration testCalibration() {
  return test::syntheticCalibration(true);
}

Pose3 testExtrinsics() {
  return makePose(R_base_opticalFrame(), Vec3(0.1, 0.0, 0.3));
}

/// Truth: a gentle curve (yaw rate 10 deg/s varying by +-4 deg/s) at 0.4 m/s, as a spline.
std::shared_ptr<BSpline> truthSpline() {
  std::vector<int64_t> t;
  std::vector<Vec2> p;
  Vec2 c(0, 0);
  double psi = 0.0;
  const double dt = 0.001;
  for (double s = 0; s <= kDuration + 1e-9; s += dt) {
    t.push_back(kEpoch + secToNs(s));
    p.push_back(c);
    const double w = kYawRate + 0.07 * std::sin(2.0 * s);
    c += kSpeed * dt * Vec2(std::cos(psi + 0.5 * w * dt), std::sin(psi + 0.5 * w * dt));
    psi += w * dt;
  }
  BSplineFitOptions o;
  o.knot_spacing_s = 0.3;
  return std::make_shared<BSpline>(fitBSpline(t, p, o));
}

BackendOptions testOptions() {
  BackendOptions o;
  // A half-resolution grid (a smoother objective for the finite-difference checks, and faster)
  // and line searches of up to Ceres' 20 evaluations: the scene and thresholds below are set for
  // them.
  o.volume.grid_scale = 0.5;
  o.max_line_search_steps = 20;
  o.volume.num_planes = 20;
  o.volume.z_min_m = 0.8;
  o.volume.z_max_m = 10;
  o.max_events_per_volume = 3000;
  // Short volumes over a 3.2 s scene (several refinements), and the VWE alone: these arcs are
  // biased on purpose, which the arcs' yaw-rate prior would hold.
  o.tau1_s = 0.2;
  o.tau2_s = 0.4;
  o.window_s = 2.0;
  o.arc_rate_prior_weight = 0.0;
  return o;
}

struct Scene {
  CameraModel cam{testCalibration()};
  std::shared_ptr<BSpline> truth = truthSpline();
  EventVector events;
  /// n events over [t_mid - half_span, t_mid + half_span] (by default the whole truth).
  explicit Scene(int n = 60000, double t_mid_s = 0.5 * kDuration,
                 double half_span_s = 0.5 * kDuration - 1e-3, int num_points = 1500) {
    const BSplineCameraModel model(truth, testExtrinsics(), kEpoch + secToNs(t_mid_s));
    events = synthetic::randomPointEvents(cam, model, n, 7, half_span_s, num_points);
  }
};

/// The pipeline's order: the events up to the arc's end (from index *next on), then the arc.
void feed(Backend* backend, const EventVector& events, size_t* next, const ArcEstimate& arc) {
  EventVector chunk;
  while (*next < events.size() && events[*next].t_ns <= arc.t_end_ns)
    chunk.push_back(events[(*next)++]);
  backend->addEvents(chunk);
  backend->addArc(arc);
  backend->process();
}

/// Front-end-like arcs every 0.1 s from the truth, with a yaw-rate bias [rad/s].
std::vector<ArcEstimate> truthArcs(const BSpline& truth, double bias) {
  std::vector<ArcEstimate> arcs;
  for (double s = 0; s + 0.1 <= kDuration + 1e-9; s += 0.1) {
    ArcEstimate a;
    a.t_start_ns = kEpoch + secToNs(s);
    a.t_end_ns = kEpoch + secToNs(s + 0.1);
    a.t_ref_ns = (a.t_start_ns + a.t_end_ns) / 2;
    a.omega = wrapAngle(truth.heading(s + 0.1) - truth.heading(s)) / 0.1 + bias;
    a.v = (truth.position(s + 0.1) - truth.position(s)).norm() / 0.1;
    arcs.push_back(a);
  }
  return arcs;
}

double headingChangeError(const BSpline& est, const BSpline& truth, double u0, double u1) {
  const double d_est = wrapAngle(est.heading(est.toSplineTime(kEpoch) + u1) -
                                 est.heading(est.toSplineTime(kEpoch) + u0));
  const double d_true = wrapAngle(truth.heading(u1) - truth.heading(u0));
  return std::abs(wrapAngle(d_est - d_true));
}

/// The refined heading's rotation RPE over 1 s pairs [deg] of a back-end fed the scene's events
/// and these arcs (the pipeline's order), with its stats.
double refinedRpeDeg(const Scene& sc, const std::vector<ArcEstimate>& arcs, const BackendOptions& o,
                     BackendStats* stats) {
  Backend backend(o, sc.cam, testExtrinsics());
  size_t e = 0;
  for (const ArcEstimate& a : arcs) feed(&backend, sc.events, &e, a);
  backend.finish();
  *stats = backend.stats();
  double sum = 0;
  int pairs = 0;
  for (double u = 0.0; u + 1.0 <= kDuration + 1e-9; u += 0.1, ++pairs)
    sum += std::pow(headingChangeError(backend.spline(), *sc.truth, u, u + 1), 2);
  return std::sqrt(sum / pairs) * 180 / kPi;
}

/// The multi-volume objective by brute force in double precision, independent of the voting
/// kernel: rays from the spline, bilinear votes into a dense double grid with the volume's
/// geometry, the contrast per volume (VolumeOptions::contrast; the density per vote without
/// each vote's own squared weights), summed. The kernel votes in
/// float, whose rounding is larger than the change a step of 1e-7 m makes: central differences
/// are taken of this reference.
/// slice_ns > 0: every event takes the pose at the middle of its slice of that length on the
/// grid of absolute times (VolumeOptions::pose_slice_s), unless the spline ends before it.
double referenceObjective(const CameraModel& cam, const ProjectiveVolume& volume,
                          const BSpline& spline, const std::vector<BackendVolume>& volumes,
                          int64_t slice_ns) {
  const int W = volume.width(), H = volume.height(), L = volume.numPlanes();
  std::vector<double> grid(size_t(W) * H * L);
  double total = 0.0;
  for (const BackendVolume& bv : volumes) {
    std::fill(grid.begin(), grid.end(), 0.0);
    double self = 0.0;  // the votes' own squared weights
    const BSplineCameraModel model(std::make_shared<BSpline>(spline), testExtrinsics(),
                                   bv.t_ref_ns);
    for (const PixelEvent& e : bv.events) {
      if (!model.covers(e.t_ns)) continue;
      int64_t t = e.t_ns;
      if (slice_ns > 0) {
        const int64_t middle = (e.t_ns / slice_ns) * slice_ns + slice_ns / 2;  // times are positive
        if (model.covers(middle)) t = middle;
      }
      const Pose3 T = model.T_Cr_Ct(t);
      const Vec3 o = T.translation(), d = T.linear() * cam.bearing(e.x, e.y).cast<double>();
      if (!(d.z() > 1e-9)) continue;
      for (int l = 0; l < L; ++l) {
        // The point of the ray on the plane z = 1/rho, projected into the volume's pinhole.
        const double z = 1.0 / volume.planeInverseDepth(l), lambda = (z - o.z()) / d.z();
        if (!(lambda > 0)) continue;
        const Vec3 X = o + lambda * d;
        const double u = volume.fx() * X.x() / z + volume.cx(),
                     v = volume.fy() * X.y() / z + volume.cy();
        if (!(u >= 0 && v >= 0 && u < W - 1 && v < H - 1)) continue;
        const int ix = int(u), iy = int(v);
        const double ax = u - ix, ay = v - iy;
        double* c = &grid[(size_t(l) * H + iy) * W + ix];
        c[0] += (1 - ax) * (1 - ay);
        c[1] += ax * (1 - ay);
        c[W] += (1 - ax) * ay;
        c[W + 1] += ax * ay;
        for (double w : {(1 - ax) * (1 - ay), ax * (1 - ay), (1 - ax) * ay, ax * ay}) self += w * w;
      }
    }
    double sum = 0.0, sq = 0.0;
    for (double g : grid) sum += g, sq += g * g;
    const double n = double(grid.size());
    total += volume.options().contrast == Contrast::kVariance ? sq / n - (sum / n) * (sum / n)
                                                              : (sq - self) / sum;
  }
  return total;
}

}  // namespace

/// (contrast, pose slice [s]): the gradient of the exact per-event objective and of the sliced one.
class BackendContrast : public ::testing::TestWithParam<std::tuple<Contrast, double>> {};

TEST_P(BackendContrast, MultiVolumeGradientMatchesCentralFiniteDifferences) {
  Scene sc(kFdEvents, 1.6, 0.45, 4000);
  // A wide margin keeps every vote inside the grid: a vote leaving the grid vanishes
  // discontinuously, which the analytic gradient cannot see (10-40 % per component with the
  // default 8 px margin on this scene).
  VolumeOptions vo = testOptions().volume;
  vo.margin_px = 100;
  vo.num_threads = 2;
  vo.contrast = std::get<0>(GetParam());
  vo.pose_slice_s = std::get<1>(GetParam());
  const int64_t slice_ns = secToNs(vo.pose_slice_s);
  VweObjectivePool vwe(sc.cam, vo);
  const ProjectiveVolume& volume = vwe.volume();
  // A perturbed copy of the truth, three volumes around the middle.
  auto spline = std::make_shared<BSpline>(*sc.truth);
  for (int i = 0; i < spline->numControlPoints(); ++i)
    spline->setControlPoint(
        i, spline->controlPoints()[i] + 0.02 * Vec2(std::sin(3.0 * i), std::cos(5.0 * i)));
  std::vector<BackendVolume> volumes;
  EventBuffer buffer;
  buffer.push(sc.events);
  for (double u : {1.3, 1.6, 1.9}) {
    const int64_t t = kEpoch + secToNs(u);
    volumes.push_back(
        {t, subsampleEvents(buffer.window(t - secToNs(0.2), t + secToNs(0.2)), kFdEvents, 1)});
  }
  const int first_free = 5;
  MultiVolumeObjective obj(spline, testExtrinsics(), first_free, volumes, &vwe);
  const Eigen::VectorXd x0 = obj.freeParams();
  Eigen::VectorXd g;
  const double f0 = obj.evaluate(x0, &g);
  ASSERT_GT(f0, 0);
  ASSERT_EQ(g.size(), x0.size());
  // One volume per thread: the same sums, in the same order, on one thread.
  {
    VolumeOptions one = vo;
    one.num_threads = 1;
    VweObjectivePool serial(sc.cam, one);
    MultiVolumeObjective obj1(spline, testExtrinsics(), first_free, volumes, &serial);
    Eigen::VectorXd g1;
    EXPECT_EQ(obj1.evaluate(x0, &g1), f0);
    EXPECT_EQ(g1, g);
  }
  // The kernel's value is the reference's up to float rounding.
  obj.evaluate(x0, nullptr);
  const double f0_ref = referenceObjective(sc.cam, volume, *spline, volumes, slice_ns);
  EXPECT_NEAR(f0, f0_ref, 1e-5 * f0_ref);
  // Central differences of the reference (the bilinear kernel is piecewise smooth: a step this
  // small crosses few voxel borders).
  const double h = 1e-7;  // [m]
  Eigen::VectorXd fd(x0.size());
  for (int k = 0; k < x0.size(); ++k) {
    Eigen::VectorXd xp = x0, xm = x0;
    xp[k] += h;
    xm[k] -= h;
    obj.evaluate(xp, nullptr);
    const double fp = referenceObjective(sc.cam, volume, *spline, volumes, slice_ns);
    obj.evaluate(xm, nullptr);
    const double fm = referenceObjective(sc.cam, volume, *spline, volumes, slice_ns);
    fd[k] = (fp - fm) / (2 * h);
  }
  double max_rel = 0.0;
  for (int k = 0; k < x0.size(); ++k) {
    const double rel = std::abs(g[k] - fd[k]) / fd.norm();
    max_rel = std::max(max_rel, rel);
    EXPECT_LT(rel, 1e-3) << "param " << k << " analytic " << g[k] << " fd " << fd[k];
  }
  const double rel_norm = (g - fd).norm() / fd.norm();
  EXPECT_LT(rel_norm, 1e-3);
  std::printf(
      "[backend] FD check: %d free params, |g - fd| / |fd| = %.2e, max per component %.2e of "
      "|fd|\n",
      int(x0.size()), rel_norm, max_rel);
  // The fixed control points are not touched.
  obj.evaluate(x0, nullptr);
  for (int i = 0; i < first_free; ++i)
    EXPECT_EQ(spline->controlPoints()[i],
              sc.truth->controlPoints()[i] + 0.02 * Vec2(std::sin(3.0 * i), std::cos(5.0 * i)));
}

INSTANTIATE_TEST_SUITE_P(Backend, BackendContrast,
                         ::testing::Combine(::testing::Values(Contrast::kDensityPerVote,
                                                              Contrast::kVariance),
                                            ::testing::Values(0.0, 0.0005)),
                         [](const ::testing::TestParamInfo<std::tuple<Contrast, double>>& info) {
                           return std::string(std::get<0>(info.param) == Contrast::kVariance
                                                  ? "Variance"
                                                  : "DensityPerVote") +
                                  (std::get<1>(info.param) > 0 ? "Sliced" : "PerEvent");
                         });

/// The spline model seen only through its full PoseJacobian (the objective's generic path).
class FullJacobianView : public TrajectoryModel {
 public:
  explicit FullJacobianView(const TrajectoryModel& m) : m_(m) {}
  int numParams() const override { return m_.numParams(); }
  int64_t referenceTime() const override { return m_.referenceTime(); }
  bool covers(int64_t t_ns) const override { return m_.covers(t_ns); }
  Pose3 T_Cr_Ct(int64_t t_ns, PoseJacobian* jac) const override { return m_.T_Cr_Ct(t_ns, jac); }

 private:
  const TrajectoryModel& m_;
};

TEST(Backend, PlanarJacobianGivesTheGradientOfTheFullPoseJacobian) {
  // The objective's factored gradient (dVar/d(psi, x, y) per ray, chained by the spline) against
  // the one through every control point's dR, dt per event; also where poses are held (a
  // standstill holding the reference, one the events run into) and with an unwrapped heading.
  Scene sc(8000);
  VolumeOptions vo = testOptions().volume;
  vo.num_threads = 1;
  VweObjectivePool vwe(sc.cam, vo);
  auto spline = std::make_shared<BSpline>(*sc.truth);
  for (int i = 0; i < spline->numControlPoints(); ++i)
    spline->setControlPoint(
        i, spline->controlPoints()[i] + 0.01 * Vec2(std::sin(2.0 * i), std::cos(3.0 * i)));
  for (const std::vector<BSpline::Interval>& still :
       {std::vector<BSpline::Interval>{}, std::vector<BSpline::Interval>{{1.0, 1.4}, {2.0, 2.3}}}) {
    spline->setStandstills(still);
    for (double u_ref : {0.9, 1.2, 2.5, -1.2}) {
      // (negative: at |u_ref| with the body tilted, pitch and roll swinging by ~1 deg)
      BSplineCameraModel model(spline, testExtrinsics(), kEpoch + secToNs(std::abs(u_ref)));
      if (u_ref < 0)
        model.setTilt([](int64_t t) {
          const double s = nsToSec(t - kEpoch);
          return (Eigen::AngleAxisd(0.02 * std::sin(2.0 * s), Vec3::UnitY()) *
                  Eigen::AngleAxisd(0.015 * std::cos(3.0 * s), Vec3::UnitX()))
              .toRotationMatrix();
        });
      ASSERT_TRUE(model.hasPlanarJacobian());
      Eigen::VectorXd g_planar, g_full;
      double f_planar = 0, f_full = 0;
      vwe.run(1, [&](int, VweObjective& obj) {
        f_planar = obj.evaluate(sc.events, model, &g_planar).contrast;
        f_full = obj.evaluate(sc.events, FullJacobianView(model), &g_full).contrast;
      });
      ASSERT_GT(f_planar, 0.0);
      EXPECT_EQ(f_planar, f_full);
      ASSERT_EQ(g_planar.size(), g_full.size());
      ASSERT_GT(g_full.norm(), 0.0);
      EXPECT_LT((g_planar - g_full).norm(), 1e-9 * g_full.norm())
          << "u_ref " << u_ref << ", " << still.size() << " standstills";
    }
  }
  // A model without a planar Jacobian says so when asked for one.
  const BSplineCameraModel model(spline, testExtrinsics(), kEpoch + secToNs(1.6));
  const FullJacobianView view(model);
  EXPECT_FALSE(view.hasPlanarJacobian());
  PlanarLocalJacobian lj;
  EXPECT_THROW(view.T_Cr_CtPlanar(kEpoch, &lj), std::logic_error);
  Eigen::VectorXd g = Eigen::VectorXd::Zero(model.numParams());
  EXPECT_THROW(model.addPlanarGradient({kEpoch}, {}, &g), std::invalid_argument);
}

TEST(Backend, SpeedPriorGradientMatchesCentralFiniteDifferences) {
  auto spline = std::make_shared<BSpline>(*truthSpline());
  const int first_free = 4;
  std::vector<double> u;
  for (double x = 0.0; x <= kDuration; x += 0.05) u.push_back(x);
  const SpeedPrior prior(spline, first_free, u, 3.0);
  EXPECT_GT(prior.numSamples(), 40u);
  Eigen::VectorXd g;
  EXPECT_NEAR(prior.evaluate(&g), 0.0, 1e-20);  // targets are the current speeds
  // Move the free control points away from the targets, then compare.
  test::expectPriorGradientMatchesCentralDifferences(spline.get(), first_free, prior, 0.03, 1e-6);
}

TEST(Backend, SpeedPriorScaleTermLeavesTheSpeedShapeFreeAndItsGradientMatches) {
  auto spline = std::make_shared<BSpline>(*truthSpline());
  const int first_free = 4;
  std::vector<double> u_scale;
  for (double x = 0.0; x <= kDuration; x += 0.05) u_scale.push_back(x);
  const SpeedPrior prior(spline, first_free, {}, 3.0, 0.05, u_scale);
  EXPECT_EQ(prior.numSamples(), 0u);
  EXPECT_GT(prior.numScaleSamples(), 40u);
  EXPECT_NEAR(prior.evaluate(nullptr), 0.0, 1e-20);
  // The mean speed alone: a path 10 % longer costs weight * 0.1^2.
  const std::vector<Vec2> P0 = spline->controlPoints();
  const SpeedPrior all_free(spline, 0, {}, 3.0, 0.05, u_scale);
  for (int i = 0; i < spline->numControlPoints(); ++i)
    spline->setControlPoint(i, 1.1 * P0[size_t(i)]);
  EXPECT_NEAR(all_free.evaluate(nullptr), 3.0 * 0.1 * 0.1, 1e-9);
  for (int i = 0; i < spline->numControlPoints(); ++i) spline->setControlPoint(i, P0[size_t(i)]);
  test::expectPriorGradientMatchesCentralDifferences(spline.get(), first_free, prior, 0.03, 1e-6);
}

TEST(Backend, ArcRatePriorIsZeroOnItsOwnArcsAndItsGradientMatchesFiniteDifferences) {
  auto spline = std::make_shared<BSpline>(*truthSpline());
  const int first_free = 4;
  // Arcs of 0.3 s and 0.15 s measuring the spline's own mean yaw rates, then the same with a
  // known error of +2 deg/s on one of them.
  // The first two arcs end in the first knot span (0.3 s), on fixed control points only.
  std::vector<ArcRatePrior::Arc> arcs = {{0.0, 0.1, 0.0}};
  for (double u = 0.1; u + 0.3 <= kDuration; u += 0.3) {
    const double d = arcs.size() % 3 == 1 ? 0.15 : 0.3;
    arcs.push_back({u, u + d, wrapAngle(spline->heading(u + d) - spline->heading(u)) / d});
  }
  const ArcRatePrior exact(spline, first_free, arcs, 1e-2);
  EXPECT_GT(exact.numArcs(), 5u);
  EXPECT_EQ(exact.numArcs(), arcs.size() - 2);
  arcs.erase(arcs.begin(), arcs.begin() + 2);
  Eigen::VectorXd g;
  EXPECT_NEAR(exact.evaluate(&g), 0.0, 1e-20);
  std::vector<ArcRatePrior::Arc> biased = arcs;
  biased.back().omega += 2.0 * kPi / 180.0;
  const ArcRatePrior prior(spline, first_free, biased, 1e-2);
  EXPECT_NEAR(prior.evaluate(nullptr), 1e-2 / double(prior.numArcs()) * 2.0 * 2.0, 1e-9);
  // Moved control points: analytic gradient against central differences.
  test::expectPriorGradientMatchesCentralDifferences(spline.get(), first_free, prior, 0.01, 1e-5);
}

TEST(Backend, RobustArcRatePriorBoundsAnOutlyingArcAndItsGradientMatchesFiniteDifferences) {
  auto spline = std::make_shared<BSpline>(*truthSpline());
  const int first_free = 4;
  std::vector<ArcRatePrior::Arc> arcs;
  for (double u = 0.4; u + 0.3 <= kDuration; u += 0.3)
    arcs.push_back({u, u + 0.3, wrapAngle(spline->heading(u + 0.3) - spline->heading(u)) / 0.3});
  // One arc off by 20 deg/s (a scan that found the wrong maximum): the quadratic prior grows
  // with its square, the Cauchy one (scale 2 deg/s) with its logarithm.
  arcs[3].omega += 20.0 * kPi / 180.0;
  const double w = 1e-2, s = 2.0;
  const ArcRatePrior quadratic(spline, first_free, arcs, w);
  const ArcRatePrior cauchy(spline, first_free, arcs, w, s);
  ASSERT_EQ(cauchy.numArcs(), arcs.size());
  const double per_arc = w / double(arcs.size());
  EXPECT_NEAR(quadratic.evaluate(nullptr), per_arc * 20.0 * 20.0, 1e-9);
  EXPECT_NEAR(cauchy.evaluate(nullptr), per_arc * s * s * std::log(1.0 + 20.0 * 20.0 / (s * s)),
              1e-9);
  test::expectPriorGradientMatchesCentralDifferences(spline.get(), first_free, cauchy, 0.01, 1e-5);
}

TEST(Backend, DeformationPriorGradientMatchesCentralFiniteDifferencesAndSparesQuadraticMoves) {
  // No volumes: the cost is the deformation prior alone (normaliser 1).
  auto spline = std::make_shared<BSpline>(*truthSpline());
  const int first_free = 4;
  MultiVolumeObjective objective(spline, testExtrinsics(), first_free, {}, nullptr);
  const Eigen::VectorXd p0 = objective.freeParams();
  const double w = 0.7;
  MultiVolumeCost cost(&objective, p0, 0.02, 1.0, {}, w);
  const int n = cost.NumParameters();
  Eigen::VectorXd x(n), g(n);
  for (int k = 0; k < n; ++k) x[k] = std::sin(1.7 * k) + 0.3 * std::cos(0.4 * k * k);
  double f = 0.0;
  ASSERT_TRUE(cost.Evaluate(x.data(), &f, g.data()));
  ASSERT_GT(f, 0.0);
  const double h = 1e-6;
  for (int k = 0; k < n; ++k) {
    Eigen::VectorXd xp = x, xm = x;
    xp[k] += h;
    xm[k] -= h;
    double fp = 0.0, fm = 0.0;
    ASSERT_TRUE(cost.Evaluate(xp.data(), &fp, nullptr));
    ASSERT_TRUE(cost.Evaluate(xm.data(), &fm, nullptr));
    EXPECT_NEAR(g[k], (fp - fm) / (2 * h), 1e-6 * g.norm()) << "param " << k;
  }
  // Moves quadratic in the control-point index that start at the fixed points cost only the
  // third difference across the boundary: far less than wiggles of the same size.
  Eigen::VectorXd quad(n), wiggle(n);
  for (int k = 0; k < n / 2; ++k) {
    const double q = 0.01 * (k + 1) * (k + 1);
    quad.segment<2>(2 * k) = Vec2(q, -q);
    wiggle.segment<2>(2 * k) = (k % 2 ? 1.0 : -1.0) * Vec2(q, -q);
  }
  double f_quad = 0.0, f_wiggle = 0.0;
  ASSERT_TRUE(cost.Evaluate(quad.data(), &f_quad, nullptr));
  ASSERT_TRUE(cost.Evaluate(wiggle.data(), &f_wiggle, nullptr));
  EXPECT_LT(f_quad, 1e-3 * f_wiggle);
}

TEST(Backend, RefinementReducesTheRotationErrorOfBiasedArcs) {
  Scene sc;
  const double bias = 3.0 * kPi / 180;
  const std::vector<ArcEstimate> arcs = truthArcs(*sc.truth, bias);
  // Front-end dead reckoning with the biased arcs (the initial guess).
  ArcChain chain(Pose3::Identity(), arcs.front().t_start_ns);
  for (const ArcEstimate& a : arcs) chain.append(a.omega, a.v, a.t_end_ns);
  const double fe_err =
      std::abs(wrapAngle(yawOf(chain.T_odom_base(kEpoch + secToNs(kDuration)).rotation()) -
                         wrapAngle(sc.truth->heading(kDuration) - sc.truth->heading(0.0))));

  Backend backend(testOptions(), sc.cam, testExtrinsics());
  // Feed in 0.1 s chunks: events then the arc of that window (as the pipeline does).
  size_t e = 0;
  const auto t0 = std::chrono::steady_clock::now();
  for (const ArcEstimate& a : arcs) feed(&backend, sc.events, &e, a);
  backend.finish();
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  ASSERT_TRUE(backend.hasSpline());
  const BSpline& est = backend.spline();
  const double be_err = headingChangeError(est, *sc.truth, 0.0, kDuration);
  // Rotation error over 1 s pairs (a rotation RPE of the heading).
  double fe_rpe = 0, be_rpe = 0;
  int pairs = 0;
  for (double u = 0.0; u + 1.0 <= kDuration + 1e-9; u += 0.1, ++pairs) {
    const double d_fe = yawOf(chain.T_odom_base(kEpoch + secToNs(u + 1)).rotation()) -
                        yawOf(chain.T_odom_base(kEpoch + secToNs(u)).rotation());
    const double d_true = sc.truth->heading(u + 1) - sc.truth->heading(u);
    fe_rpe += std::pow(wrapAngle(d_fe - d_true), 2);
    be_rpe += std::pow(headingChangeError(est, *sc.truth, u, u + 1), 2);
  }
  fe_rpe = std::sqrt(fe_rpe / pairs) * 180 / kPi;
  be_rpe = std::sqrt(be_rpe / pairs) * 180 / kPi;
  const BackendStats& st = backend.stats();
  std::printf(
      "[backend] heading error at the end: front-end %.2f deg, back-end %.2f deg (factor %.2f); "
      "rotation RPE(1 s) %.2f -> %.2f deg; %zu updates, %zu volumes, %zu skipped, %zu evaluations, "
      "solver %.2f s, wall %.2f s, last gain %.4f, rejected %zu\n",
      fe_err * 180 / kPi, be_err * 180 / kPi, fe_err / std::max(be_err, 1e-9), fe_rpe, be_rpe,
      st.updates, st.volumes, st.volumes_skipped, st.evaluations, st.solver_s, wall, st.last_gain,
      st.rejected);
  EXPECT_GE(st.updates, 3u);
  // Bounded memory: only the events of the last window (+ one volume span) are kept.
  EXPECT_LT(backend.bufferedEvents(), sc.events.size() * 0.8);
  EXPECT_GT(st.last_gain, 1.0);
  EXPECT_LT(be_err, 0.7 * fe_err);
  EXPECT_LT(be_rpe, 0.7 * fe_rpe);
  const Trajectory3 traj = backend.sampleTrajectory(20.0);
  ASSERT_GE(traj.size(), size_t(60));
  for (const StampedPose& p : traj) ASSERT_TRUE(p.T.matrix().allFinite());
}

// The yaw-rate scan: arcs biased by more than the gradient steps correct (the depth / yaw-rate
// trade of lateral structure holds the solver near its start) are turned to the rate of least
// cost first; the refined heading is then nearer the truth than without the scan.
TEST(Backend, YawRateScanStartsTheSolverNearerTheTruthThanBiasedArcs) {
  Scene sc;
  const std::vector<ArcEstimate> arcs = truthArcs(*sc.truth, 6.0 * kPi / 180);
  BackendOptions off = testOptions();
  off.yaw_scan_half_range_rad_s = 0.0;
  BackendOptions on = testOptions();
  on.yaw_scan_half_range_rad_s = 0.15;
  on.yaw_scan_step_rad_s = 0.025;
  BackendStats st_off, st_on;
  const double rpe_off = refinedRpeDeg(sc, arcs, off, &st_off);
  const double rpe_on = refinedRpeDeg(sc, arcs, on, &st_on);
  std::printf(
      "[backend] 6 deg/s biased arcs: rotation RPE(1 s) %.2f deg without the scan, %.2f with "
      "(%zu of %zu scans moved, mean |offset| %.2f deg/s)\n",
      rpe_off, rpe_on, st_on.yaw_scans_moved, st_on.yaw_scans,
      st_on.yaw_scan_abs_sum_rad_s / std::max<size_t>(1, st_on.yaw_scans) * 180 / kPi);
  EXPECT_EQ(st_off.yaw_scans, 0u);
  EXPECT_EQ(st_on.yaw_scans, st_on.updates);
  EXPECT_GE(st_on.yaw_scans_moved, 1u);
  EXPECT_LT(rpe_on, 0.8 * rpe_off);
}

// Outlying arcs: two consecutive windows whose scans found a wrong maximum (+15 deg/s, as a
// flat scan on a straight road before a corner does) start the solver in the wrong basin, where
// the gradient steps alone stay. Tried at the rates of their neighbours, the volumes' cost prefers
// the truth; the arcs' prior (Cauchy, so the outliers' pull is bounded) does not hold them.
TEST(Backend, OutlyingArcsAreReplacedByTheirNeighboursRatesWhereTheVolumesPreferIt) {
  Scene sc;
  const std::vector<ArcEstimate> true_arcs = truthArcs(*sc.truth, 0.0);
  std::vector<ArcEstimate> arcs = true_arcs;
  for (size_t i : {size_t(14), size_t(15)}) arcs[i].omega += 15.0 * kPi / 180;
  BackendOptions off = testOptions();
  off.arc_rate_prior_weight = 1e-3;
  off.arc_rate_prior_scale_deg_s = 2.0;
  BackendOptions on = off;
  on.outlier_arc_min_rad_s = 0.05;
  BackendStats st_off, st_on, st_true;
  const double rpe_off = refinedRpeDeg(sc, arcs, off, &st_off);
  const double rpe_on = refinedRpeDeg(sc, arcs, on, &st_on);
  const double rpe_true = refinedRpeDeg(sc, true_arcs, on, &st_true);
  std::printf(
      "[backend] two arcs off by 15 deg/s: rotation RPE(1 s) %.2f deg without the outlier scan, "
      "%.2f with (%zu runs tried, %zu refinements started from a replaced run); true arcs %.2f\n",
      rpe_off, rpe_on, st_on.outlier_runs_tried, st_on.outlier_runs_replaced, rpe_true);
  EXPECT_EQ(st_off.outlier_runs_tried, 0u);
  EXPECT_GE(st_on.outlier_runs_replaced, 1u);
  EXPECT_EQ(st_true.outlier_runs_replaced, 0u);  // nothing stands out of the true arcs
  EXPECT_LT(rpe_on - rpe_true, 0.5 * (rpe_off - rpe_true));
}

// The odometry stream (/vwe/odom, tf odom -> base_link) of a back-end that refines biased arcs as
// they come: Backend::poseAt re-anchors on every refinement (a jump), ContinuousOdometry does not
// (REP-105), and its increments are the back-end's current estimate of the motion.
TEST(Backend, ContinuousOdometryHasNoJumpsAtRefinements) {
  Scene sc;
  const std::vector<ArcEstimate> arcs = truthArcs(*sc.truth, 3.0 * kPi / 180);
  // Without the yaw-rate scan the refinements correct the biased arcs in the largest jumps of
  // the re-anchored poses, which is what the continuous stream must hide.
  BackendOptions options = testOptions();
  options.yaw_scan_half_range_rad_s = 0.0;
  Backend backend(options, sc.cam, testExtrinsics());
  ContinuousOdometry odometry;
  const int64_t step = secToNs(0.02);
  int64_t next = arcs.front().t_start_ns;
  size_t e = 0, outputs = 0;
  double max_raw_step = 0, max_continuous_step = 0, max_increment_error = 0;
  Pose3 raw_prev = Pose3::Identity(), out_prev = Pose3::Identity(), out_first = Pose3::Identity();
  const auto truthAt = [&](int64_t t_ns) {
    return sc.truth->T_odom_base(sc.truth->toSplineTime(t_ns));
  };
  const int64_t t_first = next;
  int64_t t_last = next;
  for (const ArcEstimate& a : arcs) {
    feed(&backend, sc.events, &e, a);
    for (; next <= a.t_end_ns; next += step) {
      Pose3 raw, out;
      ASSERT_TRUE(backend.poseAt(next, &raw, nullptr, nullptr));
      ASSERT_TRUE(odometry.next(backend, next, &out, nullptr, nullptr));
      ASSERT_TRUE(out.matrix().allFinite());
      if (outputs > 0) {
        max_raw_step = std::max(max_raw_step, (raw.translation() - raw_prev.translation()).norm());
        max_continuous_step =
            std::max(max_continuous_step, (out.translation() - out_prev.translation()).norm());
        // Each increment is the true motion over the step, up to the estimation error.
        const Pose3 d_truth = truthAt(next - step).inverse() * truthAt(next),
                    d_out = out_prev.inverse() * out;
        max_increment_error =
            std::max(max_increment_error, (d_truth.translation() - d_out.translation()).norm());
      } else {
        out_first = out;
      }
      t_last = next;
      raw_prev = raw;
      out_prev = out;
      ++outputs;
    }
  }
  // Composed, the increments turn as the truth does between the same times.
  const double turn_error_deg =
      kDegPerRad *
      std::abs(wrapAngle(yawOf((out_first.inverse() * out_prev).linear()) -
                         yawOf((truthAt(t_first).inverse() * truthAt(t_last)).linear())));
  std::printf(
      "[backend] odometry: %zu poses, largest step %.4f m raw, %.4f m continuous (%.4f m at %.1f "
      "m/s); "
      "increments off the truth by %.5f m at most, composed turn off by %.3f deg\n",
      outputs, max_raw_step, max_continuous_step, kSpeed * 0.02, kSpeed, max_increment_error,
      turn_error_deg);
  EXPECT_GE(backend.stats().updates, 3u);
  EXPECT_GT(outputs, 100u);
  // 0.4 m/s x 20 ms = 8 mm a step: the continuous stream never moves more than that (+5 %) ...
  EXPECT_LT(max_continuous_step, 1.05 * kSpeed * 0.02);
  // ... while the re-anchored poses jump at refinements (what the test guards against).
  EXPECT_GT(max_raw_step, 1.25 * kSpeed * 0.02);  // measured 1.6x
  EXPECT_LT(max_increment_error, 1.8e-4);         // measured 1.2e-4 m (a step is 8 mm)
  EXPECT_LT(turn_error_deg, 10.5);                // measured 8.0 deg over 3.2 s
}

/// The k-th 0.3 s front-end window from kEpoch as an arc at 0.4 m/s.
static ArcEstimate windowArc(int k, double omega, ArcStatus status = ArcStatus::kOk) {
  ArcEstimate a;
  a.t_start_ns = kEpoch + secToNs(0.3 * k);
  a.t_end_ns = kEpoch + secToNs(0.3 * (k + 1));
  a.t_ref_ns = (a.t_start_ns + a.t_end_ns) / 2;
  a.omega = omega;
  a.v = 0.4;
  a.status = status;
  return a;
}

TEST(Backend, InitialGuessAndOdometryFollowTheArcsRateRuleUpToTheirFinalPoses) {
  // Arcs of 0.3 s whose yaw rates step 0 -> 0.6 -> 0.6 -> 0 -> -0.3 rad/s: between the middles
  // of two arcs the rates ramp, as integrateArcs() (the front-end's trajectory) does; steps at
  // the window borders give the same heading at the middles but not in between.
  const CameraModel cam(testCalibration());
  BackendOptions o = testOptions();
  std::vector<ArcEstimate> arcs;
  const double omegas[] = {0.0, 0.6, 0.6, 0.0, -0.3};
  for (int k = 0; k < 5; ++k) arcs.push_back(windowArc(k, omegas[k]));
  const Trajectory3 ramp = integrateArcs(arcs, secToNs(0.001));
  for (bool interpolate : {true, false}) {
    o.interpolate_arc_rates = interpolate;
    Backend b(o, cam, testExtrinsics());
    for (const ArcEstimate& a : arcs) b.addArc(a);  // no process(): no spline yet
    double max_heading_error = 0.0, max_odometry_error = 0.0;
    for (const auto& sample : ramp) {
      if (sample.t_ns > arcs.back().t_ref_ns) break;
      max_heading_error = std::max(max_heading_error,
                                   std::abs(wrapAngle(yawOf(b.initialGuess(sample.t_ns).linear()) -
                                                      yawOf(sample.T.linear()))));
      Pose3 T;
      ASSERT_TRUE(b.poseAt(sample.t_ns, &T, nullptr, nullptr));
      max_odometry_error = std::max(
          max_odometry_error, std::abs(wrapAngle(yawOf(T.linear()) - yawOf(sample.T.linear()))));
    }
    if (interpolate) {
      // The odometry (poseAt beyond the spline) follows the same ramps, up to the newest arc's
      // middle: the ramp after it is not known before the next arc.
      EXPECT_LT(max_heading_error, 1e-3) << "ramps between the middles (in 8 constant pieces)";
      EXPECT_LT(max_odometry_error, 1e-3);
      EXPECT_EQ(b.finalUntil(), arcs.back().t_ref_ns);
    } else {
      EXPECT_GT(max_heading_error, 0.01) << "steps at the window borders";  // 0.6 x 0.15 / 4
      EXPECT_GT(max_odometry_error, 0.01);
      EXPECT_EQ(b.finalUntil(), arcs.back().t_end_ns);
      // Each arc's rates over its own window: at every window border the heading is the sum of
      // the arcs' turns so far, so a pose published before the next arc arrives stays right.
      double heading = 0.0;
      for (const ArcEstimate& a : arcs) {
        heading += a.omega * dtSec(a.t_end_ns, a.t_start_ns);
        Pose3 T;
        ASSERT_TRUE(b.poseAt(a.t_end_ns, &T, nullptr, nullptr));
        EXPECT_NEAR(wrapAngle(yawOf(T.linear()) - heading), 0.0, 1e-9);
      }
    }
  }
}

TEST(Backend, UnmeasuredArcsAreDeadReckonedAtTheLastMeasuredRates) {
  // OK (0.3 rad/s), LOST with a wild yaw rate, LOW_EVENTS with NaN, OK again: the two without a
  // motion estimate take the last measured rates (as backend_node warns), and only the OK ones
  // count as yaw-rate measurements. With steps each arc's turn ends at its window's end.
  const CameraModel cam(testCalibration());
  BackendOptions o = testOptions();
  o.interpolate_arc_rates = false;
  Backend b(o, cam, testExtrinsics());
  const ArcStatus status[] = {ArcStatus::kOk, ArcStatus::kLost, ArcStatus::kLowEvents,
                              ArcStatus::kOk};
  const double omega[] = {0.3, 5.0, std::nan(""), 0.1};
  for (int k = 0; k < 4; ++k) b.addArc(windowArc(k, omega[k], status[k]));
  EXPECT_EQ(b.stats().arcs_held, 2u);
  Pose3 T;
  ASSERT_TRUE(b.poseAt(kEpoch + secToNs(0.9), &T, nullptr, nullptr));
  EXPECT_NEAR(yawOf(T.linear()), 3 * 0.3 * 0.3, 1e-9);
  ASSERT_TRUE(b.poseAt(kEpoch + secToNs(1.2), &T, nullptr, nullptr));
  EXPECT_NEAR(yawOf(T.linear()), 3 * 0.3 * 0.3 + 0.1 * 0.3, 1e-9);
  EXPECT_TRUE(T.matrix().allFinite());
}

TEST(Backend, PosesTiltWithTheAccelerationsByTheBodysPitchAndRollGradients) {
  // A car braking at 2 m/s^2 (0.3 s arcs, 8 m/s down by 0.6 m/s each) on a 0.1 rad/s curve.
  // With a pitch gradient of 3 deg/g it dives 3 x 2 / g deg, and with 5 deg/g of roll it leans
  // out of the curve by 5 v omega / g deg: the published pose carries both; without measured
  // speeds (or without the gradients) it stays planar.
  const CameraModel cam(testCalibration());
  BackendOptions o = testOptions();
  o.pitch_per_g_deg = 3.0;
  o.roll_per_g_deg = 5.0;
  std::vector<ArcEstimate> arcs;
  for (int k = 0; k < 10; ++k) {
    arcs.push_back(windowArc(k, 0.1));
    arcs.back().v = 8.0 - 0.6 * k;
  }
  constexpr double g = 9.80665;
  for (const bool measured : {true, false}) {
    for (const bool gradients : {true, false}) {
      BackendOptions oc = o;
      if (!gradients) oc.pitch_per_g_deg = oc.roll_per_g_deg = 0.0;
      Backend b(oc, cam, testExtrinsics());
      b.setSpeedsMeasured(measured);
      for (const ArcEstimate& a : arcs) b.addArc(a);
      const bool tilted = measured && gradients;
      EXPECT_EQ(b.tiltInPose(), tilted);
      for (int k = 2; k < 8; ++k) {
        const int64_t t = arcs[size_t(k)].t_ref_ns;
        Pose3 T, P;
        double v = 0.0;
        ASSERT_TRUE(b.poseAt(t, &T, nullptr, nullptr));
        ASSERT_TRUE(b.planarPoseAt(t, &P, &v, nullptr));
        const Tilt tilt = b.tiltAt(t);
        // The pose is the planar one with the tilt composed in base_link.
        EXPECT_LT((T.linear() - P.linear() * tilt.rotation()).norm(), 1e-12);
        EXPECT_LT((T.translation() - P.translation()).norm(), 1e-12);
        if (!tilted) {
          EXPECT_EQ(tilt.pitch, 0.0);
          EXPECT_EQ(tilt.roll, 0.0);
          continue;
        }
        EXPECT_NEAR(tilt.pitch * kDegPerRad, 3.0 * 2.0 / g, 0.02) << "k = " << k;  // 0.61 deg
        EXPECT_NEAR(v, arcs[size_t(k)].v, 0.05);
        EXPECT_NEAR(tilt.roll * kDegPerRad, 5.0 * v * 0.1 / g, 0.01) << "k = " << k;
      }
    }
  }
}

TEST(Backend, ParallaxWedgeEventsAreCountedAndLeftOutOfTheVolumes) {
  // With parallax_mask_slope the events of the wedge beside the horizon row are dropped on
  // arrival, before the buffer the volumes are cut from: each is counted once, and exactly those
  // GroundMask names are; the refinement runs on the rest.
  Scene sc;
  BackendOptions o = testOptions();
  o.parallax_mask_slope = 0.5;
  const GroundMask wedge(sc.cam, testExtrinsics(), 0.0, o.parallax_mask_slope);
  size_t in_wedge = 0;
  for (const PixelEvent& e : sc.events) in_wedge += wedge.keeps(e) ? 0 : 1;
  ASSERT_GT(in_wedge, sc.events.size() / 10);
  ASSERT_LT(in_wedge, sc.events.size() / 2);
  Backend backend(o, sc.cam, testExtrinsics());
  backend.addEvents(sc.events);
  for (const ArcEstimate& a : truthArcs(*sc.truth, 0.0)) {
    backend.addArc(a);
    backend.process();
  }
  backend.finish();
  EXPECT_EQ(backend.stats().events_in, sc.events.size());
  EXPECT_EQ(backend.stats().events_masked, in_wedge);
  EXPECT_GT(backend.stats().volumes, 0u);
  ASSERT_TRUE(backend.hasSpline());
  Backend unmasked(testOptions(), sc.cam, testExtrinsics());
  unmasked.addEvents(sc.events);
  EXPECT_EQ(unmasked.stats().events_masked, 0u);
}

TEST(Backend, StandstillGivesFinitePosesAndSkipsVolumes) {
  Scene sc;
  std::vector<ArcEstimate> arcs = truthArcs(*sc.truth, 0.0);
  for (ArcEstimate& a : arcs) {
    const double s = dtSec(a.t_ref_ns, kEpoch);
    if (s > 1.0 && s < 2.2) {
      a.status = ArcStatus::kStandstill;
      a.omega = a.v = 0.0;
    }
  }
  arcs.front().status = ArcStatus::kStandstill;  // also a standstill at the very start
  arcs.front().omega = arcs.front().v = 0.0;
  Backend backend(testOptions(), sc.cam, testExtrinsics());
  backend.addEvents(sc.events);
  for (const ArcEstimate& a : arcs) {
    backend.addArc(a);
    backend.process();
  }
  backend.finish();
  ASSERT_TRUE(backend.hasSpline());
  const BSpline& s = backend.spline();
  ASSERT_EQ(s.standstills().size(), 2u);
  for (double u = s.validFrom() - 0.1; u <= s.validTo() + 0.1; u += 0.001) {
    ASSERT_TRUE(s.T_odom_base(u).matrix().allFinite()) << u;
  }
  const Pose3 held = s.T_odom_base(1.3);
  for (double u = 1.1; u < 2.2; u += 0.01) EXPECT_TRUE(s.T_odom_base(u).isApprox(held, 1e-12)) << u;
  EXPECT_GT(backend.stats().volumes_skipped, 0u);
  for (const StampedPose& p : backend.sampleTrajectory(50.0)) ASSERT_TRUE(p.T.matrix().allFinite());
  // The vehicle starts again where it stood (closeStandstillGaps after the refinements).
  const BSpline::Interval& stop = s.standstills()[1];
  EXPECT_LT((s.position(stop.to_s) - s.position(stop.from_s)).norm(), 1e-9);
  EXPECT_GT(backend.stats().standstill_gaps_closed, 0u);
}

namespace {

/// A path along x at 0.3 m/s that stands still in [1.6, 3.2] s (spline time) and then goes
/// on sideways-shifted by (4, -2) mm, as a refinement may leave it: uniform cubic knots 0.2 s.
BSpline gappedStandstillSpline(double stop_from_s, double stop_to_s) {
  const int p = 3, n = 30;
  const double dk = 0.2;
  std::vector<double> knots(n + p + 1);
  for (int k = 0; k <= n + p; ++k) knots[k] = (k - p) * dk;
  std::vector<Vec2> P(n);
  for (int i = 0; i < n; ++i) {
    const double t = (i - 1) * dk;  // the point's Greville abscissa
    const double x = 0.3 * (std::min(t, stop_from_s) + std::max(0.0, t - stop_to_s));
    P[i] = Vec2(x, 0.02 * std::sin(t)) +
           (t > 0.5 * (stop_from_s + stop_to_s) ? Vec2(0.004, -0.002) : Vec2(Vec2::Zero()));
  }
  BSpline s(p, knots, P, 0);
  s.setStandstills({{stop_from_s, stop_to_s}});
  return s;
}

}  // namespace

TEST(Backend, ClosingAStandstillGapStartsThePathWhereItStoodWithItsShape) {
  BSpline s = gappedStandstillSpline(1.6, 3.2);
  const BSpline before = s;
  const double a = 1.6, b = 3.2;
  ASSERT_GT((s.position(b) - s.position(a)).norm(), 1e-3);  // the gap to close
  EXPECT_EQ(closeStandstillGaps(&s, 0), 1);
  EXPECT_LT((s.position(b) - s.position(a)).norm(), 1e-12);
  for (double u = s.validFrom(); u <= a; u += 0.01)
    EXPECT_LT((s.position(u) - before.position(u)).norm(), 1e-12) << u;
  for (double u = b; u <= s.validTo(); u += 0.01) {
    const Vec2 shape = s.position(u) - s.position(b),
               shape0 = before.position(u) - before.position(b);
    EXPECT_LT((shape - shape0).norm(), 1e-12) << u;
    EXPECT_NEAR(s.heading(u), before.heading(u), 1e-12) << u;
  }
  EXPECT_EQ(closeStandstillGaps(&s, 0), 0);  // closed: nothing left to move

  // Left open: control points from `first` on cannot reach into the standstill, the standstill
  // is shorter than a blend of degree knot spans, or the vehicle still stands at the end.
  BSpline fixed = gappedStandstillSpline(1.6, 3.2);
  EXPECT_EQ(closeStandstillGaps(&fixed, 20), 0);
  BSpline shorter = gappedStandstillSpline(1.6, 2.1);
  EXPECT_EQ(closeStandstillGaps(&shorter, 0), 0);
  BSpline standing = gappedStandstillSpline(1.6, 3.2);
  standing.setStandstills({{1.6, standing.validTo()}});
  EXPECT_EQ(closeStandstillGaps(&standing, 0), 0);
  for (double u = standing.validFrom(); u <= standing.validTo(); u += 0.05)
    EXPECT_LT((standing.position(u) - before.position(u)).norm(), 1e-15) << u;
}

TEST(Backend, OptionsValidateNamesTheField) {
  auto expectField = [](const BackendOptions& o, const std::string& field) {
    try {
      o.validate();
      ADD_FAILURE() << "no exception for " << field;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
    }
  };
  EXPECT_NO_THROW(BackendOptions().validate());
  BackendOptions o;
  o.tau2_s = o.tau1_s;
  expectField(o, "tau2_s");
  o = BackendOptions();
  o.window_s = 0.1;
  expectField(o, "window_s");
  o = BackendOptions();
  o.degree = 0;
  expectField(o, "degree");
  o = BackendOptions();
  o.knot_spacing_s = -1;
  expectField(o, "knot_spacing_s");
  o = BackendOptions();
  o.max_events_per_volume = 10;
  expectField(o, "max_events_per_volume");
  o = BackendOptions();
  o.max_line_search_steps = 0;
  expectField(o, "max_line_search_steps");
  o = BackendOptions();
  o.arc_rate_prior_scale_deg_s = -1;
  expectField(o, "arc_rate_prior_scale_deg_s");
  o = BackendOptions();
  o.outlier_arc_min_rad_s = std::nan("");
  expectField(o, "outlier_arc_min_rad_s");
  o = BackendOptions();
  o.parallax_mask_slope = -0.1;
  expectField(o, "parallax_mask_slope");
  o = BackendOptions();
  o.pitch_per_g_deg = std::nan("");
  expectField(o, "pitch_per_g_deg");
  o = BackendOptions();
  o.roll_per_g_deg = 45.0;
  expectField(o, "roll_per_g_deg");
  o = BackendOptions();
  o.volume.pose_slice_s = -0.001;
  expectField(o, "pose_slice_s");
  o.volume.pose_slice_s = 0.02;
  expectField(o, "pose_slice_s");
  o = BackendOptions();
  o.volume.num_planes = 0;
  expectField(o, "num_planes");
  EXPECT_THROW(Backend(o, CameraModel(testCalibration()), testExtrinsics()), std::invalid_argument);
}

/// The turtlebot configuration for the Scene: its camera, mount, speed and volumes.
static PipelineConfig scenePipelineConfig() {
  PipelineConfig cfg = loadPipelineConfig(std::string(VWE_VO_SOURCE_DIR) + "/config/vwe_vo.yaml");
  cfg.camera = testCalibration();
  cfg.T_base_cam = testExtrinsics();
  cfg.frontend.nominal_speed_mps = kSpeed;
  cfg.frontend.standstill_event_rate_hz = 1000;  // the scene has ~19k events/s
  cfg.frontend.volume = testOptions().volume;
  cfg.backend = testOptions();
  return cfg;
}

TEST(Backend, OfflinePipelineWritesTheBackendOutputs) {
  Scene sc;
  PipelineConfig cfg = scenePipelineConfig();
  const std::string yaml = std::string(VWE_VO_SOURCE_DIR) + "/config/vwe_vo.yaml";
  EXPECT_EQ(loadPipelineConfig(yaml).backend.knot_spacing_s, 0.2);
  const std::string dir = "/tmp/vwe_vo_test_backend_" + std::to_string(::getpid());
  // The back-end on its own thread (the default) and inline after each chunk: the same outputs.
  Trajectory3 inline_backend, inline_odom;
  for (const bool thread : {false, true}) {
    cfg.backend_thread = thread;
    OfflinePipeline pipeline(cfg);
    for (size_t i = 0; i < sc.events.size(); i += 5000)
      pipeline.addEvents(EventVector(sc.events.begin() + i,
                                     sc.events.begin() + std::min(sc.events.size(), i + 5000)));
    pipeline.finish();
    ASSERT_NE(pipeline.backend(), nullptr);
    ASSERT_TRUE(pipeline.backend()->hasSpline());
    EXPECT_GE(pipeline.backend()->stats().updates, 2u);
    const nlohmann::json r = pipeline.report();
    ASSERT_TRUE(r["stages"].contains("backend"));
    EXPECT_EQ(r["event_pipeline"]["backend_thread"].get<bool>(), thread);
    // Without mapping the processing time is the event pipeline's wall time, which holds the
    // front-end's busy time (its thread), and inline the back-end's too.
    const double wall = r["event_pipeline"]["wall_s"].get<double>();
    const double fe = r["stages"]["frontend"]["processing_s"].get<double>();
    const double be = r["stages"]["backend"]["processing_s"].get<double>();
    EXPECT_EQ(r["processing_s"].get<double>(), wall);
    EXPECT_GT(fe, 0.0);
    EXPECT_GT(be, 0.0);
    EXPECT_GE(wall, thread ? fe : fe + be);
    if (!thread) {
      inline_backend = pipeline.backendTrajectory();
      inline_odom = pipeline.odometryTrajectory();
      continue;
    }
    const Trajectory3 threaded = pipeline.backendTrajectory();
    ASSERT_EQ(threaded.size(), inline_backend.size());
    for (size_t i = 0; i < threaded.size(); ++i)
      EXPECT_TRUE(threaded[i].T.isApprox(inline_backend[i].T, 0.0)) << i;
    ASSERT_EQ(pipeline.odometryTrajectory().size(), inline_odom.size());
    for (size_t i = 0; i < inline_odom.size(); ++i)
      EXPECT_TRUE(pipeline.odometryTrajectory()[i].T.isApprox(inline_odom[i].T, 0.0)) << i;
    pipeline.writeOutputs(dir);
  }
  const Trajectory3 be = readTum(dir + "/backend.tum");
  EXPECT_GE(be.size(), size_t(50));
  nlohmann::json spline;
  std::ifstream(dir + "/spline.json") >> spline;
  EXPECT_EQ(spline["degree"].get<int>(), 3);
  EXPECT_EQ(spline["knots_s"].size(), spline["control_points_m"].size() + 4);
  std::printf("[backend] offline pipeline: %zu backend poses, %zu control points\n", be.size(),
              spline["control_points_m"].size());

  cfg.frontend_only = true;
  OfflinePipeline fe_only(cfg);
  fe_only.addEvents(sc.events);
  fe_only.finish();
  EXPECT_EQ(fe_only.backend(), nullptr);
  EXPECT_FALSE(fe_only.report()["stages"].contains("backend"));
  EXPECT_EQ(std::system(("rm -rf " + dir).c_str()), 0);
}

// vwe_vo_offline --truth-arcs: the back-end is fed the truth's yaw rate over each arc's window,
// blended towards the front-end's. Blend 1 is the front-end exactly; blend 0 starts the back-end
// on the truth (here with no refinement, so what comes out is the initial fit itself).
TEST(Backend, TruthArcsBlendBetweenTheTruthAndTheFrontEnd) {
  Scene sc;
  PipelineConfig cfg = scenePipelineConfig();
  cfg.backend.max_iterations = 0;  // the back-end's output is its initial fit
  Trajectory3 truth;
  for (double u = 0.0; u <= kDuration + 1e-9; u += 0.01)
    truth.push_back({kEpoch + secToNs(u), sc.truth->T_odom_base(u)});
  struct Run {
    Trajectory3 backend;
    nlohmann::json report;
    size_t windows = 0;
  };
  auto run = [&](double blend, bool with_truth) {
    OfflinePipeline pipeline(cfg);
    if (with_truth) pipeline.setBackendArcsFromTruth(truth, blend);
    pipeline.addEvents(sc.events);
    pipeline.finish();
    return Run{pipeline.backendTrajectory(), pipeline.report(), pipeline.arcs().size()};
  };
  // RMSE over 0.5 s pairs of the heading change of est against ref (the truth if null) [deg].
  auto rotationError = [&](const Trajectory3& est, const Trajectory3* ref) {
    double sum = 0.0;
    int n = 0;
    for (double u = 0.2; u + 0.5 <= kDuration - 0.2; u += 0.1, ++n) {
      auto change = [&](const Trajectory3& tr) {
        Pose3 a, b;
        EXPECT_TRUE(interpolateTrajectory(tr, kEpoch + secToNs(u), &a) &&
                    interpolateTrajectory(tr, kEpoch + secToNs(u + 0.5), &b));
        return yawOf(a.linear().transpose() * b.linear());
      };
      const double d_ref = ref ? change(*ref) : sc.truth->heading(u + 0.5) - sc.truth->heading(u);
      sum += std::pow(wrapAngle(change(est) - d_ref), 2);
    }
    return std::sqrt(sum / n) * 180 / kPi;
  };
  const Run fe = run(0.0, false), same = run(1.0, true), exact = run(0.0, true),
            twice = run(2.0, true);
  ASSERT_EQ(fe.backend.size(), same.backend.size());
  for (size_t i = 0; i < fe.backend.size(); ++i)
    ASSERT_TRUE(fe.backend[i].T.isApprox(same.backend[i].T, 1e-12)) << "pose " << i;
  const double e_fe = rotationError(fe.backend, nullptr),
               e_exact = rotationError(exact.backend, nullptr);
  // The front-end's deviation from the truth, once and twice over.
  const double d1 = rotationError(fe.backend, &exact.backend),
               d2 = rotationError(twice.backend, &exact.backend);
  std::printf(
      "[backend] initial fit vs truth: from the front-end's arcs %.3f deg, from the truth's %.3f "
      "deg; "
      "deviation from the truth-fed fit at blend 1 / 2: %.3f / %.3f deg\n",
      e_fe, e_exact, d1, d2);
  // The truth turns 5 deg per 0.5 s; what is left is the fit of the arcs' ramps, not the rates.
  EXPECT_LT(e_exact, 0.1);
  ASSERT_GT(d1, 0.005);
  EXPECT_NEAR(d2 / d1, 2.0, 0.2);
  const nlohmann::json& tr = exact.report["stages"]["backend"]["arcs_from_truth"];
  EXPECT_EQ(tr["arcs"].get<size_t>() + tr["arcs_outside_truth"].get<size_t>(), exact.windows);
  EXPECT_GE(tr["arcs"].get<size_t>(), exact.windows - 1);
  EXPECT_FALSE(fe.report["stages"]["backend"].contains("arcs_from_truth"));

  PipelineConfig fe_only = cfg;
  fe_only.frontend_only = true;
  OfflinePipeline no_backend(fe_only);
  EXPECT_THROW(no_backend.setBackendArcsFromTruth(truth, 0.0), std::logic_error);
  OfflinePipeline started(cfg);
  EXPECT_THROW(started.setBackendArcsFromTruth({}, 0.0), std::invalid_argument);
  started.addEvents(EventVector(sc.events.begin(), sc.events.begin() + 100));
  EXPECT_THROW(started.setBackendArcsFromTruth(truth, 0.0), std::logic_error);
}

TEST(Backend, YamlIncludeLaysAFileOverTheOneItNamesSectionBySection) {
  // base.yaml in a sub-folder, with a relative calibration; over.yaml includes it by a relative
  // path and replaces one key of backend and one of backend.volume: the others stay the base's.
  const std::string dir = "/tmp/vwe_vo_test_include_" + std::to_string(::getpid());
  ASSERT_EQ(std::system(("mkdir -p " + dir + "/sub").c_str()), 0);
  ASSERT_EQ(std::system(("cp " + std::string(VWE_VO_SOURCE_DIR) + "/config/davis346.yaml " + dir +
                         "/sub/cam.yaml")
                            .c_str()),
            0);
  std::ofstream(dir + "/sub/base.yaml")
      << "camera_calibration: cam.yaml\nfrontend:\n  window_duration_s: 0.25\nbackend:\n"
         "  window_s: 3.0\n  tau1_s: 0.25\n  volume:\n    num_planes: 17\n    z_min_m: 2.0\n";
  std::ofstream(dir + "/over.yaml")
      << "include: sub/base.yaml\nbackend:\n  tau1_s: 0.3\n  volume:\n    num_planes: 20\n";
  const PipelineConfig cfg = loadPipelineConfig(dir + "/over.yaml");
  EXPECT_EQ(cfg.backend.tau1_s, 0.3);
  EXPECT_EQ(cfg.backend.volume.num_planes, 20);
  EXPECT_EQ(cfg.backend.window_s, 3.0);
  EXPECT_EQ(cfg.backend.volume.z_min_m, 2.0);
  EXPECT_EQ(cfg.frontend.window_duration_s, 0.25);
  EXPECT_EQ(cfg.camera.width, 346);  // sub/cam.yaml, found from base.yaml's folder
  EXPECT_TRUE(cfg.warnings.empty()) << cfg.warnings.front();
  // Bad includes are refused with the file's name: a cycle, a missing file, a list of files.
  auto expectRefused = [&](const std::string& file, const std::string& include,
                           const std::string& named) {
    std::ofstream(dir + "/" + file) << "include: " << include << "\n";
    try {
      loadPipelineConfig(dir + "/" + file);
      ADD_FAILURE() << "include: " << include << " accepted";
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find(named), std::string::npos) << e.what();
    }
  };
  expectRefused("loop.yaml", "loop.yaml", "loop.yaml");
  expectRefused("missing.yaml", "nowhere.yaml", "nowhere.yaml");
  expectRefused("list.yaml", "[a.yaml, b.yaml]", "list.yaml: include");
  // Warnings and errors about a key name the file that set it, included or including.
  std::ofstream(dir + "/sub/typo.yaml")
      << "camera_calibration: cam.yaml\nbackend:\n  tau_1_s: 0.3\n  volume:\n    planes: 2\n";
  std::ofstream(dir + "/typo_over.yaml")
      << "include: sub/typo.yaml\nfrontend:\n  windw_s: 0.3\nbakend:\n  tau1_s: 0.3\n";
  const PipelineConfig typos = loadPipelineConfig(dir + "/typo_over.yaml");
  auto warned = [&](const std::string& expected) {
    for (const std::string& w : typos.warnings)
      if (w == expected) return true;
    return false;
  };
  EXPECT_TRUE(warned(dir + "/sub/typo.yaml: unknown key 'backend.tau_1_s' ignored"));
  EXPECT_TRUE(warned(dir + "/sub/typo.yaml: unknown key 'backend.volume.planes' ignored"));
  EXPECT_TRUE(warned(dir + "/typo_over.yaml: unknown key 'frontend.windw_s' ignored"));
  EXPECT_TRUE(warned(dir + "/typo_over.yaml: unknown top-level key 'bakend' ignored"));
  EXPECT_EQ(typos.warnings.size(), 4u);
  std::ofstream(dir + "/sub/bad.yaml")
      << "camera_calibration: cam.yaml\nbackend:\n  tau1_s: -1.0\n";
  std::ofstream(dir + "/bad_over.yaml") << "include: sub/bad.yaml\nbackend:\n  window_s: 2.0\n";
  try {
    loadPipelineConfig(dir + "/bad_over.yaml");
    ADD_FAILURE() << "backend.tau1_s -1 accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_EQ(std::string(e.what()).rfind(dir + "/sub/bad.yaml: backend.tau1_s", 0), 0u)
        << e.what();
  }
  ASSERT_EQ(std::system(("rm -rf " + dir).c_str()), 0);
  // The shipped rigid car is car.yaml with the suspension's tilt off, and nothing else.
  const std::string config = std::string(VWE_VO_SOURCE_DIR) + "/config/";
  PipelineConfig rigid = loadPipelineConfig(config + "car_rigid.yaml");
  const PipelineConfig car = loadPipelineConfig(config + "car.yaml");
  EXPECT_EQ(rigid.backend.pitch_per_g_deg, 0.0);
  EXPECT_EQ(rigid.backend.roll_per_g_deg, 0.0);
  EXPECT_GT(car.backend.pitch_per_g_deg, 0.0);
  EXPECT_GT(car.backend.roll_per_g_deg, 0.0);
  rigid.backend.pitch_per_g_deg = car.backend.pitch_per_g_deg;
  rigid.backend.roll_per_g_deg = car.backend.roll_per_g_deg;
  EXPECT_EQ(YAML::Dump(optionsToYaml(rigid)), YAML::Dump(optionsToYaml(car)));
  EXPECT_EQ(rigid.camera.width, car.camera.width);
}

TEST(Backend, YamlLoaderFillsBackendOptionsAndNamesBadKeys) {
  const std::string calib = std::string(VWE_VO_SOURCE_DIR) + "/config/davis346.yaml";
  const std::string path = "/tmp/vwe_vo_test_backend_cfg_" + std::to_string(::getpid()) + ".yaml";
  auto write = [&](const std::string& backend) {
    std::ofstream(path) << "camera_calibration: " << calib << "\nbackend:\n" << backend;
  };
  write(
      "  window_s: 3.0\n  tau1_s: 0.25\n  max_line_search_steps: 7\n  parallax_mask_slope: 0.3\n"
      "  bogus_key: 1\n  volume:\n    num_planes: 17\n");
  const PipelineConfig cfg = loadPipelineConfig(path);
  EXPECT_EQ(cfg.backend.window_s, 3.0);
  EXPECT_EQ(cfg.backend.max_line_search_steps, 7);
  EXPECT_EQ(cfg.backend.tau1_s, 0.25);
  EXPECT_EQ(cfg.backend.volume.num_planes, 17);
  EXPECT_EQ(cfg.backend.parallax_mask_slope, 0.3);
  EXPECT_EQ(cfg.backend.tau2_s, BackendOptions().tau2_s);
  bool warned = false;
  for (const std::string& w : cfg.warnings)
    warned = warned || w.find("backend.bogus_key") != std::string::npos;
  EXPECT_TRUE(warned);
  write("  tau1_s: 0.5\n  tau2_s: 0.4\n");
  try {
    loadPipelineConfig(path);
    ADD_FAILURE() << "tau2_s <= tau1_s accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("tau2_s"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
  }
  std::remove(path.c_str());
}
