#include "vwe_vo/ros/frontend_node.h"

#include <sensor_msgs/Image.h>

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
#include "vwe_vo/sensor/subsample.h"
#include "vwe_vo/trajectory/ackermann_arc.h"
#include "vwe_vo/vwe/vwe_objective.h"

namespace vwe_vo {

namespace {
// Events kept for the VWE image are capped so that a stalled front-end cannot grow them forever.
constexpr size_t kMaxRecentEvents = 2000000;
}  // namespace

void FrontendNodeOptions::validate() const {
  auto fail = [](const std::string& m) { throw std::invalid_argument("frontend_node: " + m); };
  if (max_queue_events < 1) fail("~max_queue_events must be at least 1");
  if (threads < 0 || threads > 64) fail("~threads must be in [0, 64] (0: the config's)");
  if (max_queue_messages < 1) fail("~max_queue_messages must be at least 1");
  if (!(max_latency_s > 0)) fail("~max_latency_s must be positive [s]");
  if (!(status_period_s > 0)) fail("~status_period_s must be positive [s]");
  if (!std::isfinite(nominal_speed_mps)) fail("~nominal_speed must be finite [m/s]");
}

FrontendNode::FrontendNode(const ros::NodeHandle& nh, const ros::NodeHandle& pnh)
    : nh_(nh), pnh_(pnh) {
  readParameters();
  events_sub_ =
      subscribeInput(nh_, topics::kEvents, kEventPacketQueue, &FrontendNode::eventsCallback, this);
  camera_info_sub_ = nh_.subscribe(topics::kCameraInfo, 2, &FrontendNode::cameraInfoCallback, this);
  if (node_options_.use_odom)
    odom_sub_ = nh_.subscribe(topics::kOdom, 200, &FrontendNode::odomCallback, this);
  if (node_options_.use_imu)
    imu_sub_ = subscribeInput(nh_, topics::kImu, 2000, &FrontendNode::imuCallback, this);
  if (node_options_.follow_backend)
    trajectory_sub_ =
        nh_.subscribe(topics::kTrajectory, 10, &FrontendNode::trajectoryCallback, this);
  arcs_pub_ = nh_.advertise<AckermannArc>(topics::kArcs, 100);
  odom_pub_ = nh_.advertise<nav_msgs::Odometry>(topics::kFrontendOdom, 100);
  iwe_pub_ = nh_.advertise<sensor_msgs::Image>(topics::kFrontendIwe, 2);
  if (node_options_.publish_static_tf) {
    // The camera mount from the config, latched once: rviz and tf users see base_link -> davis.
    geometry_msgs::TransformStamped T;
    T.header.stamp = ros::Time::now();
    T.header.frame_id = frames::kBase;
    T.child_frame_id = frames::kCamera;
    T.transform = transformToMsg(T_base_cam_);
    static_tf_ = std::make_unique<tf2_ros::StaticTransformBroadcaster>();
    static_tf_->sendTransform(T);
  }
  if (!input_.hasCalibration())
    ROS_INFO("frontend_node: waiting for %s (no ~calibration given)",
             camera_info_sub_.getTopic().c_str());
  worker_ = std::thread(&FrontendNode::workerLoop, this);
}

FrontendNode::~FrontendNode() {
  // The input thread's callbacks use input_: they end before it goes.
  events_sub_.shutdown();
  imu_sub_.shutdown();
  input_.stop();
  if (worker_.joinable()) worker_.join();
}

void FrontendNode::readParameters() {
  FrontendNodeOptions& o = node_options_;
  ParamLoader params(pnh_, "frontend_node");
  params.read("config", &o.config_path);
  params.read("calibration", &o.calibration_path);
  params.read("nominal_speed", &o.nominal_speed_mps);
  params.read("use_odom", &o.use_odom);
  params.read("use_imu", &o.use_imu);
  params.read("publish_static_tf", &o.publish_static_tf);
  params.read("max_queue_events", &o.max_queue_events);
  params.read("max_queue_messages", &o.max_queue_messages);
  params.read("max_latency_s", &o.max_latency_s);
  params.read("status_period_s", &o.status_period_s);
  params.read("threads", &o.threads);
  params.read("follow_backend", &o.follow_backend);
  if (o.config_path.empty()) o.config_path = defaultConfigDir() + "/vwe_vo.yaml";
  params.finish();
  o.validate();

  const PipelineConfig config = loadPipelineConfig(o.config_path);
  for (const std::string& w : config.warnings) ROS_WARN("frontend_node: %s", w.c_str());
  frontend_options_ = config.frontend;
  if (o.threads > 0) frontend_options_.volume.num_threads = o.threads;
  if (o.nominal_speed_mps >= 0) frontend_options_.nominal_speed_mps = o.nominal_speed_mps;
  frontend_options_.validate();
  if (frontend_options_.use_gyro_prior && !o.use_imu)
    ROS_WARN(
        "frontend_node: the config's use_gyro_prior needs use_imu:=true (/dvs/imu); scanning "
        "without it");
  if (frontend_options_.one_sided.balance > 0 && !o.use_imu)
    ROS_INFO(
        "frontend_node: one-sided windows predict their depth from the previous arc "
        "(use_imu:=true: from the gyro, "
        "more reliable at the start of a turn)");
  T_base_cam_ = config.T_base_cam;

  input_.setTimestampPolicy(config.input);
  input_.setBound(InputKind::kEvents, size_t(o.max_queue_events));
  input_.setBound(InputKind::kOdometry, size_t(o.max_queue_messages));
  input_.setBound(InputKind::kImu, size_t(o.max_queue_messages));
  input_.setBound(InputKind::kTrajectory, size_t(o.max_queue_messages));
  if (!o.calibration_path.empty()) {
    input_.setCalibration(
        loadCameraCalibrationYaml(o.calibration_path));  // throws naming file and field
  }

  const FrontendOptions& f = frontend_options_;
  ROS_INFO("frontend_node: config %s, calibration %s, nominal_speed %.3f m/s%s, %d threads",
           o.config_path.c_str(),
           o.calibration_path.empty() ? "from camera_info" : o.calibration_path.c_str(),
           f.nominal_speed_mps, o.nominal_speed_mps >= 0 ? " (~nominal_speed)" : " (config)",
           f.volume.num_threads);
  ROS_INFO(
      "frontend_node: windows of %s, %zu events per volume, %d planes in [%.2f, %.2f] m at grid "
      "scale %.2f, contrast %s, "
      "scan +-%.2f rad/s (full +-%.2f), standstill below %.0f ev/s, gyro prior %d",
      f.window_by_count
          ? (std::to_string(f.window_events) + " events").c_str()
          : (std::to_string(int(std::lround(f.window_duration_s * 1000))) + " ms").c_str(),
      f.max_events_per_volume, f.volume.num_planes, f.volume.z_min_m, f.volume.z_max_m,
      f.volume.grid_scale, contrastName(f.volume.contrast), f.scan_half_range_rad_s,
      f.omega_max_rad_s, f.standstill_event_rate_hz, f.use_gyro_prior);
}

// ------------------------------------------------------------------------------------------------
// Callbacks: validate, convert, enqueue. Nothing here runs the core.

void FrontendNode::eventsCallback(const EventArray::ConstPtr& msg) {
  input_.pushEventPacket(*msg, [](EventVector&& events) {
    Input input;
    input.events = std::move(events);
    return input;
  });
}

void FrontendNode::cameraInfoCallback(const sensor_msgs::CameraInfo::ConstPtr& msg) {
  input_.acceptCameraInfo(*msg);
}

void FrontendNode::odomCallback(const nav_msgs::Odometry::ConstPtr& msg) {
  const OdometrySample sample = odometryFromMsg(*msg);
  if (!std::isfinite(sample.v_mps) || !std::isfinite(sample.yaw_rate_rad_s)) {
    input_.countRefused(InputKind::kOdometry);
    ROS_WARN_THROTTLE(
        5, "frontend_node: odometry at %.3f s with a non-finite twist refused (%zu so far)",
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

void FrontendNode::imuCallback(const sensor_msgs::Imu::ConstPtr& msg) {
  const GyroSample sample = gyroFromMsg(*msg, T_base_cam_);
  if (!std::isfinite(sample.yaw_rate_rad_s)) {
    input_.countRefused(InputKind::kImu);
    ROS_WARN_THROTTLE(5,
                      "frontend_node: IMU sample at %.3f s with a non-finite angular velocity "
                      "refused (%zu so far)",
                      nsToSec(sample.t_ns), input_.counters()[InputKind::kImu].refused);
    return;
  }
  Input input;
  input.kind = Input::Kind::kGyro;
  input.t_ns = sample.t_ns;
  input.yaw_rate = sample.yaw_rate_rad_s;  // yaw rate of base_link
  input_.push(InputKind::kImu, std::move(input));
}

void FrontendNode::trajectoryCallback(const SplineTrajectory::ConstPtr& msg) {
  Input input;
  input.kind = Input::Kind::kTrajectory;
  try {
    input.spline = std::make_shared<const BSpline>(splineFromMsg(*msg));
  } catch (const std::invalid_argument& e) {
    input_.countRefused(InputKind::kTrajectory);
    ROS_WARN_THROTTLE(10, "frontend_node: SplineTrajectory refused: %s (%zu so far)", e.what(),
                      input_.counters()[InputKind::kTrajectory].refused);
    return;
  }
  input.t_ns = toNs(msg->valid_to);
  input_.push(InputKind::kTrajectory, std::move(input));
}

// ------------------------------------------------------------------------------------------------
// Worker: the only thread that touches the front-end.

void FrontendNode::workerLoop() {
  nameThisThread("frontend_node");
  CameraCalibration calibration;
  if (!input_.waitForCalibration(&calibration)) return;
  try {
    camera_ = std::make_unique<CameraModel>(calibration);
    frontend_ = std::make_unique<Frontend>(frontend_options_, *camera_, T_base_cam_);
    FollowOptions follow;
    follow.follow_backend = node_options_.follow_backend;
    follower_ = FrontendFollower(follow, node_options_.use_odom);
    BacklogPolicyOptions backlog;
    backlog.max_latency_s = node_options_.max_latency_s;
    backlog.window_s = frontend_options_.window_duration_s;
    backlog.max_thinning = kMaxVolumeThinning;
    backlog_ = BacklogPolicy(backlog);
  } catch (const std::exception& e) {
    ROS_ERROR("frontend_node: the front-end cannot start: %s", e.what());
    return;
  }
  last_status_ = ros::WallTime::now();
  // One window per pass: the backlog, and with it the thinning, is looked at again after every
  // window, with whatever arrived meanwhile.
  while (true) {
    std::deque<Input> batch;
    const bool pending = frontend_->pendingWindows() > 0;
    if (!input_.takeAll(&batch, std::chrono::milliseconds(pending ? 0 : 100))) break;
    if (!batch.empty() || pending) {
      const ros::WallTime start = ros::WallTime::now();
      for (const Input& input : batch) {
        switch (input.kind) {
          case Input::Kind::kEvents:
            handleEvents(input.events, input.reset_why);
            break;
          case Input::Kind::kOdometry:
            frontend_->addOdometry(input.t_ns, input.v, input.yaw_rate);
            break;
          case Input::Kind::kGyro:
            frontend_->addGyro(input.t_ns, input.yaw_rate);
            break;
          case Input::Kind::kTrajectory:
            handleTrajectory(*input.spline);
            break;
        }
      }
      if (newest_event_ns_ >= 0) backlog_.observeInput(start.toSec(), nsToSec(newest_event_ns_));
      const double window_s =
          frontend_options_.window_duration_s;  // by-count windows: an approximation
      const double backlog_s = frontend_->pendingWindows() * window_s;
      // Behind: each next window votes half as many events as the one before, down to
      // 1/kMaxVolumeThinning (cheaper windows, none lost). Whole windows are skipped only when
      // even those are estimated slower than the events arrive (BacklogPolicy).
      const size_t thinning = frontend_->volumeThinning();
      const size_t next = backlog_.nextThinning(backlog_s, thinning);
      frontend_->setVolumeThinning(next);
      if (next > thinning)
        ROS_WARN_THROTTLE(5,
                          "frontend_node: %.2f s of events behind: windows vote 1/%zu of "
                          "max_events_per_volume (%zu windows thinned so far)",
                          backlog_s, next, frontend_->stats().windows_thinned);
      if (backlog_.mustSkip(backlog_s, next)) {
        const size_t keep = std::max<size_t>(1, size_t(node_options_.max_latency_s / window_s));
        // The skipped windows go out as LOST arcs: the back-end holds its rates through them
        // instead of finding a gap in the arcs (a reset beyond its max_gap_s).
        std::vector<ArcEstimate> skipped;
        const size_t dropped = frontend_->dropBacklog(keep, &skipped);
        for (const ArcEstimate& arc : skipped) publishArc(arc);
        ROS_WARN_THROTTLE(5,
                          "frontend_node: %.2f s of events behind (> ~max_latency_s %.2f), "
                          "windows estimated at %.2fx real time but events arriving at %.2fx: "
                          "%zu windows skipped (%zu so far)",
                          backlog_s, node_options_.max_latency_s, backlog_.progressRate(),
                          backlog_.arrivalRate(), dropped, frontend_->stats().windows_dropped);
      }
      const std::vector<ArcEstimate> arcs = frontend_->process(1);
      for (const ArcEstimate& arc : arcs) publishArc(arc);
      const double pass_s = (ros::WallTime::now() - start).toSec();
      if (!arcs.empty())
        backlog_.observeWindow(dtSec(arcs.back().t_end_ns, arcs.front().t_start_ns), pass_s);
      busy_wall_s_ += pass_s;
    }
    if ((ros::WallTime::now() - last_status_).toSec() >= node_options_.status_period_s) logStatus();
  }
}

void FrontendNode::handleEvents(const EventVector& events, const std::string& reset_why) {
  if (!reset_why.empty()) {
    frontend_->reset();
    ROS_WARN("frontend_node: %s: front-end reset, dead reckoning restarts at the identity",
             reset_why.c_str());
    recent_events_.clear();
    newest_event_ns_ = -1;
    follower_.reset(events.front().t_ns);
    backlog_.reset();
  }
  int64_t oldest = events.front().t_ns;
  for (const PixelEvent& e : events) oldest = std::min(oldest, e.t_ns);
  const int64_t newest_before = newest_event_ns_;
  if (frontend_->addEvents(events)) {
    ROS_WARN(
        "frontend_node: event time jumped back by %.3f s (%.3f -> %.3f s; a looped bag?): "
        "front-end reset, "
        "dead reckoning restarts at the identity (reset %zu)",
        dtSec(newest_before, oldest), nsToSec(newest_before), nsToSec(oldest),
        frontend_->stats().resets);
    recent_events_.clear();
    newest_event_ns_ = events.back().t_ns;
    follower_.reset(oldest);
    backlog_.reset();
  } else {
    newest_event_ns_ = std::max(newest_event_ns_, events.back().t_ns);
  }
  const FrontendStats& stats = frontend_->stats();
  if (stats.events_out_of_order > reported_out_of_order_) {
    ROS_WARN_THROTTLE(
        10,
        "frontend_node: %zu events older than the newest one dropped (time went back by less than "
        "%.3f s; %zu so far)",
        stats.events_out_of_order - reported_out_of_order_, frontend_options_.max_backwards_jump_s,
        stats.events_out_of_order);
    reported_out_of_order_ = stats.events_out_of_order;
  }
  if (iwe_pub_.getNumSubscribers() == 0) {
    recent_events_.clear();
    return;
  }
  if (recent_events_.size() > kMaxRecentEvents)
    recent_events_.erase(recent_events_.begin(),
                         recent_events_.begin() + recent_events_.size() / 2);
  for (const PixelEvent& e : events)
    if (camera_->inside(e.x, e.y) &&
        (recent_events_.empty() || e.t_ns >= recent_events_.back().t_ns))
      recent_events_.push_back(e);
}

void FrontendNode::handleTrajectory(const BSpline& spline) {
  if (!follower_.follow(spline, newest_event_ns_, frontend_.get())) return;
  ROS_INFO_THROTTLE(
      10,
      "frontend_node: re-anchored on the back-end's spline at %.3f s, speed %.3f m/s (%zu so far)",
      nsToSec(follower_.lastTime()), follower_.lastSpeed(), follower_.reanchors());
}

void FrontendNode::publishArc(const ArcEstimate& arc) {
  switch (arc.status) {
    case ArcStatus::kOk:
      ++windows_ok_;
      break;
    case ArcStatus::kStandstill:
      ++windows_standstill_;
      break;
    case ArcStatus::kLost:
      ++windows_lost_;
      break;
    case ArcStatus::kLowEvents:
      ++windows_low_;
      break;
  }
  processed_data_s_ += dtSec(arc.t_end_ns, arc.t_start_ns);
  arcs_pub_.publish(sharedMsg(arcToMsg(arc, frames::kBase)));

  nav_msgs::Odometry odom;
  odom.header.stamp = toRosTime(arc.t_end_ns);
  odom.header.frame_id = frames::kOdom;
  odom.child_frame_id = frames::kBase;
  odom.pose.pose = poseToMsg(anchoredPose(arc.t_end_ns));
  odom.twist.twist.linear.x = arc.v;
  odom.twist.twist.angular.z = arc.omegaWithoutRoll();
  odom_pub_.publish(sharedMsg(std::move(odom)));

  if (iwe_pub_.getNumSubscribers() > 0) publishImage(arc);
}

void FrontendNode::publishImage(const ArcEstimate& arc) {
  const auto by_time = [](const PixelEvent& e, int64_t t) { return e.t_ns < t; };
  const auto begin =
      std::lower_bound(recent_events_.begin(), recent_events_.end(), arc.t_start_ns, by_time);
  const auto end = std::lower_bound(begin, recent_events_.end(), arc.t_end_ns, by_time);
  const EventVector window = subsampleEvents(
      EventVector(begin, end), frontend_options_.max_events_per_volume, frontend_options_.seed);
  recent_events_.erase(recent_events_.begin(), end);
  if (!renderer_)
    renderer_ = std::make_unique<VweImageRenderer>(*camera_, frontend_options_.volume);
  const AckermannArcModel model(arc.omega, arc.v, arc.t_ref_ns, T_base_cam_);
  const cv::Mat image = renderer_->render(window, model);

  sensor_msgs::Image msg;
  msg.header.stamp = toRosTime(arc.t_ref_ns);
  msg.header.frame_id = frames::kCamera;
  msg.height = uint32_t(image.rows);
  msg.width = uint32_t(image.cols);
  msg.encoding = "mono8";
  msg.step = uint32_t(image.cols);
  msg.data.resize(size_t(image.rows) * image.cols);
  for (int y = 0; y < image.rows; ++y)
    std::copy_n(image.ptr<uint8_t>(y), image.cols, &msg.data[size_t(y) * image.cols]);
  iwe_pub_.publish(sharedMsg(std::move(msg)));
}

void FrontendNode::logStatus() {
  const ros::WallTime now = ros::WallTime::now();
  const double wall_s = std::max(1e-6, (now - last_status_).toSec());
  const FrontendStats& s = frontend_->stats();
  ROS_INFO(
      "frontend_node: %zu windows (%zu split in two) (%zu one-sided, %zu one-sided but near) (%zu "
      "at a roll rate) (%zu with the road's yaw rate, %zu of them the road's alone, %zu the VWE's "
      "alone, %zu with too little road) -> "
      "%zu arcs (%zu ok, %zu standstill, %zu lost, %zu "
      "low events), %zu windows skipped behind, %zu thinned behind; "
      "%.0f events/s in, %zu outside the sensor, %zu late, %zu on the near ground not voted; %zu "
      "resets; real-time factor %.3f; input: %s",
      s.windows, s.windows_split, s.windows_one_sided, s.windows_one_sided_near, s.windows_rolled,
      s.windows_ground, s.windows_ground_alone, s.windows_ground_refused, s.windows_ground_few,
      windows_ok_ + windows_standstill_ + windows_lost_ + windows_low_, windows_ok_,
      windows_standstill_, windows_lost_, windows_low_, s.windows_dropped, s.windows_thinned,
      double(s.events_in - last_status_events_) / wall_s,
      s.events_outside + input_.counters().events_outside, s.events_out_of_order,
      s.events_ground_masked, s.resets,
      processed_data_s_ > 0 ? busy_wall_s_ / processed_data_s_ : 0.0, input_.statusLine().c_str());
  last_status_ = now;
  last_status_events_ = s.events_in;
}

}  // namespace vwe_vo
