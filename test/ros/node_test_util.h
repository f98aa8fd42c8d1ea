// Shared by the node rostests: wait until a node has logged a line (collected from /rosout by the
// harness) containing some text at a level or above, or until a counter of its input's status line
// has grown; a camera_info of another size. Header-only.
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
inline bool waitForLog(std::mutex& mutex, const std::vector<rosgraph_msgs::Log>& logs,
                       const std::string& text, uint8_t level, double timeout_s) {
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

/// The value of `key` in the `kind` part of the newest status line with the node's input counters
/// ("... input: events in=120 lost=0 empty=3 ...; odom in=60 ...; camera_info refused=0", the
/// format of NodeInput::statusLine); -1 while there is none. The caller holds the mutex guarding
/// `logs`.
inline long inputCounter(const std::vector<rosgraph_msgs::Log>& logs, const std::string& kind,
                         const std::string& key) {
  for (auto l = logs.rbegin(); l != logs.rend(); ++l) {
    const size_t input = l->msg.find("input: ");
    if (input == std::string::npos) continue;
    const std::string line = "; " + l->msg.substr(input + 7);
    const size_t part = line.find("; " + kind + " ");
    if (part == std::string::npos) return -1;
    const size_t end = line.find("; ", part + 2);
    const std::string fields =
        line.substr(part, end == std::string::npos ? std::string::npos : end - part) + " ";
    const size_t at = fields.find(" " + key + "=");
    if (at == std::string::npos) return -1;
    return std::stol(fields.substr(at + key.size() + 2));
  }
  return -1;
}

/// True if inputCounter(kind, key) exceeds `above` within timeout_s of wall time.
inline bool waitForInputCounterAbove(std::mutex& mutex, const std::vector<rosgraph_msgs::Log>& logs,
                                     const std::string& kind, const std::string& key, long above,
                                     double timeout_s) {
  const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(timeout_s);
  do {
    {
      std::lock_guard<std::mutex> lock(mutex);
      if (inputCounter(logs, kind, key) > above) return true;
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
