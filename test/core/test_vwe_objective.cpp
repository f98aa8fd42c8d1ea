// The VWE objective against independent truths: a brute-force variance over the whole grid,
// central finite differences of its gradient, single- vs multi-threaded results, and the
// location of its maximum for events generated from a known motion.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "../common/synthetic_events.h"
#include "../common/test_camera.h"
#include "vwe_vo/sensor/subsample.h"
#include "vwe_vo/vwe/ray_builder.h"
#include "vwe_vo/vwe/vwe_objective.h"

using namespace vwe_vo;

namespace {

/// Camera yawing at w [rad/s] about its up axis (-y) while moving forward (+z) at v [m/s].
class YawForwardModel : public TrajectoryModel {
 public:
  YawForwardModel(double w, double v) : w_(w), v_(v) {}
  int numParams() const override { return 2; }
  int64_t referenceTime() const override { return 0; }
  bool covers(int64_t) const override { return true; }
  Pose3 T_Cr_Ct(int64_t t_ns, PoseJacobian* jac) const override {
    const double dt = nsToSec(t_ns);
    const Vec3 axis(0, -1, 0);
    const Mat3 R = Eigen::AngleAxisd(w_ * dt, axis).toRotationMatrix();
    const Vec3 t(0, 0, v_ * dt);
    if (jac) {
      jac->clear();
      jac->add(0, dt * skew(axis) * R, Vec3::Zero());
      jac->add(1, Mat3::Zero(), Vec3(0, 0, dt));
    }
    return makePose(R, t);
  }
  double w_, v_;
};

CameraCalibration testCalibration() {
  return test::syntheticCalibration(true);
}

EventVector makeEvents(const CameraModel& cam, const TrajectoryModel& truth, int n, unsigned seed) {
  return vwe_vo::synthetic::randomPointEvents(cam, truth, n, seed);
}

VolumeOptions volumeOptions(int threads, Contrast contrast = Contrast::kDensityPerVote) {
  VolumeOptions o;
  o.num_planes = 20;
  o.z_min_m = 0.8;
  o.z_max_m = 10;
  o.num_threads = threads;
  o.contrast = contrast;
  return o;
}

/// The contrast of the grid's voxels by brute force, independent of ProjectiveVolume's sums.
/// The contrast of the grid the rays voted; the density per vote leaves out each vote's own
/// squared weights, recomputed here from the rays' vote positions in double.
double bruteForceContrast(const ProjectiveVolume& volume, const std::vector<VolumeRay>& rays,
                          Contrast contrast, double* sum) {
  double s = 0, q = 0;
  for (float v : volume.data()) {
    s += v;
    q += double(v) * v;
  }
  *sum = s;
  const double nv = double(volume.numVoxels());
  if (contrast == Contrast::kVariance) return q / nv - (s / nv) * (s / nv);
  double self = 0;
  for (const VolumeRay& r : rays)
    for (int l = 0; l < volume.numPlanes(); ++l) {
      const float rho = float(volume.planeInverseDepth(l));
      if (!(rho < r.rho_max)) continue;
      const float u = r.u0 + rho * r.du, v = r.v0 + rho * r.dv;
      if (!(u >= 0 && v >= 0 && u < float(volume.width() - 1) && v < float(volume.height() - 1)))
        continue;
      const double ax = u - std::floor(u), ay = v - std::floor(v);
      self += ((1 - ax) * (1 - ax) + ax * ax) * ((1 - ay) * (1 - ay) + ay * ay);
    }
  return (q - self) / s;
}

TEST(VweObjective, DensityPerVoteLeavesOutEachVotesOwnWeights) {
  // One ray alone meets no other vote: whether it lands on a voxel centre (its own squares sum
  // to 1) or between four (1/4), the density is zero. Two rays that meet give each the other's
  // weights: on centres 1 per vote; the variance keeps the paper's definition.
  const VolumeOptions options = volumeOptions(1, Contrast::kDensityPerVote);
  ProjectiveVolume volume(options, 346, 260, 250, 250, 173, 130);
  const VolumeRay on_centre{100.0f, 80.0f, 0.0f, 0.0f, std::numeric_limits<float>::infinity()};
  const VolumeRay between{100.5f, 80.5f, 0.0f, 0.0f, std::numeric_limits<float>::infinity()};
  size_t votes = 0;
  EXPECT_EQ(volume.contrastOfRays({on_centre}, &votes), 0.0);
  EXPECT_EQ(votes, size_t(options.num_planes));
  EXPECT_NEAR(volume.contrastOfRays({between}, &votes), 0.0, 1e-9);
  EXPECT_NEAR(volume.contrastOfRays({on_centre, on_centre}, &votes), 1.0, 1e-9);
  EXPECT_NEAR(volume.contrastOfRays({between, between}, &votes), 0.25, 1e-9);
  // The grid's path (vote(), clear()) says the same; a DSI's votes (no contrast) say NaN.
  volume.vote({on_centre, on_centre});
  EXPECT_NEAR(volume.contrast(), 1.0, 1e-9);
  EXPECT_NEAR(volume.clear({on_centre, on_centre}), 1.0, 1e-9);
  EXPECT_EQ(volume.vote({between, between}, false), size_t(2 * options.num_planes));
  EXPECT_TRUE(std::isnan(volume.contrast()));
  EXPECT_TRUE(std::isnan(volume.clear({between, between})));
  for (float v : volume.data()) ASSERT_EQ(v, 0.0f);
  volume.vote({between, between});
  EXPECT_NEAR(volume.clear({between, between}), 0.25, 1e-9);
  // The sensitivities are the derivatives of that density: central differences of a ray that
  // overlaps another off-centre (its own squares alone would pull it to a voxel centre).
  const VolumeRay fixed{100.2f, 80.7f, 0.0f, 0.0f, std::numeric_limits<float>::infinity()};
  const VolumeRay moved{100.6f, 80.4f, 0.0f, 0.0f, std::numeric_limits<float>::infinity()};
  std::vector<Eigen::Vector4d> sens;
  volume.contrastOfRays({moved, fixed}, &votes, &sens);
  ASSERT_EQ(sens.size(), size_t(2));
  const float h = 1e-2f;
  for (int axis : {0, 2}) {
    VolumeRay plus = moved, minus = moved;
    (axis == 0 ? plus.u0 : plus.v0) += h;
    (axis == 0 ? minus.u0 : minus.v0) -= h;
    const double fd = (volume.contrastOfRays({plus, fixed}, &votes) -
                       volume.contrastOfRays({minus, fixed}, &votes)) /
                      (2.0 * double(h));
    EXPECT_NEAR(sens[0][axis], fd, 1e-4) << "axis " << axis;
    EXPECT_GT(std::abs(fd), 0.01);
  }
}

TEST(VweObjective, PoseSlicesLieOnAFixedGridOfAbsoluteTimes) {
  // Slices [k s, (k + 1) s) share the time k s + s / 2, for negative times too.
  const int64_t s = 500000;
  EXPECT_EQ(poseSliceTime(0, s), 250000);
  EXPECT_EQ(poseSliceTime(499999, s), 250000);
  EXPECT_EQ(poseSliceTime(500000, s), 750000);
  EXPECT_EQ(poseSliceTime(secToNs(3.0) + 123, s), secToNs(3.0) + 250000);
  EXPECT_EQ(poseSliceTime(-1, s), -250000);
  EXPECT_EQ(poseSliceTime(-500000, s), -250000);
  EXPECT_EQ(poseSliceTime(-500001, s), -750000);
  // No slices: each event's own time.
  EXPECT_EQ(poseSliceTime(123456789, 0), 123456789);
  EXPECT_EQ(poseSliceTime(123456789, 1), 123456789);
}

}  // namespace

TEST(VweObjective, ContrastFromClearingEqualsBruteForce) {
  const CameraModel cam(testCalibration());
  for (Contrast contrast : {Contrast::kVariance, Contrast::kDensityPerVote}) {
    for (int threads : {1, 2}) {
      ProjectiveVolume volume(volumeOptions(threads, contrast), cam.width(), cam.height(), 250, 250,
                              173, 130);
      VweObjective obj(cam, &volume);
      const YawForwardModel truth(0.5, 0.4);
      // Sparse votes (clear() visits the votes) and dense ones (clear() sweeps whole planes).
      for (int n : {3000, 400000}) {
        const EventVector ev = makeEvents(cam, truth, n, 1);
        const double from_clear = obj.evaluate(ev, truth).contrast;
        for (float v : volume.data()) ASSERT_EQ(v, 0.0f);
        const VweEvaluation e = obj.voteOnly(ev, truth);
        double s = 0;
        const double brute = bruteForceContrast(volume, obj.lastRays(), contrast, &s);
        EXPECT_NEAR(from_clear, brute, 1e-6 * brute) << n << " events, " << threads << " threads";
        // (The density divides by the exact vote count, the brute force by the grid's float sum.)
        EXPECT_NEAR(e.contrast, brute, (contrast == Contrast::kVariance ? 1e-9 : 1e-6) * brute);
        EXPECT_NEAR(s, double(e.votes), 1e-4 * s);  // bilinear weights sum to one per vote
        EXPECT_GT(e.votes, size_t(n) * 10);
        EXPECT_NEAR(volume.clear(obj.lastRays()), brute, 1e-6 * brute);
        for (float v : volume.data()) ASSERT_EQ(v, 0.0f);
      }
    }
  }
}

// setPerCameraMinDepth: rays of the cameras ahead of the reference (forward motion) vote only
// from z_min_m in front of their own camera, so fewer votes land; the grid still holds exactly
// what the rays say (brute force over their rho_max).
TEST(VweObjective, PerCameraMinDepthLeavesOutTheNearPlanesOfCamerasAhead) {
  const CameraModel cam(testCalibration());
  ProjectiveVolume volume(volumeOptions(2), cam.width(), cam.height(), 250, 250, 173, 130);
  VweObjective obj(cam, &volume);
  const YawForwardModel truth(0.2, 3.0);
  const EventVector ev = makeEvents(cam, truth, 20000, 3);
  const VweEvaluation off = obj.voteOnly(ev, truth);
  volume.clear(obj.lastRays());
  obj.setPerCameraMinDepth(true);
  const VweEvaluation on = obj.voteOnly(ev, truth);
  EXPECT_EQ(on.rays, off.rays);
  EXPECT_LT(on.votes, off.votes);
  size_t cut = 0;
  for (const VolumeRay& r : obj.lastRays())
    if (r.rho_max < float(1.0 / volume.options().z_min_m)) ++cut;
  EXPECT_GT(cut, on.rays / 10);
  double s = 0;
  const double brute = bruteForceContrast(volume, obj.lastRays(), Contrast::kDensityPerVote, &s);
  EXPECT_NEAR(s, double(on.votes), 1e-4 * s);
  EXPECT_NEAR(on.contrast, brute, 1e-6 * brute);
  volume.clear(obj.lastRays());
}

TEST(VweObjective, GradientMatchesCentralFiniteDifferences) {
  const CameraModel cam(testCalibration());
  for (Contrast contrast : {Contrast::kVariance, Contrast::kDensityPerVote}) {
    ProjectiveVolume volume(volumeOptions(2, contrast), cam.width(), cam.height(), 250, 250, 173,
                            130);
    VweObjective obj(cam, &volume);
    const EventVector ev = makeEvents(cam, YawForwardModel(0.5, 0.4), 4000, 2);
    for (double w : {0.3, 0.45, 0.7}) {
      YawForwardModel m(w, 0.4);
      Eigen::VectorXd g;
      obj.evaluate(ev, m, &g);
      for (int k = 0; k < 2; ++k) {
        const double h = 1e-4;
        YawForwardModel mp = m, mm = m;
        (k == 0 ? mp.w_ : mp.v_) += h;
        (k == 0 ? mm.w_ : mm.v_) -= h;
        const double fd = (obj.evaluate(ev, mp).contrast - obj.evaluate(ev, mm).contrast) / (2 * h);
        EXPECT_NEAR(g[k], fd, 5e-3 * std::abs(fd) + 1e-9) << "param " << k << " at w=" << w;
      }
    }
  }
}

// What the density per vote is for: unfocused votes (rays that meet nothing) raise the variance,
// which grows with every vote in the grid, but lower the density per vote. So the variance
// rewards a trajectory for turning rays into the grid, focused or not; the density does not.
TEST(VweObjective, UnfocusedVotesRaiseTheVarianceButNotTheDensityPerVote) {
  const CameraModel cam(testCalibration());
  const YawForwardModel truth(0.5, 0.4);
  const EventVector ev = makeEvents(cam, truth, 4000, 5);
  for (Contrast contrast : {Contrast::kVariance, Contrast::kDensityPerVote}) {
    ProjectiveVolume volume(volumeOptions(1, contrast), cam.width(), cam.height(), 250, 250, 173,
                            130);
    VweObjective obj(cam, &volume);
    obj.voteOnly(ev, truth);
    const std::vector<VolumeRay> focused = obj.lastRays();
    volume.clear(focused);
    // As many rays again, each through its own random pixel: they meet nothing.
    std::vector<VolumeRay> more = focused;
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> u(0.0f, float(volume.width() - 1)),
        v(0.0f, float(volume.height() - 1));
    for (VolumeRay r : focused) {
      r.u0 = u(rng);
      r.v0 = v(rng);
      r.du = r.dv = 0.0f;  // the same pixel in every plane
      more.push_back(r);
    }
    size_t votes_focused = 0, votes_more = 0;
    const double c_focused = volume.contrastOfRays(focused, &votes_focused);
    const double c_more = volume.contrastOfRays(more, &votes_more);
    ASSERT_GT(votes_more, votes_focused + votes_focused / 2);
    if (contrast == Contrast::kVariance)
      EXPECT_GT(c_more, 1.05 * c_focused);
    else
      EXPECT_LT(c_more, 0.8 * c_focused);
  }
}

TEST(VweObjective, MultiThreadedEqualsSingleThreaded) {
  const CameraModel cam(testCalibration());
  ProjectiveVolume v1(volumeOptions(1), cam.width(), cam.height(), 250, 250, 173, 130);
  ProjectiveVolume v2(volumeOptions(2), cam.width(), cam.height(), 250, 250, 173, 130);
  VweObjective o1(cam, &v1), o2(cam, &v2);
  const EventVector ev = makeEvents(cam, YawForwardModel(0.5, 0.4), 3000, 3);
  const YawForwardModel m(0.4, 0.4);
  Eigen::VectorXd g1, g2;
  const double var1 = o1.evaluate(ev, m, &g1).contrast, var2 = o2.evaluate(ev, m, &g2).contrast;
  EXPECT_NEAR(var1, var2, 1e-9 * var1);
  EXPECT_NEAR(g1[0], g2[0], 1e-5 * g1.norm());
  EXPECT_NEAR(g1[1], g2[1], 1e-5 * g1.norm());
}

TEST(VweObjective, MaximumAtTheTrueYawRate) {
  const CameraModel cam(testCalibration());
  ProjectiveVolume volume(volumeOptions(2), cam.width(), cam.height(), 250, 250, 173, 130);
  VweObjective obj(cam, &volume);
  const double w_true = 25.0 / kDegPerRad;
  const EventVector ev = makeEvents(cam, YawForwardModel(w_true, 0.4), 6000, 4);
  double best = -1, best_w = 0;
  for (double w_deg = 0; w_deg <= 50; w_deg += 0.25) {
    const double var = obj.evaluate(ev, YawForwardModel(w_deg / kDegPerRad, 0.4)).contrast;
    if (var > best) best = var, best_w = w_deg;
  }
  EXPECT_NEAR(best_w, 25.0, 0.5);
}

TEST(VweObjective, SubsamplingIsDeterministicAndBounded) {
  EventVector ev(10000);
  for (size_t i = 0; i < ev.size(); ++i) ev[i].t_ns = int64_t(i);
  const EventVector a = subsampleEvents(ev, 1000, 7), b = subsampleEvents(ev, 1000, 7);
  ASSERT_EQ(a.size(), 1000u);
  for (size_t i = 0; i < a.size(); ++i) ASSERT_EQ(a[i].t_ns, b[i].t_ns);
  for (size_t i = 1; i < a.size(); ++i) ASSERT_GT(a[i].t_ns, a[i - 1].t_ns);
  EXPECT_GT(a.back().t_ns, 9000);  // spans the window
  EXPECT_EQ(subsampleEvents(ev, 20000, 7).size(), ev.size());
}

// A street's facade on one side, 5 m away, from 4 m ahead to the horizon (points uniform in
// inverse depth down to 400 m: uniform over the image), seen while driving straight at 7.5 m/s.
// A yaw error towards the facade only brings its points nearer; the opposite error moves its
// distant points past infinity. Planes that end at a finite depth lose those votes, so the
// facade pulls the yaw towards itself; planes continued through infinity (z_max_m < 0) see both
// errors alike. Both sides, two draws of points; the same plane spacing both ways.
TEST(VweObjective, PlanesThroughInfinityKeepADistantFacadeFromPullingTheYaw) {
  const CameraModel cam(testCalibration());
  {
    VolumeOptions o = volumeOptions(1);
    o.z_min_m = 4.5;
    o.z_max_m = -10.0;
    o.num_planes = 36;
    const ProjectiveVolume volume(o, cam.width(), cam.height(), 250, 250, 173, 130);
    EXPECT_NEAR(volume.planeDepth(0), 4.5, 1e-12);
    EXPECT_NEAR(volume.planeInverseDepth(35), -0.1, 1e-12);
    EXPECT_TRUE(std::isinf(volume.planeDepth(35)));  // past infinity: deeper than any depth
  }
  // The maximum over the yaw rate [deg/s], positive towards the facade.
  auto pullTowardsFacade = [&](double side, unsigned seed, double z_max_m, int num_planes) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(0, 1);
    std::vector<Vec3> facade;  // camera frame: x right, y down; 1.5 m below to 6 m above
    for (int i = 0; i < 3000; ++i)
      facade.emplace_back(5.0 * side, 1.5 - 7.5 * u(rng), 1.0 / (0.25 - 0.2475 * u(rng)));
    const EventVector ev =
        synthetic::pointEvents(cam, YawForwardModel(0.0, 7.5), facade, 8000, &rng, 0.15);
    VolumeOptions o = volumeOptions(2);
    o.grid_scale = 1.0;
    o.z_min_m = 4.5;
    o.z_max_m = z_max_m;
    o.num_planes = num_planes;
    ProjectiveVolume volume(o, cam.width(), cam.height(), 250, 250, 173, 130);
    VweObjective obj(cam, &volume);
    double best = -1, best_w = 0;
    for (double w_deg = -4; w_deg <= 4; w_deg += 0.125) {
      const double c = obj.evaluate(ev, YawForwardModel(w_deg / kDegPerRad, 7.5)).contrast;
      if (c > best) best = c, best_w = w_deg;
    }
    // YawForwardModel turns about the up axis (-y): positive w turns left, towards x < 0.
    return -best_w * side;
  };
  double finite_sum = 0, through_sum = 0;
  for (double side : {-1.0, 1.0})
    for (unsigned seed : {5u, 6u}) {
      const double finite = pullTowardsFacade(side, seed, 60.0, 30),
                   through = pullTowardsFacade(side, seed, -10.0, 36);
      std::printf(
          "[vwe objective] facade on the %s (seed %u): yaw pulled %.3f deg/s towards it "
          "with planes to 60 m, %.3f through infinity\n",
          side < 0 ? "left" : "right", seed, finite, through);
      EXPECT_LT(std::abs(through), std::abs(finite));
      finite_sum += finite;
      through_sum += through;
    }
  EXPECT_GT(finite_sum / 4, 0.6);              // measured 1.06
  EXPECT_LT(std::abs(through_sum / 4), 0.35);  // measured 0.125
}
