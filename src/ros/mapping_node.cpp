#include "vwe_vo/ros/mapping_node.h"

#include <sensor_msgs/Image.h>
#include <sensor_msgs/PointCloud2.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

#include "vwe_vo/io/files.h"
#include "vwe_vo/io/options_yaml.h"
#include "vwe_vo/ros/conversions.h"
#include "vwe_vo/ros/input_callback_thread.h"
#include "vwe_vo/ros/param_loader.h"
#include "vwe_vo/ros/process_priority.h"
#include "vwe_vo/ros/shared_msg.h"
#include "vwe_vo/ros/topics.h"

namespace vwe_vo {

void MappingNodeOptions::validate() const {
  auto fail = [](const std::string& m) { throw std::invalid_argument("mapping_node: " + m); };
  if (!(cloud_period_s > 0)) fail("~cloud_period_s must be positive [s]");
  if (threads < 0 || threads > 64) fail("~threads must be in [0, 64] (0: the config's)");
  if (!(trajectory_margin_s >= 0) || !std::isfinite(trajectory_margin_s))
    fail("~trajectory_margin_s must be finite and >= 0 [s]");
  if (!(keyframe_timeout_s >= 0)) fail("~keyframe_timeout_s must be >= 0 [s]");
  if (max_queue_events < 1) fail("~max_queue_events must be at least 1");
  if (!(status_period_s > 0)) fail("~status_period_s must be positive [s]");
  if (nice < 0 || nice > 19) fail("~nice must be in [0, 19]");
}

MappingNode::MappingNode(const ros::NodeHandle& nh, const ros::NodeHandle& pnh, Hosting hosting)
    : nh_(nh), pnh_(pnh), hosting_(hosting) {
  readParameters();
  events_sub_ =
      subscribeInput(nh_, topics::kEvents, kEventPacketQueue, &MappingNode::eventsCallback, this);
  camera_info_sub_ = nh_.subscribe(topics::kCameraInfo, 2, &MappingNode::cameraInfoCallback, this);
  trajectory_sub_ = nh_.subscribe(topics::kTrajectory, 5, &MappingNode::trajectoryCallback, this);
  points_pub_ = nh_.advertise<sensor_msgs::PointCloud2>(topics::kMapPoints, 10);
  cloud_pub_ = nh_.advertise<sensor_msgs::PointCloud2>(topics::kMapCloud, 1, /*latch=*/true);
  depth_pub_ = nh_.advertise<sensor_msgs::Image>(topics::kMapDepth, 2);
  if (!input_.hasCalibration())
    ROS_INFO("mapping_node: waiting for %s (no ~calibration given)",
             camera_info_sub_.getTopic().c_str());
  worker_ = std::thread(&MappingNode::workerLoop, this);
}

MappingNode::~MappingNode() {
  // The input thread's callbacks use input_: they end before it goes.
  events_sub_.shutdown();
  input_.stop();
  if (worker_.joinable()) worker_.join();
}

void MappingNode::readParameters() {
  MappingNodeOptions& o = node_options_;
  ParamLoader params(pnh_, "mapping_node");
  params.read("config", &o.config_path);
  params.read("calibration", &o.calibration_path);
  params.read("cloud_period_s", &o.cloud_period_s);
  params.read("trajectory_margin_s", &o.trajectory_margin_s);
  params.read("keyframe_timeout_s", &o.keyframe_timeout_s);
  params.read("max_queue_events", &o.max_queue_events);
  params.read("status_period_s", &o.status_period_s);
  params.read("threads", &o.threads);
  params.read("nice", &o.nice);
  if (o.config_path.empty()) o.config_path = defaultConfigDir() + "/vwe_vo.yaml";
  params.finish();
  o.validate();

  const PipelineConfig config = loadPipelineConfig(o.config_path);
  for (const std::string& w : config.warnings) ROS_WARN("mapping_node: %s", w.c_str());
  emvs_options_ = config.mapping;
  if (o.threads > 0) emvs_options_.volume.num_threads = o.threads;
  global_map_options_ = config.global_map;
  emvs_options_.validate();
  global_map_options_.validate();
  T_base_cam_ = config.T_base_cam;

  input_.setTimestampPolicy(config.input);
  input_.setBound(InputKind::kEvents, size_t(o.max_queue_events));
  input_.setBound(InputKind::kTrajectory, 1, Overflow::kReplaceOldest);
  if (!o.calibration_path.empty()) {
    input_.setCalibration(
        loadCameraCalibrationYaml(o.calibration_path));  // throws naming file and field
  }

  const EmvsOptions& e = emvs_options_;
  ROS_INFO("mapping_node: config %s, calibration %s, %d threads", o.config_path.c_str(),
           o.calibration_path.empty() ? "from camera_info" : o.calibration_path.c_str(),
           emvs_options_.volume.num_threads);
  ROS_INFO(
      "mapping_node: keyframe every %.2f m or %.1f deg or %zu events; DSI %d planes in [%.2f, "
      "%.2f] m at grid scale %.2f; %zu events may wait for the trajectory; at most %.0f events/s "
      "voted (0: all); global map voxel %.3f m, %zu points max",
      e.kf_distance_m, e.kf_rotation_deg, e.max_events_per_keyframe, e.volume.num_planes,
      e.volume.z_min_m, e.volume.z_max_m, e.volume.grid_scale, e.max_pending_events,
      e.max_event_rate_hz, global_map_options_.voxel_size_m, global_map_options_.max_points);
}

// ------------------------------------------------------------------------------------------------
// Callbacks: validate, convert, enqueue. Nothing here runs the core.

void MappingNode::eventsCallback(const EventArray::ConstPtr& msg) {
  input_.pushEventPacket(*msg, [](EventVector&& events) {
    Input input;
    input.events = std::move(events);
    return input;
  });
}

void MappingNode::cameraInfoCallback(const sensor_msgs::CameraInfo::ConstPtr& msg) {
  input_.acceptCameraInfo(*msg);
}

void MappingNode::trajectoryCallback(const SplineTrajectory::ConstPtr& msg) {
  Input input;
  try {
    input.spline = std::make_shared<const BSpline>(splineFromMsg(*msg));
    if (!msg->tilt_t.empty()) input.tilt = std::make_shared<const TiltHistory>(tiltFromMsg(*msg));
  } catch (const std::invalid_argument& e) {
    input_.countRefused(InputKind::kTrajectory);
    const InputKindCounters c = input_.counters()[InputKind::kTrajectory];
    ROS_WARN_THROTTLE(5, "mapping_node: trajectory refused: %s (%zu of %zu refused so far)",
                      e.what(), c.refused, c.in);
    return;
  }
  if (!msg->header.frame_id.empty() && msg->header.frame_id != frames::kOdom)
    ROS_WARN_THROTTLE(30, "mapping_node: trajectory in frame '%s', used as '%s'",
                      msg->header.frame_id.c_str(), frames::kOdom);
  input_.push(InputKind::kTrajectory, std::move(input));
}

// ------------------------------------------------------------------------------------------------
// Worker: the only thread that touches the mapper and the global map.

void MappingNode::workerLoop() {
  nameThisThread("mapping_node");
  lowerCpuPriority(node_options_.nice, "mapping_node", hosting_);
  CameraCalibration calibration;
  if (!input_.waitForCalibration(&calibration)) return;
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
    std::deque<Input> inputs;
    if (!input_.takeAll(&inputs, std::chrono::milliseconds(100))) break;
    const ros::WallTime start = ros::WallTime::now();
    try {
      // In arrival order, each packet mapped as far as the trajectory covers it before the next
      // is buffered: only events the trajectory does not cover yet wait in the mapper (bounded
      // by max_pending_events), however many packets a busy worker finds queued.
      for (Input& input : inputs) {
        if (input.spline)
          spline_ = std::move(input.spline), tilt_ = std::move(input.tilt);
        else
          handleEvents(input.events, input.reset_why);
        mapCovered();
      }
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

void MappingNode::handleEvents(const EventVector& events, const std::string& reset_why) {
  last_events_wall_ = ros::WallTime::now();
  if (!reset_why.empty()) {
    ++resets_;
    ROS_WARN("mapping_node: %s: mapper, global map and trajectory reset (reset %zu)",
             reset_why.c_str(), resets_);
    mapper_->reset();
    map_->clear();
    spline_.reset();
    tilt_.reset();
    map_changed_ = true;
    newest_event_ns_ = -1;
  }
  for (const PixelEvent& e : events) newest_event_ns_ = std::max(newest_event_ns_, e.t_ns);
  mapper_->addEvents(events);
  if (mapper_->droppedOutOfOrder() > reported_out_of_order_) {
    ROS_WARN_THROTTLE(10, "mapping_node: %zu events older than the newest one dropped (%zu so far)",
                      mapper_->droppedOutOfOrder() - reported_out_of_order_,
                      mapper_->droppedOutOfOrder());
    reported_out_of_order_ = mapper_->droppedOutOfOrder();
  }
  if (mapper_->thinnedPending() > reported_thinned_pending_) {
    ROS_WARN_THROTTLE(
        5,
        "mapping_node: %zu events waiting for %s (more than max_pending_events %zu buffered): "
        "thinned to every second one, evenly in time (%zu so far)",
        mapper_->thinnedPending() - reported_thinned_pending_, trajectory_sub_.getTopic().c_str(),
        emvs_options_.max_pending_events, mapper_->thinnedPending());
    reported_thinned_pending_ = mapper_->thinnedPending();
  }
  if (!spline_)
    ROS_INFO_THROTTLE(10, "mapping_node: %zu events buffered, waiting for %s",
                      mapper_->pendingEvents(), trajectory_sub_.getTopic().c_str());
}

void MappingNode::mapCovered() {
  if (!spline_) return;
  const std::shared_ptr<const BSpline> spline = spline_;
  const std::shared_ptr<const TiltHistory> tilt = tilt_;
  const Pose3 T_base_cam = T_base_cam_;
  const auto pose = [&spline, &tilt, &T_base_cam](int64_t t_ns, Pose3* T_odom_cam) {
    if (!spline->covers(t_ns)) return false;
    Pose3 T_odom_base = spline->T_odom_base(spline->toSplineTime(t_ns));
    if (tilt) T_odom_base.linear() = T_odom_base.linear() * tilt->at(t_ns).rotation();
    *T_odom_cam = T_odom_base * T_base_cam;
    return true;
  };
  // The end of the spline still moves with new data: only events before it are final.
  const int64_t t_final_ns =
      spline->epochNs() + secToNs(spline->validTo()) - secToNs(node_options_.trajectory_margin_s);
  for (const EmvsKeyframe& kf : mapper_->process(pose, t_final_ns)) handleKeyframe(kf);
}

void MappingNode::handleKeyframe(const EmvsKeyframe& kf) {
  ++keyframes_;
  const EmvsCounts& c = kf.counts;
  counts_ += c;
  if (counts_.skipped_time > reported_skipped_time_) {
    ROS_WARN_THROTTLE(10,
                      "mapping_node: %zu events not covered by the trajectory skipped (%zu so far)",
                      counts_.skipped_time - reported_skipped_time_, counts_.skipped_time);
    reported_skipped_time_ = counts_.skipped_time;
  }
  if (counts_.skipped_nan > reported_skipped_nan_) {
    ROS_WARN_THROTTLE(10, "mapping_node: %zu events with a non-finite pose skipped (%zu so far)",
                      counts_.skipped_nan - reported_skipped_nan_, counts_.skipped_nan);
    reported_skipped_nan_ = counts_.skipped_nan;
  }
  if (depth_pub_.getNumSubscribers() > 0 && !kf.depth_m.empty())
    depth_pub_.publish(sharedMsg(imageToMsg(
        colorizeDepth(kf.depth_m, emvs_options_.volume.z_min_m, emvs_options_.volume.z_max_m),
        kf.t_kf_ns, frames::kCamera)));
  if (kf.points_odom.empty()) {
    ++keyframes_empty_;
    ROS_WARN_THROTTLE(10,
                      "mapping_node: keyframe at %.3f s has no points (%zu events voted; %zu empty "
                      "keyframes of %zu so far)",
                      nsToSec(kf.t_kf_ns), c.voted, keyframes_empty_, keyframes_);
    return;
  }
  points_pub_.publish(sharedMsg(cloudToMsg(kf.points_odom, frames::kOdom, kf.t_kf_ns)));
  map_->insert(kf.points_odom);
  map_changed_ = true;
}

void MappingNode::publishCloud() {
  map_changed_ = false;
  cloud_pub_.publish(
      sharedMsg(cloudToMsg(map_->points(), frames::kOdom, std::max<int64_t>(0, newest_event_ns_))));
}

void MappingNode::logStatus() {
  const ros::WallTime now = ros::WallTime::now();
  ROS_INFO(
      "mapping_node: %zu keyframes (%zu empty, %zu left out by the rate limit), global map %zu "
      "points (%zu dropped); events: %zu voted (%zu thinned to the rate limit), %zu waiting, %zu "
      "not covered by the trajectory, %zu "
      "non-finite pose, %zu late, %zu "
      "thinned waiting; %zu resets; busy %.1f s; input: %s",
      keyframes_, keyframes_empty_, mapper_->keyframesSkipped(), map_->size(), map_->dropped(),
      counts_.voted, mapper_->thinned(), mapper_->pendingEvents(), counts_.skipped_time,
      counts_.skipped_nan, mapper_->droppedOutOfOrder(), mapper_->thinnedPending(), resets_,
      busy_wall_s_, input_.statusLine().c_str());
  last_status_ = now;
}

}  // namespace vwe_vo
