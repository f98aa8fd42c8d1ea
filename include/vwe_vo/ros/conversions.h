// Every translation between ROS messages and core types, and the one place where time is
// converted (ros::Time <-> int64 nanoseconds). Nodes and tools call these; the core never
// sees a message.
#pragma once

#include <geometry_msgs/Pose.h>
#include <geometry_msgs/Transform.h>
#include <nav_msgs/Odometry.h>
#include <ros/time.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/Imu.h>
#include <sensor_msgs/PointCloud2.h>

#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "vwe_vo/AckermannArc.h"
#include "vwe_vo/EventArray.h"
#include "vwe_vo/SplineTrajectory.h"
#include "vwe_vo/common/math.h"
#include "vwe_vo/frontend/frontend.h"
#include "vwe_vo/mapping/emvs.h"
#include "vwe_vo/sensor/camera.h"
#include "vwe_vo/sensor/events.h"
#include "vwe_vo/sensor/imu.h"
#include "vwe_vo/trajectory/bspline.h"

namespace vwe_vo {

int64_t toNs(const ros::Time& t);
/// Throws std::invalid_argument for negative times (ros::Time cannot hold them).
ros::Time toRosTime(int64_t t_ns);

struct EventConversionStats {
  size_t converted = 0;
  size_t dropped = 0;  // outside the message's width x height
};

/// Replaces *events with the events of msg; events outside msg.width x msg.height are dropped
/// and counted (the caller also checks the size against the calibration).
void eventsFromMsg(const EventArray& msg, EventVector* events,
                   EventConversionStats* stats = nullptr);
/// Fills msg.events from core events (header and size are the caller's).
void eventsToMsg(const EventVector& events, EventArray* msg);
/// A whole EventArray of events[begin, end) with times shifted by epoch_ns; header stamp =
/// stamp_ns + epoch_ns (or the last event's time when stamp_ns < 0).
EventArray eventsToMsg(const EventVector& events, size_t begin, size_t end, int width, int height,
                       const std::string& frame_id, int64_t epoch_ns = 0, int64_t stamp_ns = -1);

/// Calibration from CameraInfo (plumb_bob or an empty D). Throws std::invalid_argument naming
/// the field if it is unusable (zero focal length, wrong distortion model, ...).
CameraCalibration calibrationFromMsg(const sensor_msgs::CameraInfo& msg);
sensor_msgs::CameraInfo calibrationToMsg(const CameraCalibration& calib,
                                         const std::string& frame_id = "");

geometry_msgs::Pose poseToMsg(const Pose3& T);
/// Throws std::invalid_argument for a zero quaternion.
Pose3 poseFromMsg(const geometry_msgs::Pose& msg);
geometry_msgs::Transform transformToMsg(const Pose3& T);
geometry_msgs::Point pointToMsg(const Vec3& p);
geometry_msgs::Vector3 vectorToMsg(const Vec3& v);
geometry_msgs::Quaternion quaternionToMsg(const Quat& q);

/// A mono8 (or 8UC1) image as a cv::Mat (deep copy). Throws std::invalid_argument naming the
/// encoding or the inconsistent sizes.
cv::Mat imageFromMsg(const sensor_msgs::Image& msg);
/// A BGR or mono cv::Mat as bgr8 / mono8.
sensor_msgs::Image imageToMsg(const cv::Mat& image, int64_t t_ns, const std::string& frame_id);

/// The forward speed and yaw rate of an Odometry's twist (in its child frame, base_link).
struct OdometrySample {
  int64_t t_ns = 0;
  double v_mps = 0.0;
  double yaw_rate_rad_s = 0.0;
};
OdometrySample odometryFromMsg(const nav_msgs::Odometry& msg);

/// The yaw rate of base_link from a gyro in the camera frame (the DAVIS IMU):
/// (R_base_cam * angular_velocity).z.
struct GyroSample {
  int64_t t_ns = 0;
  double yaw_rate_rad_s = 0.0;
};
GyroSample gyroFromMsg(const sensor_msgs::Imu& msg, const Pose3& T_base_cam);
/// The whole sample in the IMU's frame (Backend::addImu drops non-finite ones).
ImuSample imuFromMsg(const sensor_msgs::Imu& msg);

AckermannArc arcToMsg(const ArcEstimate& arc, const std::string& frame_id);
ArcEstimate arcFromMsg(const AckermannArc& msg);

/// The spline (knots, control points, standstills; stamp = its validTo()) in frame_id.
SplineTrajectory splineToMsg(const BSpline& spline, int first_free, const std::string& frame_id);
/// Throws std::invalid_argument naming what is inconsistent (sizes, knots, standstills).
BSpline splineFromMsg(const SplineTrajectory& msg);
/// Appends the body's tilt at t_ns to the message's tilt samples (times after the last sample).
void addTiltToMsg(int64_t t_ns, const Tilt& tilt, SplineTrajectory* msg);
/// The message's tilt samples (empty: none). Throws std::invalid_argument naming what is wrong:
/// unequal sizes, non-finite values, times not increasing or more than 1e8 s from the epoch.
TiltHistory tiltFromMsg(const SplineTrajectory& msg);

/// PointCloud2 of x y z float32 + intensity float32 (= MapPoint::confidence), unorganised
/// (height 1), little-endian; non-finite points are left out.
sensor_msgs::PointCloud2 cloudToMsg(const std::vector<MapPoint>& points,
                                    const std::string& frame_id, int64_t stamp_ns);

}  // namespace vwe_vo
