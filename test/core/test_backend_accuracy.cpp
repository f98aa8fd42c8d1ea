// Regression of the back-end's accuracy on the simulator's standard sequences (generated in
// process with their fixed seeds), with the shipped configuration: the front-end + back-end
// pipeline as vwe_vo_offline runs it, scored with the paper's metric against the ground truth.
// The back-end must beat the front-end alone (rotation RMSE 10-20 % lower) and
// keep the scale. Thresholds carry margin over the measured values printed by the test.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>

#include "vwe_vo/eval/evaluation.h"
#include "vwe_vo/io/options_yaml.h"
#include "vwe_vo/pipeline/offline_pipeline.h"
#include "vwe_vo/sim/imu_simulator.h"
#include "vwe_vo/sim/scene.h"
#include "vwe_vo/sim/sequences.h"

using namespace vwe_vo;

namespace {

struct PipelineRun {
  EvaluationResult frontend, backend;
  size_t nonfinite_poses = 0;
  double yaw_bias_error_deg_s = 0.0;  // with the IMU: the estimated yaw-rate bias - the true one
  double yaw_bias_deg_s = 0.0;        // ... the true one
  double max_tilt_deg = 0.0;          // the back-end poses' largest angle off the vertical
  BackendStats backend_stats;
};

/// Simulates `name` and runs front-end + back-end on it with config/<config>, the speed from
/// the simulated wheel speed (as --use-odom gives it from /odom) and the gyro's yaw rate (as
/// vwe_vo_offline gives it from the bag's /dvs/imu), both noise-free here (the bag's carry a 1 %
/// speed scale error, white noise and a gyro bias). Nothing before start_s is fed
/// (a system started late: its windows fall at other times). With `imu`, the back-end also fuses
/// the sequence's DAVIS-like IMU (noise and bias, as --use-imu on its bag). Without `odom`, no
/// speed is fed: the front-end drives at the config's nominal speed and follows the back-end's
/// (vwe_vo_offline without --use-odom).
PipelineRun run(const std::string& name, const std::string& config_file = "vwe_vo.yaml",
                double start_s = 0.0, bool imu = false, bool odom = true) {
  const sim::SequenceSpec spec = sim::findSequence(name);
  PipelineConfig config =
      loadPipelineConfig(std::string(VWE_VO_SOURCE_DIR) + "/config/" + config_file);
  config.T_base_cam = spec.T_base_cam;
  const CameraModel camera(config.camera);
  const auto trajectory = sim::VehicleTrajectory::fromProfile(spec.profile, spec.trajectory);
  sim::EventSimulator simulator(sim::buildSequenceScene(spec, trajectory), camera, spec.T_base_cam,
                                trajectory, spec.simulator);
  OfflinePipeline pipeline(config);
  if (!odom) {
    pipeline.setFrontendFollowsBackend(FollowOptions(), false);
    pipeline.setSpeedsMeasured(false);
  }
  std::unique_ptr<sim::ImuSimulator> imu_sim;
  int64_t next_imu_ns = 0;
  if (imu) {
    imu_sim = std::make_unique<sim::ImuSimulator>(trajectory, spec.T_base_cam, spec.imu);
    pipeline.enableImu();
  }
  EventVector chunk;
  for (int64_t t = 0; t < trajectory.durationNs();) {
    const int64_t t1 = std::min(trajectory.durationNs(), t + secToNs(0.05));
    chunk.clear();  // simulateUntil appends
    simulator.simulateUntil(t1, &chunk);
    if (t1 > secToNs(start_s)) {
      if (odom) pipeline.addOdometry(t1, trajectory.speed(t1), trajectory.yawRate(t1));
      pipeline.addGyro(t1, trajectory.yawRate(t1));
      chunk.erase(chunk.begin(),
                  std::lower_bound(chunk.begin(), chunk.end(), secToNs(start_s),
                                   [](const PixelEvent& e, int64_t t) { return e.t_ns < t; }));
      for (; imu_sim && next_imu_ns < t1; next_imu_ns += imu_sim->periodNs())
        if (next_imu_ns >= secToNs(start_s)) pipeline.addImu(imu_sim->measure(next_imu_ns));
      pipeline.addEvents(chunk);
    }
    t = t1;
  }
  pipeline.finish();
  const Trajectory3 gt = trajectory.sample(secToNs(0.005));
  const Trajectory3 be = pipeline.backendTrajectory();
  PipelineRun r;
  r.backend_stats = pipeline.backend()->stats();
  for (const StampedPose& p : be) {
    r.nonfinite_poses += !p.T.matrix().allFinite();
    const double up = std::clamp(p.T.linear()(2, 2), -1.0, 1.0);
    r.max_tilt_deg = std::max(r.max_tilt_deg, std::acos(up) * kDegPerRad);
  }
  if (imu_sim) {
    // The yaw-rate bias: the camera-frame gyro bias along base_link's up axis.
    const Vec3 up_cam = spec.T_base_cam.linear().transpose() * Vec3::UnitZ();
    r.yaw_bias_deg_s = up_cam.dot(imu_sim->gyroBias()) * kDegPerRad;
    r.yaw_bias_error_deg_s =
        pipeline.backend()->imuStats().yaw_bias_rad_s * kDegPerRad - r.yaw_bias_deg_s;
  }
  const EvaluationOptions o;
  r.frontend = evaluate(gt, pipeline.frontendTrajectory(), o);
  r.backend = evaluate(gt, be, o);
  std::printf(
      "[backend accuracy] %s from %.2f s: rotation RMSE front-end %.3f, back-end %.3f deg/s (%.0f "
      "%% lower); "
      "back-end translation direction %.3f deg/s, ATE %.2f %% of %.1f m, tracked %.2f, "
      "scale per %.0f m %.3f-%.3f\n",
      name.c_str(), start_s, r.frontend.rpe.rot_rmse_deg_s, r.backend.rpe.rot_rmse_deg_s,
      100.0 * (1.0 - r.backend.rpe.rot_rmse_deg_s / r.frontend.rpe.rot_rmse_deg_s),
      r.backend.rpe.trans_dir_rmse_deg_s, r.backend.ate_percent_of_path, r.backend.path_length_m,
      r.backend.tracked_fraction, o.segment_m, r.backend.scale_drift.min_ratio,
      r.backend.scale_drift.max_ratio);
  return r;
}

/// The targets indoors: at least 20 % below the front-end, translation direction
/// <= 0.3 deg/s, ATE <= 2 %, no NaN (indoor_long: through its 3 s standstill), tracked.
void expectIndoorTargets(const PipelineRun& r, double max_rot_rmse_deg_s,
                         double max_trans_dir_rmse_deg_s, double max_ate_percent) {
  EXPECT_EQ(r.nonfinite_poses, 0u);
  EXPECT_LE(r.backend.rpe.rot_rmse_deg_s, 0.8 * r.frontend.rpe.rot_rmse_deg_s);
  EXPECT_LE(r.backend.rpe.rot_rmse_deg_s, max_rot_rmse_deg_s);
  EXPECT_LE(r.backend.rpe.trans_dir_rmse_deg_s, max_trans_dir_rmse_deg_s);
  EXPECT_LE(r.backend.ate_percent_of_path, max_ate_percent);
  EXPECT_GE(r.backend.tracked_fraction, 0.95);
}

}  // namespace

// Measured: back-end 0.137 deg/s against the front-end's 0.270 (49 % lower), translation
// direction 0.075 deg/s, ATE 0.04 %.
TEST(BackendAccuracy, IndoorCircle) {
  expectIndoorTargets(run("indoor_circle"), 0.24, 0.14, 0.09);
}

// Measured: 0.200 against 0.385 (48 % lower), translation direction 0.155 deg/s, ATE 0.11 %.
TEST(BackendAccuracy, IndoorLongWithStandstill) {
  expectIndoorTargets(run("indoor_long"), 0.29, 0.21, 0.18);
}

// Without /odom the speed is the back-end's: its scale from the nominal speed, its shape from
// the volumes, and braking into the 3 s standstill from the event rate (stop_ramp_max_s). The
// turns' events outnumber the straights' at the same speed: when the front-end drove windows
// below half the moving event rate slower (slow_rate_fraction 0.5), the straights after the
// turns went at half speed (here yaw RPE 0.79, translation direction 1.06 deg/s).
TEST(BackendAccuracy, IndoorLongWithoutOdometry) {
  const PipelineRun r = run("indoor_long", "vwe_vo.yaml", 0.0, false, false);
  EXPECT_EQ(r.nonfinite_poses, 0u);
  EXPECT_GE(r.backend.tracked_fraction, 0.95);
  EXPECT_LE(r.backend.rpe.yaw_rmse_deg_s, 0.5);         // measured 0.401
  EXPECT_LE(r.backend.rpe.trans_dir_rmse_deg_s, 0.65);  // measured 0.504
}

// Without /odom through indoor_drive's two stops in bends: braking, the flow and the events fall
// with the speed, and the back-end's first fit follows them into the stop (stop_ramp_max_s) and
// out of it (start_ramps).
TEST(BackendAccuracy, IndoorDriveWithoutOdometryBrakesIntoItsStops) {
  const PipelineRun r = run("indoor_drive", "vwe_vo.yaml", 0.0, false, false);
  EXPECT_EQ(r.nonfinite_poses, 0u);
  EXPECT_EQ(r.backend_stats.stop_ramps, 2u);  // one into each stop, counted once
  EXPECT_EQ(r.backend_stats.start_ramps, 2u);
  EXPECT_GE(r.backend.tracked_fraction, 0.95);
  // Measured 0.220; 0.302 with the braking ramps each fit within its own window only (the last
  // 0.4 s before a stop braked hard and the fit rang), 0.264 without ramps.
  EXPECT_LE(r.backend.rpe.yaw_rmse_deg_s, 0.28);
  // Measured 0.262; 0.331 with the path after each stop left going on from where the refinement
  // put it, millimetres from where the stop held the pose (closeStandstillGaps); without the
  // ramps into and out of the stops the chords of the bends drift (0.8 at the cruise speed).
  EXPECT_LE(r.backend.rpe.trans_dir_rmse_deg_s, 0.4);
  std::printf("[backend accuracy] indoor_drive without odometry: yaw RPE %.3f deg/s\n",
              r.backend.rpe.yaw_rmse_deg_s);
}

// Continuous steering at 0.24-0.36 m/s on an uneven floor (pitch/roll ~0.5 deg, no tilt in
// the estimate), two 2 s stops in bends: the turtlebot brakes into and restarts from them while
// it turns, which the standstill windows' moving edges keep (holding the whole windows lost a
// degree at each restart: yaw RPE 0.28 on the bag).
TEST(BackendAccuracy, IndoorDriveStopsInBendsOnAnUnevenFloor) {
  const PipelineRun r = run("indoor_drive");
  EXPECT_EQ(r.nonfinite_poses, 0u);
  EXPECT_EQ(r.backend_stats.stop_ramps + r.backend_stats.start_ramps, 0u);  // /odom: no ramps
  EXPECT_GE(r.backend.tracked_fraction, 0.95);
  EXPECT_LE(r.backend.rpe.yaw_rmse_deg_s, 0.2);         // measured 0.154
  EXPECT_LE(r.backend.rpe.trans_dir_rmse_deg_s, 0.22);  // measured 0.166
  std::printf("[backend accuracy] indoor_drive: yaw RPE %.3f deg/s\n",
              r.backend.rpe.yaw_rmse_deg_s);
}

// Measured: back-end 0.653 deg/s against the front-end's 0.664, translation direction 0.370
// deg/s, ATE 0.47 %, scale per 10 m 0.996-1.011. On the straights of this street (true yaw rate
// exactly zero) the 1 s volumes place the yaw to about 1 deg/s, so the back-end gains little
// over the masked front-end here. Before car.yaml's ground mask and without its yaw-rate scan
// this test measured 0.578 against 0.674 and ATE 0.31 %; on the bag, over two subsampling seeds
// and two late starts, the change moved street_long 0.616 -> 0.587 (ATE 0.41 % both) and
// street_drive 1.03 -> 0.69 (ATE 1.46 -> 0.22 %). The ratio moves with where the windows fall
// (subsampling seed, bag start), so the street asks only that the back-end is not much worse
// (the road's yaw rate makes the front-end's arcs as good on this flat street).
TEST(BackendAccuracy, StreetLongWithTheCarConfig) {
  // A car at 5-8 m/s with 90-degree turns; config/car.yaml (its mount, one-sided windows with
  // planes from 10 m where the facade is deep enough), for this rigid car without the suspension's
  // tilt (car_rigid.yaml). The scale comes from the wheel speed: no drift along 250 m.
  const PipelineRun r = run("street_long", "car_rigid.yaml");
  EXPECT_EQ(r.nonfinite_poses, 0u);
  // With the road's yaw rate in its arcs (car.yaml's frontend.ground) the front-end's own
  // odometry on this flat street is as good as the refinement: on the bag, from 0, 0.5, 1.1 and
  // 2.3 s, the back-end over the front-end 1.26 / 1.00 / 0.81 / 0.94 (means 0.225 and 0.227), so
  // one run's back-end may be worse by up to 30 % (before the road: 0.440 vs 0.551).
  EXPECT_LE(r.backend.rpe.rot_rmse_deg_s, 1.3 * r.frontend.rpe.rot_rmse_deg_s);  // 0.278 / 0.237
  EXPECT_LE(r.backend.rpe.rot_rmse_deg_s, 0.36);                                 // measured 0.278
  EXPECT_LE(r.backend.rpe.trans_dir_rmse_deg_s, 0.3);                            // measured 0.158
  EXPECT_LE(r.backend.ate_percent_of_path, 0.4);                                 // measured 0.15
  ASSERT_GE(r.backend.scale_drift.ratios.size(), 20u);
  EXPECT_LE(r.backend.scale_drift.max_ratio / r.backend.scale_drift.min_ratio,
            1.03);  // measured 1.021 (1.015 with the back-end's volumes unmasked)
}

TEST(BackendAccuracy, StreetLongStartedLate) {
  // The same street with the system started 0.25 s into it: every window falls elsewhere. The
  // halves of a split window once rescanned the full range there and won spurious peaks 26-68
  // deg/s off on straight driving (vwe_vo_offline --start 0.25 on the bag: 2.0 deg/s).
  // Started there, the back-end gains little on the straights (see above), and the road-aided
  // front-end is as good (the test above).
  const PipelineRun r = run("street_long", "car_rigid.yaml", 0.25);
  EXPECT_EQ(r.nonfinite_poses, 0u);
  EXPECT_LE(r.backend.rpe.rot_rmse_deg_s,
            1.3 * r.frontend.rpe.rot_rmse_deg_s);  // measured 0.246 vs 0.228
  EXPECT_LE(r.backend.rpe.rot_rmse_deg_s, 0.36);   // measured 0.246
  EXPECT_LE(r.backend.ate_percent_of_path, 0.4);   // measured 0.23
}

// A car weaving in the right lane of a street (5.6-9.4 m/s, lane changes, a bend; the flat twin:
// yaw is all that is estimated). The facades are asymmetric: with front-end planes that ended
// at 60 m, each side's distant facade pulled the yaw towards itself and the busier side won
// (front-end 0.76 x true + 0.6 deg/s on the bag). Measured: front-end 0.634, back-end 0.474
// deg/s, translation direction 0.266 deg/s (with the back-end's volumes unmasked: back-end 0.685,
// 0.372); before car.yaml's ground mask, with its yaw-rate
// scan: 1.490, 1.073, 0.589 (with each vote's own weights in the density, whose spike at zero
// yaw rate held 26 of 171 windows at zero on the bag: 1.480, 1.353, 0.730; planes ending at 60 m
// as well: 1.917, 1.766, 0.940).
TEST(BackendAccuracy, StreetDriveWeavingInTheRightLane) {
  const PipelineRun r = run("street_drive_flat", "car_rigid.yaml");
  EXPECT_EQ(r.nonfinite_poses, 0u);
  EXPECT_GE(r.backend.tracked_fraction, 0.95);
  EXPECT_LE(r.backend.rpe.yaw_rmse_deg_s, r.frontend.rpe.yaw_rmse_deg_s);
  EXPECT_LE(r.backend.rpe.yaw_rmse_deg_s, 0.7);        // measured 0.195 (before the road 0.474)
  EXPECT_LE(r.backend.rpe.trans_dir_rmse_deg_s, 0.4);  // measured 0.119 (0.266)
}

// The car on its suspension (pitch/roll 1-2 deg, bumps, braking dives) with the DAVIS's IMU: the
// tilt comes from gyro and accelerometer, the car's own acceleration removed with a central
// difference of the odometry's speed; the yaw-rate bias is estimated against the events' yaw.
// The first fit turns at the gyro's rate less the bias estimate; the bias is measured per window
// against the yaw-rate offset the volumes prefer (Huber-weighted). Measured: 3D rotation RMSE
// 0.199, tilt 0.129, translation direction 0.140 deg/s, yaw-rate bias 0.002 deg/s off (the
// street's windows measure it to about 1 deg/s each; the estimate's own sigma at the end is
// 0.25 deg/s). With the arcs' rates as the first fit and the bias from the spline's own offset:
// 0.496 / 0.117 / 0.284; the speed's difference cut at the newest arc: 0.82, 0.72, 0.80 on the
// bag; the accelerometer's correction at 1 s instead of car.yaml's 3 s: tilt 0.219.
TEST(BackendAccuracy, StreetDriveOnItsSuspensionWithTheImu) {
  // (the body's tilt is in the pose: street_drive pitches and rolls 1-2 deg)
  const PipelineRun r = run("street_drive", "car.yaml", 0.0, true);
  EXPECT_EQ(r.nonfinite_poses, 0u);
  EXPECT_GE(r.backend.tracked_fraction, 0.95);
  EXPECT_LE(r.backend.rpe.tilt_rmse_deg_s, 0.18);
  EXPECT_LE(r.backend.rpe.rot_rmse_deg_s, 0.3);
  EXPECT_LE(r.backend.rpe.trans_dir_rmse_deg_s, 0.2);
  EXPECT_LE(std::abs(r.yaw_bias_error_deg_s), 0.15);
  std::printf(
      "[backend accuracy] street_drive with the IMU: tilt RPE %.3f deg/s, yaw-rate bias "
      "%+.3f deg/s off (true %+.3f)\n",
      r.backend.rpe.tilt_rmse_deg_s, r.yaw_bias_error_deg_s, r.yaw_bias_deg_s);
}

// The same car on its suspension without the IMU: the pose's tilt is the suspension's response
// to the trajectory's accelerations (car.yaml's pitch and roll gradients, 3 and 5 deg/g; the
// simulated car's are 3.75 and 4), in the pose and in the back-end's volumes. Measured: yaw 0.573,
// tilt 0.284, translation direction 0.346 deg/s, largest tilt 1.51 deg (with the tilt in the pose
// only: 0.533, 0.278, 0.332; single runs move by 0.05-0.1, the bag's four-start means improved). A
// planar pose scores a tilt RPE of ~0.6 here (the truth's own planar projection: 0.62 deg/s of
// rotation). On the bag (from 0 s) planar: translation direction 0.377, 3D rotation 0.793 deg/s;
// with the tilt 0.309 / 0.565.
TEST(BackendAccuracy, StreetDriveOnItsSuspensionTiltsWithTheAccelerations) {
  const PipelineRun r = run("street_drive", "car.yaml");
  EXPECT_EQ(r.nonfinite_poses, 0u);
  EXPECT_GE(r.backend.tracked_fraction, 0.95);
  EXPECT_GT(r.max_tilt_deg, 0.5);  // braking at up to 0.3 g
  EXPECT_LE(r.max_tilt_deg, 3.0);
  EXPECT_LE(r.backend.rpe.trans_dir_rmse_deg_s, 0.38);
  EXPECT_LE(r.backend.rpe.tilt_rmse_deg_s, 0.35);
  EXPECT_LE(r.backend.rpe.yaw_rmse_deg_s, 0.7);
  std::printf(
      "[backend accuracy] street_drive, tilt from the accelerations: yaw %.3f, tilt %.3f, "
      "translation direction %.3f deg/s, largest tilt %.2f deg\n",
      r.backend.rpe.yaw_rmse_deg_s, r.backend.rpe.tilt_rmse_deg_s,
      r.backend.rpe.trans_dir_rmse_deg_s, r.max_tilt_deg);
}

// With the IMU but without /odom the speed, so the vehicle's own acceleration, is unknown, and the
// accelerometer's tilt was worse than none (from the bag: translation direction 0.41 deg/s with
// it, 0.32 planar; street_drive 1.80 and 0.28). The pose stays planar; the gyro's yaw rate is
// fused and its bias measured in the stops.
TEST(BackendAccuracy, IndoorDriveWithTheImuWithoutOdometryStaysPlanar) {
  const PipelineRun r = run("indoor_drive", "vwe_vo.yaml", 0.0, true, false);
  EXPECT_EQ(r.nonfinite_poses, 0u);
  EXPECT_GE(r.backend.tracked_fraction, 0.95);
  EXPECT_LE(r.max_tilt_deg, 1e-6);
  EXPECT_LE(r.backend.rpe.trans_dir_rmse_deg_s, 0.5);
  EXPECT_LE(r.backend.rpe.yaw_rmse_deg_s, 0.5);
  EXPECT_LE(std::abs(r.yaw_bias_error_deg_s), 0.05);
  std::printf(
      "[backend accuracy] indoor_drive with the IMU, no /odom: yaw RPE %.3f deg/s, "
      "yaw-rate bias %+.3f deg/s off (true %+.3f)\n",
      r.backend.rpe.yaw_rmse_deg_s, r.yaw_bias_error_deg_s, r.yaw_bias_deg_s);
}
