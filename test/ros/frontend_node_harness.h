// Test harness of the frontend_node rostests: publishes synthetic events of random 3D points seen
// along a known Ackermann arc (and optionally /odom) on one continuous data clock, and records what
// the node publishes and logs. Header-only, used by test/ros/frontend_node*_test.cpp.
#pragma once

#include <gtest/gtest.h>
#include <nav_msgs/Odometry.h>
#include <ros/ros.h>
#include <rosgraph_msgs/Log.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>

#include <algorithm>
#include <functional>
#include <memory>
#include <mutex>

#include "../common/synthetic_events.h"
#include "node_test_util.h"
#include "vwe_vo/io/files.h"
#include "vwe_vo/io/options_yaml.h"
#include "vwe_vo/ros/conversions.h"
#include "vwe_vo/ros/topics.h"
#include "vwe_vo/trajectory/ackermann_arc.h"

namespace vwe_vo {
namespace test {

inline constexpr double kOmega = 20.0 / kDegPerRad;  // true yaw rate [rad/s]
inline constexpr double kV = 0.4;                    // true speed [m/s]
inline constexpr double kWindowS = 0.3;              // window_duration_s of config/vwe_vo.yaml
inline constexpr double kPacketS = 0.01;             // EventArray period [s]
inline constexpr int kEventsPerSecond = 50000;       // above the config's standstill rate (30000)

struct StreamOptions {
  uint32_t width = 346, height = 260;  // EventArray size (events are kept inside it)
  bool empty_packets = false;          // publish an empty EventArray every 10th packet
  bool outside_events = false;         // add events outside the sensor to every packet
  bool late_packet = false;            // replay one packet 20 ms late (a small backwards jump)
  bool advance_clock = true;           // false: the data is expected to be refused
  double odom_speed = -1;      // >= 0: also publish /odom (this speed, the true yaw rate) at 50 Hz
  bool burst = false;          // publish as fast as possible instead of in real time
  double rate_factor = 1.0;    // events per second: kEventsPerSecond x this
  double packet_s = kPacketS;  // EventArray period [s] (0.3 s at 10x: 150 k events a packet)
  int duplicate_every = 0;     // > 0: every Nth packet is published twice
  int reorder_every = 0;       // > 0: every Nth packet swaps places with the next one
};

class Harness {
 public:
  Harness()
      : camera_(loadCameraCalibrationYaml(defaultConfigDir() + "/davis346.yaml")),
        T_base_cam_(loadPipelineConfig(defaultConfigDir() + "/vwe_vo.yaml").T_base_cam) {
    events_pub_ = nh_.advertise<EventArray>(topics::kEvents, 2000);
    info_pub_ = nh_.advertise<sensor_msgs::CameraInfo>(topics::kCameraInfo, 10);
    odom_pub_ = nh_.advertise<nav_msgs::Odometry>(topics::kOdom, 1000);
    imu_pub_ = nh_.advertise<sensor_msgs::Imu>(topics::kImu, 1000);
    arcs_sub_ = nh_.subscribe(topics::kArcs, 1000, &Harness::onArc, this);
    odom_sub_ = nh_.subscribe(topics::kFrontendOdom, 1000, &Harness::onOdom, this);
    iwe_sub_ = nh_.subscribe(topics::kFrontendIwe, 10, &Harness::onImage, this);
    rosout_sub_ = nh_.subscribe("/rosout", 1000, &Harness::onLog, this);
  }

  bool waitForNode(double timeout_s) {
    const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(timeout_s);
    while (ros::WallTime::now() < end) {
      if (events_pub_.getNumSubscribers() > 0 && info_pub_.getNumSubscribers() > 0 &&
          arcs_sub_.getNumPublishers() > 0 && odom_sub_.getNumPublishers() > 0 &&
          iwe_sub_.getNumPublishers() > 0)
        return true;
      ros::WallDuration(0.05).sleep();
    }
    return false;
  }

  void publishCameraInfo(sensor_msgs::CameraInfo info) {
    for (int i = 0; i < 3; ++i) {
      info.header.stamp = toRosTime(clock_ns_);
      info_pub_.publish(info);
      ros::WallDuration(0.1).sleep();
    }
    ros::WallDuration(0.3).sleep();
  }
  sensor_msgs::CameraInfo validCameraInfo() const {
    return calibrationToMsg(camera_.calibration());
  }

  /// Publishes duration_s of events along the true arc from the data clock on, in real time.
  /// Returns the data interval [t0, t1).
  std::pair<int64_t, int64_t> stream(double duration_s, const StreamOptions& o = StreamOptions()) {
    const int64_t t0 = clock_ns_, t1 = t0 + secToNs(duration_s);
    EventVector events;
    for (int64_t c = t0; c < t1; c += secToNs(1.0)) {  // 1 s chunks, each with its own points
      const double span_s = std::min(1.0, nsToSec(t1 - c));
      const AckermannArcModel truth(kOmega, kV, c + secToNs(span_s / 2), T_base_cam_);
      const EventVector chunk = synthetic::randomPointEvents(
          camera_, truth, int(kEventsPerSecond * o.rate_factor * span_s), unsigned(seed_++),
          span_s / 2, 600);
      for (const PixelEvent& e : chunk)
        if (e.t_ns >= c && e.t_ns < t1 && e.x < o.width && e.y < o.height) events.push_back(e);
    }
    std::vector<EventArray> packets;
    size_t i = 0;
    const int64_t packet_ns = secToNs(o.packet_s);
    for (int64_t p = t0; p < t1; p += packet_ns) {
      EventArray msg;
      msg.width = o.width;
      msg.height = o.height;
      EventVector packet;
      while (i < events.size() && events[i].t_ns < p + packet_ns) packet.push_back(events[i++]);
      if (packet.empty()) continue;
      if (o.outside_events)
        for (int k = 0; k < 5; ++k) {
          PixelEvent e = packet.back();
          e.x = uint16_t(o.width + 10 * k);
          e.y = uint16_t(k % 2 ? o.height + 3 : 5);
          packet.push_back(e);
        }
      eventsToMsg(packet, &msg);
      msg.header.stamp = toRosTime(packet.back().t_ns);
      packets.push_back(msg);
    }
    for (size_t k = 1; o.reorder_every > 0 && k + 1 < packets.size(); ++k)
      if (k % size_t(o.reorder_every) == 0) std::swap(packets[k], packets[k + 1]);
    ros::WallRate rate(1.0 / kPacketS);
    for (size_t k = 0; k < packets.size(); ++k) {
      if (o.odom_speed >= 0 &&
          k % 2 == 0) {  // samples covering the next two packets, sent before them
        nav_msgs::Odometry odom;
        odom.header.stamp = toRosTime(t0 + int64_t(k) * secToNs(kPacketS));
        odom.header.frame_id = "odom";
        odom.child_frame_id = "base_link";
        odom.twist.twist.linear.x = o.odom_speed;
        odom.twist.twist.angular.z = kOmega;
        odom_pub_.publish(odom);
        odom.header.stamp += ros::Duration(kPacketS);
        odom_pub_.publish(odom);
      }
      events_pub_.publish(packets[k]);
      if (o.duplicate_every > 0 && k % size_t(o.duplicate_every) == 0)
        events_pub_.publish(packets[k]);
      if (o.empty_packets && k % 10 == 0) {
        EventArray empty;
        empty.header.stamp = packets[k].header.stamp;
        empty.width = o.width;
        empty.height = o.height;
        events_pub_.publish(empty);
      }
      if (o.late_packet && k == packets.size() / 2) events_pub_.publish(packets[k - 2]);
      if (!o.burst) {
        if (o.packet_s == kPacketS)
          rate.sleep();
        else
          ros::WallDuration(o.packet_s).sleep();
      }
    }
    if (o.advance_clock) clock_ns_ = t1;
    return {t0, t1};
  }

  /// One /odom and one /dvs/imu message at the data clock with the given twist and angular
  /// velocity (NaN or Inf: what a node must refuse and count).
  void publishOdomAndImu(double v, double yaw_rate) {
    nav_msgs::Odometry odom;
    odom.header.stamp = toRosTime(clock_ns_);
    odom.header.frame_id = "odom";
    odom.child_frame_id = "base_link";
    odom.twist.twist.linear.x = v;
    odom.twist.twist.angular.z = yaw_rate;
    odom_pub_.publish(odom);
    sensor_msgs::Imu imu;
    imu.header.stamp = odom.header.stamp;
    imu.header.frame_id = "davis";
    imu.angular_velocity.x = imu.angular_velocity.y = imu.angular_velocity.z = yaw_rate;
    imu_pub_.publish(imu);
  }
  bool waitForImuSubscriber(double timeout_s) {
    const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(timeout_s);
    while (ros::WallTime::now() < end && imu_pub_.getNumSubscribers() == 0)
      ros::WallDuration(0.05).sleep();
    return imu_pub_.getNumSubscribers() > 0;
  }

  /// Waits until at least min_count arcs with a reference time in [t0, t1) have arrived (or the
  /// timeout), then a little longer for stragglers; returns them.
  std::vector<AckermannArc> arcsIn(int64_t t0, int64_t t1, size_t min_count,
                                   double timeout_s = 15.0) {
    const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(timeout_s);
    while (ros::WallTime::now() < end && select(t0, t1).size() < min_count)
      ros::WallDuration(0.05).sleep();
    ros::WallDuration(0.5).sleep();
    return select(t0, t1);
  }

  size_t numArcs() {
    std::lock_guard<std::mutex> lock(mutex_);
    return arcs_.size();
  }
  std::vector<nav_msgs::Odometry> odometry() {
    std::lock_guard<std::mutex> lock(mutex_);
    return odoms_;
  }
  std::vector<sensor_msgs::Image> images() {
    std::lock_guard<std::mutex> lock(mutex_);
    return images_;
  }
  /// True if the node logged a line containing `text` at `level` or above.
  bool logged(const std::string& text, uint8_t level, double timeout_s = 3.0) {
    return test::waitForLog(mutex_, logs_, text, level, timeout_s);
  }
  void rewindClock(double dt_s) { clock_ns_ -= secToNs(dt_s); }
  /// The newest value of a counter of the node's input status line (-1: none yet).
  long inputCounter(const std::string& kind, const std::string& key) {
    std::lock_guard<std::mutex> lock(mutex_);
    return test::inputCounter(logs_, kind, key);
  }
  /// The newest status line of the node (empty: none yet).
  std::string statusLine() {
    std::lock_guard<std::mutex> lock(mutex_);
    for (auto l = logs_.rbegin(); l != logs_.rend(); ++l)
      if (l->msg.find("input: ") != std::string::npos) return l->msg;
    return "";
  }
  /// True once that counter exceeds `above` (the node logs its status every ~status_period_s).
  bool inputCounterAbove(const std::string& kind, const std::string& key, long above,
                         double timeout_s = 10.0) {
    return test::waitForInputCounterAbove(mutex_, logs_, kind, key, above, timeout_s);
  }

 private:
  std::vector<AckermannArc> select(int64_t t0, int64_t t1) {
    std::lock_guard<std::mutex> lock(mutex_);
    std::vector<AckermannArc> out;
    for (const AckermannArc& a : arcs_)
      if (toNs(a.header.stamp) >= t0 && toNs(a.header.stamp) < t1) out.push_back(a);
    return out;
  }
  void onArc(const AckermannArc::ConstPtr& m) {
    std::lock_guard<std::mutex> lock(mutex_);
    arcs_.push_back(*m);
  }
  void onOdom(const nav_msgs::Odometry::ConstPtr& m) {
    std::lock_guard<std::mutex> lock(mutex_);
    odoms_.push_back(*m);
  }
  void onImage(const sensor_msgs::Image::ConstPtr& m) {
    std::lock_guard<std::mutex> lock(mutex_);
    images_.push_back(*m);
  }
  void onLog(const rosgraph_msgs::Log::ConstPtr& m) {
    if (m->name != "/frontend_node") return;
    std::lock_guard<std::mutex> lock(mutex_);
    logs_.push_back(*m);
  }

  ros::NodeHandle nh_;
  ros::Publisher events_pub_, info_pub_, odom_pub_, imu_pub_;
  ros::Subscriber arcs_sub_, odom_sub_, iwe_sub_, rosout_sub_;
  CameraModel camera_;
  Pose3 T_base_cam_;
  int64_t clock_ns_ = secToNs(100.0);
  int seed_ = 1;
  std::mutex mutex_;  // guards the received messages below
  std::vector<AckermannArc> arcs_;
  std::vector<nav_msgs::Odometry> odoms_;
  std::vector<sensor_msgs::Image> images_;
  std::vector<rosgraph_msgs::Log> logs_;
};

/// The fixture of the frontend_node rostests: one Harness (one node, one data clock) for every
/// test, created and connected once; main() destroys it after the spinner stopped, since no
/// callback may run while it goes.
class HarnessTest : public testing::Test {
 public:
  inline static std::unique_ptr<Harness> harness;

 protected:
  static void SetUpTestSuite() {
    if (harness) return;
    harness = std::make_unique<Harness>();
    connected_ = harness->waitForNode(20.0);
  }
  void SetUp() override { ASSERT_TRUE(connected_) << "frontend_node did not connect"; }
  inline static bool connected_ = false;
};

/// Arcs of valid data: OK, the true yaw rate within 1 deg/s, the nominal speed.
inline void expectTrueArcs(const std::vector<AckermannArc>& arcs) {
  for (const AckermannArc& a : arcs) {
    EXPECT_EQ(a.status, AckermannArc::OK) << "arc at " << a.header.stamp;
    EXPECT_NEAR(a.omega * kDegPerRad, kOmega * kDegPerRad, 1.0) << "arc at " << a.header.stamp;
    EXPECT_DOUBLE_EQ(a.v, kV);
    EXPECT_EQ(a.header.frame_id, "base_link");
  }
}

}  // namespace test
}  // namespace vwe_vo
