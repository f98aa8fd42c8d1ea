// backend_node behind frontend_node, both fed synthetic events of random 3D points along a known
// Ackermann arc (omega = 20 deg/s, v = 0.4 m/s): the refined spline on /vwe/trajectory, the
// odometry on /vwe/odom, the tf odom -> base_link, and resets on a looped stream and a gap.
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>

#include "frontend_node_harness.h"
#include "node_test_util.h"
#include "vwe_vo/SplineTrajectory.h"

using namespace vwe_vo;
using namespace vwe_vo::test;

namespace {

class BackendRecorder {
 public:
  BackendRecorder() {
    trajectory_sub_ = nh_.subscribe(topics::kTrajectory, 100, &BackendRecorder::onTrajectory, this);
    odom_sub_ = nh_.subscribe(topics::kBackendOdom, 10000, &BackendRecorder::onOdom, this);
    rosout_sub_ = nh_.subscribe("/rosout", 1000, &BackendRecorder::onLog, this);
  }
  bool waitForNode(double timeout_s) {
    const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(timeout_s);
    while (ros::WallTime::now() < end) {
      if (trajectory_sub_.getNumPublishers() > 0 && odom_sub_.getNumPublishers() > 0) return true;
      ros::WallDuration(0.05).sleep();
    }
    return false;
  }
  /// Waits until at least n trajectories have arrived after `after` were there.
  bool waitForTrajectories(size_t n, double timeout_s) {
    const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(timeout_s);
    while (ros::WallTime::now() < end) {
      if (trajectories().size() >= n) return true;
      ros::WallDuration(0.05).sleep();
    }
    return false;
  }
  std::vector<SplineTrajectory> trajectories() {
    std::lock_guard<std::mutex> lock(mutex_);
    return trajectories_;
  }
  std::vector<nav_msgs::Odometry> odometry() {
    std::lock_guard<std::mutex> lock(mutex_);
    return odoms_;
  }
  /// True if the node logged a line containing `text` at `level` or above.
  bool logged(const std::string& text, uint8_t level, double timeout_s = 3.0) {
    return test::waitForLog(mutex_, logs_, text, level, timeout_s);
  }
  /// Log lines of either node so far (a mark for loggedSince).
  size_t numLogs() {
    std::lock_guard<std::mutex> lock(mutex_);
    return logs_.size();
  }
  /// True if a line after the first `from` contains `text`.
  bool loggedSince(size_t from, const std::string& text) {
    std::lock_guard<std::mutex> lock(mutex_);
    for (size_t i = from; i < logs_.size(); ++i)
      if (logs_[i].msg.find(text) != std::string::npos) return true;
    return false;
  }
  /// The newest value of a counter of backend_node's input status line (-1: none yet).
  long backendCounter(const std::string& kind, const std::string& key) {
    std::lock_guard<std::mutex> lock(mutex_);
    std::vector<rosgraph_msgs::Log> own;
    for (const rosgraph_msgs::Log& l : logs_)
      if (l.name == "/backend_node") own.push_back(l);
    return test::inputCounter(own, kind, key);
  }

 private:
  void onTrajectory(const SplineTrajectory::ConstPtr& m) {
    std::lock_guard<std::mutex> lock(mutex_);
    trajectories_.push_back(*m);
  }
  void onOdom(const nav_msgs::Odometry::ConstPtr& m) {
    std::lock_guard<std::mutex> lock(mutex_);
    odoms_.push_back(*m);
  }
  void onLog(const rosgraph_msgs::Log::ConstPtr& m) {
    if (m->name != "/backend_node" && m->name != "/frontend_node") return;
    std::lock_guard<std::mutex> lock(mutex_);
    logs_.push_back(*m);
  }
  ros::NodeHandle nh_;
  ros::Subscriber trajectory_sub_, odom_sub_, rosout_sub_;
  std::mutex mutex_;
  std::vector<SplineTrajectory> trajectories_;
  std::vector<nav_msgs::Odometry> odoms_;
  std::vector<rosgraph_msgs::Log> logs_;
};

}  // namespace

/// One frontend_node + backend_node pair for every test, connected and calibrated once; main()
/// destroys the recorders after the spinner stopped.
class BackendNode : public HarnessTest {
 public:
  inline static std::unique_ptr<BackendRecorder> recorder;
  inline static std::unique_ptr<tf2_ros::Buffer> tf_buffer;
  inline static std::unique_ptr<tf2_ros::TransformListener> tf_listener;

 protected:
  static void SetUpTestSuite() {
    HarnessTest::SetUpTestSuite();
    if (recorder) return;
    recorder = std::make_unique<BackendRecorder>();
    tf_buffer = std::make_unique<tf2_ros::Buffer>(ros::Duration(120.0));
    tf_listener = std::make_unique<tf2_ros::TransformListener>(*tf_buffer);
    backend_connected_ = recorder->waitForNode(20.0);
    if (connected_ && backend_connected_) harness->publishCameraInfo(harness->validCameraInfo());
  }
  void SetUp() override {
    HarnessTest::SetUp();
    ASSERT_TRUE(backend_connected_) << "backend_node did not connect";
  }
  inline static bool backend_connected_ = false;
};

TEST_F(BackendNode, PublishesTheRefinedSplineOdometryAndTf) {
  const size_t trajectories_before = recorder->trajectories().size();
  const size_t odoms_before = recorder->odometry().size();
  const auto [t0, t1] = harness->stream(4.0);
  ASSERT_TRUE(recorder->waitForTrajectories(trajectories_before + 2, 60.0))
      << "fewer than 2 refinements published";

  const SplineTrajectory traj = recorder->trajectories().back();
  EXPECT_EQ(traj.header.frame_id, "odom");
  EXPECT_EQ(traj.degree, 3);
  ASSERT_EQ(traj.control_x.size(), traj.control_y.size());
  EXPECT_EQ(traj.knots.size(), traj.control_x.size() + traj.degree + 1);
  EXPECT_GT(traj.valid_to, traj.valid_from);
  const BSpline spline = splineFromMsg(traj);
  EXPECT_EQ(spline.numControlPoints(), int(traj.control_x.size()));
  EXPECT_TRUE(traj.tilt_t.empty());  // without /odom and the IMU the body is planar
  for (double x : traj.control_x) EXPECT_TRUE(std::isfinite(x));
  // Speed along the refined spline near the nominal 0.4 m/s.
  const double u_mid = 0.5 * (spline.validFrom() + spline.validTo());
  EXPECT_NEAR(spline.velocity(u_mid).norm(), kV, 0.1);

  const std::vector<nav_msgs::Odometry> all_odoms = recorder->odometry();
  const std::vector<nav_msgs::Odometry> odoms(all_odoms.begin() + long(odoms_before),
                                              all_odoms.end());
  ASSERT_GE(odoms.size(), 20u);
  for (size_t i = 1; i < odoms.size(); ++i)
    ASSERT_GT(odoms[i].header.stamp, odoms[i - 1].header.stamp);
  const nav_msgs::Odometry& last = odoms.back();
  EXPECT_EQ(last.header.frame_id, "odom");
  EXPECT_EQ(last.child_frame_id, "base_link");
  EXPECT_NEAR(last.twist.twist.angular.z * kDegPerRad, kOmega * kDegPerRad, 5.0);
  // Heading change over the stream: omega * elapsed (within a few degrees).
  const nav_msgs::Odometry& first = odoms.front();
  const double dyaw = yawOf(poseFromMsg(first.pose.pose).linear().transpose() *
                            poseFromMsg(last.pose.pose).linear());
  const double elapsed = (last.header.stamp - first.header.stamp).toSec();
  EXPECT_NEAR(dyaw * kDegPerRad, kOmega * elapsed * kDegPerRad, 5.0);

  // frontend_node follows the refined spline (~follow_backend).
  EXPECT_TRUE(recorder->logged("re-anchored on the back-end's spline", rosgraph_msgs::Log::INFO));

  // tf odom -> base_link at the stamps of the odometry.
  std::string error;
  EXPECT_TRUE(
      tf_buffer->canTransform("odom", "base_link", last.header.stamp, ros::Duration(5.0), &error))
      << error;
  const geometry_msgs::TransformStamped tf =
      tf_buffer->lookupTransform("odom", "base_link", last.header.stamp);
  EXPECT_NEAR(tf.transform.translation.x, last.pose.pose.position.x, 1e-6);
  EXPECT_NEAR(tf.transform.translation.y, last.pose.pose.position.y, 1e-6);
  (void)t0;
  (void)t1;
}

TEST_F(BackendNode, LoopedStreamResetsAndRefinementsKeepComing) {
  harness->stream(2.0);  // data to loop back from, whatever ran before
  const size_t before = recorder->trajectories().size();
  harness->rewindClock(10.0);
  harness->stream(3.5);
  // The input's timestamp policy resets once and says why.
  EXPECT_TRUE(recorder->logged("events jump back", rosgraph_msgs::Log::WARN, 20.0));
  EXPECT_TRUE(
      recorder->logged("back-end reset, the trajectory restarts", rosgraph_msgs::Log::WARN, 20.0));
  EXPECT_TRUE(recorder->waitForTrajectories(before + 1, 60.0)) << "no refinement after the loop";
  // The trajectory restarted near the identity: the newest odometry is within the looped data.
  const nav_msgs::Odometry last = recorder->odometry().back();
  EXPECT_LT(poseFromMsg(last.pose.pose).translation().norm(), 2.0 * kV * 3.5);
}

TEST_F(BackendNode, MultiSecondGapWithoutEventsResetsAndRecovers) {
  harness->stream(1.0);  // data before the gap, whatever ran before
  const size_t before = recorder->trajectories().size();
  harness->rewindClock(-4.0);  // 4 s without events
  harness->stream(3.5);
  EXPECT_TRUE(recorder->logged("events resume 4.", rosgraph_msgs::Log::WARN, 20.0));
  EXPECT_TRUE(recorder->waitForTrajectories(before + 1, 60.0)) << "no refinement after the gap";
  const nav_msgs::Odometry last = recorder->odometry().back();
  EXPECT_TRUE(std::isfinite(last.pose.pose.position.x));
  EXPECT_LT(poseFromMsg(last.pose.pose).translation().norm(), 2.0 * kV * 3.5);
}

// A burst of 10x the event rate (500 kev/s for 1 s, published as fast as possible) into
// backend_node's small event queue (~max_queue_events 100000 in the .test): the queue stays
// bounded, nothing is dropped, the back-end does not reset, refinements go on after it, and the
// odometry stays continuous (no step longer than the true motion allows).
TEST_F(BackendNode, ABurstAtTenTimesTheEventRateNeitherResetsNorBreaksTheOdometry) {
  harness->stream(1.5);            // steady state first
  ros::WallDuration(2.5).sleep();  // counters (cumulative over the suite) that include it
  const long dropped_before = recorder->backendCounter("events", "dropped");
  const long resets_before = recorder->backendCounter("timestamps", "resets");
  ASSERT_GE(dropped_before, 0) << "no status line of backend_node";
  const size_t logs_before = recorder->numLogs();
  const size_t trajectories_before = recorder->trajectories().size();
  StreamOptions burst;
  burst.rate_factor = 10.0;
  burst.burst = true;
  const auto [b0, b1] = harness->stream(1.0, burst);
  const auto [a0, a1] = harness->stream(3.0);
  (void)b0, (void)a0;
  ASSERT_TRUE(recorder->waitForTrajectories(trajectories_before + 2, 90.0))
      << "no refinement after the burst";
  // Odometry up to the data after the burst.
  const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(60.0);
  while (ros::WallTime::now() < end &&
         (recorder->odometry().empty() ||
          toNs(recorder->odometry().back().header.stamp) < a1 - secToNs(1.5)))
    ros::WallDuration(0.05).sleep();
  ros::WallDuration(2.5).sleep();  // a status line (every 1 s) that counts all of it
  EXPECT_FALSE(recorder->loggedSince(logs_before, "back-end reset"));
  EXPECT_EQ(recorder->backendCounter("events", "dropped"), dropped_before);
  EXPECT_EQ(recorder->backendCounter("timestamps", "resets"), resets_before);
  const long max_queued = recorder->backendCounter("overload", "max_queued");
  EXPECT_LE(max_queued, 100000 + 50000) << "queued events past the bound (+ one burst packet)";
  // Continuous: between consecutive poses (20 Hz) at most the true motion plus a margin, across
  // the burst and the refinements that followed it.
  const std::vector<nav_msgs::Odometry> odom = recorder->odometry();
  size_t checked = 0;
  for (size_t i = 1; i < odom.size(); ++i) {
    const int64_t t = toNs(odom[i].header.stamp), t_prev = toNs(odom[i - 1].header.stamp);
    if (t < b1 - secToNs(2.0) || t <= t_prev) continue;
    const double step = (poseFromMsg(odom[i].pose.pose).translation() -
                         poseFromMsg(odom[i - 1].pose.pose).translation())
                            .norm();
    EXPECT_LE(step, 3.0 * kV * nsToSec(t - t_prev) + 0.005) << "jump at " << nsToSec(t) << " s";
    ++checked;
  }
  EXPECT_GE(checked, 40u);
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "backend_node_test");
  ros::AsyncSpinner spinner(2);
  spinner.start();
  const int result = RUN_ALL_TESTS();
  spinner.stop();  // no callback may run while the recorders (their subscribers, mutexes) are
                   // destroyed
  BackendNode::tf_listener.reset();
  BackendNode::tf_buffer.reset();
  BackendNode::recorder.reset();
  HarnessTest::harness.reset();
  ros::shutdown();
  return result;
}
