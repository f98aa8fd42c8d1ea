// EMVS on the standard simulated sequences, scored against the depth the simulator renders for
// each keyframe's true camera: the median relative depth error of the semi-dense points and the
// fraction within 5 %, with the true trajectory and with the pipeline's own (front-end +
// back-end, aligned to the truth by one Sim(3)).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "vwe_vo/eval/evaluation.h"
#include "vwe_vo/io/options_yaml.h"
#include "vwe_vo/mapping/emvs.h"
#include "vwe_vo/pipeline/offline_pipeline.h"
#include "vwe_vo/sim/event_simulator.h"
#include "vwe_vo/sim/scene.h"
#include "vwe_vo/sim/sequences.h"
#include "vwe_vo/sim/vehicle_trajectory.h"

using namespace vwe_vo;

namespace {

struct DepthScore {
  size_t keyframes = 0;
  size_t points = 0;     // points of all keyframes
  size_t compared = 0;   // points that project onto a pixel with a rendered surface
  double median = 0.0;   // median |z - z_true| / z_true of the compared points
  double within5 = 0.0;  // fraction of all points within 5 % of the true depth
};

enum class Poses { kTrue, kEstimated };

/// Simulates `name` up to t_to_s and maps the events from t_from_s on with the shipped
/// `config`'s mapping options, on the exact trajectory or on the pipeline's back-end trajectory
/// (run on the same events with the true speed as wheel odometry, aligned to the truth by
/// Sim(3)). Every keyframe's points are scored against the depth rendered from the keyframe's
/// true camera (nearest pixel of the point's projection).
DepthScore mapEvents(const std::string& name, const std::string& config, double t_from_s,
                     double t_to_s, Poses poses) {
  const sim::SequenceSpec spec = sim::findSequence(name);
  PipelineConfig cfg = loadPipelineConfig(std::string(VWE_VO_SOURCE_DIR) + "/config/" + config);
  const CameraModel camera(cfg.camera);
  const auto trajectory = sim::VehicleTrajectory::fromProfile(spec.profile, spec.trajectory);
  const sim::Scene scene = sim::buildScene(spec.scene, spec.seed, trajectory);
  sim::EventSimulator simulator(scene, camera, spec.T_base_cam, trajectory, spec.simulator);
  EventVector all;
  simulator.simulateUntil(secToNs(t_to_s), &all);
  const auto from = std::lower_bound(all.begin(), all.end(), secToNs(t_from_s),
                                     [](const PixelEvent& e, int64_t t) { return e.t_ns < t; });
  const EventVector events(from, all.end());
  const auto T_odom_cam_true = [&](int64_t t_ns) {
    return Pose3(trajectory.T_odom_base(t_ns) * spec.T_base_cam);
  };

  Trajectory3 estimate;  // base_link in the truth's odom (Sim(3)-aligned), kEstimated only
  if (poses == Poses::kEstimated) {
    cfg.frontend_only = false;
    OfflinePipeline pipeline(cfg);
    for (int64_t t = 0; t <= secToNs(t_to_s); t += secToNs(0.02))
      pipeline.addOdometry(t, trajectory.speed(t), trajectory.yawRate(t));
    pipeline.addEvents(all);
    pipeline.finish();
    const Trajectory3 est = pipeline.backendTrajectory();
    std::vector<Vec3> src, dst;
    for (const StampedPose& p : est) {
      src.push_back(p.T.translation());
      dst.push_back(trajectory.T_odom_base(p.t_ns).translation());
    }
    const Sim3 a = alignUmeyama(src, dst);
    for (const StampedPose& p : est) {
      Pose3 T = Pose3::Identity();
      T.linear() = a.R * p.T.linear();
      T.translation() = a.apply(p.T.translation());
      estimate.push_back({p.t_ns, T});
    }
  }

  EmvsMapper mapper(cfg.mapping, camera);
  mapper.addEvents(events);
  const auto pose = [&](int64_t t_ns, Pose3* T_odom_cam) {
    if (poses == Poses::kTrue) {
      if (t_ns < 0 || t_ns > trajectory.durationNs()) return false;
      *T_odom_cam = T_odom_cam_true(t_ns);
      return true;
    }
    Pose3 T_odom_base;
    if (!interpolateTrajectory(estimate, t_ns, &T_odom_base)) return false;
    *T_odom_cam = T_odom_base * spec.T_base_cam;
    return true;
  };
  std::vector<EmvsKeyframe> keyframes = mapper.process(pose, secToNs(t_to_s));
  EmvsKeyframe last;
  if (mapper.finish(&last)) keyframes.push_back(last);

  DepthScore s;
  s.keyframes = keyframes.size();
  sim::SceneRenderer renderer(scene, camera);
  std::vector<float> depth(size_t(camera.width()) * camera.height());
  std::vector<double> errors;
  size_t within5 = 0;
  for (const EmvsKeyframe& kf : keyframes) {
    renderer.render(T_odom_cam_true(kf.t_kf_ns), nullptr, depth.data());
    for (const MapPoint& m : kf.points_cam) {
      ++s.points;
      Vec2 uv;
      if (!camera.project(m.p.cast<double>(), &uv)) continue;
      const int x = int(std::lround(uv.x())), y = int(std::lround(uv.y()));
      if (x < 0 || y < 0 || x >= camera.width() || y >= camera.height()) continue;
      const double z_true = depth[size_t(y) * camera.width() + x];
      if (!(z_true > 0)) continue;
      const double e = std::abs(double(m.p.z()) - z_true) / z_true;
      errors.push_back(e);
      if (e <= 0.05) ++within5;
    }
  }
  s.compared = errors.size();
  if (!errors.empty()) {
    std::nth_element(errors.begin(), errors.begin() + errors.size() / 2, errors.end());
    s.median = errors[errors.size() / 2];
  }
  s.within5 = s.points ? double(within5) / s.points : 0.0;
  std::printf(
      "[emvs %s, %s poses] %zu keyframes, %zu points (%zu on a rendered surface): median rel. "
      "depth error "
      "%.2f %%, %.1f %% of the points within 5 %%\n",
      name.c_str(), poses == Poses::kTrue ? "true" : "estimated", s.keyframes, s.points, s.compared,
      100 * s.median, 100 * s.within5);
  return s;
}

}  // namespace

// Turtlebot in the lab room: straight, then the first 30 deg/s left turn.
TEST(EmvsOnSequences, IndoorLongWithTruePoses) {
  const DepthScore s = mapEvents("indoor_long", "vwe_vo.yaml", 1.0, 4.5, Poses::kTrue);
  ASSERT_GE(s.keyframes, 3u);
  ASSERT_GE(s.points, 2000u);
  EXPECT_GE(s.compared, s.points * 9 / 10);
  EXPECT_LE(s.median, 0.03);
  EXPECT_GE(s.within5, 0.60);
}

// Car in the street at 5-8 m/s: facades, parked cars, poles, the road.
TEST(EmvsOnSequences, StreetLongWithTruePoses) {
  const DepthScore s = mapEvents("street_long", "car_rigid.yaml", 1.0, 3.5, Poses::kTrue);
  ASSERT_GE(s.keyframes, 3u);
  ASSERT_GE(s.points, 2000u);
  EXPECT_GE(s.compared, s.points * 9 / 10);
  EXPECT_LE(s.median, 0.03);
  EXPECT_GE(s.within5, 0.60);
}

// The same on the pipeline's own trajectory (at most 8 % median after Sim(3)).
TEST(EmvsOnSequences, IndoorLongWithEstimatedPoses) {
  const DepthScore s = mapEvents("indoor_long", "vwe_vo.yaml", 1.0, 4.5, Poses::kEstimated);
  ASSERT_GE(s.keyframes, 3u);
  ASSERT_GE(s.points, 2000u);
  EXPECT_LE(s.median, 0.08);
}

// Measured 3.83 %, with car.yaml's back-end volumes also leaving out the parallax wedge; 11.0 %
// without it (10.5 % with per_camera_min_depth off). Before car.yaml's
// front-end ground mask it was 6.55 %: the masked arcs made street_drive's trajectory much better
// (yaw RPE 1.03 -> 0.69 deg/s, ATE 1.46 -> 0.22 %), but here the back-end's yaw swings by 2.6 deg
// in the first 3 s (Sim(3) scale 1.000, positions within 6 cm), and a keyframe's depth feels 0.3 s
// of yaw-rate error. Over 8 stretches from 1 to 29 s (80 planes) the median is 5.9 % on
// average, 5.0 % without the mask.
TEST(EmvsOnSequences, StreetLongWithEstimatedPoses) {
  const DepthScore s = mapEvents("street_long", "car_rigid.yaml", 1.0, 3.5, Poses::kEstimated);
  ASSERT_GE(s.keyframes, 3u);
  ASSERT_GE(s.points, 2000u);
  EXPECT_LE(s.median, 0.07);
}

namespace {

struct KeyframeScore {
  size_t points = 0;
  double median = 0.0, p90 = 0.0;  // relative depth error of the points on a rendered surface
};

/// One DSI (one keyframe) of the events in (t0_s, t1_s] on the true poses with the shipped
/// `config`'s mapping options, scored against the depth rendered at its reference view.
KeyframeScore mapOneKeyframe(const std::string& name, const std::string& config, double t0_s,
                             double t1_s) {
  const sim::SequenceSpec spec = sim::findSequence(name);
  const PipelineConfig cfg =
      loadPipelineConfig(std::string(VWE_VO_SOURCE_DIR) + "/config/" + config);
  const CameraModel camera(cfg.camera);
  const auto trajectory = sim::VehicleTrajectory::fromProfile(spec.profile, spec.trajectory);
  const sim::Scene scene = sim::buildScene(spec.scene, spec.seed, trajectory);
  sim::EventSimulator simulator(scene, camera, spec.T_base_cam, trajectory, spec.simulator);
  EventVector all, events;
  simulator.simulateUntil(secToNs(t1_s), &all);
  for (const PixelEvent& e : all)
    if (e.t_ns > secToNs(t0_s)) events.push_back(e);
  EmvsOptions o = cfg.mapping;
  o.kf_distance_m = 1e6;
  o.kf_rotation_deg = 179.0;
  o.max_events_per_keyframe = 100000000;
  o.max_pending_events = 100000000;
  const auto T_true = [&](int64_t t_ns) {
    return Pose3(trajectory.T_odom_base(t_ns) * spec.T_base_cam);
  };
  EmvsMapper mapper(o, camera);
  mapper.addEvents(events);
  mapper.process(
      [&](int64_t t_ns, Pose3* T) {
        *T = T_true(t_ns);
        return true;
      },
      secToNs(t1_s));
  EmvsKeyframe kf;
  EXPECT_TRUE(mapper.finish(&kf));
  sim::SceneRenderer renderer(scene, camera);
  std::vector<float> depth(size_t(camera.width()) * camera.height());
  renderer.render(T_true(kf.t_kf_ns), nullptr, depth.data());
  std::vector<double> errors;
  for (const MapPoint& m : kf.points_cam) {
    Vec2 uv;
    if (!camera.project(m.p.cast<double>(), &uv)) continue;
    const int x = int(std::lround(uv.x())), y = int(std::lround(uv.y()));
    if (x < 0 || y < 0 || x >= camera.width() || y >= camera.height()) continue;
    const double z_true = depth[size_t(y) * camera.width() + x];
    if (z_true > 0) errors.push_back(std::abs(double(m.p.z()) - z_true) / z_true);
  }
  KeyframeScore s;
  s.points = kf.points_cam.size();
  std::sort(errors.begin(), errors.end());
  if (!errors.empty()) {
    s.median = errors[errors.size() / 2];
    s.p90 = errors[size_t(0.9 * double(errors.size() - 1))];
  }
  std::printf(
      "[emvs %s one keyframe] %zu events, %zu voted, %zu points: median %.2f %%, 90th "
      "percentile %.1f %%\n",
      name.c_str(), events.size(), kf.counts.voted, s.points, 100 * s.median, 100 * s.p90);
  return s;
}

}  // namespace

// The keyframes of the comparison with rpg_emvs (Rebecq et al. 2018, uzh-rpg/rpg_emvs built with
// -O3, same events and true poses, 346x260x100 planes): indoors 650 k events over 0.525 m it kept
// 4229 points, median 1.66 %, 90th percentile 15 %; on the street 569 k events over 2 m, 2456
// points, median 2.08 %, 90th percentile 44 % (re-run with the reference view at this mapper's:
// 4221 points, 1.63 / 15.4 %; street 2488 points, 2.14 / 44.2 %). Measured here: 4376 points,
// 1.39 / 6.0 %; street (car.yaml, 64 planes) 3146 points, 2.14 / 44.1 % (bootstrap spread of the
// median 0.07, of the 90th percentile 0.4). Rays voting from volume.z_min_m in front of their own
// camera (per_camera_min_depth) took the 90th percentiles from 9.0 and 45.7 % (street median
// 2.03 %); the street's tail is mostly edge rounding: foreground points 6.6 m away whose nearest
// pixel shows the background at 12 m, as for rpg_emvs.
TEST(EmvsOnSequences, IndoorKeyframeAsDenseAsRpgEmvs) {
  const KeyframeScore s = mapOneKeyframe("indoor_long", "vwe_vo.yaml", 1.0, 2.5);
  EXPECT_GE(s.points, 4229u);
  EXPECT_LE(s.median, 0.0166);
  EXPECT_LE(s.p90, 0.10);  // rpg_emvs 15 %
}

TEST(EmvsOnSequences, StreetKeyframeAsDenseAsRpgEmvs) {
  const KeyframeScore s = mapOneKeyframe("street_long", "car_rigid.yaml", 1.0, 1.35);
  EXPECT_GE(s.points, 2488u);
  EXPECT_LE(s.median, 0.0225);  // rpg_emvs 2.08-2.14 %, within the bootstrap spread
  EXPECT_LE(s.p90, 0.46);
}
