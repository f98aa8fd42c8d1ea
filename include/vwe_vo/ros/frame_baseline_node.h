// frame_baseline_node: the frame-based baseline (KLT + 1-point Ackermann RANSAC) on /dvs/image_raw,
// for comparison with the event front-end. Callbacks validate, convert and enqueue into a bounded
// queue; one worker runs vwe_vo::FrameBaseline and publishes a dead-reckoned Odometry per frame
// and (when watched) an image of the tracks.
#pragma once

#include <nav_msgs/Odometry.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>

#include <cstdint>
#include <deque>
#include <memory>
#include <opencv2/core.hpp>
#include <string>
#include <thread>

#include "vwe_vo/baseline/frame_baseline.h"
#include "vwe_vo/common/math.h"
#include "vwe_vo/ros/node_input.h"
#include "vwe_vo/sensor/camera.h"

namespace vwe_vo {

/// Everything the node reads from the parameter server, once, at start-up.
struct FrameBaselineNodeOptions {
  std::string config_path;        // ~config: pipeline YAML (baseline options, T_base_cam); empty:
                                  // vwe_vo.yaml in defaultConfigDir()
  std::string calibration_path;   // ~calibration: CameraInfo-style YAML; empty: /dvs/camera_info
  double nominal_speed_mps = -1;  // ~nominal_speed: overrides the config when >= 0 [m/s]
  bool use_odom = false;          // ~use_odom: speed (and standstill) from /odom
  int max_queue_frames =
      10;  // ~max_queue_frames: bound of the queued frames (oldest dropped) [frames]
  int max_queue_messages = 2000;  // ~max_queue_messages: bound of the queued odometry [messages]
  void validate() const;          // throws std::invalid_argument naming the parameter
};

class FrameBaselineNode {
 public:
  /// Reads the parameters and the configuration (throws std::exception on unusable ones),
  /// subscribes, advertises and starts the worker.
  FrameBaselineNode(const ros::NodeHandle& nh, const ros::NodeHandle& pnh);
  /// Stops and joins the worker.
  ~FrameBaselineNode();
  FrameBaselineNode(const FrameBaselineNode&) = delete;
  FrameBaselineNode& operator=(const FrameBaselineNode&) = delete;

 private:
  struct Input {
    enum class Kind { kFrame, kOdometry } kind = Kind::kFrame;
    int64_t t_ns = 0;
    cv::Mat image;
    double v = 0.0, yaw_rate = 0.0;
  };

  void readParameters();
  void imageCallback(const sensor_msgs::Image::ConstPtr& msg);
  void cameraInfoCallback(const sensor_msgs::CameraInfo::ConstPtr& msg);
  void odomCallback(const nav_msgs::Odometry::ConstPtr& msg);
  void workerLoop();
  void handleFrame(const Input& input);

  ros::NodeHandle nh_, pnh_;
  ros::Subscriber image_sub_, camera_info_sub_, odom_sub_;
  ros::Publisher odom_pub_, tracks_pub_;
  FrameBaselineNodeOptions node_options_;
  FrameBaselineOptions baseline_options_;
  Pose3 T_base_cam_ = Pose3::Identity();

  NodeInput<Input> input_{"frame_baseline_node"};  // callbacks -> worker, open once calibrated

  // Owned by the worker thread.
  std::unique_ptr<CameraModel> camera_;
  std::unique_ptr<FrameBaseline> baseline_;
  FrameStatus last_status_ = FrameStatus::kFirst;
  std::thread worker_;
};

}  // namespace vwe_vo
