#include "vwe_vo/io/files.h"
#include "vwe_vo/ros/mapping_node.h"

#include <sensor_msgs/Image.h>
#include <sensor_msgs/PointCloud2.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

#include "vwe_vo/io/options_yaml.h"
#include "vwe_vo/ros/conversions.h"
#include "vwe_vo/ros/event_input.h"
#include "vwe_vo/ros/process_priority.h"
#include "vwe_vo/ros/topics.h"

namespace vwe_vo {

void MappingNodeOptions::validate() const {
  auto fail = [](const std::string& m) { throw std::invalid_argument("mapping_node: " + m); };
  if (!(cloud_period_s > 0)) fail("~cloud_period_s must be positive [s]");
  if (!(trajectory_margin_s >= 0) || !std::isfinite(trajectory_margin_s))
    fail("~trajectory_margin_s must be finite and >= 0 [s]");
  if (!(keyframe_timeout_s >= 0)) fail("~keyframe_timeout_s must be >= 0 [s]");
  if (!(max_backwards_jump_s > 0)) fail("~max_backwards_jump_s must be positive [s]");
  if (max_queue_packets < 1) fail("~max_queue_packets must be at least 1");
  if (!(status_period_s > 0)) fail("~status_period_s must be positive [s]");
  if (nice < 0 || nice > 19) fail("~nice must be in [0, 19]");
}

MappingNode::MappingNode(const ros::NodeHandle& nh, const ros::NodeHandle& pnh)
    : nh_(nh), pnh_(pnh) {
  readParameters();
  events_sub_ = nh_.subscribe(topics::kEvents, 1000, &MappingNode::eventsCallback, this);
  camera_info_sub_ = nh_.subscribe(topics::kCameraInfo, 2, &MappingNode::cameraInfoCallback, this);
  trajectory_sub_ = nh_.subscribe(topics::kTrajectory, 5, &MappingNode::trajectoryCallback, this);
  points_pub_ = nh_.advertise<sensor_msgs::PointCloud2>(topics::kMapPoints, 10);
  cloud_pub_ = nh_.advertise<sensor_msgs::PointCloud2>(topics::kMapCloud, 1, /*latch=*/true);
  depth_pub_ = nh_.advertise<sensor_msgs::Image>(topics::kMapDepth, 2);
  if (!have_calibration_)
    ROS_INFO("mapping_node: waiting for %s (no ~calibration given)",
             camera_info_sub_.getTopic().c_str());
  lowerCpuPriority(node_options_.nice, "mapping_node");  // before the worker: it inherits it
  worker_ = std::thread(&MappingNode::workerLoop, this);
}

MappingNode::~MappingNode() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  cv_.notify_all();
  if (worker_.joinable()) worker_.join();
}

void MappingNode::readParameters() {
  MappingNodeOptions& o = node_options_;
  pnh_.param<std::string>("config", o.config_path, defaultConfigDir() + "/vwe_vo.yaml");
  pnh_.param<std::string>("calibration", o.calibration_path, "");
  pnh_.param("cloud_period_s", o.cloud_period_s, 2.0);
  pnh_.param("trajectory_margin_s", o.trajectory_margin_s, 0.2);
  pnh_.param("keyframe_timeout_s", o.keyframe_timeout_s, 3.0);
  pnh_.param("max_backwards_jump_s", o.max_backwards_jump_s, 0.5);
  pnh_.param("max_queue_packets", o.max_queue_packets, 5000);  // ~5 s of the driver at 1 kHz: bursts of keyframes
  pnh_.param("status_period_s", o.status_period_s, 10.0);
  pnh_.param("nice", o.nice, 0);
  o.validate();

  const PipelineConfig config = loadPipelineConfig(o.config_path);
  for (const std::string& w : config.warnings) ROS_WARN("mapping_node: %s", w.c_str());
  emvs_options_ = config.mapping;
  global_map_options_ = config.global_map;
  emvs_options_.validate();
  global_map_options_.validate();
  T_base_cam_ = config.T_base_cam;

  if (!o.calibration_path.empty()) {
    calibration_ = loadCameraCalibrationYaml(o.calibration_path);  // throws naming file and field
    have_calibration_ = true;
  }

  const EmvsOptions& e = emvs_options_;
  ROS_INFO(
      "mapping_node: config %s, calibration %s, cloud_period_s %.2f, trajectory_margin_s %.2f, "
      "keyframe_timeout_s %.1f, max_queue_packets %d",
      o.config_path.c_str(),
      o.calibration_path.empty() ? "from camera_info" : o.calibration_path.c_str(),
      o.cloud_period_s, o.trajectory_margin_s, o.keyframe_timeout_s, o.max_queue_packets);
  ROS_INFO(
      "mapping_node: keyframe every %.2f m or %.1f deg or %zu events; DSI %d planes in [%.2f, "
      "%.2f] m at grid scale %.2f; %zu events may wait for the trajectory; at most %.0f events/s "
      "voted (0: all); global map voxel %.3f m, %zu points max",
      e.kf_distance_m, e.kf_rotation_deg, e.max_events_per_keyframe, e.volume.num_planes,
      e.volume.z_min_m, e.volume.z_max_m, e.volume.grid_scale, e.max_pending_events, e.max_event_rate_hz,
      global_map_options_.voxel_size_m, global_map_options_.max_points);
}

// ------------------------------------------------------------------------------------------------
// Callbacks: validate, convert, enqueue. Nothing here runs the core.

void MappingNode::eventsCallback(const EventArray::ConstPtr& msg) {
  ++packets_in_;
  countArrivingPacket(msg->header, "mapping_node", &packet_sequence_, packets_lost_);
  int width = 0, height = 0;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!have_calibration_) {
      ++packets_before_calibration_;
      return;
    }
    width = calibration_.width;
    height = calibration_.height;
  }
  EventVector events;
  if (!acceptEventPacket(*msg, width, height, "mapping_node", {packets_empty_, packets_wrong_size_, events_outside_msg_},
                         &events))
    return;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (queue_.size() < size_t(node_options_.max_queue_packets)) {
      queue_.push_back(std::move(events));
      cv_.notify_one();
      return;
    }
  }
  ++packets_queue_full_;
  ROS_WARN_THROTTLE(5,
                    "mapping_node: input queue full (%d packets), the mapper cannot keep up: "
                    "packet dropped (%zu so far)",
                    node_options_.max_queue_packets, packets_queue_full_.load());
}

void MappingNode::cameraInfoCallback(const sensor_msgs::CameraInfo::ConstPtr& msg) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (acceptCameraInfo(*msg, "mapping_node", &have_calibration_, &calibration_, camera_info_refused_)) cv_.notify_all();
}

void MappingNode::trajectoryCallback(const SplineTrajectory::ConstPtr& msg) {
  ++splines_in_;
  std::shared_ptr<BSpline> spline;
  try {
    spline = std::make_shared<BSpline>(splineFromMsg(*msg));
  } catch (const std::invalid_argument& e) {
    ++splines_refused_;
    ROS_WARN_THROTTLE(5, "mapping_node: trajectory refused: %s (%zu of %zu refused so far)",
                      e.what(), splines_refused_.load(), splines_in_.load());
    return;
  }
  if (!msg->header.frame_id.empty() && msg->header.frame_id != frames::kOdom)
    ROS_WARN_THROTTLE(30, "mapping_node: trajectory in frame '%s', used as '%s'",
                      msg->header.frame_id.c_str(), frames::kOdom);
  std::lock_guard<std::mutex> lock(mutex_);
  new_spline_ = std::move(spline);  // the newest replaces any not yet taken
  cv_.notify_one();
}

// ------------------------------------------------------------------------------------------------
// Worker: the only thread that touches the mapper and the global map.

void MappingNode::workerLoop() {
  CameraCalibration calibration;
  {
    std::unique_lock<std::mutex> lock(mutex_);
    cv_.wait(lock, [this] { return stop_ || have_calibration_; });
    if (stop_) return;
    calibration = calibration_;
  }
  try {
    camera_ = std::make_unique<CameraModel>(calibration);
    mapper_ = std::make_unique<EmvsMapper>(emvs_options_, *camera_);
    map_ = std::make_unique<GlobalMap>(global_map_options_);
  } catch (const std::exception& e) {
    ROS_ERROR("mapping_node: the mapper cannot start: %s", e.what());
    return;
  }
  last_events_wall_ = last_cloud_wall_ = last_status_ = ros::WallTime::now();
  while (true) {
    std::deque<EventVector> batch;
    std::shared_ptr<const BSpline> spline;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      cv_.wait_for(lock, std::chrono::milliseconds(100),
                   [this] { return stop_ || !queue_.empty() || new_spline_; });
      if (stop_) break;
      batch.swap(queue_);
      spline.swap(new_spline_);
    }
    const ros::WallTime start = ros::WallTime::now();
    try {
      for (const EventVector& events : batch) handleEvents(events);
      if (spline) spline_ = spline;
      if (!batch.empty() || spline) mapCovered();
      if (mapper_->hasKeyframe() && node_options_.keyframe_timeout_s > 0 &&
          (start - last_events_wall_).toSec() > node_options_.keyframe_timeout_s) {
        EmvsKeyframe last;
        if (mapper_->finish(&last)) {
          ROS_INFO("mapping_node: no events for %.1f s: keyframe closed",
                   node_options_.keyframe_timeout_s);
          handleKeyframe(last);
        }
      }
    } catch (const std::exception& e) {
      ROS_ERROR_THROTTLE(5, "mapping_node: mapping failed: %s; mapper reset", e.what());
      mapper_->reset();
    }
    busy_wall_s_ += (ros::WallTime::now() - start).toSec();
    const ros::WallTime now = ros::WallTime::now();
    if (map_changed_ && (now - last_cloud_wall_).toSec() >= node_options_.cloud_period_s) {
      publishCloud();
      last_cloud_wall_ = now;
    }
    if ((now - last_status_).toSec() >= node_options_.status_period_s) logStatus();
  }
}

void MappingNode::handleEvents(const EventVector& events) {
  last_events_wall_ = ros::WallTime::now();
  int64_t oldest = events.front().t_ns;
  for (const PixelEvent& e : events) oldest = std::min(oldest, e.t_ns);
  if (newest_event_ns_ >= 0 && oldest < newest_event_ns_ - secToNs(node_options_.max_backwards_jump_s)) {
    ++resets_;
    ROS_WARN(
        "mapping_node: event time jumped back by %.3f s (%.3f -> %.3f s; a looped bag?): mapper, "
        "global map and trajectory reset (reset %zu)",
        dtSec(newest_event_ns_, oldest), nsToSec(newest_event_ns_), nsToSec(oldest), resets_);
    mapper_->reset();
    map_->clear();
    spline_.reset();
    map_changed_ = true;
    newest_event_ns_ = -1;
  }
  for (const PixelEvent& e : events) newest_event_ns_ = std::max(newest_event_ns_, e.t_ns);
  mapper_->addEvents(events);
  if (mapper_->droppedOutOfOrder() > reported_out_of_order_) {
    ROS_WARN_THROTTLE(10,
                      "mapping_node: %zu events older than the newest one dropped (%zu so far)",
                      mapper_->droppedOutOfOrder() - reported_out_of_order_,
                      mapper_->droppedOutOfOrder());
    reported_out_of_order_ = mapper_->droppedOutOfOrder();
  }
  if (mapper_->droppedPending() > reported_dropped_pending_) {
    ROS_WARN_THROTTLE(
        5,
        "mapping_node: %zu events waited too long for %s (more than max_pending_events %zu "
        "buffered): oldest dropped (%zu so far)",
        mapper_->droppedPending() - reported_dropped_pending_, trajectory_sub_.getTopic().c_str(),
        emvs_options_.max_pending_events, mapper_->droppedPending());
    reported_dropped_pending_ = mapper_->droppedPending();
  }
  if (!spline_)
    ROS_INFO_THROTTLE(10, "mapping_node: %zu events buffered, waiting for %s",
                      mapper_->pendingEvents(), trajectory_sub_.getTopic().c_str());
}

void MappingNode::mapCovered() {
  if (!spline_) return;
  const std::shared_ptr<const BSpline> spline = spline_;
  const Pose3 T_base_cam = T_base_cam_;
  const auto pose = [&spline, &T_base_cam](int64_t t_ns, Pose3* T_odom_cam) {
    if (!spline->covers(t_ns)) return false;
    *T_odom_cam = spline->T_odom_cam(spline->toSplineTime(t_ns), T_base_cam);
    return true;
  };
  // The end of the spline still moves with new data: only events before it are final.
  const int64_t t_final_ns = spline->epochNs() + secToNs(spline->validTo()) -
                             secToNs(node_options_.trajectory_margin_s);
  for (const EmvsKeyframe& kf : mapper_->process(pose, t_final_ns)) handleKeyframe(kf);
}

void MappingNode::handleKeyframe(const EmvsKeyframe& kf) {
  ++keyframes_;
  const EmvsCounts& c = kf.counts;
  counts_.events += c.events;
  counts_.voted += c.voted;
  counts_.skipped_time += c.skipped_time;
  counts_.skipped_nan += c.skipped_nan;
  counts_.skipped_behind += c.skipped_behind;
  counts_.skipped_outside += c.skipped_outside;
  counts_.points += c.points;
  if (counts_.skipped_time > reported_skipped_time_) {
    ROS_WARN_THROTTLE(10,
                      "mapping_node: %zu events not covered by the trajectory skipped (%zu so far)",
                      counts_.skipped_time - reported_skipped_time_, counts_.skipped_time);
    reported_skipped_time_ = counts_.skipped_time;
  }
  if (counts_.skipped_nan > reported_skipped_nan_) {
    ROS_WARN_THROTTLE(10,
                      "mapping_node: %zu events with a non-finite pose skipped (%zu so far)",
                      counts_.skipped_nan - reported_skipped_nan_, counts_.skipped_nan);
    reported_skipped_nan_ = counts_.skipped_nan;
  }
  if (depth_pub_.getNumSubscribers() > 0 && !kf.depth_m.empty())
    depth_pub_.publish(imageToMsg(
        colorizeDepth(kf.depth_m, emvs_options_.volume.z_min_m, emvs_options_.volume.z_max_m), kf.t_kf_ns,
        frames::kCamera));
  if (kf.points_odom.empty()) {
    ++keyframes_empty_;
    ROS_WARN_THROTTLE(10,
                      "mapping_node: keyframe at %.3f s has no points (%zu events voted; %zu empty "
                      "keyframes of %zu so far)",
                      nsToSec(kf.t_kf_ns), c.voted, keyframes_empty_, keyframes_);
    return;
  }
  points_pub_.publish(cloudToMsg(kf.points_odom, frames::kOdom, kf.t_kf_ns));
  map_->insert(kf.points_odom);
  map_changed_ = true;
}

void MappingNode::publishCloud() {
  map_changed_ = false;
  cloud_pub_.publish(cloudToMsg(map_->points(), frames::kOdom, std::max<int64_t>(0, newest_event_ns_)));
}

void MappingNode::logStatus() {
  const ros::WallTime now = ros::WallTime::now();
  ROS_INFO(
      "mapping_node: %zu keyframes (%zu empty), global map %zu points (%zu dropped); events: %zu "
      "voted (%zu thinned to the rate limit), %zu waiting, %zu not covered by the trajectory, %zu non-finite pose, %zu late, %zu "
      "dropped waiting; packets %zu (%zu lost before the node, %zu empty, %zu wrong size, %zu queue full, %zu before the "
      "calibration); trajectories "
      "%zu (%zu refused); %zu resets; busy %.1f s",
      keyframes_, keyframes_empty_, map_->size(), map_->dropped(), counts_.voted, mapper_->thinned(),
      mapper_->pendingEvents(), counts_.skipped_time, counts_.skipped_nan,
      mapper_->droppedOutOfOrder(), mapper_->droppedPending(), packets_in_.load(),
      packets_lost_.load(), packets_empty_.load(), packets_wrong_size_.load(), packets_queue_full_.load(),
      packets_before_calibration_.load(), splines_in_.load(), splines_refused_.load(), resets_, busy_wall_s_);
  last_status_ = now;
}

}  // namespace vwe_vo
