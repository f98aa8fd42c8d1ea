// frame_baseline_node against the simulator's APS frames of indoor_circle (25 deg/s at 0.4 m/s,
// DAVIS346-like frames: exposure blur, noise, auto-exposure), rendered with the configuration's
// camera mount and published at 25 Hz in real time with /dvs/camera_info, on one node and one data
// clock (in any order): nothing comes out before a valid calibration; odometry arrives
// at the frame rate with the true yaw rate; black, saturated and identical frames give LOST (said
// in the log, no odometry for them, never NaN) and a frame of another size an error, after each of
// which tracking resumes; a camera_info of another size is refused and the first kept.
#include <gtest/gtest.h>
#include <nav_msgs/Odometry.h>
#include <ros/ros.h>
#include <rosgraph_msgs/Log.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <mutex>
#include <set>
#include <vector>

#include "node_test_util.h"
#include "vwe_vo/io/files.h"
#include "vwe_vo/io/options_yaml.h"
#include "vwe_vo/ros/conversions.h"
#include "vwe_vo/ros/topics.h"
#include "vwe_vo/sim/frame_simulator.h"
#include "vwe_vo/sim/sequences.h"

using namespace vwe_vo;

namespace {

constexpr double kOmegaDeg = 25.0;   // indoor_circle's yaw rate [deg/s]
constexpr double kRateHz = 25.0;     // the simulator's frame rate
const int64_t kT0 = secToNs(100.0);  // data clock of the first simulated frame

enum class Kind { kGood, kBlack, kSaturated, kRepeat, kWrongSize };

class Harness {
 public:
  Harness() : config_(loadPipelineConfig(defaultConfigDir() + "/vwe_vo.yaml")) {
    image_pub_ = nh_.advertise<sensor_msgs::Image>(topics::kImageRaw, 100);
    info_pub_ = nh_.advertise<sensor_msgs::CameraInfo>(topics::kCameraInfo, 10);
    odom_sub_ = nh_.subscribe(topics::kBaselineOdom, 1000, &Harness::onOdom, this);
    rosout_sub_ = nh_.subscribe("/rosout", 1000, &Harness::onLog, this);
  }

  /// The first seconds of indoor_circle's frames (the node's mount, the sequence's motion).
  void render(double duration_s) {
    const sim::SequenceSpec spec = sim::findSequence("indoor_circle");
    const auto tr = sim::VehicleTrajectory::fromProfile(spec.profile, spec.trajectory);
    const CameraModel cam(config_.camera);
    sim::EventSimulator esim(sim::buildScene(spec.scene, spec.seed, tr), cam, config_.T_base_cam,
                             tr, spec.simulator);
    sim::FrameSimulatorOptions fo;
    fo.seed = spec.seed;
    fo.max_blur_renders = 3;  // fewer renders per frame: the test renders ~200 frames up front
    sim::FrameSimulator fsim(&esim, fo);
    for (const sim::SimulatedFrame& f : fsim.simulateUntil(secToNs(duration_s))) {
      frames_.push_back(f.image);
      stamps_.push_back(kT0 + f.t_ns);
    }
  }

  bool waitForNode(double timeout_s) {
    const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(timeout_s);
    while (ros::WallTime::now() < end) {
      if (image_pub_.getNumSubscribers() > 0 && info_pub_.getNumSubscribers() > 0 &&
          odom_sub_.getNumPublishers() > 0)
        return true;
      ros::WallDuration(0.05).sleep();
    }
    return false;
  }

  sensor_msgs::CameraInfo validCameraInfo() const { return calibrationToMsg(config_.camera); }
  void publishCameraInfo(sensor_msgs::CameraInfo info) {
    for (int i = 0; i < 3; ++i) {
      info.header.stamp = toRosTime(next_ < stamps_.size() ? stamps_[next_] : kT0);
      info_pub_.publish(info);
      ros::WallDuration(0.1).sleep();
    }
    ros::WallDuration(0.3).sleep();
  }

  /// Publishes the next n frame slots at the frame rate in real time, as `kind`; returns their
  /// stamps. kRepeat publishes the first slot's frame in every slot.
  std::vector<int64_t> publish(size_t n, Kind kind = Kind::kGood) {
    std::vector<int64_t> stamps;
    ros::WallRate rate(kRateHz);
    const size_t first = next_;
    for (size_t k = 0; k < n; ++k) {
      if (next_ >= frames_.size()) {
        ADD_FAILURE() << "harness: only " << frames_.size() << " frames rendered";
        break;
      }
      const size_t i = next_++;
      cv::Mat1b image;
      switch (kind) {
        case Kind::kGood:
          image = frames_[i];
          break;
        case Kind::kBlack:
          image = cv::Mat1b::zeros(frames_[i].size());
          break;
        case Kind::kSaturated:
          image = cv::Mat1b(frames_[i].size(), uint8_t(255));
          break;
        case Kind::kRepeat:
          image = frames_[first];
          break;
        case Kind::kWrongSize:
          image = cv::Mat1b(180, 240, uint8_t(100));
          break;
      }
      image_pub_.publish(imageToMsg(image, stamps_[i], "davis"));
      stamps.push_back(stamps_[i]);
      rate.sleep();
    }
    return stamps;
  }

  /// Waits until the odometry of the frame at t1 (the node always processes the newest frame:
  /// its queue drops the oldest) or at least min_count odometry messages stamped in [t0, t1] have
  /// arrived, or the timeout; returns those in [t0, t1] in stamp order. What the node processed
  /// by then is all it will: the count depends on the CPU (a node behind drops frames), not the
  /// data time reached.
  std::vector<nav_msgs::Odometry> odomsIn(int64_t t0, int64_t t1, size_t min_count,
                                          double timeout_s = 60.0) {
    const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(timeout_s);
    while (ros::WallTime::now() < end) {
      const std::vector<nav_msgs::Odometry> in = select(t0, t1);
      if (in.size() >= min_count || (!in.empty() && toNs(in.back().header.stamp) == t1)) break;
      ros::WallDuration(0.05).sleep();
    }
    return select(t0, t1);
  }
  std::vector<nav_msgs::Odometry> allOdoms() { return select(0, INT64_MAX); }

  /// True if the node logged a line containing `text` at `level` or above.
  bool logged(const std::string& text, uint8_t level, double timeout_s = 3.0) {
    return test::waitForLog(mutex_, logs_, text, level, timeout_s);
  }

 private:
  std::vector<nav_msgs::Odometry> select(int64_t t0, int64_t t1) {
    std::lock_guard<std::mutex> lock(mutex_);
    std::vector<nav_msgs::Odometry> out;
    for (const nav_msgs::Odometry& o : odoms_)
      if (toNs(o.header.stamp) >= t0 && toNs(o.header.stamp) <= t1) out.push_back(o);
    std::sort(out.begin(), out.end(),
              [](const auto& a, const auto& b) { return a.header.stamp < b.header.stamp; });
    return out;
  }
  void onOdom(const nav_msgs::Odometry::ConstPtr& m) {
    std::lock_guard<std::mutex> lock(mutex_);
    odoms_.push_back(*m);
  }
  void onLog(const rosgraph_msgs::Log::ConstPtr& m) {
    if (m->name != "/frame_baseline_node") return;
    std::lock_guard<std::mutex> lock(mutex_);
    logs_.push_back(*m);
  }

  ros::NodeHandle nh_;
  ros::Publisher image_pub_, info_pub_;
  ros::Subscriber odom_sub_, rosout_sub_;
  PipelineConfig config_;
  std::vector<cv::Mat1b> frames_;
  std::vector<int64_t> stamps_;
  size_t next_ = 0;   // next frame slot
  std::mutex mutex_;  // guards the received messages below
  std::vector<nav_msgs::Odometry> odoms_;
  std::vector<rosgraph_msgs::Log> logs_;
};

/// One frame_baseline_node for every test, on one data clock. Before any test: a camera_info with
/// a zero focal length and 5 frames (what came out is kept for the first test), then the valid
/// calibration. main() destroys the harness after the spinner stopped.
class FrameBaselineNode : public testing::Test {
 public:
  inline static std::unique_ptr<Harness> harness;

 protected:
  static void SetUpTestSuite() {
    if (harness) return;
    harness = std::make_unique<Harness>();
    harness->render(8.8);  // 221 frames; the tests use 204
    connected_ = harness->waitForNode(20.0);
    if (!connected_) return;
    sensor_msgs::CameraInfo bad = harness->validCameraInfo();
    bad.K[0] = 0.0;
    harness->publishCameraInfo(bad);
    harness->publish(5);
    ros::WallDuration(1.0).sleep();
    odoms_before_calibration_ = harness->allOdoms().size();
    harness->publishCameraInfo(harness->validCameraInfo());
  }
  void SetUp() override { ASSERT_TRUE(connected_) << "frame_baseline_node did not connect"; }
  inline static bool connected_ = false;
  inline static size_t odoms_before_calibration_ = 0;
};

Harness& harness() {
  return *FrameBaselineNode::harness;
}

bool finite(const nav_msgs::Odometry& o) {
  const auto& p = o.pose.pose;
  const auto& t = o.twist.twist;
  return std::isfinite(p.position.x) && std::isfinite(p.position.y) &&
         std::isfinite(p.position.z) && std::isfinite(p.orientation.w) &&
         std::isfinite(p.orientation.x) && std::isfinite(p.orientation.y) &&
         std::isfinite(p.orientation.z) && std::isfinite(t.linear.x) && std::isfinite(t.angular.z);
}

/// Tracking on good frames after a disturbance: odometry for most of them (the first one restarts
/// the tracks), every yaw rate near the truth, all finite.
void expectTracking(const std::vector<int64_t>& stamps, size_t restart_frames = 1) {
  ASSERT_FALSE(stamps.empty());
  const size_t expected = stamps.size() - restart_frames;
  const auto odoms = harness().odomsIn(stamps.front(), stamps.back(), expected);
  // Frames are a live stream: a node behind drops the oldest (by design), so at least half.
  EXPECT_GE(odoms.size(), expected / 2)
      << "odometry for " << odoms.size() << " of " << stamps.size();
  for (const auto& o : odoms) {
    EXPECT_TRUE(finite(o));
    EXPECT_NEAR(o.twist.twist.angular.z * kDegPerRad, kOmegaDeg, 1.5) << "at " << o.header.stamp;
    EXPECT_DOUBLE_EQ(o.twist.twist.linear.x, 0.4);
  }
}

/// No odometry was published for frames with these stamps.
void expectNoOdometryAt(const std::vector<int64_t>& stamps) {
  const std::set<int64_t> bad(stamps.begin(), stamps.end());
  for (const auto& o : harness().allOdoms())
    EXPECT_EQ(bad.count(toNs(o.header.stamp)), 0u)
        << "odometry for a bad frame at " << o.header.stamp;
}

}  // namespace

TEST_F(FrameBaselineNode, NothingBeforeAValidCalibration) {
  EXPECT_TRUE(harness->logged("camera_info refused", rosgraph_msgs::Log::WARN));
  EXPECT_EQ(odoms_before_calibration_, 0u) << "odometry without a valid calibration";
}

TEST_F(FrameBaselineNode, OdometryAtTheFrameRateWithTheTrueYawRate) {
  EXPECT_TRUE(harness->logged("calibration from camera_info", rosgraph_msgs::Log::INFO));
  EXPECT_TRUE(
      harness->logged("inputs before the calibration were ignored", rosgraph_msgs::Log::INFO));
  const auto stamps = harness->publish(50);  // 2 s
  const auto odoms = harness->odomsIn(stamps.front(), stamps.back(), stamps.size());
  // One per frame the node processed (the first starts the tracks and says so with a zero
  // twist); a node behind drops the oldest frames, so at least half, each at a frame's stamp.
  ASSERT_GE(odoms.size(), stamps.size() / 2);
  EXPECT_LE(odoms.size(), stamps.size());
  const std::set<int64_t> frame_stamps(stamps.begin(), stamps.end());
  for (const auto& o : odoms)
    EXPECT_EQ(frame_stamps.count(toNs(o.header.stamp)), 1u) << "at " << o.header.stamp;
  for (size_t i = 1; i < odoms.size(); ++i) {
    EXPECT_TRUE(finite(odoms[i]));
    EXPECT_NEAR(odoms[i].twist.twist.angular.z * kDegPerRad, kOmegaDeg, 1.5)
        << "at " << odoms[i].header.stamp;
  }
  EXPECT_EQ(odoms.back().header.frame_id, "odom");
  EXPECT_EQ(odoms.back().child_frame_id, "base_link");
  // The dead-reckoned heading turns at the true rate.
  const double yaw = yawOf(poseFromMsg(odoms.back().pose.pose).linear()) -
                     yawOf(poseFromMsg(odoms.front().pose.pose).linear());
  const double elapsed_s = (odoms.back().header.stamp - odoms.front().header.stamp).toSec();
  EXPECT_NEAR(yaw * kDegPerRad, kOmegaDeg * elapsed_s, 2.0);
}

TEST_F(FrameBaselineNode, BlackFramesAreLostThenTrackingResumes) {
  const auto bad = harness->publish(8, Kind::kBlack);
  EXPECT_TRUE(harness->logged("LOST at", rosgraph_msgs::Log::WARN));
  EXPECT_TRUE(harness->logged("low contrast", rosgraph_msgs::Log::WARN));
  expectTracking(harness->publish(25));
  expectNoOdometryAt(bad);
}

TEST_F(FrameBaselineNode, SaturatedFramesAreLostThenTrackingResumes) {
  const auto bad = harness->publish(8, Kind::kSaturated);
  EXPECT_TRUE(harness->logged("over-exposed (100 % saturated)", rosgraph_msgs::Log::WARN));
  expectTracking(harness->publish(25));
  expectNoOdometryAt(bad);
}

TEST_F(FrameBaselineNode, IdenticalFramesAreLostThenTrackingResumes) {
  auto bad = harness->publish(6, Kind::kRepeat);
  bad.erase(bad.begin());  // the first one is a real frame
  EXPECT_TRUE(harness->logged("frame identical to the previous one", rosgraph_msgs::Log::WARN));
  expectTracking(harness->publish(25), 0);
  expectNoOdometryAt(bad);
}

TEST_F(FrameBaselineNode, FrameOfAnotherSizeIsRefusedWithAnError) {
  const auto bad = harness->publish(2, Kind::kWrongSize);
  EXPECT_TRUE(harness->logged("frame is 240x180 but the calibration is 346x260",
                              rosgraph_msgs::Log::ERROR));
  expectTracking(harness->publish(25), 0);
  expectNoOdometryAt(bad);
}

TEST_F(FrameBaselineNode, CameraInfoOfAnotherSizeIsRefusedAndTheFirstKept) {
  harness->publishCameraInfo(test::cameraInfoOfAnotherSize(harness->validCameraInfo()));
  EXPECT_TRUE(harness->logged("camera_info is 240x180 but the calibration in use is 346x260",
                              rosgraph_msgs::Log::ERROR));
  expectTracking(harness->publish(25), 0);
  for (const auto& o : harness->allOdoms()) EXPECT_TRUE(finite(o)) << "at " << o.header.stamp;
}

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "frame_baseline_node_test");
  ros::AsyncSpinner spinner(1);
  spinner.start();
  const int result = RUN_ALL_TESTS();
  spinner.stop();  // no callback may run while the harness (its subscribers, mutex) is destroyed
  FrameBaselineNode::harness.reset();
  ros::shutdown();
  return result;
}
