// The one module that translates between ROS messages and core types (time, events, camera
// calibration, poses). Nothing else converts messages.
//
// Name clash: the generated message type vwe_vo::Event (dvs_msgs-identical, the name is part of
// the wire contract) collides with the core's vwe_vo::Event. Through this header the message is
// called vwe_vo::EventMsg; include this header instead of "vwe_vo/Event.h"/"vwe_vo/EventArray.h".
#pragma once

#include <cstdint>
#include <string>

#include <geometry_msgs/Pose.h>
#include <geometry_msgs/PoseStamped.h>
#include <geometry_msgs/Transform.h>
#include <ros/time.h>
#include <sensor_msgs/CameraInfo.h>
#include <std_msgs/Header.h>

#define Event EventMsg
#include "vwe_vo/Event.h"
#include "vwe_vo/EventArray.h"
#undef Event

#include "vwe_vo/core/camera.h"
#include "vwe_vo/core/events.h"
#include "vwe_vo/core/math.h"

namespace vwe_vo {

/// int64 nanoseconds <-> ros::Time, exact (never through float seconds). Negative times throw.
ros::Time toRosTime(int64_t t_ns);
int64_t fromRosTime(const ros::Time& t);

/// Events [begin, end) of `events` as one EventArray; header.stamp = time of the last event
/// (or of `stamp_ns` if >= 0), event times offset by `epoch_ns`.
EventArray toEventArrayMsg(const EventVector& events, size_t begin, size_t end, int width, int height,
                           const std::string& frame_id, int64_t epoch_ns = 0, int64_t stamp_ns = -1);
/// Appends the events of a message (times minus epoch_ns). Events outside width x height of the
/// message are not appended; their number is returned (0 if all were inside).
size_t appendEventArrayMsg(const EventArray& msg, EventVector* out, int64_t epoch_ns = 0);

sensor_msgs::CameraInfo toCameraInfoMsg(const CameraCalibration& calib, const std::string& frame_id);
/// Throws std::invalid_argument if the distortion model is not plumb_bob (or empty) or the
/// calibration is invalid.
CameraCalibration fromCameraInfoMsg(const sensor_msgs::CameraInfo& msg);

geometry_msgs::Pose toPoseMsg(const Pose3& T);
Pose3 fromPoseMsg(const geometry_msgs::Pose& msg);
geometry_msgs::Transform toTransformMsg(const Pose3& T);
geometry_msgs::Point toPointMsg(const Vec3& p);
geometry_msgs::Vector3 toVector3Msg(const Vec3& v);
geometry_msgs::Quaternion toQuaternionMsg(const Quat& q);

}  // namespace vwe_vo
