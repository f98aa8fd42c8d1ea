// Front-end against known arcs: events of random 3D points seen along a constant Ackermann arc.
#include <gtest/gtest.h>

#include <cstdio>
#include <opencv2/calib3d.hpp>
#include <random>

#include "../common/synthetic_events.h"
#include "../common/test_camera.h"
#include "vwe_vo/frontend/backlog_policy.h"
#include "vwe_vo/frontend/frontend.h"
#include "vwe_vo/io/config.h"
#include "vwe_vo/sensor/ground_mask.h"
#include "vwe_vo/vwe/ray_builder.h"

using namespace vwe_vo;

namespace {
const CameraModel& camera() {
  return test::davis346Camera();
}
FrontendOptions options() {
  FrontendOptions o;
  o.window_duration_s = 0.3;
  o.nominal_speed_mps = 0.4;
  o.standstill_event_rate_hz = 5000;
  return o;
}
}  // namespace

TEST(Frontend, RecoversTheYawRateOfAConstantArc) {
  for (double w_deg : {-30.0, 0.0, 20.0}) {
    const double w = w_deg / kDegPerRad;
    const AckermannArcModel truth(w, 0.4, secToNs(5.0), defaultTBaseCam());
    // 1.5 s of events around t = 5 s: windows [4.25, 4.55), ... each fully covered.
    const EventVector events = synthetic::randomPointEvents(camera(), truth, 60000, 11, 0.75, 600);
    Frontend fe(options(), camera(), defaultTBaseCam());
    fe.addEvents(events);
    const std::vector<ArcEstimate> arcs = fe.process();
    ASSERT_GE(arcs.size(), 4u);
    for (const ArcEstimate& a : arcs) {
      EXPECT_EQ(a.status, ArcStatus::kOk);
      EXPECT_NEAR(a.omega * kDegPerRad, w_deg, 0.5) << "window at " << nsToSec(a.t_ref_ns);
      EXPECT_DOUBLE_EQ(a.v, 0.4);
      EXPECT_GT(a.confidence, 0.05);
    }
    // Dead reckoning along the arcs reproduces the true arc's relative motion.
    const Pose3 T_a = fe.T_odom_base(arcs.front().t_start_ns),
                T_b = fe.T_odom_base(arcs.back().t_end_ns);
    const double dyaw = wrapAngle(yawOf((T_a.inverse() * T_b).linear()));
    EXPECT_NEAR(dyaw, w * nsToSec(arcs.back().t_end_ns - arcs.front().t_start_ns), 0.01);
  }
}

// The front-end votes the events off the near ground (the turtlebot's mount: the rows below
// about 220 see the floor nearer than the first plane at 0.8 m), and all of a window's events
// when the mask would leave fewer than min_events.
TEST(Frontend, VotesTheEventsOffTheNearGroundUnlessTooFewRemain) {
  FrontendOptions o = options();
  o.min_events = 4;
  ASSERT_TRUE(o.ground_mask);
  const Frontend fe(o, camera(), defaultTBaseCam());
  const PixelEvent floor{0, 170, 255, 1}, wall{0, 170, 40, 1};
  const GroundMask mask(camera(), defaultTBaseCam(), o.volume.z_min_m);
  ASSERT_FALSE(mask.keeps(floor));
  ASSERT_TRUE(mask.keeps(wall));
  const EventVector mixed = {floor, wall, floor, wall, wall, floor, wall};
  EventVector storage;
  const EventVector seen = fe.offGround(mixed, &storage);
  ASSERT_EQ(seen.size(), 4u);
  for (const PixelEvent& e : seen) EXPECT_EQ(e.y, wall.y);
  const EventVector few = {floor, wall, floor, wall, floor};  // 2 off the ground < min_events
  EXPECT_EQ(fe.offGround(few, &storage).size(), few.size());
  o.ground_mask = false;
  EXPECT_EQ(Frontend(o, camera(), defaultTBaseCam()).offGround(mixed, &storage).size(),
            mixed.size());
}

// A node behind its input thins its windows instead of skipping them: each window votes
// max_events_per_volume / k events and still finds the arc.
TEST(Frontend, ThinnedWindowsVoteFewerEventsAndStillFindTheArc) {
  const double w_deg = 20.0;
  const AckermannArcModel truth(w_deg / kDegPerRad, 0.4, secToNs(5.0), defaultTBaseCam());
  const EventVector events = synthetic::randomPointEvents(camera(), truth, 60000, 11, 0.75, 600);
  for (size_t k : {size_t(1), size_t(2), size_t(4)}) {
    Frontend fe(options(), camera(), defaultTBaseCam());
    fe.setVolumeThinning(k);
    fe.addEvents(events);
    const std::vector<ArcEstimate> arcs = fe.process();
    ASSERT_GE(arcs.size(), 4u);
    for (const ArcEstimate& a : arcs) {
      ASSERT_GT(a.window_events, options().max_events_per_volume);
      EXPECT_EQ(a.num_events, options().max_events_per_volume / k);
      EXPECT_NEAR(a.omega * kDegPerRad, w_deg, 0.5) << "1/" << k;
    }
    EXPECT_EQ(fe.stats().windows_thinned, k > 1 ? fe.stats().windows : 0u);
  }
}

// A node far behind skips windows; they go out as LOST arcs at the last yaw rate, so the arcs
// stay continuous in time (the back-end holds its rates through them instead of resetting).
TEST(Frontend, SkippedWindowsBecomeContinuousLostArcs) {
  const double w_deg = 20.0;
  const AckermannArcModel truth(w_deg / kDegPerRad, 0.4, secToNs(5.0), defaultTBaseCam());
  const EventVector events = synthetic::randomPointEvents(camera(), truth, 60000, 11, 0.75, 600);
  Frontend fe(options(), camera(), defaultTBaseCam());
  const size_t half = events.size() / 3;
  fe.addEvents(EventVector(events.begin(), events.begin() + long(half)));
  std::vector<ArcEstimate> arcs = fe.process();
  ASSERT_FALSE(arcs.empty());
  fe.addEvents(EventVector(events.begin() + long(half), events.end()));
  const size_t pending = fe.pendingWindows();
  ASSERT_GE(pending, 3u);
  std::vector<ArcEstimate> skipped;
  EXPECT_EQ(fe.dropBacklog(1, &skipped), pending - 1);
  ASSERT_EQ(skipped.size(), pending - 1);
  EXPECT_EQ(fe.stats().windows_dropped, pending - 1);
  for (const ArcEstimate& a : skipped) {
    EXPECT_EQ(a.status, ArcStatus::kLost);
    EXPECT_DOUBLE_EQ(a.omega, arcs.back().omega);  // the last yaw rate held
    EXPECT_EQ(a.v, 0.0);                           // no /odom: the position holds
  }
  const std::vector<ArcEstimate> rest = fe.process();
  ASSERT_EQ(rest.size(), 1u);
  arcs.insert(arcs.end(), skipped.begin(), skipped.end());
  arcs.insert(arcs.end(), rest.begin(), rest.end());
  for (size_t i = 1; i < arcs.size(); ++i) EXPECT_EQ(arcs[i].t_start_ns, arcs[i - 1].t_end_ns) << i;
  EXPECT_NEAR(rest.front().omega * kDegPerRad, w_deg, 1.0);
}

TEST(Frontend, CoarseToFineFullScanFindsATurnWithFewerEvaluations) {
  // A 0.3 s window of a 35 deg/s turn scanned around a previous yaw rate of 0: the peak lies
  // beyond the local scan, so the full range is scanned; coarse to fine must land on the same
  // peak as the fine full scan for well under its cost.
  const double w = 35.0 / kDegPerRad;
  const AckermannArcModel truth(w, 0.4, secToNs(5.0), defaultTBaseCam());
  const EventVector events = synthetic::randomPointEvents(camera(), truth, 8000, 5, 0.15, 600);
  FrontendOptions fine = options(), coarse = options();
  fine.full_scan_step_rad_s = fine.scan_step_rad_s;
  coarse.full_scan_step_rad_s = 0.09;
  Frontend fe_fine(fine, camera(), defaultTBaseCam()),
      fe_coarse(coarse, camera(), defaultTBaseCam());
  const ArcEstimate a_fine =
      fe_fine.estimateWindow(events, secToNs(5.0), 0.4, 0.0, fine.scan_half_range_rad_s);
  const ArcEstimate a_coarse =
      fe_coarse.estimateWindow(events, secToNs(5.0), 0.4, 0.0, coarse.scan_half_range_rad_s);
  EXPECT_NEAR(a_fine.omega * kDegPerRad, 35.0, 0.5);
  EXPECT_NEAR(a_coarse.omega * kDegPerRad, 35.0, 0.5);
  EXPECT_NEAR(a_coarse.omega, a_fine.omega, 1e-3);
  EXPECT_EQ(a_coarse.status, ArcStatus::kOk);
  EXPECT_LT(a_coarse.evaluations, 0.6 * a_fine.evaluations)
      << a_coarse.evaluations << " vs " << a_fine.evaluations << " evaluations";
  EXPECT_EQ(size_t(a_coarse.evaluations), fe_coarse.stats().evaluations);
  // The coarse grid votes every 4th event (full_scan_max_events 2000 of 8000): it only picks the
  // basin, so the arc is the one of the coarse grid on all events, and so is the confidence (its
  // lowest point is evaluated on all events).
  FrontendOptions all = coarse;
  all.full_scan_max_events = 0;
  ASSERT_EQ(coarse.full_scan_max_events, 2000u);
  Frontend fe_all(all, camera(), defaultTBaseCam());
  const ArcEstimate a_all =
      fe_all.estimateWindow(events, secToNs(5.0), 0.4, 0.0, all.scan_half_range_rad_s);
  EXPECT_NEAR(a_coarse.omega, a_all.omega, 1e-3);
  EXPECT_NEAR(a_coarse.confidence, a_all.confidence, 0.1 * a_all.confidence);
  std::printf(
      "[frontend] full scan: confidence %.4f thinned, %.4f all events; %d / %d evaluations\n",
      a_coarse.confidence, a_all.confidence, a_coarse.evaluations, a_all.evaluations);

  // A rescan bounded as for the halves of a split window (+-10 deg/s here) does not reach the turn:
  // its coarse grid stays in the range, and only the refinement around its best point (by up to
  // a coarse step and a few fine ones) goes beyond. The one-sided planes are refused when the
  // options have none.
  WindowScan bounded;
  bounded.rescan_lo_rad_s = -10.0 / kDegPerRad;
  bounded.rescan_hi_rad_s = 10.0 / kDegPerRad;
  const ArcEstimate a_bounded = fe_coarse.estimateWindow(events, secToNs(5.0), 0.4, 0.0,
                                                         coarse.scan_half_range_rad_s, bounded);
  const double reach_deg_s =
      (coarse.full_scan_step_rad_s + 3 * coarse.scan_step_rad_s) * kDegPerRad;
  EXPECT_LT(std::abs(a_bounded.omega) * kDegPerRad, 10.0 + reach_deg_s);
  EXPECT_LT(a_bounded.evaluations, a_coarse.evaluations);
  ASSERT_EQ(coarse.one_sided.balance, 0.0);
  WindowScan deep;
  deep.deep_planes = true;
  EXPECT_THROW(
      fe_coarse.estimateWindow(events, secToNs(5.0), 0.4, 0.0, coarse.scan_half_range_rad_s, deep),
      std::logic_error);
}

TEST(Frontend, LowEventRateIsStandstillNotARandomOmega) {
  FrontendOptions o = options();
  o.standstill_event_rate_hz = 20000;
  Frontend fe(o, camera(), defaultTBaseCam());
  EventVector noise;
  for (int i = 0; i < 3000; ++i) {  // 3000 events over 1 s: 3 kev/s of noise
    PixelEvent e;
    e.t_ns = secToNs(1.0 + i / 3000.0);
    e.x = uint16_t((i * 7919) % 346);
    e.y = uint16_t((i * 104729) % 260);
    noise.push_back(e);
  }
  fe.addEvents(noise);
  const auto arcs = fe.process();
  ASSERT_GE(arcs.size(), 3u);
  for (const ArcEstimate& a : arcs) {
    EXPECT_EQ(a.status, ArcStatus::kStandstill);
    EXPECT_EQ(a.omega, 0.0);
    EXPECT_EQ(a.v, 0.0);
  }
}

TEST(Frontend, OdometryAtRestMeansStandstill) {
  const AckermannArcModel truth(0.3, 0.4, secToNs(5.0), defaultTBaseCam());
  const EventVector events = synthetic::randomPointEvents(camera(), truth, 20000, 3, 0.5, 600);
  Frontend fe(options(), camera(), defaultTBaseCam());
  for (double t = 4.0; t < 6.0; t += 0.02) fe.addOdometry(secToNs(t), 0.0, 0.0);
  fe.addEvents(events);
  const std::vector<ArcEstimate> arcs = fe.process();
  ASSERT_FALSE(arcs.empty());
  for (const ArcEstimate& a : arcs) EXPECT_EQ(a.status, ArcStatus::kStandstill);
}

// A standstill window (by its mean /odom speed) whose end starts moving, and one whose start
// still brakes: the moving edges become arcs at their /odom speed on the curvature estimated
// before the stop, and only the rest is held.
TEST(Frontend, StandstillWindowsKeepTheirMovingEdgesAtTheCurvatureBeforeTheStop) {
  const double w = 20.0 / kDegPerRad, v = 0.4, kappa = w / v;
  const AckermannArcModel truth(w, v, secToNs(5.0), defaultTBaseCam());
  const EventVector events = synthetic::randomPointEvents(camera(), truth, 60000, 7, 0.75, 600);
  Frontend fe(options(), camera(), defaultTBaseCam());
  // Windows [4.25, 4.55) and [4.55, 4.85) move at 0.4 m/s; [4.85, 5.15) stands still but
  // for 0.06 m/s over its last 70 ms; [5.15, 5.45) creeps at 0.06 m/s for its first 50 ms.
  auto speed = [](double t) {
    if (t < 4.85) return 0.4;
    if (t >= 5.09 && t < 5.2) return 0.06;
    return 0.0;
  };
  for (int k = 0; k <= 150; ++k) {
    const double t = 4.25 + 0.01 * k;
    fe.addOdometry(secToNs(t), speed(t), 0.0);
  }
  fe.addEvents(events);
  const std::vector<ArcEstimate> arcs = fe.process();
  ASSERT_GE(arcs.size(), 6u);
  EXPECT_EQ(fe.stats().windows_standstill_edges, 2u);
  // The arcs tile the time, and each /odom-moving edge is an arc on the curvature before.
  double kappa_before = 0;
  size_t edges = 0;
  for (size_t i = 0; i < arcs.size(); ++i) {
    const ArcEstimate& a = arcs[i];
    if (i > 0) {
      EXPECT_EQ(a.t_start_ns, arcs[i - 1].t_end_ns);
    }
    const double t0 = nsToSec(a.t_start_ns), t1 = nsToSec(a.t_end_ns);
    if (t1 <= 4.85 + 1e-6) {
      ASSERT_EQ(a.status, ArcStatus::kOk);
      EXPECT_NEAR(a.omega * kDegPerRad, 20.0, 0.5);
      kappa_before = a.omega / a.v;
    } else if (a.status == ArcStatus::kOk) {
      ++edges;
      // The mean of the edge's /odom samples, the still one at its stopped end included.
      EXPECT_GT(a.v, 0.04) << "edge [" << t0 << ", " << t1 << "]";
      EXPECT_LE(a.v, 0.06);
      EXPECT_NEAR(a.omega, kappa_before * a.v, 1e-12);
      EXPECT_NEAR(a.omega / a.v, kappa, 0.05 * kappa);  // as the estimate before: +-0.5 deg/s
      EXPECT_LT(t1 - t0, 0.075);
    } else {
      EXPECT_EQ(a.status, ArcStatus::kStandstill);
    }
  }
  EXPECT_EQ(edges, 2u);
}

// Without odometry, a turtlebot turning away from a stop at 2.5 cm/s: at the nominal 0.4 m/s the
// first window's parallax is 16 times too large and pulls the yaw rate; restart_speed_scan also
// tries 1/16 and 1/4 of the speed there and keeps the arc of highest contrast (at the nominal
// speed, which the back-end's start ramps rescale).
TEST(Frontend, WithoutOdometryTheFirstWindowAfterAStopAlsoTriesSlowerSpeeds) {
  const double w_deg = 10.0;
  const AckermannArcModel still(0.0, 0.0, secToNs(4.55), defaultTBaseCam());
  const AckermannArcModel start(w_deg / kDegPerRad, 0.025, secToNs(5.15), defaultTBaseCam());
  // A wall on the left, 1 m beside the camera from 1.5 to 6 m ahead: the structure along which a
  // yaw rate trades for parallax. [4.25, 4.85): 1000 events/s, a standstill; [4.85, 5.45): the
  // slow turn.
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<Vec3> wall;
  for (int i = 0; i < 600; ++i) wall.emplace_back(-1.0, 0.6 * u(rng) - 0.3, 1.5 + 4.5 * u(rng));
  EventVector events = synthetic::pointEvents(camera(), still, wall, 600, &rng, 0.3);
  const EventVector moving = synthetic::pointEvents(camera(), start, wall, 40000, &rng, 0.3);
  events.insert(events.end(), moving.begin(), moving.end());
  double error[2] = {0, 0};
  for (const bool scan : {false, true}) {
    FrontendOptions o = options();
    o.restart_speed_scan = scan;
    Frontend fe(o, camera(), defaultTBaseCam());
    fe.addEvents(events);
    const std::vector<ArcEstimate> arcs = fe.process();
    const ArcEstimate* first = nullptr;
    size_t standstills = 0;
    for (const ArcEstimate& a : arcs) {
      standstills += a.status == ArcStatus::kStandstill;
      if (!first && a.status == ArcStatus::kOk) first = &a;
    }
    EXPECT_EQ(standstills, 2u);
    ASSERT_NE(first, nullptr);
    EXPECT_NEAR(nsToSec(first->t_start_ns), 4.85, 0.01);
    EXPECT_DOUBLE_EQ(first->v, 0.4);
    error[scan] = std::abs(first->omega * kDegPerRad - w_deg);
    // The window and, as its yaw rate left the standstill's, its two halves (split_omega_change).
    EXPECT_EQ(fe.stats().windows_restart_slower, scan ? 3u : 0u);
    std::printf("restart_speed_scan %d: first window's yaw rate off by %.2f deg/s\n", int(scan),
                error[scan]);
  }
  EXPECT_LT(error[1], 1.0);
  EXPECT_GT(error[0], 2.0 * error[1] + 0.5);
}

// A window /odom says is still for most of its time but whose mean speed is above the standstill
// speed (a start): its events barely moved, so it is held and its moving end keeps the curvature
// from before the stop; a window still for less than half its time keeps its events' estimate.
TEST(Frontend, AMostlyStillWindowIsAStandstillWithAMovingEdge) {
  const double w = 20.0 / kDegPerRad, v = 0.4, kappa = w / v;
  const AckermannArcModel truth(w, v, secToNs(5.0), defaultTBaseCam());
  const EventVector events = synthetic::randomPointEvents(camera(), truth, 60000, 7, 0.75, 600);
  Frontend fe(options(), camera(), defaultTBaseCam());
  // Windows [4.25, 4.55) and [4.55, 4.85) move; [4.85, 5.15) stands until 5.05 (mean speed
  // 0.13 m/s, above standstill_speed_mps); [5.15, 5.45) stands from 5.17 to 5.27 only.
  auto speed = [&](double t) {
    const bool still = (t >= 4.85 && t < 5.05) || (t >= 5.17 && t < 5.27);
    return still ? 0.0 : v;
  };
  for (int k = 0; k <= 150; ++k) {
    const double t = 4.25 + 0.01 * k;
    fe.addOdometry(secToNs(t), speed(t), 0.0);
  }
  fe.addEvents(events);
  const std::vector<ArcEstimate> arcs = fe.process();
  EXPECT_EQ(fe.stats().windows_standstill_edges, 1u);
  double kappa_before = 0;
  bool held = false, edge = false, kept = false;
  for (size_t i = 0; i < arcs.size(); ++i) {
    const ArcEstimate& a = arcs[i];
    if (i > 0) {
      EXPECT_EQ(a.t_start_ns, arcs[i - 1].t_end_ns);  // the arcs tile the time
    }
    const double t0 = nsToSec(a.t_start_ns), t1 = nsToSec(a.t_end_ns);
    if (t1 <= 4.85 + 1e-6) {
      ASSERT_EQ(a.status, ArcStatus::kOk);
      kappa_before = a.omega / a.v;
    } else if (t0 < 5.15 - 1e-6) {  // the mostly still window
      if (a.status == ArcStatus::kStandstill) {
        held = true;
        EXPECT_EQ(a.omega, 0.0);
        EXPECT_LT(t1, 5.06);
      } else {
        edge = true;
        ASSERT_EQ(a.status, ArcStatus::kOk);
        EXPECT_GT(t0, 5.03);
        EXPECT_GT(a.v, 0.3);  // the mean of its /odom samples, the last still one included
        EXPECT_LE(a.v, v);
        EXPECT_NEAR(a.omega, kappa_before * a.v, 1e-12);
        EXPECT_NEAR(a.omega / a.v, kappa, 0.05 * kappa);
      }
    } else if (t0 >= 5.15 - 1e-6 && t1 <= 5.45 + 1e-6) {  // still for a third: its events' arc
      kept = true;
      EXPECT_EQ(a.status, ArcStatus::kOk);
      EXPECT_NEAR(t1 - t0, 0.3, 1e-6);
    }
  }
  EXPECT_TRUE(held);
  EXPECT_TRUE(edge);
  EXPECT_TRUE(kept);
}

// Without /odom a slow window (braking: fewer events per second) is driven slower; the speed the
// back-end refines there is smoothed across the step to the faster windows and says nothing
// about the moving speed, so the follower's speed is taken only in windows at the moving rate.
TEST(Frontend, FollowedSpeedIsTakenOnlyInWindowsAtTheMovingRate) {
  const AckermannArcModel truth(0.1, 0.4, secToNs(5.0), defaultTBaseCam());
  const EventVector all = synthetic::randomPointEvents(camera(), truth, 60000, 9, 0.75, 600);
  // Windows [4.25, 4.55), ..., [4.85, 5.15) at the full rate, then [5.15, 5.45) at 30 % of it.
  EventVector events;
  for (size_t i = 0; i < all.size(); ++i)
    if (all[i].t_ns < secToNs(5.15) || i % 10 < 3) events.push_back(all[i]);
  FrontendOptions o = options();
  o.slow_rate_fraction = 0.5;
  Frontend fe(o, camera(), defaultTBaseCam());
  fe.addEvents(events);
  const std::vector<ArcEstimate> arcs = fe.process();
  ASSERT_GE(arcs.size(), 4u);
  ASSERT_EQ(fe.stats().windows_slow, 1u);
  const ArcEstimate& slow = arcs.back();
  EXPECT_NEAR(slow.v, 0.4 * 0.3 / o.slow_rate_fraction, 0.05);
  const int64_t t_slow = slow.t_ref_ns, t_moving = arcs.front().t_ref_ns;
  fe.setNominalSpeed(0.9, t_slow);  // a smoothed speed in the slow window: ignored
  EXPECT_DOUBLE_EQ(fe.options().nominal_speed_mps, 0.4);
  fe.setNominalSpeed(0.5, t_moving);  // at the moving rate: taken
  EXPECT_DOUBLE_EQ(fe.options().nominal_speed_mps, 0.5);
}

TEST(Frontend, BadInputIsCountedAndLoopedDataResets) {
  Frontend fe(options(), camera(), defaultTBaseCam());
  EventVector ev(3);
  ev[0].t_ns = secToNs(2.0);
  ev[1].t_ns = secToNs(2.001);
  ev[1].x = 400;                // outside the 346x260 sensor
  ev[2].t_ns = secToNs(1.999);  // 2 ms back: late, dropped
  EXPECT_FALSE(fe.addEvents(ev));
  EXPECT_EQ(fe.stats().events_outside, 1u);
  EXPECT_EQ(fe.stats().events_out_of_order, 1u);
  EventVector looped(1);
  looped[0].t_ns = secToNs(0.5);  // 1.5 s back: a looped bag
  EXPECT_TRUE(fe.addEvents(looped));
  EXPECT_EQ(fe.stats().resets, 1u);
  EXPECT_TRUE(fe.process().empty());
  EXPECT_NO_THROW(fe.addEvents({}));
}

// A body rolling at p turns the image about the optical axis: a horizontal flow proportional to
// the row. With every point above the horizon that shifts them all one way, as a yaw rate does,
// and the 1-DoF arc absorbs it into omega. With roll_rate_step_rad_s the window's roll rate is a
// nuisance, one coordinate step (roll at the biased omega, then omega at that roll): the bias
// shrinks by about half and the roll rate found has the truth's sign, not beyond it.
TEST(Frontend, ARollRateNuisanceKeepsTheYawRateOfARollingBody) {
  const double w = 10.0 / kDegPerRad, p = 4.0 / kDegPerRad;
  const int64_t t_ref = secToNs(5.0);
  AckermannArcModel truth(w, 0.4, t_ref, defaultTBaseCam());
  truth.setRollRate(p);
  std::mt19937 rng(5);
  std::vector<Vec3> points = synthetic::randomPoints(&rng, 800);
  for (Vec3& q : points) q.y() = -std::abs(q.y());  // above the principal point
  const EventVector events = synthetic::pointEvents(camera(), truth, points, 20000, &rng, 0.15);
  double err[2], roll[2], omega_off = 0.0;
  for (int with_roll = 0; with_roll < 2; ++with_roll) {
    FrontendOptions o = options();
    o.ground_mask = false;
    o.roll_rate_step_rad_s = with_roll ? 2.0 / kDegPerRad : 0.0;
    Frontend fe(o, camera(), defaultTBaseCam());
    WindowScan scan;
    scan.roll_nuisance = true;  // as for a window with /odom
    const ArcEstimate a = fe.estimateWindow(events, t_ref, 0.4, w, 0.15, scan);
    err[with_roll] = (a.omega - w) * kDegPerRad;
    roll[with_roll] = a.roll_rate * kDegPerRad;
    EXPECT_EQ(fe.stats().windows_rolled, size_t(with_roll && a.roll_rate != 0.0));
    if (!with_roll) {
      omega_off = a.omega;
      EXPECT_EQ(a.omegaWithoutRoll(), a.omega);
      continue;
    }
    // The front-end's own odometry keeps the arc at roll 0: the option off's.
    EXPECT_NEAR(a.omegaWithoutRoll(), omega_off, 1e-12);
    EXPECT_NE(a.roll_omega_shift, 0.0);
    // A window without a measured speed is not tried at a roll rate: the arc of the option off.
    scan.roll_nuisance = false;
    const ArcEstimate nominal = fe.estimateWindow(events, t_ref, 0.4, w, 0.15, scan);
    EXPECT_EQ(nominal.roll_rate, 0.0);
    EXPECT_EQ(nominal.omega, omega_off);
  }
  std::printf("omega error without / with the roll nuisance: %.3f / %.3f deg/s, roll %.2f deg/s\n",
              err[0], err[1], roll[1]);
  EXPECT_EQ(roll[0], 0.0);
  EXPECT_GT(std::abs(err[0]), 0.8);
  EXPECT_LT(std::abs(err[1]), 0.65 * std::abs(err[0]));
  EXPECT_GT(roll[1], 1.0);
  EXPECT_LE(roll[1], 4.0);
}

/// validate() must refuse o with a message naming `field`.
static void expectRefusedNaming(const FrontendOptions& o, const std::string& field) {
  try {
    o.validate();
    ADD_FAILURE() << field << ": accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
  }
}

TEST(Frontend, InvalidOptionsAreRefusedNamingTheField) {
  FrontendOptions o;
  o.window_duration_s = 0;
  expectRefusedNaming(o, "window_duration_s");
  o = FrontendOptions();
  o.full_scan_max_events = 50;
  expectRefusedNaming(o, "full_scan_max_events");
  o.full_scan_max_events = 0;  // all events
  EXPECT_NO_THROW(o.validate());
  o.volume.pose_slice_s = -1e-3;
  expectRefusedNaming(o, "pose_slice_s");
  o = FrontendOptions();
  o.roll_rate_step_rad_s = -0.01;
  expectRefusedNaming(o, "roll_rate_step_rad_s");
  o.roll_rate_step_rad_s = 0.5;
  expectRefusedNaming(o, "roll_rate_step_rad_s");
  o = FrontendOptions();
  o.volume.num_planes = 1;
  EXPECT_THROW(o.validate(), std::invalid_argument);
}

TEST(Frontend, ForwardPixelIsTheFocusOfExpansionOnTheHorizon) {
  const CameraCalibration c =
      loadCameraCalibrationYaml(std::string(VWE_VO_SOURCE_DIR) + "/config/davis346.yaml");
  const CameraModel cam(c);
  // The raw (distorted) pixel of the normalised pinhole coordinates (x, y), by OpenCV.
  const auto raw = [&c](double x, double y) {
    const cv::Matx33d K(c.fx, 0, c.cx, 0, c.fy, c.cy, 0, 0, 1);
    std::vector<cv::Point2d> uv;
    cv::projectPoints(std::vector<cv::Point3d>{{x, y, 1.0}}, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0),
                      K, std::vector<double>(c.distortion.begin(), c.distortion.end()), uv);
    return Vec2(uv[0].x, uv[0].y);
  };
  Vec2 p;
  // Level and looking forward: the principal point.
  ASSERT_TRUE(forwardPixel(cam, mountToTBaseCam(Vec3(0.1, 0, 0.3), 0, 0, 0), &p));
  EXPECT_NEAR(p.x(), c.cx, 1e-9);
  EXPECT_NEAR(p.y(), c.cy, 1e-9);
  // Pitched 5 deg down (the car mount): the horizon is tan(5 deg) above it in the pinhole.
  const double pitch = 5.0 * kPi / 180;
  ASSERT_TRUE(forwardPixel(cam, mountToTBaseCam(Vec3(1.5, 0, 1.4), 0, pitch, 0), &p));
  EXPECT_NEAR((p - raw(0, -std::tan(pitch))).norm(), 0.0, 1e-6);
  EXPECT_NEAR(p.y(), c.cy - c.fy * std::tan(pitch), 0.1);  // barely distorted near the centre
  // Yawed 20 deg to the left: straight ahead appears right of the centre.
  ASSERT_TRUE(forwardPixel(cam, mountToTBaseCam(Vec3(0, 0, 0.3), 0, 0, 20.0 * kPi / 180), &p));
  EXPECT_NEAR((p - raw(std::tan(20.0 * kPi / 180), 0)).norm(), 0.0, 1e-6);
  // Looking backwards: no forward pixel.
  EXPECT_FALSE(forwardPixel(cam, mountToTBaseCam(Vec3(0, 0, 0.3), 0, 0, kPi), &p));
}

TEST(Frontend, SideBalanceCountsTheEventsAboveTheHorizonOnEachSide) {
  const Vec2 fwd(100.0, 50.0);
  EventVector ev;
  auto add = [&](int n, uint16_t x, uint16_t y) {
    for (int i = 0; i < n; ++i) ev.push_back({int64_t(ev.size()), x, y, 1});
  };
  EXPECT_EQ(sideBalance(ev, fwd), 1.0);  // nothing above the horizon
  add(40, 10, 10);                       // left, above
  add(1000, 150, 200);                   // right, below the horizon: not counted
  EXPECT_EQ(sideBalance(ev, fwd), 0.0);  // all on the left
  add(10, 150, 20);                      // right, above
  EXPECT_NEAR(sideBalance(ev, fwd), 10.0 / 40.0, 1e-12);
  add(30, 199, 49);
  EXPECT_NEAR(sideBalance(ev, fwd), 1.0, 1e-12);
}

TEST(Frontend, OneSidedOptionsAreValidated) {
  FrontendOptions o;
  o.one_sided.balance = 1.0;
  expectRefusedNaming(o, "one_sided_balance");
  o.one_sided.balance = 0.1;
  o.one_sided.z_min_m = o.volume.z_max_m + 1;
  expectRefusedNaming(o, "one_sided_z_min_m");
  o.one_sided.z_min_m = 0.5 * o.volume.z_min_m;  // not deeper than the normal planes
  expectRefusedNaming(o, "one_sided_z_min_m");
  o.one_sided.z_min_m = 10.0;
  o.one_sided.min_depth_m = 0.0;
  expectRefusedNaming(o, "one_sided_min_depth_m");
  o.one_sided.min_depth_m = 11.0;
  EXPECT_NO_THROW(o.validate());
}

TEST(Frontend, OneSidedDepthIsWhereTheRaysOfTheBusierUpperSideMeet) {
  // Points seen from five camera positions (a sideways and forward baseline, as a window's
  // rays): the rays of each point meet at its depth. Above the horizon (v0 < 100) the left
  // holds facade points 20 m away, the right a nearer facade 7 m away; below it, a road 3 m away.
  VolumeOptions vo;
  vo.grid_scale = 1.0;
  vo.num_planes = 30;
  vo.z_min_m = 2.5;
  vo.z_max_m = 60.0;
  const double fx = 250, fy = 250, cx = 180, cy = 140;
  ProjectiveVolume volume(vo, 346, 260, fx, fy, cx, cy);
  const Vec2 horizon(cx, 100.0);
  const VolumeRayBuilder<double> make_ray(fx, fy, cx, cy);
  std::vector<VolumeRay> rays;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  auto addPoints = [&](int n, double u_lo, double u_hi, double v_lo, double v_hi, double z) {
    for (int i = 0; i < n; ++i) {
      const double u = u_lo + (u_hi - u_lo) * unit(rng), v = v_lo + (v_hi - v_lo) * unit(rng);
      const Vec3 P((u - cx) / fx * z, (v - cy) / fy * z, z);
      for (int k = -2; k <= 2; ++k) {
        const Vec3 o(0.15 * k, 0.0, 0.5 * k);
        VolumeRay r;
        ASSERT_TRUE(make_ray(RayPose<double>(Mat3::Identity(), o), (P - o).normalized(), &r));
        rays.push_back(r);
      }
    }
  };
  const double spacing = volume.planeInverseDepth(0) - volume.planeInverseDepth(1);
  EXPECT_EQ(oneSidedDepth(volume, rays, horizon), 0.0);  // no rays
  addPoints(300, 20, 150, 20, 90, 20.0);                 // left, above the horizon
  addPoints(100, 220, 330, 20, 90, 7.0);                 // right, above
  addPoints(600, 20, 330, 150, 250, 3.0);                // below the horizon: not counted
  EXPECT_EQ(volume.peakDepth(rays.front()), 0.0);        // nothing voted yet
  volume.vote(rays);
  EXPECT_NEAR(1.0 / oneSidedDepth(volume, rays, horizon), 1.0 / 20.0, spacing);
  volume.clear(rays);
  // More on the right: the right's depth.
  addPoints(400, 220, 330, 20, 90, 7.0);
  volume.vote(rays);
  EXPECT_NEAR(1.0 / oneSidedDepth(volume, rays, horizon), 1.0 / 7.0, spacing);
}

// ---------------------------------------------------------------------------------------------
// BacklogPolicy: a live front-end behind its input thins before it skips, and skips only when
// the thinned windows cannot keep pace.

namespace {

BacklogPolicyOptions backlogOptions() {
  BacklogPolicyOptions o;
  o.max_latency_s = 1.0;
  o.window_s = 0.3;
  o.max_thinning = 16;
  o.rate_horizon_s = 2.0;
  o.hard_latency_factor = 4.0;
  return o;
}

// Input arriving at `rate` data seconds per wall second for `wall_s`, sampled every 10 ms.
void feed(BacklogPolicy* p, double wall0, double data0, double rate, double wall_s) {
  for (double w = 0; w <= wall_s + 1e-9; w += 0.01) p->observeInput(wall0 + w, data0 + rate * w);
}

}  // namespace

TEST(BacklogPolicy, MeasuresTheArrivalRateOverItsHorizonAndForgetsAJumpBack) {
  BacklogPolicy p(backlogOptions());
  EXPECT_LT(p.arrivalRate(), 0);  // nothing yet
  feed(&p, 100.0, 5.0, 0.5, 0.5);
  EXPECT_LT(p.arrivalRate(), 0);  // less than half the horizon seen
  feed(&p, 100.5, 5.25, 2.0, 3.0);
  EXPECT_NEAR(p.arrivalRate(), 2.0, 0.02);  // the 0.5 rate left the 2 s horizon
  p.observeInput(103.6, 1.0);               // a bag looped: the data time went back
  EXPECT_LT(p.arrivalRate(), 0);
}

TEST(BacklogPolicy, ThinsWhileBehindUntilTheWindowsWorkTheBacklogOff) {
  BacklogPolicy p(backlogOptions());
  // Rates unknown: every window halves its events while more than half a second waits.
  EXPECT_EQ(p.nextThinning(0.6, 1), 2u);
  EXPECT_EQ(p.nextThinning(0.6, 8), 16u);
  EXPECT_EQ(p.nextThinning(0.6, 16), 16u);  // the coarsest
  EXPECT_EQ(p.nextThinning(0.4, 4), 4u);    // under half a second: held
  EXPECT_EQ(p.nextThinning(0.2, 4), 2u);    // under one window: back towards all events
  EXPECT_EQ(p.nextThinning(0.0, 1), 1u);
  // Events at 2x real time; windows estimated at 3.5x: 0.9 s of backlog drains in
  // 0.9 / (3.5 - 2) = 0.6 s of wall time, within max_latency_s: no coarser than 2.
  feed(&p, 0.0, 0.0, 2.0, 2.0);
  for (int i = 0; i < 10; ++i) p.observeWindow(0.3, 0.3 / 3.5);
  EXPECT_NEAR(p.progressRate(), 3.5, 1e-9);
  EXPECT_EQ(p.nextThinning(0.9, 2), 2u);
  EXPECT_EQ(p.nextThinning(0.9, 1), 2u);  // all events: always the first halving
  // At 2.5x the same backlog would take 1.8 s: coarser.
  for (int i = 0; i < 40; ++i) p.observeWindow(0.3, 0.3 / 2.5);
  EXPECT_EQ(p.nextThinning(0.9, 2), 4u);
}

TEST(BacklogPolicy, SkipsOnlyWhenTheCoarsestWindowsCannotKeepPace) {
  BacklogPolicy p(backlogOptions());
  // Rates unknown (start-up): beyond max_latency_s at the coarsest thinning, skip.
  EXPECT_TRUE(p.mustSkip(1.5, 16));
  EXPECT_FALSE(p.mustSkip(1.5, 8));   // coarser windows first
  EXPECT_FALSE(p.mustSkip(0.9, 16));  // within max_latency_s
  // A burst: a stalled player sent 3 s of events at once; over the horizon they still arrive
  // at 2x, and the coarsest windows are estimated at 6x: they work it off, nothing skipped.
  feed(&p, 0.0, 0.0, 2.0, 2.0);
  for (int i = 0; i < 10; ++i) p.observeWindow(0.3, 0.05);
  EXPECT_FALSE(p.mustSkip(3.0, 16));
  EXPECT_TRUE(p.mustSkip(4.5, 16));  // beyond 4 x max_latency_s: skipped regardless
  EXPECT_TRUE(p.mustSkip(4.5, 1));
  // Sustained overload: the coarsest windows at 1.5x against events at 2x never catch up.
  for (int i = 0; i < 40; ++i) p.observeWindow(0.3, 0.2);
  EXPECT_NEAR(p.progressRate(), 1.5, 1e-3);  // the running mean forgets 6x by 0.75^40
  EXPECT_TRUE(p.mustSkip(1.2, 16));
  p.reset();
  EXPECT_LT(p.progressRate(), 0);
  EXPECT_LT(p.arrivalRate(), 0);
}

TEST(BacklogPolicy, RefusesOptionsThatCannotWork) {
  BacklogPolicyOptions o = backlogOptions();
  o.max_latency_s = 0;
  EXPECT_THROW(BacklogPolicy{o}, std::invalid_argument);
  o = backlogOptions();
  o.max_thinning = 0;
  EXPECT_THROW(BacklogPolicy{o}, std::invalid_argument);
  o = backlogOptions();
  o.hard_latency_factor = 0.5;
  EXPECT_THROW(BacklogPolicy{o}, std::invalid_argument);
}
