#!/usr/bin/python3
"""Starts davis_ros_driver (rpg_dvs_ros) with this node's name, namespace and parameters when the
package is installed; otherwise logs one warning saying how to get it, and exits.

Used by launch/live.launch so that the launch file works with and without the driver."""
import os
import sys

import rospkg
import rospy

HINT = ("davis_ros_driver is not installed: build rpg_dvs_ros "
        "(https://github.com/uzh-rpg/rpg_dvs_ros, needs libcaer) in a catkin workspace and "
        "source it, or start your driver elsewhere and use live.launch driver:=false; "
        "the vwe_vo nodes wait for /dvs/events and /dvs/camera_info")


def main():
    try:
        rospkg.RosPack().get_path("davis_ros_driver")
    except rospkg.ResourceNotFound:
        rospy.init_node("davis_ros_driver", anonymous=False)
        rospy.logwarn(HINT)
        rospy.sleep(1.0)  # let the warning reach /rosout before the node ends
        return 0
    # roslaunch's __name:=, __ns:= and remappings are passed on, so the driver takes this
    # node's place (and its private parameters, e.g. streaming_rate).
    os.execvp("rosrun", ["rosrun", "davis_ros_driver", "davis_ros_driver"] + sys.argv[1:])
    return 1


if __name__ == "__main__":
    sys.exit(main())
