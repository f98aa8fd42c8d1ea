#include "vwe_vo/io/config.h"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <stdexcept>
#include <vector>

namespace vwe_vo {

Pose3 mountToTBaseCam(const Vec3& translation, double roll, double pitch, double yaw) {
  const Mat3 R_base_body =
      (Eigen::AngleAxisd(yaw, Vec3::UnitZ()) * Eigen::AngleAxisd(pitch, Vec3::UnitY()) *
       Eigen::AngleAxisd(roll, Vec3::UnitX()))
          .toRotationMatrix();
  return makePose(R_base_body * R_base_opticalFrame(), translation);
}

Pose3 defaultTBaseCam() {
  return mountToTBaseCam(Vec3(0.10, 0.0, 0.30), 0.0, 0.0, 0.0);
}

namespace {
std::vector<double> readVector(const YAML::Node& n, const std::string& key, size_t size,
                               const std::string& path) {
  const YAML::Node v = n[key];
  if (!v || !v.IsSequence() || v.size() != size)
    throw std::runtime_error(path + ": T_base_cam." + key + " must be a list of " +
                             std::to_string(size) + " numbers");
  std::vector<double> out;
  for (const auto& e : v) {
    const double x = e.as<double>();
    if (!std::isfinite(x))
      throw std::runtime_error(path + ": T_base_cam." + key + " has a non-finite value");
    out.push_back(x);
  }
  return out;
}
}  // namespace

Pose3 loadTBaseCam(const std::string& path, std::vector<std::string>* warnings) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::Exception& e) {
    throw std::runtime_error(path + ": cannot read: " + e.what());
  }
  return loadTBaseCam(root, path, warnings);
}

Pose3 loadTBaseCam(const YAML::Node& root, const std::string& path,
                   std::vector<std::string>* warnings) {
  const YAML::Node n = root["T_base_cam"];
  if (!n) return defaultTBaseCam();
  if (!n.IsMap()) throw std::runtime_error(path + ": T_base_cam must be a map");
  for (const auto& kv : n) {
    const std::string key = kv.first.as<std::string>();
    if (key == "translation" || key == "rpy_deg" || key == "quaternion_xyzw") continue;
    const std::string message = "unknown key 'T_base_cam." + key + "' ignored";
    if (!warnings) throw std::runtime_error(path + ": " + message);
    warnings->push_back(path + ": " + message);
  }
  if (n["rpy_deg"] && n["quaternion_xyzw"])
    throw std::runtime_error(path + ": T_base_cam: give rpy_deg or quaternion_xyzw, not both");
  try {
    const auto t = readVector(n, "translation", 3, path);
    if (n["quaternion_xyzw"]) {
      const auto q = readVector(n, "quaternion_xyzw", 4, path);
      const Quat quat(q[3], q[0], q[1], q[2]);
      if (std::abs(quat.norm() - 1.0) > 1e-3)
        throw std::runtime_error(path + ": T_base_cam.quaternion_xyzw is not a unit quaternion");
      return makePose(quat, Vec3(t[0], t[1], t[2]));
    }
    const auto rpy =
        n["rpy_deg"] ? readVector(n, "rpy_deg", 3, path) : std::vector<double>{0, 0, 0};
    return mountToTBaseCam(Vec3(t[0], t[1], t[2]), rpy[0] / kDegPerRad, rpy[1] / kDegPerRad,
                           rpy[2] / kDegPerRad);
  } catch (const YAML::Exception& e) {
    throw std::runtime_error(path + ": malformed T_base_cam: " + e.what());
  }
}

}  // namespace vwe_vo
