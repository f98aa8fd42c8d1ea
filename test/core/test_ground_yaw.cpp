// The road's view of the yaw rate (vwe/ground_objective.h, frontend/ground_yaw.h): events of
// random points on the road seen from a car's mount along a known arc whose body pitches.
#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <stdexcept>

#include "../common/synthetic_events.h"
#include "../common/test_camera.h"
#include "vwe_vo/frontend/frontend.h"
#include "vwe_vo/frontend/ground_yaw.h"
#include "vwe_vo/io/config.h"
#include "vwe_vo/trajectory/ackermann_arc.h"
#include "vwe_vo/vwe/ground_objective.h"

using namespace vwe_vo;

namespace {
const CameraModel& camera() {
  return test::davis346Camera();
}
// config/car.yaml's mount: 1.5 m ahead of the rear axle, 1.4 m up, pitched 5 deg down.
Pose3 carMount() {
  return mountToTBaseCam(Vec3(1.5, 0, 1.4), 0, 5 / kDegPerRad, 0);
}

constexpr double kOmega = 8 / kDegPerRad, kV = 7.0;
constexpr double kPitch = 0.3 / kDegPerRad, kPitchRate = 1.0 / kDegPerRad;
const int64_t kTRef = secToNs(5.0);

PitchedArcModel truth(double omega = kOmega, double pitch = kPitch,
                      double pitch_rate = kPitchRate) {
  return PitchedArcModel(omega, kV, kTRef, carMount(), pitch, pitch_rate);
}

/// Random texture points on the road 3-9 m ahead of base_link at t_ref, in the reference camera
/// frame of `model`'s pose there, and their events over [t_ref - 0.15 s, t_ref + 0.15 s].
EventVector roadEvents(const PitchedArcModel& model, int n, unsigned seed,
                       double half_span_s = 0.15) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> ux(3.0, 9.0), uy(-4.0, 4.0);
  const GroundPlane plane = model.groundInReference();
  // The reference camera sees the road point X where n . X + h = 0: put texture points on the
  // ray of random road pixels (x, y in base_link at t_ref: the camera's height along n).
  const Pose3 T_cam_road = model.T_Cr_Ct(kTRef);  // identity, as a check of the reference
  EXPECT_TRUE(T_cam_road.isApprox(Pose3::Identity(), 1e-12));
  const Vec3 down = -plane.n;        // towards the road
  const Vec3 foot = plane.h * down;  // the camera's foot on the road
  // Two directions along the road: base_link's x and y projected onto the plane.
  const Mat3 R_base_cam = carMount().linear();
  Vec3 ex = R_base_cam.transpose() * Vec3::UnitX(), ey = R_base_cam.transpose() * Vec3::UnitY();
  ex = (ex - ex.dot(plane.n) * plane.n).normalized();
  ey = (ey - ey.dot(plane.n) * plane.n - ey.dot(ex) * ex).normalized();
  std::vector<Vec3> points;
  for (int i = 0; i < 3000; ++i) points.push_back(foot + (ux(rng) - 1.5) * ex + uy(rng) * ey);
  return synthetic::pointEvents(camera(), model, points, n, &rng, half_span_s);
}
}  // namespace

TEST(GroundObjective, SeesTheRoadBelowTheHorizonWithinItsDepths) {
  GroundObjectiveOptions o;
  const GroundObjective objective(o, camera(), carMount());
  EXPECT_GT(objective.groundPixels(), size_t(10000));
  // Pitched 5 deg down, the horizon lies above the image's middle row: nothing above it is road;
  // the road to 7 m fills a band of rows, to 20 m a taller one that reaches further up.
  GroundObjectiveOptions far = o;
  far.max_depth_m = 20.0;
  const GroundObjective further(far, camera(), carMount());
  int rows = 0, more_rows = 0, top = 260, far_top = 260;
  for (int y = 0; y < 260; ++y) {
    EXPECT_FALSE(y < 100 && further.seesGround(173, y)) << y;
    if (objective.seesGround(173, y)) ++rows, top = std::min(top, y);
    if (further.seesGround(173, y)) ++more_rows, far_top = std::min(far_top, y);
  }
  EXPECT_GT(rows, 40);
  EXPECT_GT(more_rows, rows);
  EXPECT_LT(far_top, top);
  GroundObjectiveOptions bad = o;
  bad.max_depth_m = 1.0;
  try {
    GroundObjective(bad, camera(), carMount());
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("ground.max_depth_m"), std::string::npos) << e.what();
  }
}

TEST(GroundObjective, IsSharpestAtTheTrueYawRateAndPitch) {
  const PitchedArcModel model = truth();
  const EventVector events = roadEvents(model, 20000, 3);
  ASSERT_GT(events.size(), size_t(19000));
  GroundObjective objective(GroundObjectiveOptions(), camera(), carMount());
  auto at = [&](double omega, double pitch, double pitch_rate) {
    const PitchedArcModel m(omega, kV, kTRef, carMount(), pitch, pitch_rate);
    return objective.evaluate(events, m, m.groundInReference());
  };
  const double best = at(kOmega, kPitch, kPitchRate);
  EXPECT_GT(best, 0.0);
  for (double d : {-1.0, 1.0}) {
    EXPECT_LT(at(kOmega + d / kDegPerRad, kPitch, kPitchRate), 0.9 * best) << d;
    EXPECT_LT(at(kOmega, kPitch + 0.3 * d / kDegPerRad, kPitchRate), 0.9 * best) << d;
    EXPECT_LT(at(kOmega, kPitch, kPitchRate + d / kDegPerRad), 0.95 * best) << d;
  }
  // The same events twice: the image is left clear after each evaluation.
  EXPECT_DOUBLE_EQ(at(kOmega, kPitch, kPitchRate), best);
}

TEST(GroundObjective, DensityPerVoteCountsThePairsOfVotesThatMeet) {
  // At a standstill every event lands on its own pixel (a pinhole camera: the grid's pixel
  // centres are the sensor's). n votes on one pixel make n (n - 1) ordered pairs that meet.
  const CameraModel pinhole(test::syntheticCalibration(false));
  GroundObjective objective(GroundObjectiveOptions(), pinhole, carMount());
  const PitchedArcModel still(0.0, 0.0, kTRef, carMount(), 0.0, 0.0);
  EventVector events;
  auto add = [&](int x, int y, int n) {
    ASSERT_TRUE(objective.seesGround(x, y)) << x << " " << y;
    for (int i = 0; i < n; ++i)
      events.push_back({kTRef + int64_t(events.size()) * 100000, uint16_t(x), uint16_t(y), 1});
  };
  add(100, 240, 3);
  add(101, 240, 2);  // the neighbour: its votes do not meet the first pixel's
  add(200, 230, 1);
  add(250, 250, 4);
  const double expected = (3 * 2 + 2 * 1 + 0 + 4 * 3) / 10.0;
  EXPECT_NEAR(objective.evaluate(events, still, still.groundInReference()), expected, 1e-3);
  // An event above the horizon is not the road's: left out.
  events.push_back({kTRef + int64_t(events.size()) * 100000, 173, 10, 1});
  EXPECT_NEAR(objective.evaluate(events, still, still.groundInReference()), expected, 1e-3);
}

TEST(PitchedArcModel, IsTheArcOfABodyTiltingOnItsMount) {
  // (B(t_ref) T_base_cam)^-1 arc(t) B(t) T_base_cam, B = Ry(pitch) Rx(roll), as 4x4 transforms.
  constexpr double kRoll = -0.4 / kDegPerRad;
  const PitchedArcModel model(kOmega, kV, kTRef, carMount(), kPitch, kPitchRate, kRoll);
  auto body = [&](double dt) {
    Pose3 B = Pose3::Identity();
    B.linear() = (Eigen::AngleAxisd(kPitch + kPitchRate * dt, Vec3::UnitY()) *
                  Eigen::AngleAxisd(kRoll, Vec3::UnitX()))
                     .toRotationMatrix();
    return arcT_Vr_Vt(kOmega, kV, dt) * B * carMount();
  };
  for (double dt : {-0.15, -0.01, 0.0, 0.07, 0.15}) {
    const Pose3 expected = body(0.0).inverse() * body(dt);
    const Pose3 T = model.T_Cr_Ct(kTRef + secToNs(dt));
    EXPECT_TRUE(T.linear().isApprox(expected.linear(), 1e-12)) << dt;
    EXPECT_LT((T.translation() - expected.translation()).norm(), 1e-12) << dt;
  }
}

TEST(GroundYaw, RecoversTheYawRateOfAPitchingBody) {
  const EventVector events = roadEvents(truth(), 40000, 5);
  GroundYawOptions o;
  o.weight = 0.5;
  GroundYaw ground(o, camera(), carMount());
  ASSERT_TRUE(ground.enabled());
  // Searched from 2 deg/s off; the true pitch lies on the searched grid.
  const GroundYawEstimate e = ground.estimate(events, kTRef - secToNs(0.15), kTRef + secToNs(0.15),
                                              kTRef, kV, 0.0, kOmega + 2 / kDegPerRad, 1);
  ASSERT_TRUE(e.valid);
  EXPECT_NEAR(e.omega * kDegPerRad, kOmega * kDegPerRad, 0.2);
  // The pitch itself is found only roughly (with the speed it sets the road's scale).
  EXPECT_NEAR(e.pitch * kDegPerRad, kPitch * kDegPerRad, 0.3);
  EXPECT_EQ(e.events, size_t(10000));
  EXPECT_GT(e.evaluations, 50);
  // At pitch 0 (no nuisance) the same events give a worse yaw rate.
  GroundYawOptions rigid = o;
  rigid.pitch_rounds = 0;
  GroundYaw flat(rigid, camera(), carMount());
  const GroundYawEstimate f = flat.estimate(events, kTRef - secToNs(0.15), kTRef + secToNs(0.15),
                                            kTRef, kV, 0.0, kOmega + 2 / kDegPerRad, 1);
  ASSERT_TRUE(f.valid);
  EXPECT_GT(std::abs(f.omega - kOmega), std::abs(e.omega - kOmega));
}

TEST(GroundYaw, WarpsTheRoadWithTheLeanOfTheTurn) {
  // A body leaning out of the turn by roll_per_g v omega / g (a soft car: 0.2 rad/g, 1.1 deg
  // here); the road is warped with the lean the searched-around yaw rate predicts.
  constexpr double kGravity = 9.80665, kRollPerG = 0.2;
  const double lean = kRollPerG * kV * kOmega / kGravity;
  const PitchedArcModel leaning(kOmega, kV, kTRef, carMount(), kPitch, kPitchRate, lean);
  const EventVector events = roadEvents(leaning, 40000, 7);
  GroundYawOptions o;
  o.weight = 0.5;
  o.roll_per_g_rad = kRollPerG;
  GroundYaw ground(o, camera(), carMount());
  const int64_t t0 = kTRef - secToNs(0.15), t1 = kTRef + secToNs(0.15);
  const GroundYawEstimate e = ground.estimate(events, t0, t1, kTRef, kV, 0.0, kOmega, 1);
  ASSERT_TRUE(e.valid);
  EXPECT_DOUBLE_EQ(e.roll, lean);
  EXPECT_NEAR(e.omega * kDegPerRad, kOmega * kDegPerRad, 0.2);
  // Warped upright, the same events give a worse yaw rate.
  o.roll_per_g_rad = 0.0;
  GroundYaw upright(o, camera(), carMount());
  const GroundYawEstimate u = upright.estimate(events, t0, t1, kTRef, kV, 0.0, kOmega, 1);
  ASSERT_TRUE(u.valid);
  EXPECT_EQ(u.roll, 0.0);
  EXPECT_GT(std::abs(u.omega - kOmega), std::abs(e.omega - kOmega));
}

TEST(GroundYaw, LeavesAWindowWithoutRoadEventsAlone) {
  GroundYawOptions o;
  o.weight = 0.5;
  GroundYaw ground(o, camera(), carMount());
  EventVector sky;
  for (int i = 0; i < 5000; ++i) sky.push_back({kTRef + i * 10000, uint16_t(i % 346), 5, 1});
  const GroundYawEstimate e =
      ground.estimate(sky, kTRef - secToNs(0.15), kTRef + secToNs(0.15), kTRef, kV, 0.0, kOmega, 1);
  EXPECT_FALSE(e.valid);
  EXPECT_EQ(e.evaluations, 0);
}

TEST(GroundYaw, OptionsNameTheirKey) {
  GroundYawOptions o;
  o.weight = 1.5;
  try {
    o.validate("frontend.ground");
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("frontend.ground.weight"), std::string::npos) << e.what();
  }
  o.weight = 0.5;
  o.min_events = o.max_events + 1;
  EXPECT_THROW(o.validate("frontend.ground"), std::invalid_argument);
}

// In the front-end: windows with /odom average the road's yaw rate in, windows without do not.
TEST(GroundYaw, TheFrontendUsesTheRoadOnlyWithAMeasuredSpeed) {
  const PitchedArcModel model = truth(kOmega, 0.0, 0.0);
  const EventVector events = roadEvents(model, 120000, 7, 0.45);
  FrontendOptions o;
  o.window_duration_s = 0.3;
  o.nominal_speed_mps = kV;
  o.standstill_event_rate_hz = 5000;
  o.ground_mask = false;
  o.volume.z_min_m = 1.5;
  o.ground.weight = 0.5;
  for (bool odom : {false, true}) {
    Frontend fe(o, camera(), carMount());
    if (odom)
      for (int k = 0; k <= 100; ++k) fe.addOdometry(kTRef + secToNs(-0.5 + 0.01 * k), kV, 0.0);
    fe.addEvents(events);
    const std::vector<ArcEstimate> arcs = fe.process();
    ASSERT_FALSE(arcs.empty());
    EXPECT_EQ(fe.stats().windows_ground > 0, odom);
    if (odom) {
      EXPECT_GT(fe.stats().ground_evaluations, size_t(50));
      for (const ArcEstimate& a : arcs) {
        if (a.status == ArcStatus::kOk) {
          EXPECT_NEAR(a.omega * kDegPerRad, kOmega * kDegPerRad, 0.7);
        }
      }
    }
  }
}

TEST(GroundYaw, ClimbsTheRidgeOfPitchAndPitchRate) {
  // On the road an error of the pitch is nearly undone by one of the pitch rate of the same sign:
  // a body pitched -0.5 deg and pitching at -1.5 deg/s looks nearly as sharp at (-0.2 deg, -0.75
  // deg/s), where two rounds of pitch, pitch rate and yaw rate stop, 0.1 deg/s off in yaw rate.
  const PitchedArcModel body(kOmega, kV, kTRef, carMount(), -0.5 / kDegPerRad, -1.5 / kDegPerRad);
  const EventVector events = roadEvents(body, 40000, 11);
  const int64_t t0 = kTRef - secToNs(0.15), t1 = kTRef + secToNs(0.15);
  auto estimate = [&](int rounds) {
    GroundYawOptions o;
    o.weight = 0.5;
    o.pitch_rounds = rounds;
    GroundYaw ground(o, camera(), carMount());
    return ground.estimate(events, t0, t1, kTRef, kV, 0.0, kOmega + 1 / kDegPerRad, 1);
  };
  const GroundYawEstimate e = estimate(20), two = estimate(2);
  ASSERT_TRUE(e.valid && two.valid);
  EXPECT_NEAR(e.omega * kDegPerRad, kOmega * kDegPerRad, 0.04);
  EXPECT_NEAR(e.pitch * kDegPerRad, -0.5, 0.15);
  EXPECT_NEAR(e.pitch_rate * kDegPerRad, -1.5, 0.3);
  EXPECT_GT(std::abs(two.omega - kOmega) * kDegPerRad, 0.06);
  // The rounds stop by themselves once nothing moves: far fewer evaluations than 20 rounds of
  // three searches (~30 each).
  EXPECT_LT(e.evaluations, 250);
  // A level body at the centre of the searches: no search of the second round runs (the yaw rate
  // coarse and fine, one round of pitch, pitch rate and yaw rate: 10 + 7 + 31).
  const PitchedArcModel level(kOmega, kV, kTRef, carMount(), 0.0, 0.0);
  GroundYawOptions o;
  o.weight = 0.5;
  o.pitch_rounds = 20;
  GroundYaw ground(o, camera(), carMount());
  const GroundYawEstimate l =
      ground.estimate(roadEvents(level, 40000, 13), t0, t1, kTRef, kV, 0.0, kOmega, 1);
  ASSERT_TRUE(l.valid);
  EXPECT_NEAR(l.omega * kDegPerRad, kOmega * kDegPerRad, 0.06);
  EXPECT_EQ(l.evaluations, 48);
  EXPECT_GT(l.curvature, 0.0);
}

TEST(GroundYaw, SearchesAroundThePreviousYawRateWhenTheVwesJumped) {
  // The VWE's yaw rate 12 deg/s off (a spurious peak of its full scan), the previous window's
  // 1 deg/s off: the road searches around both, finds the truth near the previous one and takes
  // the window alone.
  const PitchedArcModel level(kOmega, kV, kTRef, carMount(), 0.0, 0.0);
  const EventVector events = roadEvents(level, 40000, 17);
  const int64_t t0 = kTRef - secToNs(0.15), t1 = kTRef + secToNs(0.15);
  GroundYawOptions o;
  o.weight = 0.8;
  GroundYaw ground(o, camera(), carMount());
  const double spurious = kOmega + 12 / kDegPerRad, previous = kOmega + 1 / kDegPerRad;
  const GroundYawEstimate e =
      ground.estimate(events, t0, t1, kTRef, kV, 0.0, spurious, 1, previous);
  ASSERT_TRUE(e.valid);
  EXPECT_NEAR(e.omega * kDegPerRad, kOmega * kDegPerRad, 0.1);
  EXPECT_TRUE(e.apart);
  EXPECT_TRUE(e.near_prior);
  EXPECT_EQ(ground.share(e), 1.0);
  // Without the previous yaw rate the rounds climb there from the edge of the VWE's range (254
  // evaluations against 57), but nothing confirms the road's against the VWE's: no share.
  const GroundYawEstimate alone = ground.estimate(events, t0, t1, kTRef, kV, 0.0, spurious, 1);
  ASSERT_TRUE(alone.valid);
  EXPECT_GT(alone.evaluations, 2 * e.evaluations);
  EXPECT_TRUE(alone.apart);
  EXPECT_FALSE(alone.near_prior);
  EXPECT_EQ(ground.share(alone), 0.0);
}

TEST(GroundYaw, SharesTheWindowByAgreement) {
  GroundYawOptions o;
  o.weight = 0.8;
  GroundYaw ground(o, camera(), carMount());
  GroundYawEstimate e;
  EXPECT_EQ(ground.share(e), 0.0);  // not valid
  e.valid = true;
  EXPECT_EQ(ground.share(e), 0.0);  // no peak
  e.curvature = 100.0;
  EXPECT_EQ(ground.share(e), 0.8);
  e.apart = true;
  EXPECT_EQ(ground.share(e), 0.0);  // apart from the VWE's and the previous window's: spurious
  e.near_prior = true;
  EXPECT_EQ(ground.share(e), 1.0);  // apart from the VWE's only: the VWE's was spurious
}
