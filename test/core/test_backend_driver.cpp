// The back-end driver's rules (stale arcs, gaps, looped data, refinement per arc or merged over a
// batch, continuous odometry) and the front-end following the back-end's spline.
#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <string>
#include <vector>

#include "../common/test_camera.h"
#include "vwe_vo/backend/backend_driver.h"

using namespace vwe_vo;

namespace {

constexpr int64_t kEpoch = 100000000000LL;  // 100 s
constexpr int64_t kArcNs = 50000000;        // 50 ms

CameraCalibration calibration() {
  return test::syntheticCalibration(false);
}

Pose3 extrinsics() {
  return makePose(R_base_opticalFrame(), Vec3(0.1, 0.0, 0.3));
}

ArcEstimate arcAt(int64_t t_start, double omega = 0.2, double v = 0.5,
                  ArcStatus status = ArcStatus::kOk) {
  ArcEstimate a;
  a.t_start_ns = t_start;
  a.t_end_ns = t_start + kArcNs;
  a.t_ref_ns = t_start + kArcNs / 2;
  a.omega = omega;
  a.v = v;
  a.status = status;
  return a;
}

/// A driver with recorded callbacks over a back-end without events (its refinements are the
/// initial fits of the dead reckoning).
struct Rig {
  CameraModel cam{calibration()};
  BackendOptions options;
  std::unique_ptr<Backend> backend;
  std::unique_ptr<BackendDriver> driver;
  Trajectory3 odometry;
  std::vector<size_t> refinements;  // merged intervals of each
  std::vector<BackendDriver::ResetCause> resets;

  // Steps (car.yaml) unless told: the odometry then reaches each newest arc's end.
  explicit Rig(BackendDriverOptions o = BackendDriverOptions(), bool ramps = false) {
    options.volume.num_planes = 10;
    options.interpolate_arc_rates = ramps;
    backend = std::make_unique<Backend>(options, cam, extrinsics());
    BackendDriver::Callbacks cb;
    cb.odometry = [this](int64_t t, const Pose3& T, double, double) { odometry.push_back({t, T}); };
    cb.refinement = [this](size_t merged) { refinements.push_back(merged); };
    cb.reset = [this](BackendDriver::ResetCause c, const std::string&) { resets.push_back(c); };
    driver = std::make_unique<BackendDriver>(backend.get(), o, cb);
  }
};

}  // namespace

TEST(BackendDriver, RefinesOncePerUpdateIntervalAndPublishesTheOdometryFirst) {
  Rig r;
  for (int k = 0; k < 70; ++k) r.driver->addArc(arcAt(kEpoch + k * kArcNs));  // 3.5 s
  // update_interval_s 1 s: due at 1.0, 2.0, 3.0 s of arcs.
  ASSERT_EQ(r.refinements.size(), 3u);
  for (size_t m : r.refinements) EXPECT_EQ(m, 0u);
  EXPECT_EQ(r.backend->processedUntil(), kEpoch + 60 * kArcNs);
  // Odometry every 50 ms from the first arc's start to the newest arc's end, once each.
  ASSERT_EQ(r.odometry.size(), 71u);
  for (size_t i = 0; i < r.odometry.size(); ++i)
    EXPECT_EQ(r.odometry[i].t_ns, kEpoch + int64_t(i) * kArcNs);
  // Each odometry pose follows the arcs' turn: 0.2 rad/s.
  EXPECT_NEAR(yawOf(r.odometry[20].T.linear()), 0.2 * 1.0, 1e-6);
}

TEST(BackendDriver, WithRampedRatesTheOdometryFollowsTheRampsUpToTheNewestArcsMiddle) {
  // Rates stepping every 4 arcs (0.2 s): with interpolate_arc_rates (vwe_vo.yaml) the odometry
  // turns as the ramps between the arcs' middles and goes out up to the newest middle only, so
  // no pose it published would have turned otherwise once the next arc arrived.
  Rig r(BackendDriverOptions(), true);
  std::vector<ArcEstimate> arcs;
  for (int k = 0; k < 18; ++k) {  // 0.9 s: before the first refinement (1 s)
    arcs.push_back(arcAt(kEpoch + k * kArcNs, (k / 4) % 2 ? 0.6 : -0.2));
    r.driver->addArc(arcs.back());
    ASSERT_FALSE(r.odometry.empty());
    EXPECT_LE(r.odometry.back().t_ns, arcs.back().t_ref_ns);
    EXPECT_GT(r.odometry.back().t_ns, arcs.back().t_ref_ns - kArcNs);
  }
  ASSERT_TRUE(r.refinements.empty());
  const Trajectory3 ramp = integrateArcs(arcs, secToNs(0.001));
  ASSERT_EQ(r.odometry.size(), 18u);  // every 50 ms from the first arc's start to 17.5 arcs
  for (const auto& pose : r.odometry) {
    const auto it = std::lower_bound(ramp.begin(), ramp.end(), pose.t_ns,
                                     [](const StampedPose& p, int64_t t) { return p.t_ns < t; });
    // The ramp has a pose at the end of every 1 ms step; the first arc's start is the identity.
    const bool start = pose.t_ns == arcs.front().t_start_ns;
    ASSERT_TRUE(start || (it != ramp.end() && it->t_ns == pose.t_ns));
    const double ramp_yaw = start ? 0.0 : yawOf(it->T.linear());
    EXPECT_NEAR(wrapAngle(yawOf(pose.T.linear()) - ramp_yaw), 0.0, 1e-3) << nsToSec(pose.t_ns);
  }
}

TEST(BackendDriver, ABatchThatKeepsUpGivesTheSameSplineAndABatchBehindMergesRefinements) {
  std::vector<ArcEstimate> arcs;
  for (int k = 0; k < 70; ++k) arcs.push_back(arcAt(kEpoch + k * kArcNs, 0.1 + 0.003 * k));
  Rig one, keeping_up, behind;
  for (const ArcEstimate& a : arcs) one.driver->addArc(a);
  // Batches of 5 arcs (0.25 s < update_interval_s): the same checks as one by one.
  for (size_t b = 0; b < arcs.size(); b += 5)
    for (size_t k = b; k < b + 5; ++k) keeping_up.driver->addArc(arcs[k], arcs[b + 4].t_end_ns);
  ASSERT_EQ(keeping_up.refinements.size(), one.refinements.size());
  EXPECT_EQ(keeping_up.backend->spline().controlPoints(), one.backend->spline().controlPoints());
  EXPECT_EQ(keeping_up.odometry.size(), one.odometry.size());
  // One batch of all 3.5 s: the refinements due at 1 s and 2 s are deferred while an arc a full
  // update interval newer is pending; one refinement at 2.55 s covers them (the last 0.95 s are
  // not due yet), the intervals it covers beyond the first counted.
  for (const ArcEstimate& a : arcs) behind.driver->addArc(a, arcs.back().t_end_ns);
  ASSERT_EQ(behind.refinements.size(), 1u);
  EXPECT_EQ(behind.refinements[0], 1u);
  EXPECT_EQ(behind.driver->stats().refinements_merged, 1u);
  EXPECT_EQ(behind.backend->processedUntil(), kEpoch + 51 * kArcNs);
  EXPECT_EQ(behind.odometry.size(), one.odometry.size());
}

TEST(BackendDriver, StaleArcsAreIgnoredAndLostArcsCounted) {
  Rig r;
  r.driver->addArc(arcAt(kEpoch));
  r.driver->addArc(arcAt(kEpoch + kArcNs));
  r.driver->addArc(arcAt(kEpoch + kArcNs));            // again: stale
  r.driver->addArc(arcAt(kEpoch + kArcNs - 1000000));  // 1 ms older: stale, no jump back
  r.driver->addArc(arcAt(kEpoch + 2 * kArcNs, 5.0, 0.5, ArcStatus::kLost));
  EXPECT_EQ(r.driver->stats().arcs_in, 5u);
  EXPECT_EQ(r.driver->stats().arcs_stale, 2u);
  EXPECT_EQ(r.driver->stats().arcs_lost, 1u);
  EXPECT_EQ(r.backend->stats().arcs_in, 3u);  // the stale ones never reached the back-end
  EXPECT_TRUE(r.resets.empty());
  EXPECT_EQ(r.backend->stats().resets, 0u);
}

TEST(BackendDriver, GapsInArcsOrEventsReset) {
  BackendDriverOptions o;
  o.max_gap_s = 1.5;
  Rig r(o);
  for (int k = 0; k < 10; ++k) r.driver->addArc(arcAt(kEpoch + k * kArcNs));
  const int64_t after = kEpoch + 10 * kArcNs + secToNs(1.6);
  r.driver->addArc(arcAt(after));
  ASSERT_EQ(r.resets.size(), 1u);
  EXPECT_EQ(r.resets[0], BackendDriver::ResetCause::kGap);
  EXPECT_EQ(r.driver->stats().gaps, 1u);
  EXPECT_EQ(r.backend->oldestArcTime(), after);  // the back-end starts again at the new arc
  // The odometry restarted at the identity there.
  EXPECT_EQ(r.odometry.back().t_ns, after + kArcNs);
  EXPECT_TRUE(r.odometry[r.odometry.size() - 2].T.isApprox(Pose3::Identity(), 1e-15));
  // 1.4 s between arcs is no gap.
  r.driver->addArc(arcAt(after + kArcNs + secToNs(1.4)));
  EXPECT_EQ(r.resets.size(), 1u);
  // Events: 1.6 s without any.
  EventVector ev = {{after, 10, 10, 1}, {after + 1000, 11, 10, 1}};
  r.driver->addEvents(ev);
  EventVector later = {{after + secToNs(1.6) + 2000, 12, 10, 1}};
  r.driver->addEvents(later);
  ASSERT_EQ(r.resets.size(), 2u);
  EXPECT_EQ(r.resets[1], BackendDriver::ResetCause::kGap);
  EXPECT_EQ(r.driver->stats().gaps, 2u);
  EXPECT_FALSE(r.backend->hasSpline());
  EXPECT_EQ(r.backend->bufferedEvents(), 1u);  // the events after the gap are kept
}

TEST(BackendDriver, ALoopedBagResetsOnceByEventsOrByArcs) {
  Rig r;
  for (int k = 0; k < 40; ++k) r.driver->addArc(arcAt(kEpoch + k * kArcNs));
  // The arcs jump back to the start (the bag looped, no events in between): one reset.
  r.driver->addArc(arcAt(kEpoch));
  ASSERT_EQ(r.resets.size(), 1u);
  EXPECT_EQ(r.resets[0], BackendDriver::ResetCause::kLoop);
  EXPECT_EQ(r.driver->stats().loops, 1u);
  EXPECT_EQ(r.backend->oldestArcTime(), kEpoch);
  EXPECT_EQ(r.backend->newestArcTime(), kEpoch + kArcNs);
  for (int k = 1; k < 40; ++k) r.driver->addArc(arcAt(kEpoch + k * kArcNs));
  EXPECT_EQ(r.resets.size(), 1u);
  // Now by the events: they jump back first, and the arcs that follow from the loop's start are
  // not stale and reset nothing more.
  r.driver->addEvents({{kEpoch + 40 * kArcNs, 10, 10, 1}});
  r.driver->addEvents({{kEpoch + 1000, 10, 10, 1}});
  ASSERT_EQ(r.resets.size(), 2u);
  EXPECT_EQ(r.resets[1], BackendDriver::ResetCause::kLoop);
  const size_t stale = r.driver->stats().arcs_stale;
  r.driver->addArc(arcAt(kEpoch));
  r.driver->addArc(arcAt(kEpoch + kArcNs));
  EXPECT_EQ(r.resets.size(), 2u);
  EXPECT_EQ(r.driver->stats().arcs_stale, stale);
  EXPECT_EQ(r.driver->stats().loops, 2u);
  EXPECT_EQ(r.backend->stats().resets, 2u);
  EXPECT_EQ(r.backend->oldestArcTime(), kEpoch);
}

TEST(BackendDriver, RequestedResetAndOptionsValidation) {
  Rig r;
  for (int k = 0; k < 5; ++k) r.driver->addArc(arcAt(kEpoch + k * kArcNs));
  r.driver->reset("the solver failed");
  ASSERT_EQ(r.resets.size(), 1u);
  EXPECT_EQ(r.resets[0], BackendDriver::ResetCause::kRequested);
  EXPECT_EQ(r.backend->oldestArcTime(), -1);
  BackendDriverOptions o;
  o.max_gap_s = 0;
  try {
    o.validate();
    ADD_FAILURE() << "max_gap_s 0 accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("max_gap_s"), std::string::npos) << e.what();
  }
  o = BackendDriverOptions();
  o.odom_rate_hz = -1;
  EXPECT_THROW(o.validate(), std::invalid_argument);
  FollowOptions f;
  f.min_speed_mps = std::nan("");
  try {
    f.validate();
    ADD_FAILURE() << "min_speed_mps NaN accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("min_speed_mps"), std::string::npos) << e.what();
  }
  EXPECT_THROW(FrontendFollower{f}, std::invalid_argument);
}

namespace {

/// A front-end that has dead-reckoned a standstill (sparse events) up to newest_ns: pose identity.
struct StandingFrontend {
  CameraModel cam{calibration()};
  FrontendOptions options;
  std::unique_ptr<Frontend> fe;
  int64_t newest_ns = 0;
  StandingFrontend() {
    options.nominal_speed_mps = 1.0;
    fe = std::make_unique<Frontend>(options, cam, extrinsics());
    std::mt19937 rng(3);
    EventVector ev;
    for (int64_t t = kEpoch; t < kEpoch + secToNs(2.0); t += 1000000)  // 1000 ev/s
      ev.push_back({t, uint16_t(rng() % 346), uint16_t(rng() % 260), int8_t((rng() & 1) ? 1 : -1)});
    fe->addEvents(ev);
    fe->process();
    newest_ns = ev.back().t_ns;
  }
};

/// A straight spline along x from (1, 2) at speed v over [0, 1] s, optionally still at its end.
BSpline straightSpline(double v, bool still_at_end) {
  const int p = 3, n = 6;
  const std::vector<double> U = BSpline::clampedUniformKnots(p, n, 0.0, 1.0);
  std::vector<Vec2> P;
  for (int i = 0; i < n; ++i)  // at the Greville abscissae: c(u) = (1 + v u, 2)
    P.emplace_back(1.0 + v * (U[i + 1] + U[i + 2] + U[i + 3]) / 3.0, 2.0);
  BSpline s(p, U, P, kEpoch);
  if (still_at_end) s.setStandstills({{0.8, 1.0}});
  return s;
}

}  // namespace

TEST(FrontendFollower, ReanchorsOnTheSplinesEndAndTakesItsSpeedOnlyWhenMovingWithoutOdometry) {
  StandingFrontend s;
  ASSERT_TRUE(s.fe->hasPose());
  const int64_t t_end = kEpoch + secToNs(1.0);
  ASSERT_TRUE(s.fe->T_odom_base(t_end).isApprox(Pose3::Identity(), 1e-12)) << "a standstill";
  {
    FrontendFollower follower;  // follow_backend, no odometry
    const BSpline spline = straightSpline(0.8, false);
    ASSERT_TRUE(follower.follow(spline, s.newest_ns, s.fe.get()));
    EXPECT_NEAR(s.fe->options().nominal_speed_mps, 0.8, 1e-9);
    EXPECT_EQ(follower.speedsTaken(), 1u);
    // The anchored dead reckoning at the spline's end is the spline's pose there.
    EXPECT_TRUE(follower.anchoredPose(*s.fe, t_end).isApprox(spline.T_odom_base(1.0), 1e-12));
    // Slower than min_speed_mps or in a standstill: re-anchored, the speed kept.
    ASSERT_TRUE(follower.follow(straightSpline(0.04, false), s.newest_ns, s.fe.get()));
    ASSERT_TRUE(follower.follow(straightSpline(0.6, true), s.newest_ns, s.fe.get()));
    EXPECT_NEAR(s.fe->options().nominal_speed_mps, 0.8, 1e-9);
    EXPECT_EQ(follower.reanchors(), 3u);
    // A named threshold: 0.04 m/s is taken below a lower one.
    FollowOptions low;
    low.min_speed_mps = 0.01;
    FrontendFollower slow(low);
    ASSERT_TRUE(slow.follow(straightSpline(0.04, false), s.newest_ns, s.fe.get()));
    EXPECT_NEAR(s.fe->options().nominal_speed_mps, 0.04, 1e-9);
  }
  {
    FrontendFollower with_odometry(FollowOptions(), true);
    EXPECT_FALSE(with_odometry.changesArcs());
    ASSERT_TRUE(with_odometry.follow(straightSpline(0.3, false), s.newest_ns, s.fe.get()));
    EXPECT_NEAR(s.fe->options().nominal_speed_mps, 0.04, 1e-9) << "odometry gives the speed";
    EXPECT_FALSE(with_odometry.anchor().isApprox(Pose3::Identity(), 1e-6));
    FollowOptions off;
    off.follow_backend = false;
    FrontendFollower not_following(off);
    EXPECT_FALSE(not_following.follow(straightSpline(0.3, false), s.newest_ns, s.fe.get()));
    EXPECT_TRUE(not_following.anchor().isApprox(Pose3::Identity(), 1e-15));
  }
  {
    FrontendFollower follower;
    // Beyond the dead reckoning, or from before a reset: ignored.
    EXPECT_FALSE(follower.follow(straightSpline(0.3, false), t_end - 1, s.fe.get()));
    follower.reset(kEpoch + 1);
    EXPECT_FALSE(follower.follow(straightSpline(0.3, false), s.newest_ns, s.fe.get()));
    EXPECT_EQ(follower.reanchors(), 0u);
  }
}
