// Regression of the front-end's accuracy on the simulator's standard sequences (generated in
// process with their fixed seeds): yaw rate per window against the ground truth's mean yaw rate
// over the same window (standstill windows are scored by their status instead), and the
// rotation RPE of the dead-reckoned trajectory. Thresholds carry margin over the measured values.
#include <gtest/gtest.h>

#include <cstdio>

#include "vwe_vo/eval/evaluation.h"
#include "vwe_vo/frontend/frontend.h"
#include "vwe_vo/io/options_yaml.h"
#include "vwe_vo/sim/scene.h"
#include "vwe_vo/sim/sequences.h"

using namespace vwe_vo;

namespace {

struct SequenceRun {
  std::vector<ArcEstimate> arcs;
  Trajectory3 ground_truth, estimate;
  size_t standstill_truth_windows = 0, standstill_detected = 0;
};

/// Simulates `name` for `seconds` and runs the front-end on it. With odometry, the speed comes
/// from the simulated wheel speed (as /odom would give it); otherwise the nominal speed is used.
SequenceRun run(const std::string& name, double seconds, double nominal_speed, bool odometry,
                const FrontendOptions& base = FrontendOptions()) {
  const sim::SequenceSpec spec = sim::findSequence(name);
  const CameraModel camera(
      loadCameraCalibrationYaml(std::string(VWE_VO_SOURCE_DIR) + "/config/davis346.yaml"));
  const auto trajectory = sim::VehicleTrajectory::fromProfile(spec.profile, spec.trajectory);
  sim::EventSimulator simulator(sim::buildScene(spec.scene, spec.seed, trajectory), camera,
                                spec.T_base_cam, trajectory, spec.simulator);
  FrontendOptions options = base;
  options.nominal_speed_mps = nominal_speed;
  Frontend frontend(options, camera, spec.T_base_cam);
  SequenceRun r;
  const int64_t end = std::min(trajectory.durationNs(), secToNs(seconds));
  EventVector chunk;
  for (int64_t t = 0; t < end;) {
    const int64_t t1 = std::min(end, t + secToNs(0.05));
    if (odometry) frontend.addOdometry(t1, trajectory.speed(t1), trajectory.yawRate(t1));
    chunk.clear();  // simulateUntil appends
    simulator.simulateUntil(t1, &chunk);
    frontend.addEvents(chunk);
    for (const ArcEstimate& a : frontend.process()) r.arcs.push_back(a);
    t = t1;
  }
  r.ground_truth = trajectory.sample(secToNs(0.005));
  r.estimate = integrateArcs(r.arcs, secToNs(0.01));
  EXPECT_EQ(frontend.stats().resets, 0u);
  EXPECT_EQ(frontend.stats().events_out_of_order, 0u);
  for (const ArcEstimate& a : r.arcs) {
    const bool still = trajectory.speed(a.t_start_ns) < 1e-3 && trajectory.speed(a.t_end_ns) < 1e-3;
    r.standstill_truth_windows += still;
    r.standstill_detected += still && a.status == ArcStatus::kStandstill;
  }
  return r;
}

WindowYawRateResult windowYawRates(const SequenceRun& r) {
  std::vector<WindowYawRate> windows;
  for (const ArcEstimate& a : r.arcs)
    windows.push_back({a.t_start_ns, a.t_end_ns, a.omega, a.status == ArcStatus::kStandstill});
  return evaluateWindowYawRates(r.ground_truth, windows);
}

double rotationRmse(const SequenceRun& r) {
  EvaluationOptions o;
  return evaluate(r.ground_truth, r.estimate, o).rpe.rot_rmse_deg_s;
}

void report(const char* name, const SequenceRun& r, const WindowYawRateResult& w) {
  std::printf(
      "[frontend accuracy] %s: window yaw rate RMSE %.3f, median %.3f, max %.3f deg/s (%zu "
      "windows); "
      "rotation RPE RMSE %.3f deg/s\n",
      name, w.rmse_deg_s, w.median_abs_deg_s, w.max_abs_deg_s, w.windows, rotationRmse(r));
}

}  // namespace

TEST(FrontendAccuracy, IndoorCircle) {
  const SequenceRun r = run("indoor_circle", 6.0, 0.4, false);
  const WindowYawRateResult w = windowYawRates(r);
  report("indoor_circle", r, w);
  ASSERT_GE(w.windows, 15u);
  EXPECT_LE(w.rmse_deg_s, 0.43);     // measured 0.324
  EXPECT_LE(rotationRmse(r), 0.37);  // measured 0.279
  for (const ArcEstimate& a : r.arcs) EXPECT_EQ(a.status, ArcStatus::kOk);
}

TEST(FrontendAccuracy, IndoorStraight) {
  const SequenceRun r = run("indoor_straight", 6.0, 0.4, false);
  const WindowYawRateResult w = windowYawRates(r);
  report("indoor_straight", r, w);
  ASSERT_GE(w.windows, 15u);
  // Straight driving is estimated like any other yaw rate: a window's events place it to a few
  // tenths of a deg/s (when each vote's own weights counted in the density, a spike at exactly
  // zero held every window there: 0.047 and 0.029).
  EXPECT_LE(w.rmse_deg_s, 0.6);      // measured 0.459
  EXPECT_LE(rotationRmse(r), 0.32);  // measured 0.242
}

TEST(FrontendAccuracy, IndoorLongWithStandstillAndOdometry) {
  const SequenceRun r = run("indoor_long", 30.5, 0.35, true);
  const WindowYawRateResult w = windowYawRates(r);
  report("indoor_long", r, w);
  ASSERT_GE(w.windows, 60u);
  // The standstill (3 s) is reported as such, not as a random yaw rate.
  ASSERT_GE(r.standstill_truth_windows, 8u);
  EXPECT_GE(r.standstill_detected, r.standstill_truth_windows - 1);
  EXPECT_LE(w.median_abs_deg_s, 0.38);  // measured 0.268 (0.074 with the spike at zero)
  // Windows straddling the 0.3 s yaw-rate ramps of this sequence dominate the RMSE (the median
  // is small).
  EXPECT_LE(w.rmse_deg_s, 1.1);      // measured 0.847
  EXPECT_LE(rotationRmse(r), 0.48);  // measured 0.385
}

TEST(FrontendAccuracy, IndoorLongWithTheShippedConfigAndAnotherSubsamplingSeed) {
  // With subsampling seed 6 a 60 deg/s turn that begins inside a window scores a local maximum
  // near the previous yaw rate that is not flat enough for a rescan at rescan_confidence 0.04,
  // and is held there (30 deg/s off, rotation RMSE 2.29); the shipped 0.07 rescans it.
  FrontendOptions o =
      loadPipelineConfig(std::string(VWE_VO_SOURCE_DIR) + "/config/vwe_vo.yaml").frontend;
  o.seed = 6;
  const SequenceRun r = run("indoor_long", 30.5, 0.35, true, o);
  const WindowYawRateResult w = windowYawRates(r);
  report("indoor_long, shipped config, seed 6", r, w);
  EXPECT_LE(w.max_abs_deg_s, 8.5);  // measured 5.4
  EXPECT_LE(rotationRmse(r), 0.6);  // measured 0.477
}
