#include "vwe_vo/ros/frame_baseline_node.h"

#include <chrono>
#include <cmath>
#include <stdexcept>

#include "vwe_vo/io/files.h"
#include "vwe_vo/io/options_yaml.h"
#include "vwe_vo/ros/conversions.h"
#include "vwe_vo/ros/param_loader.h"
#include "vwe_vo/ros/process_priority.h"
#include "vwe_vo/ros/shared_msg.h"
#include "vwe_vo/ros/topics.h"

namespace vwe_vo {

void FrameBaselineNodeOptions::validate() const {
  auto fail = [](const std::string& m) {
    throw std::invalid_argument("frame_baseline_node: " + m);
  };
  if (max_queue_frames < 1) fail("~max_queue_frames must be at least 1");
  if (max_queue_messages < 1) fail("~max_queue_messages must be at least 1");
  if (!std::isfinite(nominal_speed_mps)) fail("~nominal_speed must be finite [m/s]");
}

FrameBaselineNode::FrameBaselineNode(const ros::NodeHandle& nh, const ros::NodeHandle& pnh)
    : nh_(nh), pnh_(pnh) {
  readParameters();
  image_sub_ = nh_.subscribe(topics::kImageRaw, 5, &FrameBaselineNode::imageCallback, this);
  camera_info_sub_ =
      nh_.subscribe(topics::kCameraInfo, 2, &FrameBaselineNode::cameraInfoCallback, this);
  if (node_options_.use_odom)
    odom_sub_ = nh_.subscribe(topics::kOdom, 200, &FrameBaselineNode::odomCallback, this);
  odom_pub_ = nh_.advertise<nav_msgs::Odometry>(topics::kBaselineOdom, 100);
  tracks_pub_ = nh_.advertise<sensor_msgs::Image>(topics::kBaselineTracks, 2);
  if (!input_.hasCalibration())
    ROS_INFO("frame_baseline_node: waiting for %s (no ~calibration given)",
             camera_info_sub_.getTopic().c_str());
  worker_ = std::thread(&FrameBaselineNode::workerLoop, this);
}

FrameBaselineNode::~FrameBaselineNode() {
  input_.stop();
  if (worker_.joinable()) worker_.join();
}

void FrameBaselineNode::readParameters() {
  FrameBaselineNodeOptions& o = node_options_;
  ParamLoader params(pnh_, "frame_baseline_node");
  params.read("config", &o.config_path);
  params.read("calibration", &o.calibration_path);
  params.read("nominal_speed", &o.nominal_speed_mps);
  params.read("use_odom", &o.use_odom);
  params.read("max_queue_frames", &o.max_queue_frames);
  params.read("max_queue_messages", &o.max_queue_messages);
  if (o.config_path.empty()) o.config_path = defaultConfigDir() + "/vwe_vo.yaml";
  params.finish();
  o.validate();
  const PipelineConfig config = loadPipelineConfig(o.config_path);
  for (const std::string& w : config.warnings) ROS_WARN("frame_baseline_node: %s", w.c_str());
  baseline_options_ = config.baseline;
  if (o.nominal_speed_mps >= 0) baseline_options_.nominal_speed_mps = o.nominal_speed_mps;
  baseline_options_.validate();
  T_base_cam_ = config.T_base_cam;
  // Frames are a live stream: when the worker falls behind, the oldest queued frame goes.
  input_.setBound(InputKind::kFrame, size_t(o.max_queue_frames), Overflow::kDropOldest);
  input_.setBound(InputKind::kOdometry, size_t(o.max_queue_messages));
  if (!o.calibration_path.empty()) {
    input_.setCalibration(
        loadCameraCalibrationYaml(o.calibration_path));  // throws naming file and field
  }
  const FrameBaselineOptions& b = baseline_options_;
  ROS_INFO(
      "frame_baseline_node: config %s, calibration %s, nominal_speed %.3f m/s, use_odom %d, %d "
      "features, KLT %d px "
      "x %d levels, inliers within %.2f px, LOST below %d tracks",
      o.config_path.c_str(),
      o.calibration_path.empty() ? "from camera_info" : o.calibration_path.c_str(),
      b.nominal_speed_mps, o.use_odom, b.max_features, b.klt_window_px, b.klt_levels,
      b.inlier_threshold_px, b.min_tracks);
}

void FrameBaselineNode::imageCallback(const sensor_msgs::Image::ConstPtr& msg) {
  Input input;
  input.t_ns = toNs(msg->header.stamp);
  try {
    input.image = imageFromMsg(*msg);
  } catch (const std::invalid_argument& e) {
    input_.countRefused(InputKind::kFrame);
    ROS_ERROR_THROTTLE(5, "frame_baseline_node: frame refused: %s (%zu so far)", e.what(),
                       input_.counters()[InputKind::kFrame].refused);
    return;
  }
  input_.push(InputKind::kFrame, std::move(input));
}

void FrameBaselineNode::cameraInfoCallback(const sensor_msgs::CameraInfo::ConstPtr& msg) {
  input_.acceptCameraInfo(*msg);
}

void FrameBaselineNode::odomCallback(const nav_msgs::Odometry::ConstPtr& msg) {
  const OdometrySample sample = odometryFromMsg(*msg);
  if (!std::isfinite(sample.v_mps) || !std::isfinite(sample.yaw_rate_rad_s)) {
    input_.countRefused(InputKind::kOdometry);
    ROS_WARN_THROTTLE(
        5, "frame_baseline_node: odometry at %.3f s with a non-finite twist refused (%zu so far)",
        nsToSec(sample.t_ns), input_.counters()[InputKind::kOdometry].refused);
    return;
  }
  Input input;
  input.kind = Input::Kind::kOdometry;
  input.t_ns = sample.t_ns;
  input.v = sample.v_mps;
  input.yaw_rate = sample.yaw_rate_rad_s;
  input_.push(InputKind::kOdometry, std::move(input));
}

void FrameBaselineNode::workerLoop() {
  nameThisThread("frame_baseline");
  CameraCalibration calibration;
  if (!input_.waitForCalibration(&calibration)) return;
  try {
    camera_ = std::make_unique<CameraModel>(calibration);
    baseline_ = std::make_unique<FrameBaseline>(baseline_options_, *camera_, T_base_cam_);
  } catch (const std::exception& e) {
    ROS_ERROR("frame_baseline_node: the baseline cannot start: %s", e.what());
    return;
  }
  while (true) {
    std::deque<Input> batch;
    if (!input_.takeAll(&batch, std::chrono::milliseconds(100))) break;
    for (const Input& input : batch) {
      if (input.kind == Input::Kind::kOdometry) {
        baseline_->addOdometry(input.t_ns, input.v, input.yaw_rate);
      } else {
        handleFrame(input);
      }
    }
  }
}

void FrameBaselineNode::handleFrame(const Input& input) {
  FrameEstimate e;
  try {
    e = baseline_->addFrame(input.t_ns, input.image);
  } catch (const std::invalid_argument& ex) {
    input_.countRefused(InputKind::kFrame, /*queued=*/true);
    ROS_ERROR_THROTTLE(5, "frame_baseline_node: frame refused: %s (%zu so far)", ex.what(),
                       input_.counters()[InputKind::kFrame].refused);
    return;
  }
  // Losing track is said when it happens (throttled to 1 s), staying lost every 5 s.
  if (e.status == FrameStatus::kLost) {
    if (last_status_ != FrameStatus::kLost)
      ROS_WARN_THROTTLE(1, "frame_baseline_node: LOST at %.3f s: %s (%zu of %zu frames lost)",
                        nsToSec(e.t_ns), e.reason.c_str(), baseline_->stats().lost,
                        baseline_->stats().frames);
    else
      ROS_WARN_THROTTLE(5, "frame_baseline_node: still LOST at %.3f s: %s (%zu of %zu frames lost)",
                        nsToSec(e.t_ns), e.reason.c_str(), baseline_->stats().lost,
                        baseline_->stats().frames);
  }
  last_status_ = e.status;
  if (e.status == FrameStatus::kOk || e.status == FrameStatus::kStandstill ||
      e.status == FrameStatus::kFirst) {
    nav_msgs::Odometry odom;
    odom.header.stamp = toRosTime(e.t_ns);
    odom.header.frame_id = frames::kOdom;
    odom.child_frame_id = frames::kBase;
    odom.pose.pose = poseToMsg(baseline_->chain().T_odom_base(e.t_ns));
    odom.twist.twist.linear.x = e.v;
    odom.twist.twist.angular.z = e.omega;
    odom_pub_.publish(sharedMsg(std::move(odom)));
  }
  if (tracks_pub_.getNumSubscribers() > 0) {
    const cv::Mat img = baseline_->debugImage();
    if (!img.empty()) tracks_pub_.publish(sharedMsg(imageToMsg(img, e.t_ns, frames::kCamera)));
  }
}

}  // namespace vwe_vo
