// frontend_node against synthetic events of random 3D points seen along a known Ackermann arc
// (omega = 20 deg/s, v = 0.4 m/s = ~nominal_speed), all on one node and one continuous data clock.
// The suite's set-up offers a refused calibration and data first, then a valid calibration; each
// test then feeds valid data or bad input followed by valid data that must still give correct arcs,
// in any order.
#include "frontend_node_harness.h"

using namespace vwe_vo;
using namespace vwe_vo::test;

/// Before any test: a camera_info with a zero focal length and 0.7 s of data (what came out is
/// kept for the first test), then the valid calibration.
class FrontendNode : public HarnessTest {
 protected:
  static void SetUpTestSuite() {
    HarnessTest::SetUpTestSuite();
    if (!connected_ || calibrated_) return;
    sensor_msgs::CameraInfo bad = harness->validCameraInfo();
    bad.K[0] = 0.0;
    harness->publishCameraInfo(bad);
    StreamOptions o;
    o.advance_clock = false;
    harness->stream(0.7, o);
    ros::WallDuration(1.0).sleep();
    arcs_before_calibration_ = harness->numArcs();
    harness->publishCameraInfo(harness->validCameraInfo());
    calibrated_ = true;
  }
  inline static bool calibrated_ = false;
  inline static size_t arcs_before_calibration_ = 0;
};

TEST_F(FrontendNode, CameraInfoWithZeroFocalLengthIsRefusedAndTheNodeWaits) {
  EXPECT_TRUE(harness->logged("focal length fx", rosgraph_msgs::Log::WARN));
  EXPECT_EQ(arcs_before_calibration_, 0u) << "arcs without a valid calibration";
}

TEST_F(FrontendNode, RecoversTheYawRateAtTheWindowRate) {
  EXPECT_TRUE(harness->logged("calibration from camera_info", rosgraph_msgs::Log::INFO));
  const size_t odoms_before = harness->odometry().size();
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
  const std::vector<nav_msgs::Odometry> all_odoms = harness->odometry();
  const std::vector<nav_msgs::Odometry> odoms(all_odoms.begin() + long(odoms_before),
                                              all_odoms.end());
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

TEST_F(FrontendNode, EmptyPacketsOutsideEventsAndLateEventsAreCountedNotFatal) {
  const long empty_before = harness->inputCounter("events", "empty");
  const long outside_before = harness->inputCounter("events", "outside");
  StreamOptions o;
  o.empty_packets = true;
  o.outside_events = true;
  o.late_packet = true;
  const auto [t0, t1] = harness->stream(1.5, o);
  const std::vector<AckermannArc> arcs = harness->arcsIn(t0, t1, 4);
  EXPECT_GE(arcs.size(), 4u);
  expectTrueArcs(arcs);
  EXPECT_TRUE(harness->inputCounterAbove("events", "empty", empty_before))
      << "empty packets not counted";
  EXPECT_TRUE(harness->inputCounterAbove("events", "outside", outside_before))
      << "outside events not counted";
  // The late packet: absorbed by the input's timestamp policy, warned about and counted.
  EXPECT_TRUE(harness->logged("backward timestamp jump", rosgraph_msgs::Log::WARN));
  EXPECT_TRUE(harness->inputCounterAbove("timestamps", "jumps", 0)) << "jump not counted";
  EXPECT_EQ(harness->inputCounter("timestamps", "resets_gap"), 0);
}

TEST_F(FrontendNode, WrongSizeEventArrayIsRefusedAndValidDataStillWorks) {
  ros::WallDuration(0.5).sleep();
  const size_t before = harness->numArcs();
  const long wrong_size_before = harness->inputCounter("events", "wrong_size");
  StreamOptions o;
  o.width = 240;
  o.height = 180;
  o.advance_clock = false;
  harness->stream(0.7, o);
  EXPECT_TRUE(harness->inputCounterAbove("events", "wrong_size", wrong_size_before))
      << "wrong-size packets not counted";
  ros::WallDuration(1.0).sleep();
  EXPECT_EQ(harness->numArcs(), before) << "arcs from refused packets";
  const auto [t0, t1] = harness->stream(1.5);
  const std::vector<AckermannArc> arcs = harness->arcsIn(t0, t1, 4);
  EXPECT_GE(arcs.size(), 4u);
  expectTrueArcs(arcs);
}

TEST_F(FrontendNode, CameraInfoOfAnotherSizeIsRefusedAndTheFirstKept) {
  const long refused_before = harness->inputCounter("camera_info", "refused");
  harness->publishCameraInfo(test::cameraInfoOfAnotherSize(harness->validCameraInfo()));
  const auto [t0, t1] = harness->stream(1.2);
  EXPECT_TRUE(harness->inputCounterAbove("camera_info", "refused", refused_before))
      << "not counted as refused";
  const std::vector<AckermannArc> arcs = harness->arcsIn(t0, t1, 3);
  EXPECT_GE(arcs.size(), 3u);
  expectTrueArcs(arcs);
}

TEST_F(FrontendNode, LoopedStreamResetsAndArcsKeepComing) {
  harness->stream(1.0);  // data to loop back from, whatever ran before
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
  const int result = RUN_ALL_TESTS();
  spinner.stop();  // no callback may run while the harness (its subscribers, mutex) is destroyed
  HarnessTest::harness.reset();
  ros::shutdown();
  return result;
}
