// frontend_node under floods and faulty input (the overload policy and the input checks of
// NodeInput): for each, memory stays bounded (the queued events never pass ~max_queue_events =
// 100000, i.e. 100000 x 16 bytes = 1.6 MB, or one packet alone), what is thinned or
// refused is counted, nothing is dropped, and true arcs come again within a window after it. Every
// wait is for a condition (arcs by data time, a counter of the status line), with generous
// timeouts; nothing depends on how fast the machine is.
#include <regex>

#include "frontend_node_harness.h"

using namespace vwe_vo;
using namespace vwe_vo::test;

namespace {
constexpr long kBound = 100000;  // ~max_queue_events of the .test

/// A number of the front-end's own status line, e.g. "3 windows skipped behind" (-1: none).
long statusNumber(const std::string& line, const std::string& after) {
  std::smatch match;
  if (!std::regex_search(line, match, std::regex("(\\d+) " + after))) return -1;
  return std::stol(match[1]);
}

/// Odometry at the true speed and yaw rate over the stream (use_odom: the arcs' speed).
StreamOptions withOdometry(StreamOptions o = StreamOptions()) {
  o.odom_speed = kV;
  return o;
}

/// Waits for a status line newer than the data streamed so far: one whose counters include it.
std::string freshStatus(Harness& h, const std::string& kind, const std::string& key, long above) {
  EXPECT_TRUE(h.inputCounterAbove(kind, key, above, 30.0)) << kind << " " << key;
  return h.statusLine();
}
}  // namespace

class FrontendNodeFlood : public HarnessTest {
 protected:
  /// After a fault: valid data again must give true arcs within a window of its start.
  void expectRecovery() {
    const auto [t0, t1] = harness->stream(1.5, withOdometry());
    const std::vector<AckermannArc> arcs = harness->arcsIn(t0 + secToNs(kWindowS), t1, 3, 60.0);
    EXPECT_GE(arcs.size(), 3u);
    expectTrueArcs(arcs);
  }
  void expectBoundedAndNothingDropped() {
    EXPECT_LE(harness->inputCounter("overload", "max_queued"), kBound + 150000)
        << "queued events past the bound";
    EXPECT_EQ(harness->inputCounter("events", "dropped"), 0) << harness->statusLine();
    EXPECT_EQ(harness->inputCounter("timestamps", "resets"), 0) << harness->statusLine();
  }
};

TEST_F(FrontendNodeFlood, ABurstAtTenTimesTheEventRateIsThinnedNotDropped) {
  expectRecovery();  // steady state first
  const long in_before = harness->inputCounter("events", "in");
  StreamOptions burst = withOdometry();
  burst.rate_factor = 10.0;  // 500 kev/s for 1 s, published as fast as possible
  burst.burst = true;
  const auto [b0, b1] = harness->stream(1.0, burst);
  const std::string status = freshStatus(*harness, "events", "in", in_before + 99);
  EXPECT_GT(harness->inputCounter("overload", "thinned"), 0) << status;
  // Thinned, the burst still gives an arc for every window it spans: no lost arc, no gap.
  const std::vector<AckermannArc> arcs = harness->arcsIn(b0, b1, 3, 60.0);
  EXPECT_GE(arcs.size(), 3u) << status;
  expectTrueArcs(arcs);
  for (size_t i = 1; i < arcs.size(); ++i)
    EXPECT_NEAR((arcs[i].header.stamp - arcs[i - 1].header.stamp).toSec(), kWindowS, 0.05);
  expectRecovery();
  EXPECT_EQ(statusNumber(harness->statusLine(), "windows skipped behind"), 0)
      << harness->statusLine();
  expectBoundedAndNothingDropped();
}

TEST_F(FrontendNodeFlood, PacketsOfOneHundredFiftyThousandEventsAreTaken) {
  const long in_before = std::max(0L, harness->inputCounter("events", "in"));
  StreamOptions big = withOdometry();
  big.rate_factor = 10.0;
  big.packet_s = 0.3;  // 150 k events a packet
  const auto [b0, b1] = harness->stream(1.2, big);
  freshStatus(*harness, "events", "in", in_before + 3);
  const std::vector<AckermannArc> arcs = harness->arcsIn(b0, b1, 2, 60.0);
  EXPECT_GE(arcs.size(), 2u);
  expectTrueArcs(arcs);
  expectRecovery();
  expectBoundedAndNothingDropped();
}

TEST_F(FrontendNodeFlood, NonFiniteOdometryAndImuAreRefusedAndCounted) {
  ASSERT_TRUE(harness->waitForImuSubscriber(20.0));
  const long odom_before = std::max(0L, harness->inputCounter("odom", "refused"));
  const long imu_before = std::max(0L, harness->inputCounter("imu", "refused"));
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  for (int i = 0; i < 5; ++i) {
    harness->publishOdomAndImu(nan, nan);
    harness->publishOdomAndImu(inf, -inf);
  }
  EXPECT_TRUE(harness->inputCounterAbove("odom", "refused", odom_before + 9, 30.0))
      << harness->statusLine();
  EXPECT_TRUE(harness->inputCounterAbove("imu", "refused", imu_before + 9, 30.0))
      << harness->statusLine();
  EXPECT_TRUE(harness->logged("non-finite", rosgraph_msgs::Log::WARN));
  expectRecovery();
}

TEST_F(FrontendNodeFlood, DuplicatedAndReorderedPacketsAreAbsorbedWithoutAReset) {
  const long jumps_before = std::max(0L, harness->inputCounter("timestamps", "jumps"));
  StreamOptions o = withOdometry();
  o.duplicate_every = 7;
  o.reorder_every = 11;
  const auto [t0, t1] = harness->stream(2.0, o);
  EXPECT_TRUE(harness->inputCounterAbove("timestamps", "jumps", jumps_before, 30.0))
      << harness->statusLine();
  EXPECT_TRUE(harness->logged("backward timestamp jump", rosgraph_msgs::Log::WARN));
  const std::vector<AckermannArc> arcs = harness->arcsIn(t0, t1, 5, 60.0);
  EXPECT_GE(arcs.size(), 5u);
  expectTrueArcs(arcs);
  expectRecovery();
  expectBoundedAndNothingDropped();
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "frontend_node_flood_test");
  ros::AsyncSpinner spinner(1);
  spinner.start();
  const int result = RUN_ALL_TESTS();
  spinner.stop();  // no callback may run while the harness (its subscribers, mutex) is destroyed
  HarnessTest::harness.reset();
  ros::shutdown();
  return result;
}
