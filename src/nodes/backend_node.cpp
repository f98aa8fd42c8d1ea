// backend_node: the sliding-window spline back-end as a ROS node (see vwe_vo/ros/backend_node.h).
#include "vwe_vo/ros/backend_node.h"

#include <ros/ros.h>

int main(int argc, char** argv) {
  ros::init(argc, argv, "backend_node");
  try {
    vwe_vo::BackendNode node{ros::NodeHandle(), ros::NodeHandle("~")};
    ros::spin();
  } catch (const std::exception& e) {
    ROS_FATAL("backend_node: %s", e.what());
    return 1;
  }
  return 0;
}
