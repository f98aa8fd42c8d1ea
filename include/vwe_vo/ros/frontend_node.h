// frontend_node: runs the Ackermann front-end on /dvs/events live or from a bag. Callbacks only
// validate, convert and enqueue into a bounded queue; one worker thread runs vwe_vo::Frontend and
// publishes one AckermannArc, one dead-reckoned Odometry and (when watched) one VWE image per
// window.
#pragma once

#include <nav_msgs/Odometry.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Imu.h>
#include <tf2_ros/static_transform_broadcaster.h>

#include <cstdint>
#include <deque>
#include <memory>
#include <string>
#include <thread>

#include "vwe_vo/EventArray.h"
#include "vwe_vo/SplineTrajectory.h"
#include "vwe_vo/backend/backend_driver.h"
#include "vwe_vo/common/math.h"
#include "vwe_vo/frontend/backlog_policy.h"
#include "vwe_vo/frontend/frontend.h"
#include "vwe_vo/ros/node_input.h"
#include "vwe_vo/sensor/camera.h"
#include "vwe_vo/trajectory/bspline.h"
#include "vwe_vo/vwe/vwe_image.h"

namespace vwe_vo {

/// The front-end's coarsest thinning when it falls behind: its windows vote down to 1/4 of
/// max_events_per_volume before whole windows may be skipped (~max_latency_s, BacklogPolicy).
/// Each halving is taken only while the windows do not work the backlog off. Coarser windows
/// lose turns' ends (indoor_long at rate 2 with 1/16: no window skipped, but /vwe/odom RMSE 0.6-2.2
/// deg/s); the CPU priority of the other nodes keeps the front-end in pace instead.
constexpr size_t kMaxVolumeThinning = 4;

/// Everything the node reads from the parameter server, once, at start-up.
struct FrontendNodeOptions {
  std::string config_path;         // ~config: pipeline YAML (front-end options, T_base_cam); empty:
                                   // vwe_vo.yaml in defaultConfigDir()
  std::string calibration_path;    // ~calibration: CameraInfo-style YAML; empty: /dvs/camera_info
  double nominal_speed_mps = -1;   // ~nominal_speed: overrides the config when >= 0 [m/s]
  bool use_odom = false;           // ~use_odom: speed (and standstill) from /odom
  bool use_imu = false;            // ~use_imu: gyro yaw-rate prior from /dvs/imu
  bool publish_static_tf = true;   // ~publish_static_tf: static tf base_link -> davis (T_base_cam)
  int max_queue_events = 5000000;  // ~max_queue_events: bound of the queued event packets [events]
  int max_queue_messages = 2000;   // ~max_queue_messages: bound of each other input (IMU, odometry,
                                   // trajectories) [messages]
  double max_latency_s = 1.0;      // ~max_latency_s: backlog beyond this drops whole windows [s]
  double status_period_s = 10.0;   // ~status_period_s: period of the one-line status [s]
  int threads = 0;                 // ~threads: voting threads (0: the config's volume.num_threads)
  bool follow_backend = true;      // ~follow_backend: re-anchor on /vwe/trajectory, use its speed
  void validate() const;           // throws std::invalid_argument naming the parameter
};

class FrontendNode {
 public:
  /// Reads the parameters and the configuration (throws std::exception on unusable ones),
  /// subscribes, advertises and starts the worker.
  FrontendNode(const ros::NodeHandle& nh, const ros::NodeHandle& pnh);
  /// Stops and joins the worker.
  ~FrontendNode();
  FrontendNode(const FrontendNode&) = delete;
  FrontendNode& operator=(const FrontendNode&) = delete;

 private:
  /// One queued input, converted to core types by a callback.
  struct Input {
    enum class Kind { kEvents, kOdometry, kGyro, kTrajectory } kind = Kind::kEvents;
    EventVector events;
    std::string reset_why;  // the input's timestamp policy resets before these events
    int64_t t_ns = 0;
    double v = 0.0, yaw_rate = 0.0;
    std::shared_ptr<const BSpline> spline;  // kTrajectory
  };

  void readParameters();
  void eventsCallback(const EventArray::ConstPtr& msg);
  void cameraInfoCallback(const sensor_msgs::CameraInfo::ConstPtr& msg);
  void odomCallback(const nav_msgs::Odometry::ConstPtr& msg);
  void imuCallback(const sensor_msgs::Imu::ConstPtr& msg);
  void trajectoryCallback(const SplineTrajectory::ConstPtr& msg);

  void workerLoop();
  void handleEvents(const EventVector& events, const std::string& reset_why);
  /// Re-anchors the published dead reckoning on the refined spline's end and takes its speed
  /// (FrontendFollower).
  void handleTrajectory(const BSpline& spline);
  Pose3 anchoredPose(int64_t t_ns) const { return follower_.anchoredPose(*frontend_, t_ns); }
  void publishArc(const ArcEstimate& arc);
  void publishImage(const ArcEstimate& arc);
  void logStatus();

  ros::NodeHandle nh_, pnh_;
  ros::Subscriber events_sub_, camera_info_sub_, odom_sub_, imu_sub_, trajectory_sub_;
  ros::Publisher arcs_pub_, odom_pub_, iwe_pub_;
  std::unique_ptr<tf2_ros::StaticTransformBroadcaster> static_tf_;

  FrontendNodeOptions node_options_;
  FrontendOptions frontend_options_;
  Pose3 T_base_cam_ = Pose3::Identity();

  NodeInput<Input> input_{"frontend_node"};  // callbacks -> worker, open once calibrated

  // Owned by the worker thread.
  std::unique_ptr<CameraModel> camera_;
  std::unique_ptr<Frontend> frontend_;
  std::unique_ptr<VweImageRenderer> renderer_;
  EventVector recent_events_;     // events kept for the VWE image (only while it is watched)
  int64_t newest_event_ns_ = -1;  // for the size of a backwards jump
  BacklogPolicy backlog_;         // thinning and skipping when behind (worker)
  FrontendFollower follower_;     // the anchor on the back-end's odom and the speed it gives
  size_t windows_ok_ = 0, windows_standstill_ = 0, windows_lost_ = 0, windows_low_ = 0;
  size_t reported_out_of_order_ = 0;
  double busy_wall_s_ = 0.0,
         processed_data_s_ = 0.0;  // worker time vs data time (real-time factor)
  ros::WallTime last_status_;
  size_t last_status_events_ = 0;

  std::thread worker_;
};

}  // namespace vwe_vo
