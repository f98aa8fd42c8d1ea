// Fills the core options structs from the package's YAML configuration (config/vwe_vo.yaml),
// and writes them back under the same keys. Keys absent from the file keep the struct's
// defaults; unknown keys are reported so that a typo is not silently ignored; every struct is
// validated after loading, and errors name the full key (e.g. backend.volume.z_min_m).
#pragma once

#include <string>
#include <vector>

#include "vwe_vo/backend/backend.h"
#include "vwe_vo/baseline/frame_baseline.h"
#include "vwe_vo/common/math.h"
#include "vwe_vo/frontend/frontend.h"
#include "vwe_vo/mapping/emvs.h"
#include "vwe_vo/sensor/camera.h"
#include "vwe_vo/sensor/imu.h"
#include "vwe_vo/sensor/timestamp_policy.h"

namespace YAML {
class Node;
}

namespace vwe_vo {

/// Each reads the map node[section]; warnings get "unknown key '<section>.<key>' ignored".
void loadOptions(const YAML::Node& node, const std::string& section, FrontendOptions* options,
                 std::vector<std::string>* warnings);
void loadOptions(const YAML::Node& node, const std::string& section, BackendOptions* options,
                 std::vector<std::string>* warnings);
/// The input: section (the timestamp policy, sensor/timestamp_policy.h).
void loadOptions(const YAML::Node& node, const std::string& section,
                 TimestampPolicyOptions* options, std::vector<std::string>* warnings);
/// The mapping: section (EmvsOptions with nested volume: and global_map:).
void loadOptions(const YAML::Node& node, const std::string& section, EmvsOptions* options,
                 GlobalMapOptions* global_map, std::vector<std::string>* warnings);
/// The imu: section (T_cam_imu and the IMU fusion, sensor/imu.h).
void loadOptions(const YAML::Node& node, const std::string& section, ImuFusionOptions* options,
                 std::vector<std::string>* warnings);
/// nominal_speed_mps is not read: the baseline uses frontend.nominal_speed_mps.
void loadOptions(const YAML::Node& node, const std::string& section, FrameBaselineOptions* options,
                 std::vector<std::string>* warnings);

/// Everything a pipeline run needs from one configuration file.
struct PipelineConfig {
  std::string path;          // the file read (empty: defaults)
  CameraCalibration camera;  // from `camera_calibration` (relative to the file's folder)
  Pose3 T_base_cam = Pose3::Identity();
  TimestampPolicyOptions input;  // backward jumps and gaps of the event stamps; also sets
                                 // frontend/backend.max_backwards_jump_s (one key)
  FrontendOptions frontend;
  BackendOptions backend;
  EmvsOptions mapping;
  GlobalMapOptions global_map;
  FrameBaselineOptions
      baseline;  // the frame-based baseline (vwe_vo_offline --baseline, frame_baseline_node)
  ImuFusionOptions imu;        // T_cam_imu and the IMU fusion (vwe_vo_offline --use-imu, use_imu)
  bool frontend_only = false;  // skip the back-end (set by the caller, not the file)
  bool backend_thread = true;  // OfflinePipeline: the back-end on its own thread, fed in order
                               // (as backend_node beside frontend_node; same results)
  std::vector<std::string> warnings;  // unknown keys and the like
};

/// Reads a configuration file (throws std::runtime_error / std::invalid_argument naming the
/// file and key on malformed values). An empty path gives the shipped defaults, with the
/// calibration from default_calibration_path. A file may name another as `include: FILE`
/// (relative to its folder): it is read first, and this file's keys replace its, section by
/// section (config/car_rigid.yaml is config/car.yaml without the suspension's tilt).
PipelineConfig loadPipelineConfig(const std::string& path,
                                  const std::string& default_calibration_path = "");

/// Every option of cfg under its key, as loadPipelineConfig reads them: T_base_cam (translation
/// and quaternion_xyzw), frontend, backend, mapping (with global_map), baseline and imu. The values
/// in use, for logging; loading it again gives the same options.
YAML::Node optionsToYaml(const PipelineConfig& cfg);

}  // namespace vwe_vo
