// Every YAML file shipped in config/ loads, config/vwe_vo.yaml holds every key with the structs'
// defaults, and the loader reports what it cannot use and names bad values by their full key.
#include <dirent.h>
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <fstream>
#include <set>

#include "vwe_vo/io/options_yaml.h"
#include "vwe_vo/sim/sequences.h"

using namespace vwe_vo;

namespace {
std::string writeTemp(const std::string& name, const std::string& text) {
  const std::string path = ::testing::TempDir() + name;
  std::ofstream(path) << text;
  return path;
}

bool isNumber(const YAML::Node& n, double* x) {
  try {
    *x = n.as<double>();
    return true;
  } catch (const YAML::Exception&) {
    return false;
  }
}

/// Expects the maps `expected` (the emitted defaults) and `file` to hold the same keys, and the
/// same values: numbers within a relative 1e-12, anything else as equal text.
void expectSameKeysAndValues(const YAML::Node& expected, const YAML::Node& file,
                             const std::string& path) {
  ASSERT_TRUE(expected.IsMap()) << path;
  ASSERT_TRUE(file.IsMap()) << path << " must be a map in the file";
  std::set<std::string> file_keys;
  for (const auto& kv : file) file_keys.insert(kv.first.as<std::string>());
  for (const auto& kv : expected) {
    const std::string key = kv.first.as<std::string>();
    const std::string full = path.empty() ? key : path + "." + key;
    if (!file_keys.erase(key)) {
      ADD_FAILURE() << "vwe_vo.yaml lacks the key " << full;
      continue;
    }
    const YAML::Node e = kv.second;
    const YAML::Node v = file[key];
    if (e.IsMap()) {
      expectSameKeysAndValues(e, v, full);
      continue;
    }
    if (e.IsSequence()) {  // e.g. imu.T_cam_imu.translation
      ASSERT_TRUE(v.IsSequence()) << full;
      ASSERT_EQ(e.size(), v.size()) << full;
      for (size_t i = 0; i < e.size(); ++i)
        EXPECT_NEAR(e[i].as<double>(), v[i].as<double>(), 1e-12) << full << "[" << i << "]";
      continue;
    }
    ASSERT_TRUE(e.IsScalar() && v.IsScalar()) << full;
    double a = 0, b = 0;
    if (isNumber(e, &a) && isNumber(v, &b))
      EXPECT_LE(std::abs(a - b), 1e-12 * std::max(std::abs(a), std::abs(b)))
          << full << ": struct default " << e.as<std::string>() << ", vwe_vo.yaml "
          << v.as<std::string>();
    else
      EXPECT_EQ(e.as<std::string>(), v.as<std::string>()) << full;
  }
  for (const std::string& key : file_keys)
    ADD_FAILURE() << "vwe_vo.yaml has the key " << (path.empty() ? key : path + "." + key)
                  << " that the loader does not know";
}
}  // namespace

TEST(OptionsYaml, EveryShippedConfigLoads) {
  const std::string dir = std::string(VWE_VO_SOURCE_DIR) + "/config";
  DIR* d = opendir(dir.c_str());
  ASSERT_NE(d, nullptr);
  int pipeline_configs = 0;
  while (dirent* e = readdir(d)) {
    const std::string name = e->d_name;
    if (name.size() < 5 || name.substr(name.size() - 5) != ".yaml") continue;
    const std::string path = dir + "/" + name;
    const YAML::Node root = YAML::LoadFile(path);
    if (root["image_width"]) {
      EXPECT_NO_THROW(loadCameraCalibrationYaml(path)) << path;
    } else {
      PipelineConfig cfg;
      ASSERT_NO_THROW(cfg = loadPipelineConfig(path)) << path;
      EXPECT_TRUE(cfg.warnings.empty())
          << path << ": " << (cfg.warnings.empty() ? "" : cfg.warnings[0]);
      ++pipeline_configs;
    }
  }
  closedir(d);
  EXPECT_GE(pipeline_configs, 2);
}

// config/vwe_vo.yaml is the structs' defaults, written out: every key the loader knows, no other,
// and the same values (the emitter writes what the loader reads, key by key).
TEST(OptionsYaml, ShippedDefaultsFileHoldsEveryKeyWithTheStructDefaults) {
  const std::string path = std::string(VWE_VO_SOURCE_DIR) + "/config/vwe_vo.yaml";
  PipelineConfig defaults;
  defaults.T_base_cam = defaultTBaseCam();
  YAML::Node expected = optionsToYaml(defaults);
  YAML::Node file = YAML::Clone(YAML::LoadFile(path));
  // The file gives the mount as rpy_deg, the emitter as a quaternion: compare the poses; the
  // calibration is the default one.
  const PipelineConfig loaded = loadPipelineConfig(path);
  EXPECT_TRUE(loaded.T_base_cam.isApprox(defaultTBaseCam(), 1e-12));
  EXPECT_EQ(file["camera_calibration"].as<std::string>(), "davis346.yaml");
  ASSERT_TRUE(expected.remove("T_base_cam"));
  ASSERT_TRUE(file.remove("T_base_cam"));
  ASSERT_TRUE(file.remove("camera_calibration"));
  expectSameKeysAndValues(expected, file, "");
  // And through the loader: the options it reads from the file are the defaults exactly.
  PipelineConfig from_file = loaded;
  from_file.T_base_cam = defaults.T_base_cam;
  EXPECT_EQ(YAML::Dump(optionsToYaml(from_file)), YAML::Dump(optionsToYaml(defaults)));
}

// What optionsToYaml writes loads again, with no warnings, to the same options.
TEST(OptionsYaml, EmittedOptionsLoadBackUnchanged) {
  const std::string dir = std::string(VWE_VO_SOURCE_DIR) + "/config/";
  const PipelineConfig car = loadPipelineConfig(dir + "car.yaml");
  YAML::Node emitted = optionsToYaml(car);
  emitted["camera_calibration"] = dir + "davis346.yaml";
  const PipelineConfig again =
      loadPipelineConfig(writeTemp("cfg_emitted.yaml", YAML::Dump(emitted)));
  EXPECT_TRUE(again.warnings.empty()) << again.warnings[0];
  EXPECT_TRUE(again.T_base_cam.isApprox(car.T_base_cam, 1e-12));
  // The rest exactly (the quaternion goes through a rotation matrix: its last digit may move).
  YAML::Node a = optionsToYaml(again), b = optionsToYaml(car);
  a.remove("T_base_cam");
  b.remove("T_base_cam");
  EXPECT_EQ(YAML::Dump(a), YAML::Dump(b));
  EXPECT_EQ(again.backend.volume.z_min_m, 6.0);  // the car's, not the default
}

// The shipped configurations carry the mounts the simulator records with: the turtlebot one
// for the indoor sequences, the car one for the street (a mismatch costs ~10 deg/s).
TEST(OptionsYaml, ShippedMountsMatchTheSimulatedSequences) {
  const std::string dir = std::string(VWE_VO_SOURCE_DIR) + "/config/";
  const PipelineConfig bot = loadPipelineConfig(dir + "vwe_vo.yaml");
  const PipelineConfig car = loadPipelineConfig(dir + "car.yaml");
  EXPECT_TRUE(bot.T_base_cam.isApprox(sim::findSequence("indoor_long").T_base_cam, 1e-9));
  EXPECT_TRUE(car.T_base_cam.isApprox(sim::findSequence("street_long").T_base_cam, 1e-9));
  EXPECT_FALSE(car.T_base_cam.isApprox(bot.T_base_cam, 1e-3));
  EXPECT_GT(car.frontend.nominal_speed_mps, 10 * bot.frontend.nominal_speed_mps);
}

TEST(OptionsYaml, ValuesOverrideDefaultsAndNestedSectionsWork) {
  const std::string cal = std::string(VWE_VO_SOURCE_DIR) + "/config/davis346.yaml";
  const std::string p = writeTemp("cfg_ok.yaml", "camera_calibration: " + cal +
                                                     "\nfrontend:\n  max_events_per_volume: 30000\n"
                                                     "  volume: {num_planes: 44}\n");
  const PipelineConfig cfg = loadPipelineConfig(p);
  EXPECT_EQ(cfg.frontend.max_events_per_volume, 30000u);
  EXPECT_EQ(cfg.frontend.volume.num_planes, 44);
  EXPECT_EQ(cfg.frontend.window_duration_s, FrontendOptions().window_duration_s);
  EXPECT_TRUE(cfg.warnings.empty());
}

TEST(OptionsYaml, UnknownKeysAreReportedAndBadValuesRefused) {
  const std::string cal = std::string(VWE_VO_SOURCE_DIR) + "/config/davis346.yaml";
  const PipelineConfig cfg = loadPipelineConfig(writeTemp(
      "cfg_typo.yaml", "camera_calibration: " + cal + "\nfrontend:\n  windw_duration_s: 0.5\n"));
  ASSERT_EQ(cfg.warnings.size(), 1u);
  EXPECT_NE(cfg.warnings[0].find("frontend.windw_duration_s"), std::string::npos);
  EXPECT_NE(cfg.warnings[0].find("cfg_typo.yaml"), std::string::npos);
  try {
    loadPipelineConfig(writeTemp(
        "cfg_bad.yaml", "camera_calibration: " + cal + "\nfrontend:\n  window_duration_s: -1\n"));
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("frontend.window_duration_s"), std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find("cfg_bad.yaml"), std::string::npos) << e.what();
  }
}

// A bad value in one of the three volume sections is named by its full key.
TEST(OptionsYaml, NestedErrorsNameTheFullKey) {
  const std::string cal = std::string(VWE_VO_SOURCE_DIR) + "/config/davis346.yaml";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"backend:\n  volume: {z_min_m: -1}\n", "backend.volume.z_min_m"},
      {"frontend:\n  volume: {num_planes: 1}\n", "frontend.volume.num_planes"},
      {"mapping:\n  volume: {z_max_m: 0.1}\n", "mapping.volume.z_max_m"},
      {"mapping:\n  volume: {z_max_m: -10}\n",
       "mapping.volume.z_max_m"},  // no depth map past infinity
      {"backend:\n  volume: {z_max_m: 0}\n", "backend.volume.z_max_m"},
      {"mapping:\n  global_map: {voxel_size_m: 0}\n", "mapping.global_map.voxel_size_m"},
      {"frontend:\n  one_sided_balance: 2\n", "frontend.one_sided_balance"},
      {"frontend:\n  roll_rate_step_rad_s: 1\n", "frontend.roll_rate_step_rad_s"},
      {"baseline:\n  klt_window_px: 4\n", "baseline.klt_window_px"},
      {"backend:\n  volume: {margin_px: x}\n", "backend.volume.margin_px"},
  };
  for (const auto& c : cases) {
    try {
      loadPipelineConfig(
          writeTemp("cfg_nested_bad.yaml", "camera_calibration: " + cal + "\n" + c.first));
      ADD_FAILURE() << c.first << " was accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(c.second), std::string::npos) << e.what();
    }
  }
  // The same names when a struct is validated outside the loader.
  BackendOptions b;
  b.volume.z_min_m = -1;
  try {
    b.validate();
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("backend.volume.z_min_m"), std::string::npos) << e.what();
  }
}

// Unknown keys are reported in every section, the mount and the DSI's volume included (the DSI
// has no contrast), and every FrameBaselineOptions field is read.
TEST(OptionsYaml, UnknownKeysAreReportedEverywhere) {
  const std::string cal = std::string(VWE_VO_SOURCE_DIR) + "/config/davis346.yaml";
  const PipelineConfig cfg = loadPipelineConfig(
      writeTemp("cfg_unknown.yaml",
                "camera_calibration: " + cal +
                    "\nT_base_cam:\n  translation: [0.1, 0.0, 0.3]\n  rpy: [0.0, 10.0, 0.0]\n"
                    "mapping:\n  volume: {contrast: variance}\nsimulator: {seed: 3}\n"
                    "baseline: {seed: 7}\n"));
  ASSERT_EQ(cfg.warnings.size(), 3u);
  EXPECT_NE(cfg.warnings[0].find("'simulator'"), std::string::npos) << cfg.warnings[0];
  EXPECT_NE(cfg.warnings[1].find("T_base_cam.rpy"), std::string::npos) << cfg.warnings[1];
  EXPECT_NE(cfg.warnings[2].find("mapping.volume.contrast"), std::string::npos) << cfg.warnings[2];
  EXPECT_EQ(cfg.baseline.seed, 7u);
}

// One key for the timestamp rule: input.max_backward_jump_s sets the policy and the stages' guards;
// the shipped files and the struct defaults agree.
TEST(OptionsYaml, InputSectionIsTheOneTimestampRule) {
  const std::string dir = std::string(VWE_VO_SOURCE_DIR) + "/config/";
  for (const char* name : {"vwe_vo.yaml", "car.yaml"}) {
    const PipelineConfig shipped = loadPipelineConfig(dir + name);
    EXPECT_EQ(shipped.input.max_backward_jump_s, TimestampPolicyOptions().max_backward_jump_s)
        << name;
    EXPECT_EQ(shipped.input.max_gap_s, TimestampPolicyOptions().max_gap_s) << name;
    EXPECT_EQ(YAML::LoadFile(dir + name)["input"]["max_backward_jump_s"].as<double>(),
              shipped.input.max_backward_jump_s)
        << name;
  }
  EXPECT_EQ(FrontendOptions().max_backwards_jump_s, TimestampPolicyOptions().max_backward_jump_s);
  EXPECT_EQ(BackendOptions().max_backwards_jump_s, TimestampPolicyOptions().max_backward_jump_s);
  const std::string cal = dir + "davis346.yaml";
  const PipelineConfig cfg = loadPipelineConfig(writeTemp(
      "cfg_input.yaml",
      "camera_calibration: " + cal + "\ninput:\n  max_backward_jump_s: 0.25\n  max_gap_s: 3\n"));
  EXPECT_TRUE(cfg.warnings.empty());
  EXPECT_EQ(cfg.input.max_backward_jump_s, 0.25);
  EXPECT_EQ(cfg.input.max_gap_s, 3.0);
  EXPECT_EQ(cfg.frontend.max_backwards_jump_s, 0.25);
  EXPECT_EQ(cfg.backend.max_backwards_jump_s, 0.25);
  // The stages' keys are gone: a leftover one is reported, not silently used.
  const PipelineConfig old = loadPipelineConfig(
      writeTemp("cfg_old_jump.yaml",
                "camera_calibration: " + cal + "\nfrontend:\n  max_backwards_jump_s: 0.1\n"));
  ASSERT_EQ(old.warnings.size(), 1u);
  EXPECT_NE(old.warnings[0].find("frontend.max_backwards_jump_s"), std::string::npos);
  EXPECT_EQ(old.frontend.max_backwards_jump_s, 0.5);
  try {
    loadPipelineConfig(
        writeTemp("cfg_bad_input.yaml",
                  "camera_calibration: " + cal + "\ninput:\n  max_backward_jump_s: -1\n"));
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("max_backward_jump_s"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("cfg_bad_input.yaml"), std::string::npos) << e.what();
  }
}

TEST(OptionsYaml, VolumeContrastIsReadAndUnknownMeasuresRefused) {
  const std::string cal = std::string(VWE_VO_SOURCE_DIR) + "/config/davis346.yaml";
  const PipelineConfig cfg = loadPipelineConfig(
      writeTemp("cfg_contrast.yaml",
                "camera_calibration: " + cal + "\nbackend:\n  volume: {contrast: variance}\n"));
  EXPECT_EQ(cfg.backend.volume.contrast, Contrast::kVariance);
  EXPECT_EQ(cfg.frontend.volume.contrast, Contrast::kDensityPerVote);  // the default
  try {
    loadPipelineConfig(
        writeTemp("cfg_contrast_bad.yaml",
                  "camera_calibration: " + cal + "\nfrontend:\n  volume: {contrast: varaince}\n"));
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("frontend.volume.contrast: 'varaince'"), std::string::npos)
        << e.what();
  }
}

TEST(OptionsYaml, MappingSection) {
  const std::string cal = std::string(VWE_VO_SOURCE_DIR) + "/config/davis346.yaml";
  const PipelineConfig cfg = loadPipelineConfig(writeTemp(
      "cfg_map.yaml",
      "camera_calibration: " + cal +
          "\nmapping:\n  kf_distance_m: 0.5\n  nms_radius_px: 2\n  volume: {num_planes: 64}\n"
          "  global_map: {voxel_size_m: 0.1}\n  median_filtr_size: 3\n"));
  EXPECT_EQ(cfg.mapping.kf_distance_m, 0.5);
  EXPECT_EQ(cfg.mapping.nms_radius_px, 2);
  EXPECT_EQ(cfg.mapping.volume.num_planes, 64);
  EXPECT_EQ(cfg.mapping.volume.z_max_m,
            EmvsOptions().volume.z_max_m);  // EMVS defaults, not the VWE's
  EXPECT_EQ(cfg.global_map.voxel_size_m, 0.1);
  EXPECT_EQ(cfg.mapping.median_filter_size, EmvsOptions().median_filter_size);
  ASSERT_EQ(cfg.warnings.size(), 1u);
  EXPECT_NE(cfg.warnings[0].find("mapping.median_filtr_size"), std::string::npos);
  try {
    loadPipelineConfig(writeTemp(
        "cfg_map_bad.yaml", "camera_calibration: " + cal + "\nmapping:\n  nms_radius_px: -1\n"));
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("mapping.nms_radius_px"), std::string::npos) << e.what();
  }
}
