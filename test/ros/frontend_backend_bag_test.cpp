// End to end: `rosbag play --clock -r 0.5` of a simulated bag (indoor_circle, 5 s,
// 0.4 m/s, 25 deg/s; generated into a temporary directory) into frontend_node + backend_node on
// simulated time. Half rate: the two need ~0.9 + ~1.25 core-seconds per second of this data
// (scripts/replay_check.py), more than the 2 cores of the machines this runs on; latencies below
// are on the simulated clock. The back-end must publish /vwe/trajectory once per update_interval_s
// of config/vwe_vo.yaml, /vwe/odom and the tf odom -> base_link at ~odom_rate_hz in data time, keep
// up with the playback, and the tf tree odom -> base_link -> davis must answer lookups at recent
// times while it plays.
#include <tf2_eigen/tf2_eigen.h>
#include <tf2_msgs/TFMessage.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_listener.h>

#include <memory>

#include "bag_replay.h"
#include "vwe_vo/SplineTrajectory.h"
#include "vwe_vo/io/files.h"
#include "vwe_vo/io/options_yaml.h"
#include "vwe_vo/ros/topics.h"

using namespace vwe_vo;
using namespace vwe_vo::test;

namespace {

constexpr double kBagDurationS = 5.0;
constexpr double kOdomRateHz = 20.0;  // ~odom_rate_hz in frontend_backend_bag_test.test
constexpr double kRate = 0.5;         // playback rate

/// One look at the tf tree while the bag plays.
struct TfSample {
  ros::Time now;  // simulated clock when looked
  bool base_ok = false, camera_ok = false;
  ros::Time base_stamp;           // stamp of the newest odom -> base_link
  Pose3 T_odom_base, T_odom_cam;  // at base_stamp
  std::string error;
};

struct Replay {
  std::unique_ptr<TempDir> dir;
  SimulatedBag bag;
  std::vector<TopicRecorder<SplineTrajectory>::Stamped> trajectories;
  std::vector<TopicRecorder<nav_msgs::Odometry>::Stamped> odoms;
  std::vector<geometry_msgs::TransformStamped> tf_base;  // odom -> base_link from /tf
  std::vector<TfSample> tf_samples;
  std::string play_log;
  int play_exit_code = -1;
  std::string error;  // why the bag could not be played (empty: it was)
};

TfSample lookAtTf(const tf2_ros::Buffer& tf) {
  TfSample s;
  s.now = ros::Time::now();
  try {
    const geometry_msgs::TransformStamped b = tf.lookupTransform("odom", "base_link", ros::Time(0));
    s.base_ok = true;
    s.base_stamp = b.header.stamp;
    s.T_odom_base = tf2::transformToEigen(b);
    const geometry_msgs::TransformStamped c = tf.lookupTransform("odom", "davis", b.header.stamp);
    s.camera_ok = true;
    s.T_odom_cam = tf2::transformToEigen(c);
  } catch (const tf2::TransformException& e) {
    s.error = e.what();
  }
  return s;
}

void playBag(ros::NodeHandle& nh, Replay* replay) {
  replay->dir = std::make_unique<TempDir>();
  replay->bag = simulateBag(replay->dir->path(), "indoor_circle", kBagDurationS);
  TopicRecorder<SplineTrajectory> trajectories(nh, topics::kTrajectory);
  TopicRecorder<nav_msgs::Odometry> odoms(nh, topics::kBackendOdom);
  TopicRecorder<tf2_msgs::TFMessage> tf_msgs(nh, "/tf");
  tf2_ros::Buffer tf(ros::Duration(30.0));
  tf2_ros::TransformListener listener(tf);
  if (!waitUntil([&] { return trajectories.numPublishers() > 0 && odoms.numPublishers() > 0; },
                 30.0))
    throw std::runtime_error("backend_node did not come up");
  ChildProcess play({"rosbag", "play", "--clock", "--delay", "2", "--quiet", "-r",
                     std::to_string(kRate), replay->bag.bag_path},
                    replay->dir->path() + "/play.log");
  // While it plays: look at the tf tree every 0.5 s (wall) once the odometry has started.
  const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(kBagDurationS / kRate + 60.0);
  while (play.running() && ros::WallTime::now() < end) {
    if (odoms.size() > 0) replay->tf_samples.push_back(lookAtTf(tf));
    ros::WallDuration(0.5).sleep();
  }
  play.stop();
  // The nodes finish: odometry up to the last window, then nothing new for 3 s.
  const int64_t end_ns = replay->bag.gt.back().t_ns - secToNs(0.7);
  waitUntil(
      [&] {
        const auto o = odoms.all();
        return !o.empty() && toNs(o.back().msg.header.stamp) > end_ns;
      },
      30.0);
  waitUntilQuiet([&] { return odoms.size() + trajectories.size(); }, 3.0, 30.0);
  replay->trajectories = trajectories.all();
  replay->odoms = odoms.all();
  for (const auto& m : tf_msgs.all())
    for (const geometry_msgs::TransformStamped& t : m.msg.transforms)
      if (t.header.frame_id == "odom" && t.child_frame_id == "base_link")
        replay->tf_base.push_back(t);
  replay->play_exit_code = play.exitCode();
  replay->play_log = tailOf(play.logPath());
}

double eventsStartS(const Replay& replay) {
  return nsToSec(replay.bag.gt.front().t_ns);
}

}  // namespace

/// The bag is played once for the suite; every test inspects what was recorded.
class FrontendBackendBag : public test::ReplayedOnce<Replay, playBag> {};

TEST_F(FrontendBackendBag, PlaybackExitedCleanly) {
  EXPECT_EQ(replay->play_exit_code, 0) << replay->play_log;
}

TEST_F(FrontendBackendBag, TrajectoryComesOncePerUpdateInterval) {
  const BackendOptions b = loadPipelineConfig(defaultConfigDir() + "/vwe_vo.yaml").backend;
  const auto& trajs = replay->trajectories;
  // A refinement once update_interval_s (1 s) of new arcs are in: with 0.3 s windows every 4th
  // arc (1.2 s), so the 16 windows of 5 s give 4. One less is allowed: a back-end that is behind
  // (a short CPU) folds an interval into the next refinement.
  const double window_s =
      loadPipelineConfig(defaultConfigDir() + "/vwe_vo.yaml").frontend.window_duration_s;
  const double spacing_s = std::ceil(b.update_interval_s / window_s - 1e-9) * window_s;
  const int expected = int(int(kBagDurationS / window_s) * window_s / spacing_s);
  for (const auto& t : trajs)
    std::printf("refinement up to %.3f s received at %.3f s\n", t.msg.valid_to.toSec(),
                t.received.toSec());
  EXPECT_GE(int(trajs.size()), expected - 1);
  EXPECT_LE(int(trajs.size()), expected);
  for (size_t i = 0; i < trajs.size(); ++i) {
    const SplineTrajectory& t = trajs[i].msg;
    EXPECT_EQ(t.header.frame_id, "odom");
    if (i > 0) {  // valid_to advances by one spacing, by two if an interval was folded in
      const double dt = (t.valid_to - trajs[i - 1].msg.valid_to).toSec();
      EXPECT_GT(dt, spacing_s - 0.01) << "refinement " << i;
      EXPECT_LT(dt, 2 * spacing_s + 0.01) << "refinement " << i;
    }
    // Published within 3 s (simulated clock) of the data it covers: the back-end keeps up.
    EXPECT_LT((trajs[i].received - t.valid_to).toSec(), 3.0) << "refinement " << i << " came late";
  }
}

TEST_F(FrontendBackendBag, OdometryAndTfAtTheOdomRate) {
  const auto& odoms = replay->odoms;
  ASSERT_GE(odoms.size(), 2u);
  const double step_s = 1.0 / kOdomRateHz;
  for (size_t i = 1; i < odoms.size(); ++i)  // every step of 50 ms in data time, none missing
    ASSERT_NEAR((odoms[i].msg.header.stamp - odoms[i - 1].msg.header.stamp).toSec(), step_s, 1e-3)
        << "odom " << i;
  // From the first window to the last: 5 s less one window at either end, at 20 Hz.
  const double first_s = odoms.front().msg.header.stamp.toSec() - eventsStartS(*replay);
  const double last_s = odoms.back().msg.header.stamp.toSec() - eventsStartS(*replay);
  EXPECT_LT(first_s, 0.7);
  EXPECT_GT(last_s, kBagDurationS - 0.7);
  EXPECT_GE(double(odoms.size()), (kBagDurationS - 1.4) * kOdomRateHz);
  // Arrival on the simulated clock follows the data: within 2 s (the arc of a window comes after
  // the window; the back-end publishes the odometry with each arc).
  std::vector<double> latency;
  for (const auto& o : odoms) latency.push_back((o.received - o.msg.header.stamp).toSec());
  std::printf("%zu odometry messages from %.2f to %.2f s, latency median %.2f max %.2f s\n",
              odoms.size(), first_s, last_s, median(latency),
              *std::max_element(latency.begin(), latency.end()));
  EXPECT_LT(median(latency), 1.0);
  EXPECT_LT(*std::max_element(latency.begin(), latency.end()), 3.0);
  // The circle's 25 deg/s in the odometry's twist.
  std::vector<double> yaw_rates;
  for (const auto& o : odoms) yaw_rates.push_back(o.msg.twist.twist.angular.z * kDegPerRad);
  EXPECT_NEAR(median(yaw_rates), 25.0, 2.0);
  EXPECT_EQ(odoms.back().msg.header.frame_id, "odom");
  EXPECT_EQ(odoms.back().msg.child_frame_id, "base_link");

  // The tf odom -> base_link: one per odometry message, at the same stamps and poses.
  const auto& tf = replay->tf_base;
  ASSERT_EQ(tf.size(), odoms.size());
  for (size_t i = 0; i < tf.size(); ++i) {
    ASSERT_EQ(tf[i].header.stamp, odoms[i].msg.header.stamp) << "tf " << i;
    EXPECT_NEAR(tf[i].transform.translation.x, odoms[i].msg.pose.pose.position.x, 1e-9);
    EXPECT_NEAR(tf[i].transform.translation.y, odoms[i].msg.pose.pose.position.y, 1e-9);
  }
}

TEST_F(FrontendBackendBag, TfTreeAnswersAtRecentTimesWhileItPlays) {
  const Pose3 T_base_cam = loadPipelineConfig(defaultConfigDir() + "/vwe_vo.yaml").T_base_cam;
  const auto& samples = replay->tf_samples;
  // About one look per 0.5 s (wall) of the 10 s of playing once the odometry has started.
  ASSERT_GE(samples.size(), 10u);
  for (size_t i = 0; i < samples.size(); ++i) {
    const TfSample& s = samples[i];
    ASSERT_TRUE(s.base_ok && s.camera_ok) << "look " << i << " at " << s.now << ": " << s.error;
    // The newest odom -> base_link is recent: within 2 s of the simulated clock.
    EXPECT_LT((s.now - s.base_stamp).toSec(), 2.0) << "look " << i;
    // odom -> davis is odom -> base_link composed with the static base_link -> davis of the config.
    const Pose3 expected = s.T_odom_base * T_base_cam;
    EXPECT_LT((s.T_odom_cam.translation() - expected.translation()).norm(), 1e-6) << "look " << i;
    EXPECT_LT((s.T_odom_cam.linear() - expected.linear()).norm(), 1e-6) << "look " << i;
  }
  // The vehicle moved: the newest base_link is away from the first one it was seen at.
  EXPECT_GT(
      (samples.back().T_odom_base.translation() - samples.front().T_odom_base.translation()).norm(),
      0.3);
}

int main(int argc, char** argv) {
  return runReplayTests(argc, argv, "frontend_backend_bag_test");
}
