// mapping_node: EMVS mapping on the back-end's trajectory, live or from a bag. Callbacks only
// validate, convert and enqueue (events into a bounded queue; the newest SplineTrajectory replaces
// the previous one); one worker thread runs vwe_vo::EmvsMapper on the events the spline covers and
// publishes a cloud and a colour-coded depth image per keyframe and, throttled, the global map.
#pragma once

#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>

#include <cstdint>
#include <deque>
#include <memory>
#include <string>
#include <thread>

#include "vwe_vo/EventArray.h"
#include "vwe_vo/SplineTrajectory.h"
#include "vwe_vo/common/math.h"
#include "vwe_vo/mapping/emvs.h"
#include "vwe_vo/ros/node_input.h"
#include "vwe_vo/ros/process_priority.h"
#include "vwe_vo/sensor/camera.h"
#include "vwe_vo/sensor/imu.h"
#include "vwe_vo/trajectory/bspline.h"

namespace vwe_vo {

/// Everything the node reads from the parameter server, once, at start-up.
struct MappingNodeOptions {
  std::string config_path;       // ~config: pipeline YAML (its mapping: section, T_base_cam);
                                 // empty: vwe_vo.yaml in defaultConfigDir()
  std::string calibration_path;  // ~calibration: CameraInfo-style YAML; empty: camera_info
  double cloud_period_s = 2.0;   // ~cloud_period_s: minimum period of /vwe/map/cloud [s]
  double trajectory_margin_s =
      0.2;  // ~trajectory_margin_s: map events older than valid_to - this [s]
  double keyframe_timeout_s = 3.0;  // ~keyframe_timeout_s: close the open keyframe after this
                                    // long without events (end of a bag) [wall s]; 0: never
  int max_queue_events = 10000000;  // ~max_queue_events: bound of the queued event packets
                                    // (room for bursts while keyframes close) [events]
  double status_period_s = 10.0;    // ~status_period_s: period of the one-line status [s]
  int nice = 0;                     // ~nice: CPU priority (0..19; higher yields to the others)
  int threads = 0;                  // ~threads: voting threads (0: the config's volume.num_threads)
  void validate() const;            // throws std::invalid_argument naming the parameter
};

class MappingNode {
 public:
  /// Reads the parameters and the configuration (throws std::exception on unusable ones),
  /// subscribes, advertises and starts the worker. `hosting`: kSharedProcess in a nodelet manager.
  MappingNode(const ros::NodeHandle& nh, const ros::NodeHandle& pnh,
              Hosting hosting = Hosting::kOwnProcess);
  /// Stops and joins the worker.
  ~MappingNode();
  MappingNode(const MappingNode&) = delete;
  MappingNode& operator=(const MappingNode&) = delete;

 private:
  /// One queued input, converted to core types by a callback.
  struct Input {
    EventVector events;                       // event packets
    std::string reset_why;                    // the input's timestamp policy resets before these
    std::shared_ptr<const BSpline> spline;    // a trajectory (then events is empty)
    std::shared_ptr<const TiltHistory> tilt;  // its body's tilt (null: planar)
  };

  void readParameters();
  void eventsCallback(const EventArray::ConstPtr& msg);
  void cameraInfoCallback(const sensor_msgs::CameraInfo::ConstPtr& msg);
  void trajectoryCallback(const SplineTrajectory::ConstPtr& msg);

  void workerLoop();
  void handleEvents(const EventVector& events, const std::string& reset_why);
  void mapCovered();
  void handleKeyframe(const EmvsKeyframe& keyframe);
  void publishCloud();
  void logStatus();

  ros::NodeHandle nh_, pnh_;
  const Hosting hosting_;
  ros::Subscriber events_sub_, camera_info_sub_, trajectory_sub_;
  ros::Publisher points_pub_, cloud_pub_, depth_pub_;

  MappingNodeOptions node_options_;
  EmvsOptions emvs_options_;
  GlobalMapOptions global_map_options_;
  Pose3 T_base_cam_ = Pose3::Identity();

  // Callbacks -> worker, open once calibrated; the newest trajectory replaces one not yet taken.
  NodeInput<Input> input_{"mapping_node"};

  // Owned by the worker thread.
  std::unique_ptr<CameraModel> camera_;
  std::unique_ptr<EmvsMapper> mapper_;
  std::unique_ptr<GlobalMap> map_;
  std::shared_ptr<const BSpline> spline_;    // the trajectory in use
  std::shared_ptr<const TiltHistory> tilt_;  // its body's tilt (null: planar)
  int64_t newest_event_ns_ = -1;
  size_t resets_ = 0, keyframes_ = 0, keyframes_empty_ = 0;
  EmvsCounts counts_;  // summed over keyframes
  size_t reported_skipped_time_ = 0, reported_skipped_nan_ = 0, reported_out_of_order_ = 0,
         reported_thinned_pending_ = 0;
  bool map_changed_ = false;
  ros::WallTime last_events_wall_, last_cloud_wall_, last_status_;
  double busy_wall_s_ = 0.0;

  std::thread worker_;
};

}  // namespace vwe_vo
