#!/usr/bin/python3
"""Turns ground-truth poses (/gt/pose, geometry_msgs/PoseStamped, as in vwe_vo_sim bags) into a
nav_msgs/Path (/gt/path) for rviz. Poses are decimated (~min_spacing_m, default 0.02 m) and the
path is bounded (~max_poses, default 20000; the oldest are dropped). Time going back (a looped
bag) restarts the path."""
import math

import rospy
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Path


class GtPath:
    def __init__(self):
        self.min_spacing_m = float(rospy.get_param("~min_spacing_m", 0.02))
        self.max_poses = int(rospy.get_param("~max_poses", 20000))
        self.path = Path()
        self.pub = rospy.Publisher("/gt/path", Path, queue_size=1, latch=True)
        self.sub = rospy.Subscriber("/gt/pose", PoseStamped, self.on_pose, queue_size=100)
        self.last_publish = rospy.Time(0)

    def on_pose(self, msg):
        poses = self.path.poses
        if poses and msg.header.stamp < poses[-1].header.stamp:
            rospy.logwarn("gt_path: /gt/pose time went back (a looped bag?): path restarted")
            del poses[:]
        if poses:
            a, b = poses[-1].pose.position, msg.pose.position
            if math.hypot(a.x - b.x, a.y - b.y) < self.min_spacing_m:
                return
        poses.append(msg)
        if len(poses) > self.max_poses:
            del poses[: len(poses) - self.max_poses]
        self.path.header.frame_id = msg.header.frame_id or "odom"
        self.path.header.stamp = msg.header.stamp
        now = rospy.Time.now()
        if now < self.last_publish or (now - self.last_publish).to_sec() >= 0.2:
            self.pub.publish(self.path)
            self.last_publish = now


if __name__ == "__main__":
    rospy.init_node("gt_path")
    GtPath()
    rospy.spin()
