// frame_baseline_node: the frame-based baseline as a ROS node (see
// vwe_vo/ros/frame_baseline_node.h).
#include "vwe_vo/ros/frame_baseline_node.h"

#include <ros/ros.h>

int main(int argc, char** argv) {
  ros::init(argc, argv, "frame_baseline_node");
  try {
    vwe_vo::FrameBaselineNode node{ros::NodeHandle(), ros::NodeHandle("~")};
    ros::spin();
  } catch (const std::exception& e) {
    ROS_FATAL("frame_baseline_node: %s", e.what());
    return 1;
  }
  return 0;
}
