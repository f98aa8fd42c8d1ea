// Message <-> core conversions: exact round trips (time in ns, events, calibration, poses).
#include <gtest/gtest.h>

#include "vwe_vo/ros/conversions.h"

namespace vwe_vo {
namespace {

TEST(Conversions, TimeRoundTripIsExact) {
  for (int64_t t : {int64_t(0), int64_t(1), int64_t(999999999), int64_t(1000000000),
                    int64_t(1700000000123456789)}) {
    EXPECT_EQ(toNs(toRosTime(t)), t);
  }
  EXPECT_EQ(toRosTime(1500000001).sec, 1u);
  EXPECT_EQ(toRosTime(1500000001).nsec, 500000001u);
  EXPECT_THROW(toRosTime(-1), std::invalid_argument);
}

TEST(Conversions, EventsRoundTrip) {
  EventVector ev{{10, 1, 2, 1}, {20, 345, 259, -1}, {30, 0, 0, 1}};
  const EventArray msg = eventsToMsg(ev, 0, ev.size(), 346, 260, "davis", 1000000000);
  EXPECT_EQ(msg.width, 346u);
  EXPECT_EQ(msg.height, 260u);
  EXPECT_EQ(msg.header.frame_id, "davis");
  EXPECT_EQ(toNs(msg.header.stamp), 1000000030);
  EventVector back;
  EventConversionStats stats;
  eventsFromMsg(msg, &back, &stats);
  EXPECT_EQ(stats.dropped, 0u);
  ASSERT_EQ(back.size(), ev.size());
  for (size_t i = 0; i < ev.size(); ++i) {
    EXPECT_EQ(back[i].t_ns, ev[i].t_ns + 1000000000);
    EXPECT_EQ(back[i].x, ev[i].x);
    EXPECT_EQ(back[i].y, ev[i].y);
    EXPECT_EQ(back[i].polarity, ev[i].polarity);
  }
  EventArray bad = msg;
  bad.events[1].x = 400;
  eventsFromMsg(bad, &back, &stats);
  EXPECT_EQ(stats.dropped, 1u);
  EXPECT_EQ(back.size(), 2u);
}

TEST(Conversions, CameraInfoRoundTrip) {
  CameraCalibration c;
  c.width = 346;
  c.height = 260;
  c.fx = 255.2;
  c.fy = 255.0;
  c.cx = 172.6;
  c.cy = 129.4;
  c.distortion = {-0.331, 0.128, 0.0004, -0.0002, 0.0};
  const sensor_msgs::CameraInfo msg = calibrationToMsg(c, "davis");
  EXPECT_EQ(msg.distortion_model, "plumb_bob");
  const CameraCalibration b = calibrationFromMsg(msg);
  EXPECT_EQ(b.width, 346);
  EXPECT_DOUBLE_EQ(b.fx, c.fx);
  EXPECT_DOUBLE_EQ(b.cy, c.cy);
  EXPECT_DOUBLE_EQ(b.distortion[0], c.distortion[0]);
  sensor_msgs::CameraInfo bad = msg;
  bad.distortion_model = "equidistant";
  EXPECT_THROW(calibrationFromMsg(bad), std::invalid_argument);
  bad = msg;
  bad.K[0] = 0;
  EXPECT_THROW(calibrationFromMsg(bad), std::invalid_argument);
}

TEST(Conversions, SplineRoundTripKeepsKnotsControlPointsAndStandstills) {
  std::vector<double> knots;
  for (int k = 0; k < 11; ++k) knots.push_back((k - 3) * 0.3);
  std::vector<Vec2> P;
  for (int i = 0; i < 7; ++i) P.emplace_back(0.1 * i, 0.02 * i * i);
  BSpline spline(3, knots, P, 5000000000);
  spline.setStandstills({{0.4, 0.6}});
  const SplineTrajectory msg = splineToMsg(spline, 4, "odom");
  EXPECT_EQ(msg.header.frame_id, "odom");
  EXPECT_EQ(msg.first_free_control_point, 4u);
  EXPECT_EQ(toNs(msg.valid_from), 5000000000 + secToNs(spline.validFrom()));
  const BSpline back = splineFromMsg(msg);
  EXPECT_EQ(back.epochNs(), spline.epochNs());
  EXPECT_EQ(back.knots(), spline.knots());
  ASSERT_EQ(back.standstills().size(), 1u);
  for (double u = 0.0; u < 1.2; u += 0.05)
    EXPECT_TRUE(back.T_odom_base(u).isApprox(spline.T_odom_base(u), 1e-12)) << u;
  SplineTrajectory bad = msg;
  bad.control_y.pop_back();
  EXPECT_THROW(splineFromMsg(bad), std::invalid_argument);
  bad = msg;
  bad.knots.pop_back();
  EXPECT_THROW(splineFromMsg(bad), std::invalid_argument);
}

TEST(Conversions, OdometryGivesTheTwistOfBaseLink) {
  nav_msgs::Odometry msg;
  msg.header.stamp = toRosTime(12345678901);
  msg.twist.twist.linear.x = 0.7;
  msg.twist.twist.linear.y = 5.0;  // not the forward speed
  msg.twist.twist.angular.z = -0.2;
  msg.twist.twist.angular.x = 3.0;
  const OdometrySample o = odometryFromMsg(msg);
  EXPECT_EQ(o.t_ns, 12345678901);
  EXPECT_EQ(o.v_mps, 0.7);
  EXPECT_EQ(o.yaw_rate_rad_s, -0.2);
}

TEST(Conversions, GyroInTheCameraFrameGivesTheYawRateOfBaseLink) {
  // A forward-looking optical frame (z forward, x right, y down) on base_link (x forward, y left,
  // z up): base z = -camera y, so a left turn (+yaw) is a negative rate about the camera's y.
  Mat3 R_base_cam;
  R_base_cam << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  const Pose3 T_base_cam = makePose(Quat(R_base_cam), Vec3(0.1, 0.0, 0.3));
  sensor_msgs::Imu msg;
  msg.header.stamp = toRosTime(5000000007);
  msg.angular_velocity.x = 0.05;
  msg.angular_velocity.y = -0.4;
  msg.angular_velocity.z = 0.02;
  const GyroSample g = gyroFromMsg(msg, T_base_cam);
  EXPECT_EQ(g.t_ns, 5000000007);
  EXPECT_NEAR(g.yaw_rate_rad_s, 0.4, 1e-12);
  // Pitched down by 10 deg about the camera's x: the yaw rate is the projection on base z.
  const Pose3 T_pitched = makePose(
      Quat(R_base_cam * Eigen::AngleAxisd(0.17453292519943295, Vec3::UnitX())), Vec3::Zero());
  msg.angular_velocity.x = 0.0;
  msg.angular_velocity.z = 0.0;
  EXPECT_NEAR(gyroFromMsg(msg, T_pitched).yaw_rate_rad_s, 0.4 * std::cos(0.17453292519943295),
              1e-12);
}

TEST(Conversions, PoseRoundTrip) {
  const Pose3 T =
      makePose(Quat(Eigen::AngleAxisd(0.7, Vec3(1, 2, 3).normalized())), Vec3(1, -2, 3));
  const Pose3 B = poseFromMsg(poseToMsg(T));
  EXPECT_LT((B.matrix() - T.matrix()).norm(), 1e-12);
  const geometry_msgs::Transform tf = transformToMsg(T);
  EXPECT_DOUBLE_EQ(tf.translation.y, -2.0);
}

}  // namespace
}  // namespace vwe_vo
