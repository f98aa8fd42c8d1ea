// Our in-tree Event/EventArray must be wire-identical to the DAVIS driver's dvs_msgs so that
// driver bags play into our nodes unchanged: the MD5 sums are the contract.
#include <gtest/gtest.h>
#include <ros/message_traits.h>

#include "vwe_vo/AckermannArc.h"
#include "vwe_vo/Event.h"
#include "vwe_vo/EventArray.h"
#include "vwe_vo/SplineTrajectory.h"

TEST(Messages, EventArrayMd5MatchesDvsMsgs) {
  EXPECT_STREQ(ros::message_traits::MD5Sum<vwe_vo::EventArray>::value(),
               "5e8beee5a6c107e504c2e78903c224b8");
}

TEST(Messages, EventMd5MatchesDvsMsgs) {
  EXPECT_STREQ(ros::message_traits::MD5Sum<vwe_vo::Event>::value(),
               "40d339b261445b8ce9a6fef01267cd5d");
}

TEST(Messages, AckermannArcStatusConstants) {
  EXPECT_EQ(vwe_vo::AckermannArc::OK, 0);
  EXPECT_EQ(vwe_vo::AckermannArc::STANDSTILL, 1);
  EXPECT_EQ(vwe_vo::AckermannArc::LOST, 2);
  EXPECT_EQ(vwe_vo::AckermannArc::LOW_EVENTS, 3);
}

TEST(Messages, SplineTrajectoryHasDesignFields) {
  vwe_vo::SplineTrajectory s;
  s.degree = 3;
  s.knots = {0, 0, 0, 0, 1, 1, 1, 1};
  s.control_x = {0, 1, 2, 3};
  s.control_y = {0, 0, 0, 0};
  s.first_free_control_point = 1;
  EXPECT_EQ(s.knots.size(), s.control_x.size() + s.degree + 1);
}
