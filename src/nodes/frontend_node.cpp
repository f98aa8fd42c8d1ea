// frontend_node: the Ackermann front-end as a ROS node (see vwe_vo/ros/frontend_node.h).
#include "vwe_vo/ros/frontend_node.h"

#include <ros/ros.h>

int main(int argc, char** argv) {
  ros::init(argc, argv, "frontend_node");
  try {
    vwe_vo::FrontendNode node{ros::NodeHandle(), ros::NodeHandle("~")};
    ros::spin();
  } catch (const std::exception& e) {
    ROS_FATAL("frontend_node: %s", e.what());
    return 1;
  }
  return 0;
}
