// EMVS mapping against independent truths: exact events of known 3D points (a frontal wall,
// random points) seen along known trajectories, compared to the points' true depths; bad input
// (uncovered times, NaN poses, empty keyframes); the global map's bound; a PLY round trip.
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <cstdio>
#include <fstream>
#include <limits>
#include <memory>
#include <sstream>

#include "../common/synthetic_events.h"
#include "../common/test_camera.h"
#include "vwe_vo/io/config.h"
#include "vwe_vo/io/ply.h"
#include "vwe_vo/mapping/emvs.h"
#include "vwe_vo/trajectory/ackermann_arc.h"
#include "vwe_vo/vwe/projective_volume.h"
#include "vwe_vo/vwe/ray_builder.h"

using namespace vwe_vo;

namespace {

/// The options of these tests of the mapper's geometry and counting: every event voted, 100
/// planes, non-maximum suppression and a local-max ratio of 0.5 (the shipped selection is
/// scored on the simulated sequences in test_emvs_sequences.cpp).
EmvsOptions unitOptions() {
  EmvsOptions o;
  o.max_event_rate_hz = 0.0;
  o.volume.num_planes = 100;
  o.nms_radius_px = 1;
  o.local_max_ratio = 0.5;
  return o;
}

CameraCalibration testCalibration() {
  return test::syntheticCalibration(true);
}

const CameraModel& camera() {
  static const CameraModel cam(testCalibration());
  return cam;
}

/// Camera translating at constant velocity (reference camera frame), covering [from, to].
class LinearMotionModel : public TrajectoryModel {
 public:
  LinearMotionModel(const Vec3& v_mps, int64_t t_ref_ns, int64_t from_ns, int64_t to_ns)
      : v_(v_mps), t_ref_(t_ref_ns), from_(from_ns), to_(to_ns) {}
  int numParams() const override { return 0; }
  int64_t referenceTime() const override { return t_ref_; }
  bool covers(int64_t t_ns) const override { return t_ns >= from_ && t_ns <= to_; }
  Pose3 T_Cr_Ct(int64_t t_ns, PoseJacobian* jac = nullptr) const override {
    if (jac) jac->clear();
    return makePose(Mat3::Identity(), v_ * dtSec(t_ns, t_ref_));
  }

 private:
  Vec3 v_;
  int64_t t_ref_, from_, to_;
};

/// The odom frame is the reference camera of `truth`.
EmvsMapper::PoseFunction poseFunction(const TrajectoryModel& truth) {
  return [&truth](int64_t t, Pose3* T) {
    if (!truth.covers(t)) return false;
    *T = truth.T_Cr_Ct(t);
    return true;
  };
}

double median(std::vector<double> v) {
  if (v.empty()) return std::numeric_limits<double>::infinity();
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

// --- The frontal wall -------------------------------------------------------------------------

constexpr double kWallDepth = 3.0;

struct WallScene {
  LinearMotionModel truth{Vec3(0.6, 0.05, 0.2), secToNs(0.25), 0, secToNs(0.5)};
  EventVector events;
  WallScene() {
    std::mt19937 rng(7);
    const auto points = synthetic::frontalWallPoints(&rng, 3000, kWallDepth, 2.6, 1.9);
    events = synthetic::pointEvents(camera(), truth, points, 300000, &rng, 0.25);
  }
};
const WallScene& wall() {
  static const WallScene scene;
  return scene;
}

/// Relative depth errors of a keyframe of the wall (the wall is z = 3 m in odom, no rotation).
std::vector<double> wallDepthErrors(const EmvsKeyframe& kf) {
  const double true_z = kWallDepth - kf.T_odom_cam.translation().z();
  std::vector<double> err;
  for (const MapPoint& p : kf.points_cam) err.push_back(std::abs(p.p.z() - true_z) / true_z);
  return err;
}

/// The wall mapped by the incremental mapper in one keyframe over the whole 0.32 m baseline.
EmvsKeyframe mapWall(EmvsOptions o) {
  o.kf_distance_m = 1.0;
  EmvsMapper mapper(o, camera());
  mapper.addEvents(wall().events);
  EXPECT_TRUE(
      mapper.process(poseFunction(wall().truth), std::numeric_limits<int64_t>::max()).empty());
  EmvsKeyframe out;
  EXPECT_TRUE(mapper.finish(&out));
  return out;
}
const EmvsKeyframe& wallKeyframe() {
  static const EmvsKeyframe kf = mapWall(unitOptions());
  return kf;
}

/// RMS distance to the least-squares plane and its normal.
double planeRms(const std::vector<MapPoint>& points, Eigen::Vector3d* normal) {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const MapPoint& p : points) mean += p.p.cast<double>();
  mean /= double(points.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const MapPoint& p : points) {
    const Eigen::Vector3d d = p.p.cast<double>() - mean;
    cov += d * d.transpose();
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
  *normal = es.eigenvectors().col(0);
  double ss = 0.0;
  for (const MapPoint& p : points) ss += std::pow(normal->dot(p.p.cast<double>() - mean), 2);
  return std::sqrt(ss / double(points.size()));
}

TEST(Emvs, FrontalWallIsAtTheRightDepth) {
  const EmvsKeyframe& kf = wallKeyframe();
  ASSERT_GT(kf.points_odom.size(), 1000u);
  EXPECT_EQ(kf.counts.voted, wall().events.size());
  EXPECT_EQ(kf.counts.skipped_time + kf.counts.skipped_nan + kf.counts.skipped_outside, 0u);
  Eigen::Vector3d n;
  const double rms = planeRms(kf.points_odom, &n);
  const double med = median(wallDepthErrors(kf));
  std::printf(
      "[wall] %zu points, plane RMS %.4f m (%.2f %% of depth), normal (%.3f %.3f %.3f), median "
      "rel. error %.2f %%\n",
      kf.points_odom.size(), rms, 100 * rms / kWallDepth, n.x(), n.y(), n.z(), 100 * med);
  EXPECT_GT(std::abs(n.z()), 0.99);  // frontal
  EXPECT_LE(med, 0.019);             // measured 1.28 %
  // The reference view is the pose of a slice: the middle of a 0.5 ms slice of absolute time.
  const int64_t slice_ns = secToNs(EmvsOptions().volume.pose_slice_s);
  EXPECT_EQ(kf.t_kf_ns % slice_ns, slice_ns / 2);
  // The depth map holds exactly the cloud.
  EXPECT_EQ(size_t(cv::countNonZero(kf.depth_m)), kf.points_cam.size());
}

// per_camera_min_depth: a camera 1 m ahead of the reference votes from z_min_m in front of itself
// (depth > 3 m of the reference), not from the reference's nearest plane (2 m); behind the
// reference the reference's own range is the stricter one.
TEST(Emvs, RaysVoteFromTheNearestDepthInFrontOfTheirOwnCamera) {
  VolumeOptions vo = EmvsOptions().volume;  // full resolution, no margin, 40 planes
  vo.z_min_m = 2.0;
  vo.z_max_m = 40.0;
  vo.num_threads = 1;
  const CameraCalibration c = testCalibration();
  const VolumeRayBuilder<float> make_ray(c.fx, c.fy, c.cx, c.cy);
  for (const float min_depth : {0.0f, 2.0f}) {
    ProjectiveVolume volume(vo, c.width, c.height, c.fx, c.fy, c.cx, c.cy);
    const RayPose<float> pose(Eigen::Matrix3f::Identity(), Eigen::Vector3f(0.0f, 0.0f, 1.0f),
                              min_depth);
    EXPECT_FLOAT_EQ(pose.rho_max, 1.0f / (1.0f + min_depth));
    VolumeRay ray;
    ASSERT_TRUE(make_ray(pose, Eigen::Vector3f(0.05f, 0.02f, 1.0f).normalized(), &ray));
    volume.vote({ray}, false);
    for (int l = 0; l < volume.numPlanes(); ++l) {
      double plane_sum = 0.0;
      for (int y = 0; y < volume.height(); ++y)
        for (int x = 0; x < volume.width(); ++x) plane_sum += volume.at(x, y, l);
      const double z = volume.planeDepth(l);
      if (z > 1.0 + min_depth + 1e-3)
        EXPECT_NEAR(plane_sum, 1.0, 1e-4) << "plane at " << z << " m, min_depth " << min_depth;
      else
        EXPECT_EQ(plane_sum, 0.0) << "plane at " << z << " m, min_depth " << min_depth;
    }
  }
  EXPECT_EQ(
      RayPose<float>(Eigen::Matrix3f::Identity(), Eigen::Vector3f(0.0f, 0.0f, -3.0f), 2.0f).rho_max,
      std::numeric_limits<float>::infinity());
}

TEST(Emvs, FrontalWallIsPlanar) {
  Eigen::Vector3d n;
  EXPECT_LE(planeRms(wallKeyframe().points_odom, &n), 0.02 * kWallDepth);  // measured 1.54 %
}

// The refinement must beat the plane spacing. With the reference view in the middle of the
// events (as the mapper does) the rays spread symmetrically around a point and the peak
// centroid in inverse depth finds the depth between planes.
TEST(Emvs, SubpixelRefinementBeatsPlainArgmax) {
  EmvsOptions o = unitOptions();
  o.volume.num_planes = 60;  // coarser planes: the refinement must beat their spacing
  const EmvsKeyframe refined = mapWall(o);
  o.subpixel = false;
  const EmvsKeyframe plain = mapWall(o);
  const double med_refined = median(wallDepthErrors(refined)),
               med_plain = median(wallDepthErrors(plain));
  std::printf("[subpixel] median rel. error: argmax %.2f %%, refined in inverse depth %.2f %%\n",
              100 * med_plain, 100 * med_refined);
  ASSERT_GT(refined.points_cam.size(), 1000u);
  EXPECT_LE(med_refined, 0.006);             // measured 0.39 %
  EXPECT_LT(med_refined, 0.15 * med_plain);  // measured 0.39 % vs 4.08 %
}

// --- Random points along an Ackermann arc -------------------------------------------------------

/// A camera looking to the left of a vehicle turning left at 2 m/s (a forward-facing camera sees
/// too little parallax near the focus of expansion for 3 % at 8 m with this baseline), 400 random
/// points at 1-8 m, events over 0.8 m of travel.
struct ArcScene {
  std::unique_ptr<AckermannArcModel> truth;
  std::vector<Vec3> points;
  EventVector events;
  ArcScene() {
    Pose3 T_base_cam = defaultTBaseCam();
    Mat3 R_base_cam;
    R_base_cam.col(0) = Vec3(1, 0, 0);   // camera x (right) = vehicle forward
    R_base_cam.col(1) = Vec3(0, 0, -1);  // camera y (down)
    R_base_cam.col(2) = Vec3(0, 1, 0);   // camera z (optical axis) = vehicle left
    T_base_cam.linear() = R_base_cam;
    truth =
        std::make_unique<AckermannArcModel>(0.3, 2.0, 0, T_base_cam, secToNs(-0.2), secToNs(0.2));
    events = synthetic::randomPointEvents(camera(), *truth, 300000, 11, 0.2, 400, &points);
  }
};
const ArcScene& arc() {
  static const ArcScene scene;
  return scene;
}

EmvsOptions arcOptions() {
  EmvsOptions o = unitOptions();
  o.kf_distance_m = 0.6;
  o.volume.z_min_m = 0.8;
  o.volume.z_max_m = 10.0;
  o.max_depth_m = 10.0;
  o.outlier_radius_m = 0.0;  // isolated points are the scene here
  return o;
}

struct DepthAccuracy {
  double median = 0.0;   // median relative depth error of the matched points
  double within5 = 0.0;  // fraction of the points (matched or not) within 5 % of the true depth
  size_t compared = 0, unmatched = 0, ambiguous = 0;
};

/// Truth per recovered point: the true point projecting nearest to it in the keyframe's virtual
/// pinhole (within 2 px); points with several candidates of different depth are left out.
DepthAccuracy arcAccuracy(const EmvsKeyframe& kf, const ProjectiveVolume& vol) {
  const Pose3 T_kf_odom = kf.T_odom_cam.inverse();
  std::vector<Vec3> uvz;
  for (const Vec3& p : arc().points) {
    const Vec3 q = T_kf_odom * p;
    if (q.z() > 0.1)
      uvz.emplace_back(vol.fx() * q.x() / q.z() + vol.cx(), vol.fy() * q.y() / q.z() + vol.cy(),
                       q.z());
  }
  std::vector<double> err;
  DepthAccuracy a;
  size_t within5 = 0;
  for (const MapPoint& mp : kf.points_cam) {
    const Vec3 p = mp.p.cast<double>();
    const Vec2 uv(vol.fx() * p.x() / p.z() + vol.cx(), vol.fy() * p.y() / p.z() + vol.cy());
    double best = 4.0, z_true = 0.0, z_lo = 1e9, z_hi = 0.0;
    for (const Vec3& t : uvz) {
      const double d2 = (t.head<2>() - uv).squaredNorm();
      if (d2 > 4.0) continue;
      z_lo = std::min(z_lo, t.z());
      z_hi = std::max(z_hi, t.z());
      if (d2 < best) best = d2, z_true = t.z();
    }
    if (z_true == 0.0) {
      ++a.unmatched;
      continue;
    }
    if (z_hi > 1.05 * z_lo) {
      ++a.ambiguous;
      continue;
    }
    err.push_back(std::abs(p.z() - z_true) / z_true);
    within5 += err.back() <= 0.05;
  }
  a.compared = err.size();
  a.median = median(err);
  a.within5 = double(within5) / double(std::max<size_t>(1, err.size() + a.unmatched));
  return a;
}

TEST(Emvs, RandomPointsAlongAnArc) {
  EmvsMapper mapper(arcOptions(), camera());
  mapper.addEvents(arc().events);
  std::vector<EmvsKeyframe> kfs =
      mapper.process(poseFunction(*arc().truth), std::numeric_limits<int64_t>::max());
  EmvsKeyframe last;
  ASSERT_TRUE(mapper.finish(&last));
  kfs.push_back(last);
  ASSERT_EQ(kfs.size(), 2u);
  const EmvsKeyframe& kf = kfs.front();
  // The first keyframe spans 0.6 m of travel; its reference view lies inside that span.
  const Pose3 T_begin0 = arc().truth->T_Cr_Ct(kf.t_begin_ns),
              T_begin1 = arc().truth->T_Cr_Ct(kfs[1].t_begin_ns);
  EXPECT_NEAR((T_begin0.inverse() * T_begin1).translation().norm(), 0.6, 0.01);
  EXPECT_GT(kf.t_kf_ns, kf.t_begin_ns);
  EXPECT_LT(kf.t_kf_ns, kf.t_end_ns);
  EXPECT_EQ(kf.counts.voted + kfs[1].counts.voted, arc().events.size());
  const DepthAccuracy a = arcAccuracy(kf, mapper.volume());
  std::printf(
      "[points] %zu points: %zu compared, %zu unmatched, %zu ambiguous; median rel. error %.2f %%, "
      "%.1f %% within 5 %%\n",
      kf.points_cam.size(), a.compared, a.unmatched, a.ambiguous, 100 * a.median, 100 * a.within5);
  ASSERT_GT(a.compared, 300u);
  EXPECT_LE(a.median, 0.0078);  // measured 0.52 %
  EXPECT_GE(a.within5, 0.49);   // measured 73.9 %
}

TEST(Emvs, RandomPointsMostlyWithinFivePercent) {
  EmvsMapper mapper(arcOptions(), camera());
  mapper.addEvents(arc().events);
  auto kfs = mapper.process(poseFunction(*arc().truth), std::numeric_limits<int64_t>::max());
  ASSERT_FALSE(kfs.empty());
  EXPECT_GE(arcAccuracy(kfs.front(), mapper.volume()).within5, 0.6);  // measured 73.9 %
}

// --- Bad input ----------------------------------------------------------------------------------

TEST(Emvs, EventsOutsideTheTrajectoryAreSkippedAndCounted) {
  const LinearMotionModel covered(Vec3(0.6, 0.05, 0.2), secToNs(0.25), secToNs(0.1), secToNs(0.4));
  size_t outside = 0;
  for (const PixelEvent& e : wall().events) outside += !covered.covers(e.t_ns);
  ASSERT_GT(outside, 1000u);
  EmvsOptions o = unitOptions();
  o.kf_distance_m = 1.0;
  EmvsMapper mapper(o, camera());
  mapper.addEvents(wall().events);
  auto kfs = mapper.process(poseFunction(covered), std::numeric_limits<int64_t>::max());
  EmvsKeyframe last;
  ASSERT_TRUE(mapper.finish(&last));
  kfs.push_back(last);
  size_t skipped = 0, voted = 0;
  for (const auto& kf : kfs) skipped += kf.counts.skipped_time, voted += kf.counts.voted;
  EXPECT_EQ(skipped, outside);
  EXPECT_EQ(voted, wall().events.size() - outside);
  EXPECT_GE(kfs.front().t_kf_ns, secToNs(0.1));
  EXPECT_LE(kfs.back().t_end_ns, secToNs(0.4));
  EXPECT_EQ(mapper.pendingEvents(), 0u);
}

TEST(Emvs, EventsAfterTheFinalTimeWaitForTheTrajectory) {
  EmvsOptions o = unitOptions();
  o.kf_distance_m = 1.0;
  EmvsMapper mapper(o, camera());
  mapper.addEvents(wall().events);
  mapper.process(poseFunction(wall().truth), secToNs(0.2));
  size_t later = 0;
  for (const PixelEvent& e : wall().events) later += e.t_ns > secToNs(0.2);
  EXPECT_EQ(mapper.pendingEvents(), later);
  // Out-of-order events are refused and counted, events outside the sensor counted.
  PixelEvent old = wall().events.front(), off = wall().events.back();
  off.x = 400;
  mapper.addEvents({old, off});
  EXPECT_EQ(mapper.droppedOutOfOrder(), 1u);
  mapper.process(poseFunction(wall().truth), std::numeric_limits<int64_t>::max());
  EmvsKeyframe kf;
  ASSERT_TRUE(mapper.finish(&kf));
  EXPECT_EQ(kf.counts.skipped_outside, 1u);
  EXPECT_EQ(kf.counts.voted, wall().events.size());
}

TEST(Emvs, EventsWaitingTooLongAreThinnedEvenlyNotCut) {
  // A trajectory that lags: the buffer is thinned to every second event whenever it overflows,
  // so it keeps the whole time span (the keyframe it waits for keeps its start) in bounded memory.
  EmvsOptions o = unitOptions();
  o.kf_distance_m = 1.0;
  o.max_pending_events = wall().events.size() / 5;
  EmvsMapper mapper(o, camera());
  for (size_t i = 0; i < wall().events.size(); i += 1000) {
    const size_t end = std::min(wall().events.size(), i + 1000);
    mapper.addEvents(
        EventVector(wall().events.begin() + long(i), wall().events.begin() + long(end)));
    ASSERT_LE(mapper.pendingEvents(), o.max_pending_events);
  }
  EXPECT_GT(mapper.thinnedPending(), 0u);
  EXPECT_EQ(mapper.pendingEvents() + mapper.thinnedPending(), wall().events.size());
  mapper.process(poseFunction(wall().truth), std::numeric_limits<int64_t>::max());
  EmvsKeyframe kf;
  ASSERT_TRUE(mapper.finish(&kf));
  EXPECT_EQ(kf.counts.events, wall().events.size() - mapper.thinnedPending());
  // The keyframe spans the events' whole time: its first event is within the first 2 % of it.
  const int64_t t0 = wall().events.front().t_ns, t1 = wall().events.back().t_ns;
  EXPECT_LT(dtSec(kf.t_begin_ns, t0), 0.02 * dtSec(t1, t0));
  // One batch of more than twice the bound: thinned as often as it takes.
  o.max_pending_events = 1000;
  EmvsMapper small(o, camera());
  small.addEvents(EventVector(wall().events.begin(), wall().events.begin() + 5000));
  EXPECT_LE(small.pendingEvents(), 1000u);
  EXPECT_EQ(small.pendingEvents() + small.thinnedPending(), 5000u);
}

TEST(Emvs, RateLimitKeepsEventsEvenlyAndCountsTheRest) {
  // Thinning events, not keyframes. 100k events/s for 1 s, limited to 30k events/s: 30k kept
  // (within the 10 ms burst), as many in each half second, the rest counted as thinned.
  EventVector events;
  for (int i = 0; i < 100000; ++i) events.push_back({secToNs(1.0) + int64_t(i) * 10000, 10, 10, 1});
  EmvsOptions o;
  o.max_event_rate_hz = 30000;
  o.rate_limit_whole_keyframes = false;
  EmvsMapper mapper(o, camera());
  mapper.addEvents(EventVector(events.begin(), events.begin() + 50000));
  const size_t first_half = mapper.pendingEvents();
  mapper.addEvents(EventVector(events.begin() + 50000, events.end()));
  const size_t kept = mapper.pendingEvents();
  EXPECT_NEAR(double(kept), 30000.0, 301.0);
  EXPECT_NEAR(double(first_half), double(kept - first_half), 2.0);
  EXPECT_EQ(kept + mapper.thinned(), events.size());
  o.max_event_rate_hz = -1;
  EXPECT_THROW(o.validate(), std::invalid_argument);
}

TEST(Emvs, WholeKeyframeRateLimitVotesKeyframesWithAllTheirEvents) {
  // 100k events/s for 4 s on a camera moving 0.6 m/s: a keyframe every 0.12 m (0.2 s, 20k
  // events), limited to 50k events/s by leaving out whole keyframes. The budget starts at and
  // saves up to one second's worth, and a keyframe passes while it is not in debt: over 4 s at
  // most 5 s of budget plus one keyframe are voted, and at least 4 s of budget minus one keyframe.
  const double rate = 50000.0, duration_s = 4.0;
  const LinearMotionModel truth(Vec3(0.6, 0.0, 0.0), 0, 0, secToNs(duration_s));
  EventVector events;
  for (int i = 0; i < 400000; ++i)
    events.push_back({int64_t(i) * 10000, uint16_t(10 + i % 300), uint16_t(10 + (i / 300) % 200),
                      int8_t(i % 2 ? 1 : -1)});
  EmvsOptions o = unitOptions();
  o.volume.num_planes = 20;
  o.kf_distance_m = 0.12;
  o.max_event_rate_hz = rate;
  o.rate_limit_whole_keyframes = true;
  EmvsMapper mapper(o, camera());
  mapper.addEvents(events);
  EXPECT_EQ(mapper.thinned(), 0u);  // nothing is thinned on arrival
  std::vector<EmvsKeyframe> kfs = mapper.process(poseFunction(truth), secToNs(duration_s));
  EmvsKeyframe last;
  if (mapper.finish(&last)) kfs.push_back(last);
  size_t voted = 0;
  for (const EmvsKeyframe& kf : kfs) {
    // A keyframe voted has every one of its events (the rays behind the camera aside).
    EXPECT_EQ(kf.counts.voted + kf.counts.skipped_behind, kf.counts.events);
    EXPECT_GT(kf.counts.events, 15000u);
    voted += kf.counts.events;
  }
  const size_t per_keyframe = 20000;
  EXPECT_GT(mapper.keyframesSkipped(), 0u);
  EXPECT_EQ(kfs.size(), mapper.numKeyframes());  // numKeyframes counts those voted
  EXPECT_EQ(voted + mapper.thinned(), events.size());
  EXPECT_LE(double(voted), rate * (duration_s + 1.0) + per_keyframe);
  EXPECT_GE(double(voted), rate * duration_s - per_keyframe);
  // The same stream without the limit votes everything.
  o.max_event_rate_hz = 0.0;
  EmvsMapper all(o, camera());
  all.addEvents(events);
  size_t all_voted = 0;
  for (const EmvsKeyframe& kf : all.process(poseFunction(truth), secToNs(duration_s)))
    all_voted += kf.counts.events;
  if (all.finish(&last)) all_voted += last.counts.events;
  EXPECT_EQ(all_voted, events.size());
  EXPECT_EQ(all.keyframesSkipped(), 0u);
}

TEST(Emvs, NanPosesAreSkippedAndCounted) {
  const auto& truth = wall().truth;
  auto with_nan = [&truth](int64_t t, Pose3* T) {
    if (!truth.covers(t)) return false;
    *T = truth.T_Cr_Ct(t);
    if (t >= secToNs(0.2) && t < secToNs(0.25))
      T->translation().x() = std::numeric_limits<double>::quiet_NaN();
    return true;
  };
  size_t bad = 0;
  for (const PixelEvent& e : wall().events) bad += e.t_ns >= secToNs(0.2) && e.t_ns < secToNs(0.25);
  EmvsOptions o = unitOptions();
  o.kf_distance_m = 1.0;
  EmvsMapper mapper(o, camera());
  mapper.addEvents(wall().events);
  EXPECT_TRUE(mapper.process(with_nan, std::numeric_limits<int64_t>::max()).empty());
  EmvsKeyframe kf;
  ASSERT_TRUE(mapper.finish(&kf));
  EXPECT_EQ(kf.counts.skipped_nan, bad);
  EXPECT_EQ(kf.counts.voted, wall().events.size() - bad);
  for (const MapPoint& p : kf.points_odom) ASSERT_TRUE(p.p.allFinite());
  EXPECT_GT(kf.points_odom.size(), 1000u);
}

TEST(Emvs, EmptyKeyframeGivesAnEmptyResult) {
  const LinearMotionModel model(Vec3(0.5, 0, 0), 0, 0, secToNs(1.0));
  const EmvsOptions o = unitOptions();
  const CameraCalibration& c = camera().calibration();
  const ProjectiveVolume no_votes(o.volume, c.width, c.height, c.fx, c.fy, c.cx, c.cy);
  EmvsKeyframe kf;
  extractKeyframe(no_votes, o, Pose3::Identity(), &kf);
  EXPECT_TRUE(kf.points_cam.empty());
  EXPECT_TRUE(kf.points_odom.empty());
  EXPECT_EQ(cv::countNonZero(kf.depth_m), 0);
  EXPECT_EQ(kf.counts.voted, 0u);

  EmvsMapper mapper(unitOptions(), camera());
  EXPECT_TRUE(mapper.process(poseFunction(model), std::numeric_limits<int64_t>::max()).empty());
  EmvsKeyframe none;
  EXPECT_FALSE(mapper.finish(&none));
  // Events the trajectory never covers start no keyframe.
  PixelEvent e;
  e.t_ns = secToNs(5.0);
  mapper.addEvents({e});
  EXPECT_TRUE(mapper.process(poseFunction(model), std::numeric_limits<int64_t>::max()).empty());
  EXPECT_FALSE(mapper.hasKeyframe());
}

TEST(Emvs, OptionsNameTheBadField) {
  EmvsOptions o;
  o.median_filter_size = 4;
  try {
    o.validate();
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("median_filter_size"), std::string::npos);
  }
  o = EmvsOptions();
  o.min_ray_contrast = -1.0;
  try {
    o.validate();
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("mapping.min_ray_contrast"), std::string::npos);
  }
  o = EmvsOptions();
  o.kf_distance_m = -1;
  EXPECT_THROW(EmvsMapper(o, camera()), std::invalid_argument);
  GlobalMapOptions g;
  g.max_points = 0;
  EXPECT_THROW(GlobalMap{g}, std::invalid_argument);
}

TEST(Emvs, RadiusOutlierRemoval) {
  std::vector<MapPoint> pts;
  for (int i = 0; i < 10; ++i) pts.push_back({Eigen::Vector3f(0.01f * i, 0, 1), 1.0f});
  pts.push_back({Eigen::Vector3f(1, 1, 1), 1.0f});
  EXPECT_EQ(removeRadiusOutliers(&pts, 0.05, 3), 1u);
  EXPECT_EQ(pts.size(), 10u);
}

// --- Global map and PLY
// ---------------------------------------------------------------------------

TEST(Emvs, GlobalMapIsBoundedAndDownsampled) {
  GlobalMapOptions o;
  o.voxel_size_m = 0.1;
  o.max_points = 1000;
  GlobalMap map(o);
  // 20 points in one voxel -> one centroid.
  std::vector<MapPoint> same;
  for (int i = 0; i < 20; ++i)
    same.push_back({Eigen::Vector3f(0.51f + 0.001f * i, 0.55f, 0.55f), 2.0f});
  map.insert(same);
  ASSERT_EQ(map.size(), 1u);
  EXPECT_NEAR(map.points()[0].p.x(), 0.5195, 1e-4);
  map.clear();
  // Three clouds of 800 distinct voxels: at most 1000 kept, the newest cloud entirely.
  for (int c = 0; c < 3; ++c) {
    std::vector<MapPoint> cloud;
    for (int i = 0; i < 800; ++i)
      cloud.push_back({Eigen::Vector3f(0.1f * i + 0.05f, 0.1f * c + 0.05f, 0.05f), 1.0f});
    map.insert(cloud);
    EXPECT_LE(map.size(), o.max_points);
  }
  EXPECT_EQ(map.size(), 1000u);
  EXPECT_EQ(map.dropped(), 1400u);
  size_t newest = 0;
  for (const MapPoint& p : map.points()) newest += std::abs(p.p.y() - 0.25f) < 1e-3f;
  EXPECT_EQ(newest, 800u);
}

TEST(Emvs, PlyRoundTrip) {
  PlyCloud cloud;
  for (int i = 0; i < 50; ++i) {
    cloud.xyz.emplace_back(0.1f * i, -0.5f * i, 3.0f + i);
    cloud.rgb.push_back({uint8_t(i), uint8_t(2 * i), uint8_t(255 - i)});
    cloud.confidence.push_back(0.25f * i);
  }
  const std::string path = ::testing::TempDir() + "emvs_roundtrip.ply";
  writePly(path, cloud);
  std::ifstream f(path, std::ios::binary);
  ASSERT_TRUE(bool(f));
  std::string line;
  std::vector<std::string> header;
  while (std::getline(f, line) && line != "end_header") header.push_back(line);
  ASSERT_EQ(line, "end_header");
  ASSERT_GE(header.size(), 2u);
  EXPECT_EQ(header[0], "ply");
  EXPECT_EQ(header[1], "format binary_little_endian 1.0");
  std::vector<std::string> props;
  size_t count = 0;
  for (const auto& h : header) {
    std::istringstream ss(h);
    std::string a, b, c;
    ss >> a >> b >> c;
    if (a == "element" && b == "vertex") count = std::stoul(c);
    if (a == "property") props.push_back(b + " " + c);
  }
  EXPECT_EQ(count, 50u);
  const std::vector<std::string> expected = {"float x",         "float y",     "float z",
                                             "uchar red",       "uchar green", "uchar blue",
                                             "float confidence"};
  EXPECT_EQ(props, expected);
  for (int i = 0; i < 50; ++i) {
    float xyz[3], conf;
    uint8_t rgb[3];
    f.read(reinterpret_cast<char*>(xyz), 12);
    f.read(reinterpret_cast<char*>(rgb), 3);
    f.read(reinterpret_cast<char*>(&conf), 4);
    ASSERT_TRUE(bool(f));
    EXPECT_EQ(Eigen::Vector3f(xyz[0], xyz[1], xyz[2]), cloud.xyz[i]);
    EXPECT_EQ(rgb[0], cloud.rgb[i][0]);
    EXPECT_EQ(rgb[1], cloud.rgb[i][1]);
    EXPECT_EQ(rgb[2], cloud.rgb[i][2]);
    EXPECT_EQ(conf, cloud.confidence[i]);
  }
  char extra;
  EXPECT_FALSE(bool(f.read(&extra, 1)));  // nothing after the last vertex
  std::remove(path.c_str());
  cloud.rgb.pop_back();
  EXPECT_THROW(writePly(path, cloud), std::invalid_argument);
}

}  // namespace
