// Our in-tree Event/EventArray must be wire-identical to the DAVIS driver's dvs_msgs so that
// driver bags play into our nodes unchanged: the MD5 sums are the contract.
#include <gtest/gtest.h>
#include <ros/message_traits.h>

#include "vwe_vo/AckermannArc.h"
#include "vwe_vo/Event.h"
#include "vwe_vo/EventArray.h"
#include "vwe_vo/SplineTrajectory.h"
#include "vwe_vo/frontend/frontend.h"
#include "vwe_vo/ros/conversions.h"

TEST(Messages, EventArrayMd5MatchesDvsMsgs) {
  EXPECT_STREQ(ros::message_traits::MD5Sum<vwe_vo::EventArray>::value(),
               "5e8beee5a6c107e504c2e78903c224b8");
}

TEST(Messages, EventMd5MatchesDvsMsgs) {
  EXPECT_STREQ(ros::message_traits::MD5Sum<vwe_vo::Event>::value(),
               "40d339b261445b8ce9a6fef01267cd5d");
}

// arcToMsg writes uint8_t(ArcStatus) and arcFromMsg reads it back: the message's constants must
// be the core enum's values.
TEST(Messages, AckermannArcStatusConstantsAreTheCoreEnum) {
  EXPECT_EQ(vwe_vo::AckermannArc::OK, uint8_t(vwe_vo::ArcStatus::kOk));
  EXPECT_EQ(vwe_vo::AckermannArc::STANDSTILL, uint8_t(vwe_vo::ArcStatus::kStandstill));
  EXPECT_EQ(vwe_vo::AckermannArc::LOST, uint8_t(vwe_vo::ArcStatus::kLost));
  EXPECT_EQ(vwe_vo::AckermannArc::LOW_EVENTS, uint8_t(vwe_vo::ArcStatus::kLowEvents));
  for (vwe_vo::ArcStatus status : {vwe_vo::ArcStatus::kOk, vwe_vo::ArcStatus::kStandstill,
                                   vwe_vo::ArcStatus::kLost, vwe_vo::ArcStatus::kLowEvents}) {
    vwe_vo::ArcEstimate arc;
    arc.status = status;
    EXPECT_EQ(vwe_vo::arcFromMsg(vwe_vo::arcToMsg(arc, "base_link")).status, status)
        << toString(status);
  }
}

// A window refined at a roll rate carries both yaw rates: the back-end's (omega) and the
// front-end's own (without the roll); a sender with roll_rate 0 has only omega, whatever the other
// field holds.
TEST(Messages, AckermannArcCarriesTheYawRateWithAndWithoutTheRoll) {
  vwe_vo::ArcEstimate arc;
  arc.omega = 0.21;
  arc.roll_rate = -0.015;
  arc.roll_omega_shift = 0.04;
  const vwe_vo::AckermannArc msg = vwe_vo::arcToMsg(arc, "base_link");
  EXPECT_DOUBLE_EQ(msg.omega, 0.21);
  EXPECT_DOUBLE_EQ(msg.roll_rate, -0.015);
  EXPECT_DOUBLE_EQ(msg.omega_without_roll, 0.17);
  const vwe_vo::ArcEstimate back = vwe_vo::arcFromMsg(msg);
  EXPECT_DOUBLE_EQ(back.omega, 0.21);
  EXPECT_DOUBLE_EQ(back.roll_rate, -0.015);
  EXPECT_NEAR(back.omegaWithoutRoll(), 0.17, 1e-15);

  vwe_vo::AckermannArc unrolled = msg;
  unrolled.roll_rate = 0.0;
  unrolled.omega_without_roll = 0.0;  // never written by such a sender
  EXPECT_EQ(vwe_vo::arcFromMsg(unrolled).omegaWithoutRoll(), 0.21);
}

// The design's SplineTrajectory fields carry a spline through splineToMsg / splineFromMsg: degree,
// knots (seconds since knot_epoch) and control points survive, and knots = points + degree + 1.
TEST(Messages, SplineTrajectoryCarriesDegreeKnotsAndControlPoints) {
  for (int degree : {1, 2, 3}) {
    const int n = 6;
    std::vector<double> knots;
    for (int k = 0; k < n + degree + 1; ++k) knots.push_back(0.25 * (k - degree) + 0.01 * k * k);
    std::vector<vwe_vo::Vec2> points;
    for (int i = 0; i < n; ++i) points.emplace_back(0.3 * i - 1.0, 0.05 * i * i);
    const vwe_vo::BSpline spline(degree, knots, points, 7000000000);
    const vwe_vo::SplineTrajectory msg = vwe_vo::splineToMsg(spline, 2, "odom");
    EXPECT_EQ(msg.degree, degree);
    EXPECT_EQ(msg.knots.size(), msg.control_x.size() + msg.degree + 1);
    EXPECT_EQ(msg.first_free_control_point, 2u);
    EXPECT_EQ(vwe_vo::toNs(msg.knot_epoch), 7000000000);
    const vwe_vo::BSpline back = vwe_vo::splineFromMsg(msg);
    EXPECT_EQ(back.degree(), degree);
    EXPECT_EQ(back.knots(), knots);
    ASSERT_EQ(back.controlPoints().size(), points.size());
    for (size_t i = 0; i < points.size(); ++i) EXPECT_EQ(back.controlPoints()[i], points[i]) << i;
    EXPECT_EQ(back.epochNs(), spline.epochNs());
  }
}
