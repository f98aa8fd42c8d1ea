#include <gtest/gtest.h>

#include <fstream>

#include "vwe_vo/io/config.h"

using namespace vwe_vo;

TEST(Config, ShippedConfigGivesForwardFacingMount) {
  const Pose3 T = loadTBaseCam(std::string(VWE_VO_SOURCE_DIR) + "/config/vwe_vo.yaml");
  EXPECT_TRUE(T.linear().col(2).isApprox(Vec3::UnitX()));  // optical axis forward
  EXPECT_NEAR(T.translation().z(), 0.30, 1e-12);
  EXPECT_TRUE(T.isApprox(defaultTBaseCam()));
}

TEST(Config, PositivePitchLooksDown) {
  const Pose3 T = mountToTBaseCam(Vec3(0, 0, 0.3), 0.0, 10.0 / kDegPerRad, 0.0);
  EXPECT_LT(T.linear().col(2).z(), -0.17);  // optical axis has a downward component
}

TEST(Config, MalformedExtrinsicsNameFileAndKey) {
  const std::string path = ::testing::TempDir() + "bad_extrinsics.yaml";
  std::ofstream(path) << "T_base_cam:\n  translation: [0.1, 0.0]\n";
  try {
    loadTBaseCam(path);
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("bad_extrinsics.yaml"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("translation"), std::string::npos);
  }
}

TEST(Config, UnknownOrConflictingMountKeysAreRefusedNamingTheKey) {
  const std::string path = ::testing::TempDir() + "typo_extrinsics.yaml";
  std::ofstream(path) << "T_base_cam:\n  translation: [0.1, 0.0, 0.3]\n  rpy: [0.0, 10.0, 0.0]\n";
  try {
    loadTBaseCam(path);
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("T_base_cam.rpy"), std::string::npos) << e.what();
  }
  std::vector<std::string> warnings;
  EXPECT_TRUE(loadTBaseCam(path, &warnings).isApprox(defaultTBaseCam()));
  ASSERT_EQ(warnings.size(), 1u);
  EXPECT_NE(warnings[0].find("T_base_cam.rpy"), std::string::npos) << warnings[0];

  const std::string both = ::testing::TempDir() + "both_extrinsics.yaml";
  std::ofstream(both) << "T_base_cam:\n  translation: [0.1, 0.0, 0.3]\n  rpy_deg: [0, 0, 0]\n"
                         "  quaternion_xyzw: [0, 0, 0, 1]\n";
  EXPECT_THROW(loadTBaseCam(both), std::runtime_error);
}
