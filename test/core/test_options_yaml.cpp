// Every YAML file shipped in config/ loads, and the loader reports what it cannot use.
#include <dirent.h>
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <fstream>

#include "vwe_vo/io/options_yaml.h"
#include "vwe_vo/sim/sequences.h"

using namespace vwe_vo;

namespace {
std::string writeTemp(const std::string& name, const std::string& text) {
  const std::string path = ::testing::TempDir() + name;
  std::ofstream(path) << text;
  return path;
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
  try {
    loadPipelineConfig(writeTemp(
        "cfg_bad.yaml", "camera_calibration: " + cal + "\nfrontend:\n  window_duration_s: -1\n"));
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("window_duration_s"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("cfg_bad.yaml"), std::string::npos) << e.what();
  }
}

TEST(OptionsYaml, VolumeContrastIsReadAndUnknownMeasuresRefused) {
  const std::string cal = std::string(VWE_VO_SOURCE_DIR) + "/config/davis346.yaml";
  const PipelineConfig cfg = loadPipelineConfig(writeTemp(
      "cfg_contrast.yaml", "camera_calibration: " + cal + "\nbackend:\n  volume: {contrast: variance}\n"));
  EXPECT_EQ(cfg.backend.volume.contrast, Contrast::kVariance);
  EXPECT_EQ(cfg.frontend.volume.contrast, Contrast::kDensityPerVote);  // the default
  try {
    loadPipelineConfig(writeTemp("cfg_contrast_bad.yaml",
                                 "camera_calibration: " + cal + "\nfrontend:\n  volume: {contrast: varaince}\n"));
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("volume.contrast: 'varaince'"), std::string::npos) << e.what();
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
    EXPECT_NE(std::string(e.what()).find("nms_radius_px"), std::string::npos) << e.what();
  }
}
