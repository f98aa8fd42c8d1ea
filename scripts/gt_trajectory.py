#!/usr/bin/python3
"""Ground truth in the back-end's place: turns /gt/pose (geometry_msgs/PoseStamped of base_link in
odom, as in vwe_vo_sim bags) into a vwe_vo/SplineTrajectory on /vwe/trajectory (a degree-1
B-spline through the poses of the last ~window_s seconds, default 20 s, at ~rate_hz, default 5 Hz,
with the body's pitch and roll as its tilt samples) and, if ~publish_tf (default true), the tf
odom -> base_link. mapping_node then maps on the true
trajectory: the map without the back-end's errors (replay.launch gt_trajectory:=true; not
together with backend_node, both would publish /vwe/trajectory and the tf)."""
import math

import rospy
import tf2_ros
from geometry_msgs.msg import PoseStamped, TransformStamped
from vwe_vo.msg import SplineTrajectory


class GtTrajectory:
    def __init__(self):
        self.window_s = float(rospy.get_param("~window_s", 20.0))
        rate_hz = float(rospy.get_param("~rate_hz", 5.0))
        self.samples = []  # (stamp, x, y, roll, pitch), strictly increasing stamps
        self.tf = tf2_ros.TransformBroadcaster() if rospy.get_param("~publish_tf", True) else None
        self.pub = rospy.Publisher("/vwe/trajectory", SplineTrajectory, queue_size=2)
        self.sub = rospy.Subscriber("/gt/pose", PoseStamped, self.on_pose, queue_size=200)
        self.timer = rospy.Timer(rospy.Duration(1.0 / rate_hz), self.publish)

    def on_pose(self, msg):
        if self.samples and msg.header.stamp <= self.samples[-1][0]:
            if msg.header.stamp < self.samples[-1][0]:
                rospy.logwarn("gt_trajectory: /gt/pose time went back (a looped bag?): restarted")
                self.samples = []
            else:
                return
        # R = Rz(yaw) Ry(pitch) Rx(roll): the tilt after the planar pose, as the back-end's.
        q = msg.pose.orientation
        roll = math.atan2(2 * (q.w * q.x + q.y * q.z), 1 - 2 * (q.x * q.x + q.y * q.y))
        pitch = math.asin(max(-1.0, min(1.0, 2 * (q.w * q.y - q.z * q.x))))
        self.samples.append((msg.header.stamp, msg.pose.position.x, msg.pose.position.y, roll, pitch))
        if self.tf:
            t = TransformStamped()
            t.header.stamp = msg.header.stamp
            t.header.frame_id = "odom"
            t.child_frame_id = "base_link"
            t.transform.translation.x = msg.pose.position.x
            t.transform.translation.y = msg.pose.position.y
            t.transform.translation.z = msg.pose.position.z
            t.transform.rotation = msg.pose.orientation
            self.tf.sendTransform(t)
        while (self.samples[-1][0] - self.samples[0][0]).to_sec() > self.window_s:
            self.samples.pop(0)

    def publish(self, _event):
        samples = list(self.samples)
        if len(samples) < 2:
            return
        epoch = samples[0][0]
        u = [(s[0] - epoch).to_sec() for s in samples]
        m = SplineTrajectory()
        m.header.stamp = samples[-1][0]
        m.header.frame_id = "odom"
        m.degree = 1
        m.knot_epoch = epoch
        m.knots = [u[0]] + u + [u[-1]]  # clamped, degree 1: interpolates the samples
        m.control_x = [s[1] for s in samples]
        m.control_y = [s[2] for s in samples]
        m.valid_from = samples[0][0]
        m.valid_to = samples[-1][0]
        m.first_free_control_point = len(samples)
        m.tilt_t = u
        m.tilt_roll = [s[3] for s in samples]
        m.tilt_pitch = [s[4] for s in samples]
        self.pub.publish(m)


if __name__ == "__main__":
    rospy.init_node("gt_trajectory")
    GtTrajectory()
    rospy.spin()
