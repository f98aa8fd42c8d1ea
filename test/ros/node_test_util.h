// Shared by the node rostests: wait until a node has logged a line (collected from /rosout by the
// harness) containing some text at a level or above; a camera_info of another size. Header-only.
#pragma once

#include <ros/ros.h>
#include <rosgraph_msgs/Log.h>
#include <sensor_msgs/CameraInfo.h>

#include <mutex>
#include <string>
#include <vector>

namespace vwe_vo {
namespace test {

/// True if `logs` (guarded by `mutex`) gets a line containing `text` at `level` or above within
/// timeout_s of wall time.
inline bool waitForLog(std::mutex& mutex, const std::vector<rosgraph_msgs::Log>& logs, const std::string& text,
                       uint8_t level, double timeout_s) {
  const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(timeout_s);
  do {
    {
      std::lock_guard<std::mutex> lock(mutex);
      for (const rosgraph_msgs::Log& l : logs)
        if (l.level >= level && l.msg.find(text) != std::string::npos) return true;
    }
    ros::WallDuration(0.05).sleep();
  } while (ros::WallTime::now() < end);
  return false;
}

/// `info` resized to 240x180 (principal point moved with it): what a node must refuse once it
/// calibrated at another size ("camera_info is 240x180 but the calibration in use is WxH").
inline sensor_msgs::CameraInfo cameraInfoOfAnotherSize(sensor_msgs::CameraInfo info) {
  info.width = 240;
  info.height = 180;
  info.K[2] = 120;
  info.K[5] = 90;
  return info;
}

}  // namespace test
}  // namespace vwe_vo
