#include "vwe_vo/io/options_yaml.h"
#include "vwe_vo/io/files.h"

#include <yaml-cpp/yaml.h>

#include <cstdlib>
#include <set>
#include <stdexcept>
#include <string>

#include "vwe_vo/io/config.h"

#ifndef VWE_VO_CONFIG_DIR
#define VWE_VO_CONFIG_DIR ""
#endif

namespace vwe_vo {
namespace {

/// Reads keys of one YAML map into typed fields and remembers which keys were used.
class Section {
 public:
  Section(const YAML::Node& parent, const std::string& name) : name_(name) {
    // Const access only: yaml-cpp's non-const operator[] inserts missing keys.
    const YAML::Node& p = parent;
    present_ = p && p.IsMap() && p[name] && !p[name].IsNull();
    if (present_) node_ = p[name];
    if (present_ && !node_.IsMap())
      throw std::invalid_argument("section '" + name + "' must be a map");
  }
  template <typename T>
  void get(const char* key, T* value) {
    used_.insert(key);
    const YAML::Node& n = node_;
    if (!present_ || !n[key]) return;
    try {
      *value = n[key].as<T>();
    } catch (const YAML::Exception& e) {
      throw std::invalid_argument(name_ + "." + key + ": cannot read value (" + e.what() + ")");
    }
  }
  void nested(const char* key) { used_.insert(key); }
  void reportUnknown(std::vector<std::string>* warnings) const {
    if (!present_ || !warnings) return;
    for (const auto& kv : node_) {
      const std::string k = kv.first.as<std::string>();
      if (!used_.count(k)) warnings->push_back("unknown key '" + name_ + "." + k + "' ignored");
    }
  }
  const YAML::Node& node() const { return node_; }
  bool present() const { return present_; }

 private:
  std::string name_;
  YAML::Node node_;
  std::set<std::string> used_;
  bool present_ = false;
};

}  // namespace

void loadOptions(const YAML::Node& node, const std::string& section, VolumeOptions* o,
                 std::vector<std::string>* warnings) {
  Section s(node, section);
  s.get("grid_scale", &o->grid_scale);
  std::string contrast = contrastName(o->contrast);
  s.get("contrast", &contrast);
  if (contrast == contrastName(Contrast::kVariance))
    o->contrast = Contrast::kVariance;
  else if (contrast == contrastName(Contrast::kDensityPerVote))
    o->contrast = Contrast::kDensityPerVote;
  else
    throw std::invalid_argument(section + ".contrast: '" + contrast +
                                "' is neither variance nor density_per_vote");
  s.get("margin_px", &o->margin_px);
  s.get("num_planes", &o->num_planes);
  s.get("z_min_m", &o->z_min_m);
  s.get("z_max_m", &o->z_max_m);
  s.get("num_threads", &o->num_threads);
  s.get("pose_slice_s", &o->pose_slice_s);
  s.reportUnknown(warnings);
  o->validate();
}

void loadOptions(const YAML::Node& node, const std::string& section, FrontendOptions* o,
                 std::vector<std::string>* warnings) {
  Section s(node, section);
  s.nested("volume");
  if (s.present()) loadOptions(s.node(), "volume", &o->volume, warnings);
  s.get("window_by_count", &o->window_by_count);
  s.get("window_duration_s", &o->window_duration_s);
  s.get("window_stride_s", &o->window_stride_s);
  s.get("window_events", &o->window_events);
  s.get("max_events_per_volume", &o->max_events_per_volume);
  s.get("subsample_time_slices", &o->subsample_time_slices);
  s.get("nominal_speed_mps", &o->nominal_speed_mps);
  s.get("omega_max_rad_s", &o->omega_max_rad_s);
  s.get("scan_half_range_rad_s", &o->scan_half_range_rad_s);
  s.get("scan_step_rad_s", &o->scan_step_rad_s);
  s.get("full_scan_step_rad_s", &o->full_scan_step_rad_s);
  s.get("full_scan_candidates", &o->full_scan_candidates);
  s.get("full_scan_max_events", &o->full_scan_max_events);
  s.get("refine_tolerance_rad_s", &o->refine_tolerance_rad_s);
  s.get("standstill_event_rate_hz", &o->standstill_event_rate_hz);
  s.get("standstill_speed_mps", &o->standstill_speed_mps);
  s.get("min_events", &o->min_events);
  s.get("min_confidence", &o->min_confidence);
  s.get("rescan_confidence", &o->rescan_confidence);
  s.get("one_sided_balance", &o->one_sided.balance);
  s.get("one_sided_z_min_m", &o->one_sided.z_min_m);
  s.get("one_sided_min_depth_m", &o->one_sided.min_depth_m);
  s.get("split_omega_change_rad_s", &o->split_omega_change_rad_s);
  s.get("use_gyro_prior", &o->use_gyro_prior);
  s.get("gyro_prior_half_range_rad_s", &o->gyro_prior_half_range_rad_s);
  s.get("max_backwards_jump_s", &o->max_backwards_jump_s);
  s.get("seed", &o->seed);
  s.reportUnknown(warnings);
  o->validate();
}

void loadOptions(const YAML::Node& node, const std::string& section, BackendOptions* o,
                 std::vector<std::string>* warnings) {
  Section s(node, section);
  s.nested("volume");
  if (s.present()) loadOptions(s.node(), "volume", &o->volume, warnings);
  s.get("degree", &o->degree);
  s.get("knot_spacing_s", &o->knot_spacing_s);
  s.get("tau1_s", &o->tau1_s);
  s.get("tau2_s", &o->tau2_s);
  s.get("window_s", &o->window_s);
  s.get("update_interval_s", &o->update_interval_s);
  s.get("max_events_per_volume", &o->max_events_per_volume);
  s.get("min_events_per_volume", &o->min_events_per_volume);
  s.get("max_iterations", &o->max_iterations);
  s.get("function_tolerance", &o->function_tolerance);
  s.get("max_line_search_steps", &o->max_line_search_steps);
  s.get("step_scale_per_span", &o->step_scale_per_span);
  s.get("init_sample_interval_s", &o->init_sample_interval_s);
  s.get("smoothness_weight", &o->smoothness_weight);
  s.get("interpolate_arc_rates", &o->interpolate_arc_rates);
  s.get("speed_prior_weight", &o->speed_prior_weight);
  s.get("deformation_weight", &o->deformation_weight);
  s.get("arc_rate_prior_weight", &o->arc_rate_prior_weight);
  s.get("max_backwards_jump_s", &o->max_backwards_jump_s);
  s.get("output_rate_hz", &o->output_rate_hz);
  s.get("seed", &o->seed);
  s.reportUnknown(warnings);
  o->validate();
}

void loadOptions(const YAML::Node& node, const std::string& section, GlobalMapOptions* o,
                 std::vector<std::string>* warnings) {
  Section s(node, section);
  s.get("voxel_size_m", &o->voxel_size_m);
  s.get("max_points", &o->max_points);
  s.reportUnknown(warnings);
  o->validate();
}

void loadOptions(const YAML::Node& node, const std::string& section, EmvsOptions* o,
                 GlobalMapOptions* global_map, std::vector<std::string>* warnings) {
  Section s(node, section);
  s.nested("volume");
  s.nested("global_map");
  if (s.present()) {
    loadOptions(s.node(), "volume", &o->volume, warnings);
    loadOptions(s.node(), "global_map", global_map, warnings);
  }
  s.get("adaptive_kernel_size", &o->adaptive_kernel_size);
  s.get("adaptive_sigma_px", &o->adaptive_sigma_px);
  s.get("adaptive_c", &o->adaptive_c);
  s.get("min_confidence", &o->min_confidence);
  s.get("nms_radius_px", &o->nms_radius_px);
  s.get("nms_planes", &o->nms_planes);
  s.get("local_max_ratio", &o->local_max_ratio);
  s.get("local_max_window_px", &o->local_max_window_px);
  s.get("median_filter_size", &o->median_filter_size);
  s.get("subpixel", &o->subpixel);
  s.get("max_depth_m", &o->max_depth_m);
  s.get("outlier_radius_m", &o->outlier_radius_m);
  s.get("outlier_min_neighbours", &o->outlier_min_neighbours);
  s.get("kf_distance_m", &o->kf_distance_m);
  s.get("kf_rotation_deg", &o->kf_rotation_deg);
  s.get("max_events_per_keyframe", &o->max_events_per_keyframe);
  s.get("pose_slice_ns", &o->pose_slice_ns);
  s.get("max_pending_events", &o->max_pending_events);
  s.get("max_event_rate_hz", &o->max_event_rate_hz);
  s.reportUnknown(warnings);
  o->validate();
}

void loadOptions(const YAML::Node& node, const std::string& section, FrameBaselineOptions* o,
                 std::vector<std::string>* warnings) {
  Section s(node, section);
  s.get("max_features", &o->max_features);
  s.get("quality_level", &o->quality_level);
  s.get("min_distance_px", &o->min_distance_px);
  s.get("klt_window_px", &o->klt_window_px);
  s.get("klt_levels", &o->klt_levels);
  s.get("max_fb_error_px", &o->max_fb_error_px);
  s.get("border_px", &o->border_px);
  s.get("min_tracks", &o->min_tracks);
  s.get("min_inliers", &o->min_inliers);
  s.get("min_inlier_fraction", &o->min_inlier_fraction);
  s.get("inlier_threshold_px", &o->inlier_threshold_px);
  s.get("max_hypotheses", &o->max_hypotheses);
  s.get("omega_max_rad_s", &o->omega_max_rad_s);
  s.get("standstill_speed_mps", &o->standstill_speed_mps);
  s.get("odom_max_age_s", &o->odom_max_age_s);
  s.get("min_contrast_dn", &o->min_contrast_dn);
  s.get("max_saturated_fraction", &o->max_saturated_fraction);
  s.get("min_median_flow_px", &o->min_median_flow_px);
  s.get("max_frame_gap_s", &o->max_frame_gap_s);
  s.reportUnknown(warnings);
  o->validate();
}

PipelineConfig loadPipelineConfig(const std::string& path,
                                  const std::string& default_calibration_path) {
  PipelineConfig cfg;
  cfg.path = path;
  cfg.T_base_cam = defaultTBaseCam();
  std::string calib = default_calibration_path.empty() ? defaultConfigDir() + "/davis346.yaml"
                                                       : default_calibration_path;
  if (!path.empty()) {
    YAML::Node root;
    try {
      root = YAML::LoadFile(path);
    } catch (const YAML::Exception& e) {
      throw std::runtime_error(path + ": cannot read configuration: " + e.what());
    }
    static const std::set<std::string> known = {"camera_calibration", "T_base_cam", "frontend", "backend",
                                                "baseline", "mapping", "simulator"};
    for (const auto& kv : root)
      if (!known.count(kv.first.as<std::string>()))
        cfg.warnings.push_back(path + ": unknown top-level key '" + kv.first.as<std::string>() +
                               "' ignored");
    if (root["camera_calibration"]) {
      calib = root["camera_calibration"].as<std::string>();
      if (!calib.empty() && calib[0] != '/') {
        const size_t slash = path.find_last_of('/');
        calib =
            (slash == std::string::npos ? std::string(".") : path.substr(0, slash)) + "/" + calib;
      }
    }
    cfg.T_base_cam = loadTBaseCam(path);
    try {
      loadOptions(root, "frontend", &cfg.frontend, &cfg.warnings);
      loadOptions(root, "backend", &cfg.backend, &cfg.warnings);
      loadOptions(root, "mapping", &cfg.mapping, &cfg.global_map, &cfg.warnings);
      loadOptions(root, "baseline", &cfg.baseline, &cfg.warnings);
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument(path + ": " + e.what());
    }
  }
  // The baseline drives at the front-end's speed so that both share one scale source.
  cfg.baseline.nominal_speed_mps = cfg.frontend.nominal_speed_mps;
  cfg.camera = loadCameraCalibrationYaml(calib);
  return cfg;
}

}  // namespace vwe_vo
