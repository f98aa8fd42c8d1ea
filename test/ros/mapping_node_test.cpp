// mapping_node against synthetic events of random 3D points seen along a known Ackermann arc
// (omega = 20 deg/s, v = 0.4 m/s) and a SplineTrajectory fitted to that arc (odom = base_link at
// the reference time), all on one node calibrated once, in any order; each test streams its events
// after the newest ones so far: events wait for the trajectory, then map to clouds near the true
// points; a spline with a NaN is refused; events the trajectory does not cover are skipped and
// counted; a looped stream resets.
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <rosgraph_msgs/Log.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/PointCloud2.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <memory>
#include <mutex>

#include "../common/synthetic_events.h"
#include "node_test_util.h"
#include "vwe_vo/io/options_yaml.h"
#include "vwe_vo/ros/conversions.h"
#include "vwe_vo/ros/topics.h"
#include "vwe_vo/trajectory/ackermann_arc.h"
#include "vwe_vo/trajectory/bspline.h"

using namespace vwe_vo;

namespace {

constexpr double kOmega = 20.0 / kDegPerRad;  // true yaw rate [rad/s]
constexpr double kV = 0.4;                    // true speed [m/s]
constexpr double kPacketS = 0.01;             // EventArray period [s]

struct Cloud {
  std::string frame_id;
  std::vector<Vec3> points;
  bool all_finite = true;
};

Cloud fromMsg(const sensor_msgs::PointCloud2& m) {
  Cloud c;
  c.frame_id = m.header.frame_id;
  for (size_t i = 0; i + 1 <= m.width * m.height; ++i) {
    float v[3];
    std::memcpy(v, &m.data[i * m.point_step], sizeof(v));
    if (!std::isfinite(v[0]) || !std::isfinite(v[1]) || !std::isfinite(v[2])) c.all_finite = false;
    c.points.emplace_back(v[0], v[1], v[2]);
  }
  return c;
}

class Harness {
 public:
  explicit Harness(const PipelineConfig& config)
      : camera_(config.camera), T_base_cam_(config.T_base_cam) {
    events_pub_ = nh_.advertise<EventArray>(topics::kEvents, 2000);
    info_pub_ = nh_.advertise<sensor_msgs::CameraInfo>(topics::kCameraInfo, 10);
    trajectory_pub_ = nh_.advertise<SplineTrajectory>(topics::kTrajectory, 10);
    points_sub_ = nh_.subscribe(topics::kMapPoints, 100, &Harness::onPoints, this);
    cloud_sub_ = nh_.subscribe(topics::kMapCloud, 10, &Harness::onCloud, this);
    depth_sub_ = nh_.subscribe(topics::kMapDepth, 10, &Harness::onDepth, this);
    rosout_sub_ = nh_.subscribe("/rosout", 1000, &Harness::onLog, this);
  }

  bool waitForNode(double timeout_s) {
    const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(timeout_s);
    while (ros::WallTime::now() < end) {
      if (events_pub_.getNumSubscribers() > 0 && info_pub_.getNumSubscribers() > 0 &&
          trajectory_pub_.getNumSubscribers() > 0 && points_sub_.getNumPublishers() > 0 &&
          cloud_sub_.getNumPublishers() > 0 && depth_sub_.getNumPublishers() > 0)
        return true;
      ros::WallDuration(0.05).sleep();
    }
    return false;
  }

  void publishCameraInfo() {
    for (int i = 0; i < 3; ++i) {
      info_pub_.publish(calibrationToMsg(camera_.calibration()));
      ros::WallDuration(0.1).sleep();
    }
    ros::WallDuration(0.3).sleep();
  }

  /// Events of num_points random points (reference camera at t_ref, the middle of the span) seen
  /// along the true arc during [t_ref - span/2, t_ref + span/2], published in 10 ms packets.
  /// Returns the points in odom (= base_link at t_ref).
  std::vector<Vec3> streamEvents(int64_t t_ref_ns, double span_s, int num_events, unsigned seed) {
    const AckermannArcModel truth(kOmega, kV, t_ref_ns, T_base_cam_);
    std::vector<Vec3> points_cam;
    const EventVector events = synthetic::randomPointEvents(camera_, truth, num_events, seed,
                                                            span_s / 2, 400, &points_cam);
    size_t i = 0;
    while (i < events.size()) {
      EventArray msg;
      msg.width = uint32_t(camera_.width());
      msg.height = uint32_t(camera_.height());
      EventVector packet;
      const int64_t end = events[i].t_ns + secToNs(kPacketS);
      while (i < events.size() && events[i].t_ns < end) packet.push_back(events[i++]);
      eventsToMsg(packet, &msg);
      msg.header.stamp = toRosTime(packet.back().t_ns);
      events_pub_.publish(msg);
      ros::WallDuration(0.002).sleep();
    }
    if (!events.empty()) newest_ns_ = std::max(newest_ns_, events.back().t_ns);
    std::vector<Vec3> points_odom;
    for (const Vec3& p : points_cam) points_odom.push_back(T_base_cam_ * p);
    return points_odom;
  }
  /// A reference time for span_s of new events: 1 s after the newest streamed so far.
  int64_t nextRef(double span_s) const { return newest_ns_ + secToNs(1.0 + span_s / 2); }

  /// The true arc of base_link in odom (= base_link at t_ref), fitted by a cubic spline on
  /// [from, to] sampled at 100 Hz.
  BSpline trueSpline(int64_t t_ref_ns, int64_t from_ns, int64_t to_ns) const {
    const AckermannArcModel truth(kOmega, kV, t_ref_ns, T_base_cam_);
    std::vector<int64_t> t;
    std::vector<Vec2> p;
    for (int64_t s = from_ns; s <= to_ns; s += secToNs(0.01)) {
      const Pose3 T_odom_base = T_base_cam_ * truth.T_Cr_Ct(s) * T_base_cam_.inverse();
      t.push_back(s);
      p.push_back(T_odom_base.translation().head<2>());
    }
    BSplineFitOptions options;
    options.knot_spacing_s = 0.2;
    return fitBSpline(t, p, options);
  }
  void publishSpline(const SplineTrajectory& msg) {
    trajectory_pub_.publish(msg);
    ros::WallDuration(0.1).sleep();
  }

  /// Waits until at least n keyframe clouds have arrived (or the timeout); returns them all.
  std::vector<sensor_msgs::PointCloud2> waitForPoints(size_t n, double timeout_s) {
    const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(timeout_s);
    while (ros::WallTime::now() < end && numPoints() < n) ros::WallDuration(0.05).sleep();
    std::lock_guard<std::mutex> lock(mutex_);
    return points_;
  }
  size_t numPoints() {
    std::lock_guard<std::mutex> lock(mutex_);
    return points_.size();
  }
  bool waitForCloud(double timeout_s, sensor_msgs::PointCloud2* cloud) {
    const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(timeout_s);
    while (ros::WallTime::now() < end) {
      {
        std::lock_guard<std::mutex> lock(mutex_);
        if (!clouds_.empty()) {
          *cloud = clouds_.back();
          return true;
        }
      }
      ros::WallDuration(0.05).sleep();
    }
    return false;
  }
  std::vector<sensor_msgs::Image> depths() {
    std::lock_guard<std::mutex> lock(mutex_);
    return depths_;
  }
  /// True if the node logged a line containing `text` at `level` or above.
  bool logged(const std::string& text, uint8_t level, double timeout_s = 5.0) {
    return test::waitForLog(mutex_, logs_, text, level, timeout_s);
  }

 private:
  void onPoints(const sensor_msgs::PointCloud2::ConstPtr& m) {
    std::lock_guard<std::mutex> lock(mutex_);
    points_.push_back(*m);
  }
  void onCloud(const sensor_msgs::PointCloud2::ConstPtr& m) {
    std::lock_guard<std::mutex> lock(mutex_);
    clouds_.push_back(*m);
  }
  void onDepth(const sensor_msgs::Image::ConstPtr& m) {
    std::lock_guard<std::mutex> lock(mutex_);
    depths_.push_back(*m);
  }
  void onLog(const rosgraph_msgs::Log::ConstPtr& m) {
    if (m->name != "/mapping_node") return;
    std::lock_guard<std::mutex> lock(mutex_);
    logs_.push_back(*m);
  }

  ros::NodeHandle nh_;
  ros::Publisher events_pub_, info_pub_, trajectory_pub_;
  ros::Subscriber points_sub_, cloud_sub_, depth_sub_, rosout_sub_;
  CameraModel camera_;
  Pose3 T_base_cam_;
  int64_t newest_ns_ = secToNs(99.0);  // the data clock: newest event streamed
  std::mutex mutex_;                   // guards the received messages below
  std::vector<sensor_msgs::PointCloud2> points_, clouds_;
  std::vector<sensor_msgs::Image> depths_;
  std::vector<rosgraph_msgs::Log> logs_;
};

/// Distance from p to the nearest of the points.
double nearest(const Vec3& p, const std::vector<Vec3>& points) {
  double best = std::numeric_limits<double>::infinity();
  for (const Vec3& q : points) best = std::min(best, (p - q).norm());
  return best;
}

}  // namespace

/// One mapping_node for every test, connected and calibrated once; main() destroys the harness
/// after the spinner stopped (no callback may run while it goes).
class MappingNode : public testing::Test {
 public:
  inline static std::unique_ptr<Harness> harness;
  inline static std::string config_path;  // set by main()

 protected:
  static void SetUpTestSuite() {
    if (harness) return;
    harness = std::make_unique<Harness>(loadPipelineConfig(config_path));
    connected_ = harness->waitForNode(20.0);
    if (connected_) harness->publishCameraInfo();
  }
  void SetUp() override { ASSERT_TRUE(connected_) << "mapping_node did not connect"; }
  inline static bool connected_ = false;
};

TEST_F(MappingNode, EventsWaitForTheTrajectoryThenMapNearTheTruePoints) {
  const size_t before = harness->numPoints();
  const int64_t t_ref = harness->nextRef(2.0);
  const std::vector<Vec3> truth = harness->streamEvents(t_ref, 2.0, 120000, 7);
  ros::WallDuration(1.0).sleep();
  EXPECT_EQ(harness->numPoints(), before) << "a cloud before the trajectory";

  const BSpline spline = harness->trueSpline(t_ref, t_ref - secToNs(1.2), t_ref + secToNs(1.6));
  const SplineTrajectory msg = splineToMsg(spline, 0, "odom");
  harness->publishSpline(msg);

  // 0.8 m of travel: two keyframes of 0.3 m close on the way, the last one by the time-out.
  const std::vector<sensor_msgs::PointCloud2> all_clouds = harness->waitForPoints(before + 2, 40.0);
  const std::vector<sensor_msgs::PointCloud2> clouds(all_clouds.begin() + long(before),
                                                     all_clouds.end());
  ASSERT_GE(clouds.size(), 2u) << "no keyframe clouds on /vwe/map/points";
  size_t total = 0;
  std::vector<double> errors;
  for (const sensor_msgs::PointCloud2& m : clouds) {
    ASSERT_EQ(m.fields.size(), 4u);
    EXPECT_EQ(m.fields[3].name, "intensity");
    EXPECT_EQ(m.point_step, 16u);
    const Cloud c = fromMsg(m);
    EXPECT_EQ(c.frame_id, "odom");
    EXPECT_TRUE(c.all_finite);
    total += c.points.size();
    for (const Vec3& p : c.points)
      errors.push_back(nearest(p, truth) / std::max(1.0, p.head<2>().norm()));
  }
  EXPECT_GT(total, 100u);
  ASSERT_FALSE(errors.empty());
  std::sort(errors.begin(), errors.end());
  std::printf(
      "[mapping_node] %zu points, distance to the nearest true point / depth: 25 %% %.3f, "
      "median %.3f, 75 %% %.3f\n",
      errors.size(), errors[errors.size() / 4], errors[errors.size() / 2],
      errors[3 * errors.size() / 4]);
  EXPECT_LT(errors[errors.size() / 2], 0.05) << "median distance to the true points / depth";

  // The fused global map (throttled) and the depth image of a keyframe.
  sensor_msgs::PointCloud2 global;
  ASSERT_TRUE(harness->waitForCloud(10.0, &global)) << "no /vwe/map/cloud";
  EXPECT_EQ(global.header.frame_id, "odom");
  EXPECT_GT(global.width, 50u);
  const std::vector<sensor_msgs::Image> depths = harness->depths();
  ASSERT_FALSE(depths.empty());
  EXPECT_EQ(depths.back().encoding, "bgr8");
  EXPECT_EQ(depths.back().data.size(), size_t(depths.back().step) * depths.back().height);
}

TEST_F(MappingNode, SplineWithNanIsRefused) {
  const int64_t t_ref = harness->nextRef(2.0);
  SplineTrajectory msg = splineToMsg(
      harness->trueSpline(t_ref, t_ref - secToNs(1.0), t_ref + secToNs(1.0)), 0, "odom");
  msg.control_x[2] = std::numeric_limits<double>::quiet_NaN();
  harness->publishSpline(msg);
  EXPECT_TRUE(harness->logged("control point 2 is not finite", rosgraph_msgs::Log::WARN));
}

TEST_F(MappingNode, EventsTheTrajectoryDoesNotCoverAreSkippedAndCounted) {
  const size_t before = harness->numPoints();
  const int64_t t_ref = harness->nextRef(2.0);
  // The trajectory starts half-way through the events: the first half cannot be mapped.
  harness->publishSpline(
      splineToMsg(harness->trueSpline(t_ref, t_ref, t_ref + secToNs(1.6)), 0, "odom"));
  harness->streamEvents(t_ref, 2.0, 120000, 8);
  EXPECT_TRUE(
      harness->logged("not covered by the trajectory skipped", rosgraph_msgs::Log::WARN, 30.0));
  EXPECT_GT(harness->waitForPoints(before + 1, 30.0).size(), before) << "the covered half maps";
}

TEST_F(MappingNode, LoopedStreamResetsAndMapsAgain) {
  const int64_t t_newest = harness->nextRef(0.5);
  harness->streamEvents(t_newest, 0.5, 20000, 10);  // data to loop back from, whatever ran before
  const size_t before = harness->numPoints();
  const int64_t t_ref = t_newest - secToNs(4.0);  // 4 s back: a looped bag
  harness->streamEvents(t_ref, 2.0, 120000, 9);
  EXPECT_TRUE(harness->logged("mapper, global map and trajectory reset", rosgraph_msgs::Log::WARN));
  harness->publishSpline(splineToMsg(
      harness->trueSpline(t_ref, t_ref - secToNs(1.2), t_ref + secToNs(1.6)), 0, "odom"));
  EXPECT_GT(harness->waitForPoints(before + 2, 30.0).size(), before + 1);
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "mapping_node_test");
  ros::AsyncSpinner spinner(1);
  spinner.start();
  if (!ros::param::get("/mapping_test_config", MappingNode::config_path)) {
    std::fprintf(stderr, "mapping_node_test: /mapping_test_config is not set\n");
    return 1;
  }
  const int result = RUN_ALL_TESTS();
  spinner.stop();  // no callback may run while the harness (its subscribers, mutex) is destroyed
  MappingNode::harness.reset();
  ros::shutdown();
  return result;
}
