// mapping_node: EMVS mapping on the back-end's trajectory as a ROS node (see
// vwe_vo/ros/mapping_node.h).
#include "vwe_vo/ros/mapping_node.h"

#include <ros/ros.h>

int main(int argc, char** argv) {
  ros::init(argc, argv, "mapping_node");
  try {
    vwe_vo::MappingNode node{ros::NodeHandle(), ros::NodeHandle("~")};
    ros::spin();
  } catch (const std::exception& e) {
    ROS_FATAL("mapping_node: %s", e.what());
    return 1;
  }
  return 0;
}
