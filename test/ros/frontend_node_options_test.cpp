// frontend_node parameters: ~calibration (no camera_info is ever published), ~use_odom (the arc's
// speed and standstill come from /odom), an integer ~nominal_speed, and ~max_latency_s (a burst of
// data more than 4 x ~max_latency_s behind skips whole windows, counted, and the node recovers).
#include "frontend_node_harness.h"

using namespace vwe_vo;
using namespace vwe_vo::test;

using FrontendNodeOptions = HarnessTest;

TEST_F(FrontendNodeOptions, CalibrationParameterAndIntegerNominalSpeedAreUsed) {
  // No camera_info is ever published: arcs at all mean ~calibration was used. Without /odom the
  // speed is ~nominal_speed (1, an integer parameter), not the config's 0.3.
  const auto [t0, t1] = harness->stream(0.9);
  const std::vector<AckermannArc> arcs = harness->arcsIn(t0, t1, 2);
  ASSERT_GE(arcs.size(), 2u);
  for (const AckermannArc& a : arcs) EXPECT_DOUBLE_EQ(a.v, 1.0);
}

TEST_F(FrontendNodeOptions, SpeedComesFromOdometry) {
  StreamOptions o;
  o.odom_speed = kV;
  const auto [t0, t1] = harness->stream(1.5, o);
  const std::vector<AckermannArc> arcs = harness->arcsIn(t0, t1, 4);
  EXPECT_GE(arcs.size(), 4u);
  expectTrueArcs(arcs);  // v == 0.4 from /odom, not the nominal 1.0
}

TEST_F(FrontendNodeOptions, OdometryAtRestGivesStandstill) {
  StreamOptions o;
  o.odom_speed = 0.0;
  const auto [t0, t1] = harness->stream(1.2, o);
  const std::vector<AckermannArc> arcs = harness->arcsIn(t0 + secToNs(kWindowS), t1, 2);
  ASSERT_GE(arcs.size(), 2u);
  for (const AckermannArc& a : arcs) {
    EXPECT_EQ(a.status, AckermannArc::STANDSTILL);
    EXPECT_EQ(a.omega, 0.0);
    EXPECT_EQ(a.v, 0.0);
  }
}

TEST_F(FrontendNodeOptions, FallingBehindSkipsWindowsAndRecovers) {
  StreamOptions burst;
  burst.odom_speed = kV;
  burst.burst = true;
  const auto [b0, b1] = harness->stream(4.0, burst);  // ~13 windows at once, max_latency_s 0.1
  EXPECT_TRUE(harness->logged("windows skipped", rosgraph_msgs::Log::WARN, 10.0));
  const std::vector<AckermannArc> burst_arcs = harness->arcsIn(b0, b1, 1, 10.0);
  EXPECT_GE(burst_arcs.size(), 1u);
  // The skipped windows go out as LOST arcs: fewer estimated, none missing in time.
  size_t estimated = 0, lost = 0;
  for (const AckermannArc& a : burst_arcs) {
    estimated += a.status == AckermannArc::OK;
    lost += a.status == AckermannArc::LOST;
  }
  EXPECT_LT(estimated, size_t(4.0 / kWindowS)) << "no window was skipped";
  EXPECT_GE(lost, 1u);
  for (size_t i = 1; i < burst_arcs.size(); ++i)
    EXPECT_EQ(burst_arcs[i].t_start, burst_arcs[i - 1].t_end) << "a gap before arc " << i;
  StreamOptions o;
  o.odom_speed = kV;
  const auto [t0, t1] = harness->stream(1.5, o);
  const std::vector<AckermannArc> arcs = harness->arcsIn(t0 + secToNs(kWindowS), t1, 3);
  EXPECT_GE(arcs.size(), 3u);
  expectTrueArcs(arcs);
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "frontend_node_options_test");
  ros::AsyncSpinner spinner(1);
  spinner.start();
  const int result = RUN_ALL_TESTS();
  spinner.stop();  // no callback may run while the harness (its subscribers, mutex) is destroyed
  HarnessTest::harness.reset();
  ros::shutdown();
  return result;
}
