#include "vwe_vo/io/options_yaml.h"

#include <yaml-cpp/yaml.h>

#include <cstdlib>
#include <filesystem>
#include <map>
#include <set>
#include <stdexcept>
#include <string>

#include "vwe_vo/io/config.h"
#include "vwe_vo/io/files.h"

#ifndef VWE_VO_CONFIG_DIR
#define VWE_VO_CONFIG_DIR ""
#endif

namespace vwe_vo {
namespace {

/// Reads the keys of one YAML map (the section `path`, e.g. "backend.volume") into typed fields
/// and reports the keys it did not use.
class Reader {
 public:
  Reader(const YAML::Node& parent, const std::string& key, const std::string& path,
         std::vector<std::string>* warnings)
      : path_(path), warnings_(warnings) {
    // Const access only: yaml-cpp's non-const operator[] inserts missing keys.
    const YAML::Node& p = parent;
    present_ = p && p.IsMap() && p[key] && !p[key].IsNull();
    if (present_) node_ = p[key];
    if (present_ && !node_.IsMap())
      throw std::invalid_argument("section '" + path_ + "' must be a map");
  }
  template <typename T>
  void operator()(const char* key, T* value) {
    used_.insert(key);
    const YAML::Node& n = node_;
    if (!present_ || !n[key]) return;
    try {
      *value = n[key].as<T>();
    } catch (const YAML::Exception& e) {
      throw std::invalid_argument(path_ + "." + key + ": cannot read value (" + e.what() + ")");
    }
  }
  void operator()(const char* key, Contrast* value) {
    std::string name = contrastName(*value);
    (*this)(key, &name);
    if (name == contrastName(Contrast::kVariance))
      *value = Contrast::kVariance;
    else if (name == contrastName(Contrast::kDensityPerVote))
      *value = Contrast::kDensityPerVote;
    else
      throw std::invalid_argument(path_ + "." + key + ": '" + name +
                                  "' is neither variance nor density_per_vote");
  }
  Reader section(const char* key) {
    used_.insert(key);
    return Reader(node_, key, path_ + "." + key, warnings_);
  }
  /// Reports the keys of the section that no field read.
  void done() const {
    if (!present_ || !warnings_) return;
    for (const auto& kv : node_) {
      const std::string k = kv.first.as<std::string>();
      if (!used_.count(k)) warnings_->push_back("unknown key '" + path_ + "." + k + "' ignored");
    }
  }

 private:
  std::string path_;
  std::vector<std::string>* warnings_;
  YAML::Node node_;
  std::set<std::string> used_;
  bool present_ = false;
};

/// Writes fields under their keys into a YAML map.
class Writer {
 public:
  explicit Writer(YAML::Node node) : node_(node) {}
  template <typename T>
  void operator()(const char* key, T* value) {
    node_[key] = *value;
  }
  void operator()(const char* key, Contrast* value) { node_[key] = contrastName(*value); }
  Writer section(const char* key) {
    node_[key] = YAML::Node(YAML::NodeType::Map);
    return Writer(node_[key]);
  }
  void done() const {}

 private:
  YAML::Node node_;
};

// The keys of every options struct, once for the loader (Reader) and the emitter (Writer).

/// `vwe`: the VWE's volume (front-end, back-end); the EMVS DSI has no contrast.
template <typename Archive>
void fields(Archive& a, VolumeOptions* o, bool vwe) {
  a("grid_scale", &o->grid_scale);
  if (vwe) a("contrast", &o->contrast);
  a("margin_px", &o->margin_px);
  a("num_planes", &o->num_planes);
  a("z_min_m", &o->z_min_m);
  a("z_max_m", &o->z_max_m);
  a("num_threads", &o->num_threads);
  a("pose_slice_s", &o->pose_slice_s);
}

template <typename Archive>
void nestedVolume(Archive& a, VolumeOptions* o, bool vwe) {
  Archive v = a.section("volume");
  fields(v, o, vwe);
  v.done();
}

template <typename Archive>
void fields(Archive& a, GroundYawOptions* o) {
  a("weight", &o->weight);
  a("min_depth_m", &o->objective.min_depth_m);
  a("max_depth_m", &o->objective.max_depth_m);
  a("grid_scale", &o->objective.grid_scale);
  a("max_events", &o->max_events);
  a("min_events", &o->min_events);
  a("half_range_rad_s", &o->half_range_rad_s);
  a("step_rad_s", &o->step_rad_s);
  a("pitch_half_range_deg", &o->pitch_half_range_deg);
  a("pitch_step_deg", &o->pitch_step_deg);
  a("pitch_rate_half_range_deg_s", &o->pitch_rate_half_range_deg_s);
  a("pitch_rate_step_deg_s", &o->pitch_rate_step_deg_s);
  a("pitch_rounds", &o->pitch_rounds);
}

template <typename Archive>
void fields(Archive& a, FrontendOptions* o) {
  nestedVolume(a, &o->volume, true);
  {
    Archive g = a.section("ground");
    fields(g, &o->ground);
    g.done();
  }
  a("window_by_count", &o->window_by_count);
  a("window_duration_s", &o->window_duration_s);
  a("window_stride_s", &o->window_stride_s);
  a("window_events", &o->window_events);
  a("max_events_per_volume", &o->max_events_per_volume);
  a("subsample_time_slices", &o->subsample_time_slices);
  a("nominal_speed_mps", &o->nominal_speed_mps);
  a("omega_max_rad_s", &o->omega_max_rad_s);
  a("scan_half_range_rad_s", &o->scan_half_range_rad_s);
  a("scan_step_rad_s", &o->scan_step_rad_s);
  a("full_scan_step_rad_s", &o->full_scan_step_rad_s);
  a("full_scan_candidates", &o->full_scan_candidates);
  a("full_scan_max_events", &o->full_scan_max_events);
  a("refine_tolerance_rad_s", &o->refine_tolerance_rad_s);
  a("standstill_event_rate_hz", &o->standstill_event_rate_hz);
  a("standstill_speed_mps", &o->standstill_speed_mps);
  a("min_events", &o->min_events);
  a("min_confidence", &o->min_confidence);
  a("rescan_confidence", &o->rescan_confidence);
  a("one_sided_balance", &o->one_sided.balance);
  a("one_sided_z_min_m", &o->one_sided.z_min_m);
  a("one_sided_min_depth_m", &o->one_sided.min_depth_m);
  a("split_omega_change_rad_s", &o->split_omega_change_rad_s);
  a("slow_rate_fraction", &o->slow_rate_fraction);
  a("restart_speed_scan", &o->restart_speed_scan);
  a("use_gyro_prior", &o->use_gyro_prior);
  a("gyro_prior_half_range_rad_s", &o->gyro_prior_half_range_rad_s);
  a("ground_mask", &o->ground_mask);
  a("parallax_mask_slope", &o->parallax_mask_slope);
  a("roll_rate_step_rad_s", &o->roll_rate_step_rad_s);
  a("per_camera_min_depth", &o->per_camera_min_depth);
  a("seed", &o->seed);
}

template <typename Archive>
void fields(Archive& a, BackendOptions* o) {
  nestedVolume(a, &o->volume, true);
  a("degree", &o->degree);
  a("knot_spacing_s", &o->knot_spacing_s);
  a("tau1_s", &o->tau1_s);
  a("tau2_s", &o->tau2_s);
  a("window_s", &o->window_s);
  a("update_interval_s", &o->update_interval_s);
  a("max_events_per_volume", &o->max_events_per_volume);
  a("min_events_per_volume", &o->min_events_per_volume);
  a("max_iterations", &o->max_iterations);
  a("function_tolerance", &o->function_tolerance);
  a("max_line_search_steps", &o->max_line_search_steps);
  a("step_scale_per_span", &o->step_scale_per_span);
  a("init_sample_interval_s", &o->init_sample_interval_s);
  a("smoothness_weight", &o->smoothness_weight);
  a("interpolate_arc_rates", &o->interpolate_arc_rates);
  a("speed_prior_weight", &o->speed_prior_weight);
  a("deformation_weight", &o->deformation_weight);
  a("arc_rate_prior_weight", &o->arc_rate_prior_weight);
  a("arc_rate_prior_scale_deg_s", &o->arc_rate_prior_scale_deg_s);
  a("yaw_scan_half_range_rad_s", &o->yaw_scan_half_range_rad_s);
  a("yaw_scan_step_rad_s", &o->yaw_scan_step_rad_s);
  a("outlier_arc_min_rad_s", &o->outlier_arc_min_rad_s);
  a("parallax_mask_slope", &o->parallax_mask_slope);
  a("stop_ramp_max_s", &o->stop_ramp_max_s);
  a("start_ramps", &o->start_ramps);
  a("nominal_min_tangent_speed_mps", &o->nominal_min_tangent_speed_mps);
  a("pitch_per_g_deg", &o->pitch_per_g_deg);
  a("roll_per_g_deg", &o->roll_per_g_deg);
  a("output_rate_hz", &o->output_rate_hz);
  a("seed", &o->seed);
}

template <typename Archive>
void fields(Archive& a, TimestampPolicyOptions* o) {
  a("max_backward_jump_s", &o->max_backward_jump_s);
  a("max_gap_s", &o->max_gap_s);
  a("warn_interval_s", &o->warn_interval_s);
}

template <typename Archive>
void fields(Archive& a, GlobalMapOptions* o) {
  a("voxel_size_m", &o->voxel_size_m);
  a("max_points", &o->max_points);
}

template <typename Archive>
void fields(Archive& a, EmvsOptions* o, GlobalMapOptions* global_map) {
  nestedVolume(a, &o->volume, false);
  Archive g = a.section("global_map");
  fields(g, global_map);
  g.done();
  a("adaptive_kernel_size", &o->adaptive_kernel_size);
  a("adaptive_sigma_px", &o->adaptive_sigma_px);
  a("adaptive_c", &o->adaptive_c);
  a("min_confidence", &o->min_confidence);
  a("nms_radius_px", &o->nms_radius_px);
  a("nms_planes", &o->nms_planes);
  a("min_ray_contrast", &o->min_ray_contrast);
  a("per_camera_min_depth", &o->per_camera_min_depth);
  a("local_max_ratio", &o->local_max_ratio);
  a("local_max_window_px", &o->local_max_window_px);
  a("median_filter_size", &o->median_filter_size);
  a("subpixel", &o->subpixel);
  a("max_depth_m", &o->max_depth_m);
  a("outlier_radius_m", &o->outlier_radius_m);
  a("outlier_min_neighbours", &o->outlier_min_neighbours);
  a("kf_distance_m", &o->kf_distance_m);
  a("kf_rotation_deg", &o->kf_rotation_deg);
  a("max_events_per_keyframe", &o->max_events_per_keyframe);
  a("max_pending_events", &o->max_pending_events);
  a("max_event_rate_hz", &o->max_event_rate_hz);
  a("rate_limit_whole_keyframes", &o->rate_limit_whole_keyframes);
}

template <typename Archive>
void fields(Archive& a, ImuFusionOptions* o) {
  Archive m = a.section("T_cam_imu");
  m("translation", &o->T_cam_imu_translation);
  m("quaternion_xyzw", &o->T_cam_imu_quaternion_xyzw);
  m.done();
  a("gyro_noise_density_deg_s", &o->gyro_noise_density_deg_s);
  a("gyro_model_sigma_deg_s", &o->gyro_model_sigma_deg_s);
  a("gyro_prior_weight", &o->gyro_prior_weight);
  a("gyro_bin_s", &o->gyro_bin_s);
  a("bias_time_constant_s", &o->bias_time_constant_s);
  a("bias_sigma_deg_s", &o->bias_sigma_deg_s);
  a("bias_sigma_min_deg_s", &o->bias_sigma_min_deg_s);
  a("bias_max_jump_deg_s", &o->bias_max_jump_deg_s);
  a("bias_huber_k", &o->bias_huber_k);
  a("bias_window_sigma_deg_s", &o->bias_window_sigma_deg_s);
  a("attitude_time_constant_s", &o->attitude_time_constant_s);
  a("attitude_bias_time_constant_s", &o->attitude_bias_time_constant_s);
  a("max_accel_error_mps2", &o->max_accel_error_mps2);
  a("gravity_mps2", &o->gravity_mps2);
}

/// nominal_speed_mps is no key: the baseline drives at frontend.nominal_speed_mps.
template <typename Archive>
void fields(Archive& a, FrameBaselineOptions* o) {
  a("max_features", &o->max_features);
  a("quality_level", &o->quality_level);
  a("min_distance_px", &o->min_distance_px);
  a("klt_window_px", &o->klt_window_px);
  a("klt_levels", &o->klt_levels);
  a("max_fb_error_px", &o->max_fb_error_px);
  a("border_px", &o->border_px);
  a("min_tracks", &o->min_tracks);
  a("min_inliers", &o->min_inliers);
  a("min_inlier_fraction", &o->min_inlier_fraction);
  a("inlier_threshold_px", &o->inlier_threshold_px);
  a("max_hypotheses", &o->max_hypotheses);
  a("omega_max_rad_s", &o->omega_max_rad_s);
  a("standstill_speed_mps", &o->standstill_speed_mps);
  a("odom_max_age_s", &o->odom_max_age_s);
  a("min_contrast_dn", &o->min_contrast_dn);
  a("max_saturated_fraction", &o->max_saturated_fraction);
  a("min_median_flow_px", &o->min_median_flow_px);
  a("max_frame_gap_s", &o->max_frame_gap_s);
  a("seed", &o->seed);
}

template <typename Options>
void load(const YAML::Node& node, const std::string& section, Options* o,
          std::vector<std::string>* warnings) {
  Reader r(node, section, section, warnings);
  fields(r, o);
  r.done();
  o->validate(section);
}

template <typename Options>
void emit(YAML::Node* root, const char* section, Options o) {
  Writer w = Writer(*root).section(section);
  fields(w, &o);
}

/// The folder of a file path ("." for a bare name).
std::string folderOf(const std::string& path) {
  const size_t slash = path.find_last_of('/');
  return slash == std::string::npos ? std::string(".") : path.substr(0, slash);
}

/// over laid on base: maps merge key by key (recursively), anything else in over replaces base.
YAML::Node overlaid(const YAML::Node& base, const YAML::Node& over) {
  if (!base.IsMap() || !over.IsMap()) return YAML::Clone(over);
  YAML::Node out = YAML::Clone(base);
  for (const auto& kv : over) {
    const std::string key = kv.first.as<std::string>();
    out[key] = base[key] ? overlaid(base[key], kv.second) : YAML::Clone(kv.second);
  }
  return out;
}

/// The file that set each key of a configuration tree, by its path (section.key, section.sub.key).
using KeyOrigins = std::map<std::string, std::string>;

void recordOrigins(const YAML::Node& node, const std::string& prefix, const std::string& file,
                   KeyOrigins* origins) {
  if (!node.IsMap()) return;
  for (const auto& kv : node) {
    const std::string key = (prefix.empty() ? "" : prefix + ".") + kv.first.as<std::string>();
    (*origins)[key] = file;
    recordOrigins(kv.second, key, file, origins);
  }
}

/// The file a message about a key is about: the message's first key path (its quoted key, or its
/// first word), or the nearest section of it that a file set; else `fallback`.
std::string originOf(const std::string& message, const KeyOrigins& origins,
                     const std::string& fallback) {
  std::string key;
  const size_t quote = message.find('\'');
  if (quote != std::string::npos && message.rfind("unknown ", 0) == 0) {
    const size_t end = message.find('\'', quote + 1);
    key = message.substr(quote + 1, end == std::string::npos ? std::string::npos : end - quote - 1);
  } else {
    key = message.substr(0, message.find_first_of(": "));
  }
  for (;;) {
    const auto it = origins.find(key);
    if (it != origins.end()) return it->second;
    const size_t dot = key.rfind('.');
    if (dot == std::string::npos) return fallback;
    key.resize(dot);
  }
}

/// A configuration file over the file it names as `include` (relative to its own folder; that
/// file may include another): its keys replace the included file's, section by section. Each
/// file's relative camera_calibration is resolved against that file's folder. origins receives
/// the file each key comes from.
YAML::Node loadConfigTree(const std::string& path, int depth, KeyOrigins* origins) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::Exception& e) {
    throw std::runtime_error(path + ": cannot read configuration: " + e.what());
  }
  if (!root.IsMap()) return root;
  if (root["camera_calibration"]) {
    const std::string calib = root["camera_calibration"].as<std::string>();
    if (!calib.empty() && calib[0] != '/')
      root["camera_calibration"] = folderOf(path) + "/" + calib;
  }
  if (!root["include"]) {
    recordOrigins(root, "", path, origins);
    return root;
  }
  if (depth >= 8) throw std::runtime_error(path + ": includes nest deeper than 8 files (a cycle?)");
  if (!root["include"].IsScalar() || root["include"].Scalar().empty())
    throw std::runtime_error(path + ": include must name a file");
  std::string included = root["include"].Scalar();
  if (included[0] != '/') included = folderOf(path) + "/" + included;
  std::error_code ec;
  if (!std::filesystem::is_regular_file(included, ec))
    throw std::runtime_error(path + ": include '" + included + "' is not a readable file");
  root.remove("include");
  const YAML::Node base = loadConfigTree(included, depth + 1, origins);
  recordOrigins(root, "", path, origins);
  return overlaid(base, root);
}

}  // namespace

void loadOptions(const YAML::Node& node, const std::string& section, FrontendOptions* o,
                 std::vector<std::string>* warnings) {
  load(node, section, o, warnings);
}

void loadOptions(const YAML::Node& node, const std::string& section, BackendOptions* o,
                 std::vector<std::string>* warnings) {
  load(node, section, o, warnings);
}

void loadOptions(const YAML::Node& node, const std::string& section, TimestampPolicyOptions* o,
                 std::vector<std::string>* warnings) {
  load(node, section, o, warnings);
}

void loadOptions(const YAML::Node& node, const std::string& section, EmvsOptions* o,
                 GlobalMapOptions* global_map, std::vector<std::string>* warnings) {
  Reader r(node, section, section, warnings);
  fields(r, o, global_map);
  r.done();
  o->validate(section);
  global_map->validate(section + ".global_map");
}

void loadOptions(const YAML::Node& node, const std::string& section, ImuFusionOptions* o,
                 std::vector<std::string>* warnings) {
  load(node, section, o, warnings);
}

void loadOptions(const YAML::Node& node, const std::string& section, FrameBaselineOptions* o,
                 std::vector<std::string>* warnings) {
  load(node, section, o, warnings);
}

YAML::Node optionsToYaml(const PipelineConfig& cfg) {
  YAML::Node root(YAML::NodeType::Map);
  const Quat q(cfg.T_base_cam.linear());
  YAML::Node mount(YAML::NodeType::Map);
  const Vec3 t = cfg.T_base_cam.translation();
  mount["translation"] = std::vector<double>{t.x(), t.y(), t.z()};
  mount["quaternion_xyzw"] = std::vector<double>{q.x(), q.y(), q.z(), q.w()};
  mount["translation"].SetStyle(YAML::EmitterStyle::Flow);
  mount["quaternion_xyzw"].SetStyle(YAML::EmitterStyle::Flow);
  root["T_base_cam"] = mount;
  emit(&root, "input", cfg.input);
  emit(&root, "frontend", cfg.frontend);
  emit(&root, "backend", cfg.backend);
  EmvsOptions mapping = cfg.mapping;
  GlobalMapOptions global_map = cfg.global_map;
  Writer m = Writer(root).section("mapping");
  fields(m, &mapping, &global_map);
  emit(&root, "baseline", cfg.baseline);
  emit(&root, "imu", cfg.imu);
  return root;
}

PipelineConfig loadPipelineConfig(const std::string& path,
                                  const std::string& default_calibration_path) {
  PipelineConfig cfg;
  cfg.path = path;
  cfg.T_base_cam = defaultTBaseCam();
  std::string calib = default_calibration_path.empty() ? defaultConfigDir() + "/davis346.yaml"
                                                       : default_calibration_path;
  if (!path.empty()) {
    KeyOrigins origins;
    const YAML::Node root = loadConfigTree(path, 0, &origins);
    // Messages about a key name the file that set it (an included one, or this one).
    auto located = [&](const std::string& message) {
      return originOf(message, origins, path) + ": " + message;
    };
    static const std::set<std::string> known = {
        "camera_calibration", "T_base_cam", "input", "frontend", "backend",
        "baseline",           "mapping",    "imu"};
    for (const auto& kv : root)
      if (!known.count(kv.first.as<std::string>()))
        cfg.warnings.push_back(
            located("unknown top-level key '" + kv.first.as<std::string>() + "' ignored"));
    if (root["camera_calibration"]) calib = root["camera_calibration"].as<std::string>();
    cfg.T_base_cam = loadTBaseCam(root, path, &cfg.warnings);
    std::vector<std::string> warnings;
    try {
      loadOptions(root, "input", &cfg.input, &warnings);
      loadOptions(root, "frontend", &cfg.frontend, &warnings);
      loadOptions(root, "backend", &cfg.backend, &warnings);
      loadOptions(root, "mapping", &cfg.mapping, &cfg.global_map, &warnings);
      loadOptions(root, "baseline", &cfg.baseline, &warnings);
      loadOptions(root, "imu", &cfg.imu, &warnings);
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument(located(e.what()));
    }
    for (const std::string& w : warnings) cfg.warnings.push_back(located(w));
  }
  // One timestamp rule: the stages' own guards (a second line behind the input's policy) agree with
  // it.
  cfg.frontend.max_backwards_jump_s = cfg.input.max_backward_jump_s;
  cfg.backend.max_backwards_jump_s = cfg.input.max_backward_jump_s;
  // The road's pitch and roll centre on the dive and lean of the back-end's tilt model.
  cfg.frontend.ground.pitch_per_g_rad = cfg.backend.pitch_per_g_deg * kRadPerDeg;
  cfg.frontend.ground.roll_per_g_rad = cfg.backend.roll_per_g_deg * kRadPerDeg;
  // The baseline drives at the front-end's speed so that both share one scale source.
  cfg.baseline.nominal_speed_mps = cfg.frontend.nominal_speed_mps;
  cfg.camera = loadCameraCalibrationYaml(calib);
  return cfg;
}

}  // namespace vwe_vo
