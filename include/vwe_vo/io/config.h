// Loading of the package's YAML configuration (config/*.yaml) into core structs.
// The ROS nodes read the same keys from the parameter server; the offline tools read the file.
#pragma once

#include <string>
#include <vector>

#include "vwe_vo/common/math.h"

namespace YAML {
class Node;
}

namespace vwe_vo {

/// The default forward-facing mount: optical axis along base x, camera 0.10 m ahead of the rear
/// axle and 0.30 m above the ground.
Pose3 defaultTBaseCam();

/// Reads `T_base_cam: {translation: [x, y, z], rpy_deg: [roll, pitch, yaw]}` (rotation of the
/// camera *body* frame x-forward/z-up relative to base_link, composed with the optical-frame
/// convention) or `T_base_cam: {translation: [...], quaternion_xyzw: [...]}` (the optical frame
/// directly) from a YAML file. Falls back to defaultTBaseCam() if the key is absent.
/// Throws std::runtime_error naming the file and key on malformed values, when both rpy_deg and
/// quaternion_xyzw are given, and on unknown keys under T_base_cam if warnings is null (else
/// they are added to *warnings as "unknown key 'T_base_cam.<key>' ignored").
Pose3 loadTBaseCam(const std::string& yaml_path, std::vector<std::string>* warnings = nullptr);
/// The same from the file's parsed root; yaml_path only names the file in messages.
Pose3 loadTBaseCam(const YAML::Node& root, const std::string& yaml_path,
                   std::vector<std::string>* warnings = nullptr);

/// T_base_cam from a mount given as translation and roll/pitch/yaw [rad] of the camera body.
Pose3 mountToTBaseCam(const Vec3& translation, double roll, double pitch, double yaw);

}  // namespace vwe_vo
