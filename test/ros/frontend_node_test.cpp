// frontend_node against synthetic events of random 3D points seen along a known Ackermann arc
// (omega = 20 deg/s, v = 0.4 m/s = ~nominal_speed). The tests run in order on one node and one
// continuous data clock: a refused calibration first, then valid data, then bad input, each
// followed by valid data that must still give correct arcs.
#include "frontend_node_harness.h"

using namespace vwe_vo;
using namespace vwe_vo::test;

namespace {
std::unique_ptr<Harness> harness;
}  // namespace

TEST(FrontendNode, CameraInfoWithZeroFocalLengthIsRefusedAndTheNodeWaits) {
  ASSERT_TRUE(harness->waitForNode(20.0)) << "frontend_node did not connect";
  sensor_msgs::CameraInfo bad = harness->validCameraInfo();
  bad.K[0] = 0.0;
  harness->publishCameraInfo(bad);
  EXPECT_TRUE(harness->logged("focal length fx", rosgraph_msgs::Log::WARN));
  StreamOptions o;
  o.advance_clock = false;
  harness->stream(0.7, o);
  ros::WallDuration(1.0).sleep();
  EXPECT_EQ(harness->numArcs(), 0u) << "arcs without a valid calibration";
}

TEST(FrontendNode, RecoversTheYawRateAtTheWindowRate) {
  harness->publishCameraInfo(harness->validCameraInfo());
  EXPECT_TRUE(harness->logged("calibration from camera_info", rosgraph_msgs::Log::INFO));
  const double duration_s = 3.0;
  const auto [t0, t1] = harness->stream(duration_s);
  const size_t expected = size_t(duration_s / kWindowS);  // 10 windows; the last completes later
  const std::vector<AckermannArc> arcs = harness->arcsIn(t0, t1, expected - 1);
  EXPECT_GE(arcs.size(), expected - 2);
  EXPECT_LE(arcs.size(), expected + 1);
  expectTrueArcs(arcs);
  for (size_t i = 1; i < arcs.size(); ++i)
    EXPECT_NEAR((arcs[i].header.stamp - arcs[i - 1].header.stamp).toSec(), kWindowS, 0.05);

  // Dead-reckoned odometry: one per arc, in odom, twist = the arc, yaw = omega * elapsed time.
  const std::vector<nav_msgs::Odometry> odoms = harness->odometry();
  ASSERT_GE(odoms.size(), arcs.size());
  const nav_msgs::Odometry& last = odoms.back();
  EXPECT_EQ(last.header.frame_id, "odom");
  EXPECT_EQ(last.child_frame_id, "base_link");
  EXPECT_NEAR(last.twist.twist.angular.z * kDegPerRad, kOmega * kDegPerRad, 1.0);
  EXPECT_DOUBLE_EQ(last.twist.twist.linear.x, kV);
  const double yaw = yawOf(poseFromMsg(last.pose.pose).linear());
  const double elapsed_s = (last.header.stamp - arcs.front().t_start).toSec();
  EXPECT_NEAR(yaw, kOmega * elapsed_s, 2.0 / kDegPerRad);
  EXPECT_GT(poseFromMsg(last.pose.pose).translation().x(), 0.5 * kV * elapsed_s);

  // The VWE image of the windows (rendered because this test subscribes).
  const std::vector<sensor_msgs::Image> images = harness->images();
  ASSERT_FALSE(images.empty());
  EXPECT_EQ(images.back().encoding, "mono8");
  EXPECT_GT(images.back().width, 0u);
  EXPECT_EQ(images.back().data.size(), size_t(images.back().width) * images.back().height);
  EXPECT_EQ(images.back().header.frame_id, "davis");
}

TEST(FrontendNode, EmptyPacketsOutsideEventsAndLateEventsAreCountedNotFatal) {
  StreamOptions o;
  o.empty_packets = true;
  o.outside_events = true;
  o.late_packet = true;
  const auto [t0, t1] = harness->stream(1.5, o);
  const std::vector<AckermannArc> arcs = harness->arcsIn(t0, t1, 4);
  EXPECT_GE(arcs.size(), 4u);
  expectTrueArcs(arcs);
  EXPECT_TRUE(harness->logged("empty EventArray ignored", rosgraph_msgs::Log::WARN));
  EXPECT_TRUE(
      harness->logged("events outside the 346x260 sensor dropped", rosgraph_msgs::Log::WARN));
  EXPECT_TRUE(harness->logged("older than the newest one dropped", rosgraph_msgs::Log::WARN));
}

TEST(FrontendNode, WrongSizeEventArrayIsRefusedAndValidDataStillWorks) {
  ros::WallDuration(0.5).sleep();
  const size_t before = harness->numArcs();
  StreamOptions o;
  o.width = 240;
  o.height = 180;
  o.advance_clock = false;
  harness->stream(0.7, o);
  EXPECT_TRUE(harness->logged("EventArray is 240x180 but the calibration is 346x260",
                              rosgraph_msgs::Log::ERROR));
  ros::WallDuration(1.0).sleep();
  EXPECT_EQ(harness->numArcs(), before) << "arcs from refused packets";
  const auto [t0, t1] = harness->stream(1.5);
  const std::vector<AckermannArc> arcs = harness->arcsIn(t0, t1, 4);
  EXPECT_GE(arcs.size(), 4u);
  expectTrueArcs(arcs);
}

TEST(FrontendNode, CameraInfoOfAnotherSizeIsRefusedAndTheFirstKept) {
  harness->publishCameraInfo(test::cameraInfoOfAnotherSize(harness->validCameraInfo()));
  EXPECT_TRUE(harness->logged("camera_info is 240x180 but the calibration in use is 346x260",
                              rosgraph_msgs::Log::ERROR));
  const auto [t0, t1] = harness->stream(1.2);
  const std::vector<AckermannArc> arcs = harness->arcsIn(t0, t1, 3);
  EXPECT_GE(arcs.size(), 3u);
  expectTrueArcs(arcs);
}

TEST(FrontendNode, LoopedStreamResetsAndArcsKeepComing) {
  harness->rewindClock(5.0);
  const auto [t0, t1] = harness->stream(1.5);
  EXPECT_TRUE(harness->logged("front-end reset", rosgraph_msgs::Log::WARN));
  const std::vector<AckermannArc> arcs = harness->arcsIn(t0, t1, 4);
  EXPECT_GE(arcs.size(), 4u);
  expectTrueArcs(arcs);
  // The dead reckoning restarted: the pose at the end of the looped data is ~1.5 s of arc.
  const nav_msgs::Odometry last = harness->odometry().back();
  EXPECT_LT(poseFromMsg(last.pose.pose).translation().norm(), 2.0 * kV * 1.5);
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "frontend_node_test");
  ros::AsyncSpinner spinner(1);
  spinner.start();
  harness = std::make_unique<Harness>();
  const int result = RUN_ALL_TESTS();
  spinner.stop();  // no callback may run while the harness (its subscribers, mutex) is destroyed
  harness.reset();
  ros::shutdown();
  return result;
}
