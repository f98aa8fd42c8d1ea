// Default topic and frame names of every vwe_vo node, in one place. Topics are meant to be
// remapped (launch files, `rosrun ... /dvs/events:=/cam0/events`); frames follow REP-105.
#pragma once

namespace vwe_vo {
namespace topics {

constexpr const char* kEvents = "/dvs/events";           // vwe_vo/EventArray (dvs_msgs-identical)
constexpr const char* kCameraInfo = "/dvs/camera_info";  // sensor_msgs/CameraInfo
constexpr const char* kOdom = "/odom";                   // nav_msgs/Odometry (wheel odometry)
constexpr const char* kImu = "/dvs/imu";                 // sensor_msgs/Imu (camera frame)
constexpr const char* kArcs = "/vwe/arcs";               // vwe_vo/AckermannArc per window
constexpr const char* kFrontendOdom = "/vwe/frontend/odom";  // nav_msgs/Odometry, dead-reckoned
constexpr const char* kFrontendIwe = "/vwe/frontend/iwe";    // sensor_msgs/Image, sharpened events
constexpr const char* kTrajectory = "/vwe/trajectory";       // vwe_vo/SplineTrajectory (back-end)
constexpr const char* kImageRaw = "/dvs/image_raw";  // sensor_msgs/Image, APS frames (mono8)
constexpr const char* kBaselineOdom = "/vwe/baseline/odom";  // nav_msgs/Odometry, frame baseline
constexpr const char* kBaselineTracks = "/vwe/baseline/tracks";  // sensor_msgs/Image, KLT tracks
constexpr const char* kBackendOdom = "/vwe/odom";                // nav_msgs/Odometry on the spline
constexpr const char* kPath = "/vwe/path";  // nav_msgs/Path, the refined spline
constexpr const char* kMapPoints =
    "/vwe/map/points";                               // sensor_msgs/PointCloud2 per keyframe (odom)
constexpr const char* kMapCloud = "/vwe/map/cloud";  // sensor_msgs/PointCloud2 global map (odom)
constexpr const char* kMapDepth = "/vwe/map/depth";  // sensor_msgs/Image bgr8 keyframe depth

}  // namespace topics

namespace frames {

constexpr const char* kOdom = "odom";
constexpr const char* kBase = "base_link";
constexpr const char* kCamera = "davis";

}  // namespace frames
}  // namespace vwe_vo
