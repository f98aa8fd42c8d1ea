// backend_node: runs the sliding-window spline back-end on /dvs/events and the front-end's
// /vwe/arcs, live or from a bag. Callbacks only validate, convert and enqueue into a bounded
// queue; one worker thread runs vwe_vo::Backend and publishes the refined spline
// (/vwe/trajectory, /vwe/path) after each refinement and, in data time, /vwe/odom + the tf
// odom -> base_link at ~odom_rate_hz (on the refined spline, beyond it the front-end's arcs
// anchored on its end).
#pragma once

#include <nav_msgs/Odometry.h>
#include <nav_msgs/Path.h>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Imu.h>
#include <tf2_ros/transform_broadcaster.h>

#include <cstdint>
#include <deque>
#include <memory>
#include <string>
#include <thread>

#include "vwe_vo/AckermannArc.h"
#include "vwe_vo/EventArray.h"
#include "vwe_vo/backend/backend.h"
#include "vwe_vo/backend/backend_driver.h"
#include "vwe_vo/common/math.h"
#include "vwe_vo/frontend/frontend.h"
#include "vwe_vo/ros/node_input.h"
#include "vwe_vo/ros/process_priority.h"
#include "vwe_vo/sensor/camera.h"

namespace vwe_vo {

/// Everything the node reads from the parameter server, once, at start-up.
struct BackendNodeOptions {
  std::string config_path;         // ~config: pipeline YAML (back-end options, T_base_cam); empty:
                                   // vwe_vo.yaml in defaultConfigDir()
  std::string calibration_path;    // ~calibration: CameraInfo-style YAML; empty: /dvs/camera_info
  int max_queue_events = 5000000;  // ~max_queue_events: bound of the queued event packets [events]
  int max_queue_messages = 4000;   // ~max_queue_messages: bound of the queued arcs [messages]
  double odom_rate_hz = 20.0;      // ~odom_rate_hz: rate of /vwe/odom and the tf (data time) [Hz]
  int path_max_poses = 2000;       // ~path_max_poses: newest poses kept in /vwe/path
  double status_period_s = 10.0;   // ~status_period_s: period of the one-line status [s]
  bool publish_tf = true;          // ~publish_tf: broadcast odom -> base_link
  int nice = 0;                    // ~nice: CPU priority (0..19; higher yields to the front-end)
  int threads = 0;                 // ~threads: voting threads (0: the config's volume.num_threads)
  bool use_imu = false;   // ~use_imu: fuse /dvs/imu (gyro yaw rate, pitch and roll; config imu:)
  bool use_odom = false;  // ~use_odom: the arcs' speeds are /odom's (frontend_node's ~use_odom);
                          // without, only their scale (Backend::setSpeedsMeasured) and no tilt
  void validate() const;  // throws std::invalid_argument naming the parameter
};

class BackendNode {
 public:
  /// Reads the parameters and the configuration (throws std::exception on unusable ones),
  /// subscribes, advertises and starts the worker. `hosting`: kSharedProcess in a nodelet manager.
  BackendNode(const ros::NodeHandle& nh, const ros::NodeHandle& pnh,
              Hosting hosting = Hosting::kOwnProcess);
  /// Stops and joins the worker.
  ~BackendNode();
  BackendNode(const BackendNode&) = delete;
  BackendNode& operator=(const BackendNode&) = delete;

 private:
  struct Input {
    enum class Kind { kEvents, kArc, kImu } kind = Kind::kEvents;
    EventVector events;
    std::string reset_why;  // the input's timestamp policy resets before these events
    ArcEstimate arc;
    ImuSample imu;
  };

  void readParameters();
  void eventsCallback(const EventArray::ConstPtr& msg);
  void cameraInfoCallback(const sensor_msgs::CameraInfo::ConstPtr& msg);
  void arcCallback(const AckermannArc::ConstPtr& msg);
  void imuCallback(const sensor_msgs::Imu::ConstPtr& msg);

  void workerLoop();
  void handleEvents(const EventVector& events, const std::string& reset_why);
  /// newest_pending_arc_ns: the newest arc of the batch (BackendDriver's processing rule).
  void handleArc(const ArcEstimate& arc, int64_t newest_pending_arc_ns);
  /// Resets the back-end and what was published from it (the odometry restarts at identity).
  void resetBackend(const std::string& why);
  void onReset(const std::string& why);
  void publishRefinement(size_t merged);
  void publishOdometry(int64_t t_ns, const Pose3& T, double v, double omega);
  void logStatus();

  ros::NodeHandle nh_, pnh_;
  const Hosting hosting_;
  ros::Subscriber events_sub_, camera_info_sub_, arcs_sub_, imu_sub_;
  ros::Publisher trajectory_pub_, odom_pub_, path_pub_;
  std::unique_ptr<tf2_ros::TransformBroadcaster> tf_;

  BackendNodeOptions node_options_;
  BackendOptions backend_options_;
  BackendDriverOptions driver_options_;  // ~odom_rate_hz; max_gap_s from the config's input:
  ImuFusionOptions imu_options_;
  Pose3 T_base_cam_ = Pose3::Identity();

  NodeInput<Input> input_{"backend_node"};  // callbacks -> worker, open once calibrated

  // Owned by the worker thread.
  std::unique_ptr<CameraModel> camera_;
  std::unique_ptr<Backend> backend_;
  std::unique_ptr<BackendDriver>
      driver_;  // feeds backend_: gaps, loops, stale arcs, odometry, refinements
  size_t refinements_ = 0;
  size_t reported_out_of_order_ = 0;
  nav_msgs::Path path_;
  double busy_wall_s_ = 0.0;
  ros::WallTime last_status_;

  std::thread worker_;
};

}  // namespace vwe_vo
