#include "vwe_vo/ros/backend_node.h"

#include <geometry_msgs/TransformStamped.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

#include "vwe_vo/SplineTrajectory.h"
#include "vwe_vo/io/files.h"
#include "vwe_vo/io/options_yaml.h"
#include "vwe_vo/ros/conversions.h"
#include "vwe_vo/ros/input_callback_thread.h"
#include "vwe_vo/ros/param_loader.h"
#include "vwe_vo/ros/process_priority.h"
#include "vwe_vo/ros/shared_msg.h"
#include "vwe_vo/ros/topics.h"

namespace vwe_vo {

namespace {
// The spline message's tilt samples: the newest 30 s (what the mapper still maps: its pending
// events and the trajectory margin are a few seconds), every 20 ms (the output rate's step).
constexpr double kTiltSpan_s = 30.0;
constexpr double kTiltStep_s = 0.02;
}  // namespace

void BackendNodeOptions::validate() const {
  auto fail = [](const std::string& m) { throw std::invalid_argument("backend_node: " + m); };
  if (max_queue_events < 1) fail("~max_queue_events must be at least 1");
  if (threads < 0 || threads > 64) fail("~threads must be in [0, 64] (0: the config's)");
  if (max_queue_messages < 1) fail("~max_queue_messages must be at least 1");
  if (!(odom_rate_hz > 0 && odom_rate_hz <= 1000)) fail("~odom_rate_hz must be in (0, 1000] [Hz]");
  if (path_max_poses < 1) fail("~path_max_poses must be at least 1");
  if (!(status_period_s > 0)) fail("~status_period_s must be positive [s]");
  if (nice < 0 || nice > 19) fail("~nice must be in [0, 19]");
}

BackendNode::BackendNode(const ros::NodeHandle& nh, const ros::NodeHandle& pnh, Hosting hosting)
    : nh_(nh), pnh_(pnh), hosting_(hosting) {
  readParameters();
  events_sub_ =
      subscribeInput(nh_, topics::kEvents, kEventPacketQueue, &BackendNode::eventsCallback, this);
  camera_info_sub_ = nh_.subscribe(topics::kCameraInfo, 2, &BackendNode::cameraInfoCallback, this);
  arcs_sub_ = nh_.subscribe(topics::kArcs, 1000, &BackendNode::arcCallback, this);
  if (node_options_.use_imu)
    imu_sub_ = subscribeInput(nh_, topics::kImu, 2000, &BackendNode::imuCallback, this);
  trajectory_pub_ = nh_.advertise<SplineTrajectory>(topics::kTrajectory, 10);
  odom_pub_ = nh_.advertise<nav_msgs::Odometry>(topics::kBackendOdom, 100);
  path_pub_ = nh_.advertise<nav_msgs::Path>(topics::kPath, 2);
  if (node_options_.publish_tf) tf_ = std::make_unique<tf2_ros::TransformBroadcaster>();
  path_.header.frame_id = frames::kOdom;
  if (!input_.hasCalibration())
    ROS_INFO("backend_node: waiting for %s (no ~calibration given)",
             camera_info_sub_.getTopic().c_str());
  worker_ = std::thread(&BackendNode::workerLoop, this);
}

BackendNode::~BackendNode() {
  // The input thread's callbacks use input_: they end before it goes.
  events_sub_.shutdown();
  imu_sub_.shutdown();
  input_.stop();
  if (worker_.joinable()) worker_.join();
}

void BackendNode::readParameters() {
  BackendNodeOptions& o = node_options_;
  ParamLoader params(pnh_, "backend_node");
  params.read("config", &o.config_path);
  params.read("calibration", &o.calibration_path);
  params.read("max_queue_events", &o.max_queue_events);
  params.read("max_queue_messages", &o.max_queue_messages);
  params.read("odom_rate_hz", &o.odom_rate_hz);
  params.read("path_max_poses", &o.path_max_poses);
  params.read("status_period_s", &o.status_period_s);
  params.read("threads", &o.threads);
  params.read("publish_tf", &o.publish_tf);
  params.read("nice", &o.nice);
  params.read("use_imu", &o.use_imu);
  params.read("use_odom", &o.use_odom);
  if (o.config_path.empty()) o.config_path = defaultConfigDir() + "/vwe_vo.yaml";
  params.finish();
  o.validate();

  const PipelineConfig config = loadPipelineConfig(o.config_path);
  for (const std::string& w : config.warnings) ROS_WARN("backend_node: %s", w.c_str());
  backend_options_ = config.backend;
  if (o.threads > 0) backend_options_.volume.num_threads = o.threads;
  backend_options_.validate();
  T_base_cam_ = config.T_base_cam;
  input_.setTimestampPolicy(config.input);
  // The input policy resets on event gaps first; the driver's rule covers the arcs (0: never).
  if (config.input.max_gap_s > 0) driver_options_.max_gap_s = config.input.max_gap_s;
  driver_options_.odom_rate_hz = o.odom_rate_hz;
  driver_options_.validate();
  imu_options_ = config.imu;
  input_.setBound(InputKind::kEvents, size_t(o.max_queue_events));
  input_.setBound(InputKind::kImu, size_t(o.max_queue_messages));
  input_.setBound(InputKind::kArc, size_t(o.max_queue_messages));
  if (!o.calibration_path.empty()) {
    input_.setCalibration(
        loadCameraCalibrationYaml(o.calibration_path));  // throws naming file and field
  }
  const BackendOptions& b = backend_options_;
  ROS_INFO(
      "backend_node: config %s, calibration %s; spline degree %d, knots every %.2f s, window "
      "%.1f s refined every %.1f s, volumes every %.2f s over %.2f s with <= %zu events, "
      "contrast %s, %d iterations, %d threads; odom at %.1f Hz, reset after a %.1f s gap, tf %d",
      o.config_path.c_str(),
      o.calibration_path.empty() ? "from camera_info" : o.calibration_path.c_str(), b.degree,
      b.knot_spacing_s, b.window_s, b.update_interval_s, b.tau1_s, b.tau2_s,
      b.max_events_per_volume, contrastName(b.volume.contrast), b.max_iterations,
      b.volume.num_threads, o.odom_rate_hz, driver_options_.max_gap_s, o.publish_tf);
}

// ------------------------------------------------------------------------------------------------
// Callbacks: validate, convert, enqueue. Nothing here runs the core.

void BackendNode::eventsCallback(const EventArray::ConstPtr& msg) {
  input_.pushEventPacket(*msg, [](EventVector&& events) {
    Input input;
    input.events = std::move(events);
    return input;
  });
}

void BackendNode::cameraInfoCallback(const sensor_msgs::CameraInfo::ConstPtr& msg) {
  input_.acceptCameraInfo(*msg);
}

void BackendNode::arcCallback(const AckermannArc::ConstPtr& msg) {
  Input input;
  input.kind = Input::Kind::kArc;
  input.arc = arcFromMsg(*msg);
  input_.push(InputKind::kArc, std::move(input));
}

void BackendNode::imuCallback(const sensor_msgs::Imu::ConstPtr& msg) {
  Input input;
  input.kind = Input::Kind::kImu;
  input.imu = imuFromMsg(*msg);
  if (!input.imu.gyro.allFinite() || !input.imu.accel.allFinite()) {
    input_.countRefused(InputKind::kImu);
    ROS_WARN_THROTTLE(
        5, "backend_node: IMU sample at %.3f s with a non-finite value refused (%zu so far)",
        nsToSec(input.imu.t_ns), input_.counters()[InputKind::kImu].refused);
    return;
  }
  input_.push(InputKind::kImu, std::move(input));
}

// ------------------------------------------------------------------------------------------------
// Worker: the only thread that touches the back-end.

void BackendNode::workerLoop() {
  nameThisThread("backend_node");
  lowerCpuPriority(node_options_.nice, "backend_node", hosting_);
  CameraCalibration calibration;
  if (!input_.waitForCalibration(&calibration)) return;
  try {
    camera_ = std::make_unique<CameraModel>(calibration);
    backend_ = std::make_unique<Backend>(backend_options_, *camera_, T_base_cam_);
    backend_->setSpeedsMeasured(node_options_.use_odom);
    if (node_options_.use_imu) backend_->enableImu(imu_options_, imu_options_.T_cam_imu());
    if (node_options_.use_imu && !backend_->tiltInPose())
      ROS_INFO(
          "backend_node: ~use_imu without ~use_odom: the gyro's yaw rate is fused, the pose stays "
          "planar (pitch and roll need the vehicle's acceleration, unknown without /odom)");
    BackendDriver::Callbacks callbacks;
    callbacks.odometry = [this](int64_t t_ns, const Pose3& T, double v, double omega) {
      publishOdometry(t_ns, T, v, omega);
    };
    callbacks.refinement = [this](size_t merged) { publishRefinement(merged); };
    callbacks.reset = [this](BackendDriver::ResetCause, const std::string& why) { onReset(why); };
    driver_ = std::make_unique<BackendDriver>(backend_.get(), driver_options_, callbacks);
  } catch (const std::exception& e) {
    ROS_ERROR("backend_node: the back-end cannot start: %s", e.what());
    return;
  }
  last_status_ = ros::WallTime::now();
  while (true) {
    std::deque<Input> batch;
    if (!input_.takeAll(&batch, std::chrono::milliseconds(100))) break;
    if (!batch.empty()) {
      const ros::WallTime start = ros::WallTime::now();
      int64_t newest_arc = -1;  // the batch's last arc
      for (const Input& input : batch)
        if (input.kind == Input::Kind::kArc) newest_arc = input.arc.t_end_ns;
      for (Input& input : batch) {
        try {
          if (input.kind == Input::Kind::kEvents)
            handleEvents(input.events, input.reset_why);
          else if (input.kind == Input::Kind::kImu)
            backend_->addImu(input.imu);
          else
            handleArc(input.arc, newest_arc);
        } catch (const std::exception& e) {
          resetBackend(std::string("the back-end failed (") + e.what() + ")");
        }
      }
      busy_wall_s_ += (ros::WallTime::now() - start).toSec();
    }
    if ((ros::WallTime::now() - last_status_).toSec() >= node_options_.status_period_s) logStatus();
  }
}

void BackendNode::resetBackend(const std::string& why) {
  driver_->reset(why);
}

void BackendNode::onReset(const std::string& why) {
  path_.poses.clear();
  ROS_WARN("backend_node: %s: back-end reset, the trajectory restarts at the identity (reset %zu)",
           why.c_str(), backend_->stats().resets);
}

void BackendNode::handleEvents(const EventVector& events, const std::string& reset_why) {
  if (!reset_why.empty()) driver_->reset("the input reset: " + reset_why);
  driver_->addEvents(events);
  const BackendStats& s = backend_->stats();
  if (s.events_out_of_order > reported_out_of_order_) {
    ROS_WARN_THROTTLE(10, "backend_node: %zu events older than the newest one dropped (%zu so far)",
                      s.events_out_of_order - reported_out_of_order_, s.events_out_of_order);
    reported_out_of_order_ = s.events_out_of_order;
  }
}

void BackendNode::handleArc(const ArcEstimate& arc, int64_t newest_pending_arc_ns) {
  const BackendDriverStats before = driver_->stats();
  driver_->addArc(arc, newest_pending_arc_ns);
  const BackendDriverStats& s = driver_->stats();
  if (s.arcs_stale > before.arcs_stale)
    ROS_WARN_THROTTLE(
        10,
        "backend_node: arc ending at %.3f s is not newer than the newest arc: ignored (%zu so far)",
        nsToSec(arc.t_end_ns), s.arcs_stale);
  if (s.arcs_lost > before.arcs_lost)
    ROS_WARN_THROTTLE(10,
                      "backend_node: arc at %.3f s is %s: the last good yaw rate and speed "
                      "are held through it (%zu so far)",
                      nsToSec(arc.t_ref_ns), toString(arc.status), s.arcs_lost);
}

void BackendNode::publishRefinement(size_t merged) {
  ++refinements_;
  if (merged > 0)
    ROS_WARN_THROTTLE(
        10, "backend_node: behind: one refinement over %zu update intervals (%zu merged so far)",
        merged + 1, driver_->stats().refinements_merged);
  if (!backend_->hasSpline()) return;
  const BSpline& spline = backend_->spline();
  SplineTrajectory trajectory = splineToMsg(spline, backend_->firstFree(), frames::kOdom);
  if (backend_->tiltInPose()) {
    // The tilt the published poses carry, over the part of the spline the mapper may still map:
    // its live map then sees the camera as /vwe/odom and tf do.
    const int64_t to = spline.epochNs() + secToNs(spline.validTo());
    const int64_t from =
        std::max(spline.epochNs() + secToNs(spline.validFrom()), to - secToNs(kTiltSpan_s));
    for (int64_t t = from; t <= to; t += secToNs(kTiltStep_s))
      addTiltToMsg(t, backend_->tiltAt(t), &trajectory);
  }
  trajectory_pub_.publish(sharedMsg(std::move(trajectory)));
  // The path: the refined spline, newest path_max_poses at the odometry rate.
  const Trajectory3 traj = backend_->sampleTrajectory(node_options_.odom_rate_hz);
  const size_t n = std::min(traj.size(), size_t(node_options_.path_max_poses));
  path_.header.stamp = toRosTime(backend_->processedUntil());
  path_.poses.resize(n);
  for (size_t i = 0; i < n; ++i) {
    const auto& s = traj[traj.size() - n + i];
    path_.poses[i].header.frame_id = frames::kOdom;
    path_.poses[i].header.stamp = toRosTime(s.t_ns);
    path_.poses[i].pose = poseToMsg(s.T);
  }
  path_pub_.publish(sharedMsg(nav_msgs::Path(path_)));
}

void BackendNode::publishOdometry(int64_t t_ns, const Pose3& T, double v, double omega) {
  nav_msgs::Odometry odom;
  odom.header.stamp = toRosTime(t_ns);
  odom.header.frame_id = frames::kOdom;
  odom.child_frame_id = frames::kBase;
  odom.pose.pose = poseToMsg(T);
  odom.twist.twist.linear.x = v;
  odom.twist.twist.angular.z = omega;
  if (tf_) {
    geometry_msgs::TransformStamped tf;
    tf.header = odom.header;
    tf.child_frame_id = frames::kBase;
    tf.transform = transformToMsg(T);
    tf_->sendTransform(tf);
  }
  odom_pub_.publish(sharedMsg(std::move(odom)));
}

void BackendNode::logStatus() {
  const ros::WallTime now = ros::WallTime::now();
  const BackendStats& s = backend_->stats();
  const BackendDriverStats& d = driver_->stats();
  const NodeInputCounters in = input_.counters();
  ROS_INFO(
      "backend_node: %zu refinements (%zu reverted, %zu volumes, %.2f s in the solver), %zu "
      "arcs in (%zu lost/low held, %zu stale), %zu events in (%zu outside, %zu late, %zu masked), "
      "%zu gaps, %zu loops, %zu resets, %zu intervals merged behind; input: %s",
      s.updates, s.rejected, s.volumes, s.solver_s, in[InputKind::kArc].in, d.arcs_lost,
      d.arcs_stale, s.events_in, s.events_outside + in.events_outside, s.events_out_of_order,
      s.events_masked, d.gaps, d.loops, s.resets, d.refinements_merged,
      input_.statusLine().c_str());
  last_status_ = now;
}

}  // namespace vwe_vo
