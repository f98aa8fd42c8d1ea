#include "../common/test_camera.h"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <limits>

#include "vwe_vo/io/config.h"
#include "vwe_vo/sensor/camera.h"
#include "vwe_vo/sensor/ground_mask.h"

using namespace vwe_vo;

namespace {
const std::string kConfig = std::string(VWE_VO_SOURCE_DIR) + "/config/davis346.yaml";

std::string writeTemp(const std::string& name, const std::string& text) {
  const std::string path = ::testing::TempDir() + name;
  std::ofstream(path) << text;
  return path;
}
}  // namespace

TEST(Camera, LoadsShippedDavis346Calibration) {
  const CameraCalibration c = loadCameraCalibrationYaml(kConfig);
  EXPECT_EQ(c.width, 346);
  EXPECT_EQ(c.height, 260);
  EXPECT_GT(c.fx, 100);
  EXPECT_NE(c.distortion[0], 0.0);
}

TEST(Camera, ProjectOfBearingRoundTripsOverWholeSensor) {
  const CameraModel cam(loadCameraCalibrationYaml(kConfig));
  double worst = 0;
  for (int y = 0; y < cam.height(); ++y) {
    for (int x = 0; x < cam.width(); ++x) {
      const Eigen::Vector3f& f = cam.bearing(x, y);
      ASSERT_NEAR(f.norm(), 1.0f, 1e-5f);
      Vec2 uv;
      ASSERT_TRUE(cam.project(3.7 * f.cast<double>(), &uv));
      worst = std::max(worst, (uv - Vec2(x, y)).norm());
    }
  }
  EXPECT_LT(worst, 1e-3) << "worst round-trip error in px";
}

TEST(Camera, SubPixelBearingAgreesWithTable) {
  const CameraModel cam(loadCameraCalibrationYaml(kConfig));
  for (int y : {0, 77, 259})
    for (int x : {0, 150, 345}) {
      const Vec3 b = cam.bearingAt(x, y);
      EXPECT_LT((b - cam.bearing(x, y).cast<double>()).norm(), 1e-5);
    }
}

TEST(Camera, DistortionMovesCornersInward) {
  // Barrel distortion (k1 < 0): a corner ray lands nearer the centre than a pinhole would put it.
  const CameraModel cam(loadCameraCalibrationYaml(kConfig));
  const Vec3 p(0.6, 0.45, 1.0);
  Vec2 uv;
  ASSERT_TRUE(cam.project(p, &uv));
  const auto& c = cam.calibration();
  EXPECT_LT(uv.x(), c.fx * 0.6 + c.cx);
  EXPECT_FALSE(cam.project(Vec3(0.1, 0.1, -1.0), &uv));
}

TEST(Camera, InvalidCalibrationsAreRefusedNamingTheField) {
  CameraCalibration good = loadCameraCalibrationYaml(kConfig);
  auto expectThrowMentioning = [](CameraCalibration c, const std::string& field) {
    try {
      c.validate();
      FAIL() << "accepted a calibration with bad " << field;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
    }
  };
  CameraCalibration c = good;
  c.fx = 0;
  expectThrowMentioning(c, "fx");
  c = good;
  c.fy = std::numeric_limits<double>::quiet_NaN();
  expectThrowMentioning(c, "fy");
  c = good;
  c.width = 0;
  expectThrowMentioning(c, "image size");
  c = good;
  c.distortion[1] = std::numeric_limits<double>::infinity();
  expectThrowMentioning(c, "k2");
  c = good;
  c.cx = 1000;
  expectThrowMentioning(c, "cx");
  EXPECT_THROW(CameraModel{c}, std::invalid_argument);
}

TEST(Camera, MalformedYamlNamesFileAndField) {
  const std::string p1 = writeTemp(
      "cam_missing.yaml", "image_width: 346\ncamera_matrix: {data: [1,0,0,0,1,0,0,0,1]}\n");
  try {
    loadCameraCalibrationYaml(p1);
    FAIL();
  } catch (const std::exception& e) {
    EXPECT_NE(std::string(e.what()).find("cam_missing.yaml"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("image_height"), std::string::npos);
  }
  const std::string p2 = writeTemp(
      "cam_zero.yaml",
      "image_width: 346\nimage_height: 260\ncamera_matrix: {data: [0,0,170,0,250,130,0,0,1]}\n");
  try {
    loadCameraCalibrationYaml(p2);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("fx"), std::string::npos) << e.what();
  }
}

TEST(GroundMask, MasksTheRowsBelowTheNearestPlanesGroundLineOfALevelCamera) {
  // A level pinhole camera h above the floor sees the floor at depth h * fy / (y - cy) in row y.
  const CameraModel cam(test::syntheticCalibration(false));
  const double h = 0.3, z_min = 0.8;
  const GroundMask mask(cam, mountToTBaseCam(Vec3(0.1, 0.0, h), 0, 0, 0), z_min);
  const double boundary = 130.0 + h * 250.0 / z_min;  // row 223.75 (pixel centres at integers)
  size_t expected = 0;
  for (int y = 0; y < cam.height(); ++y) {
    const bool below = y > boundary + 0.01;
    if (std::abs(y - boundary) > 0.01) {
      for (int x : {0, 172, 345}) {
        EXPECT_EQ(mask.keeps({0, uint16_t(x), uint16_t(y), 1}), !below) << y;
      }
    }
    expected += below ? size_t(cam.width()) : 0;
  }
  EXPECT_NEAR(double(mask.maskedPixels()), double(expected), double(cam.width()));
  EXPECT_GT(mask.maskedPixels(), 30u * 346u);
}

TEST(GroundMask, FollowsTheMountAndKeepsEverythingWithoutAGroundBelow) {
  const CameraModel cam(test::syntheticCalibration(false));
  const Pose3 level = mountToTBaseCam(Vec3(1.5, 0.0, 1.4), 0, 0, 0);
  const Pose3 down = mountToTBaseCam(Vec3(1.5, 0.0, 1.4), 0, 5.0 * kRadPerDeg, 0);
  // Pitched down 5 deg, the ground line of a 4.5 m plane rises by about fy tan(5 deg) = 22 rows
  // (207.8 -> 186.2 for the pinhole at 1.4 m).
  const size_t n_level = GroundMask(cam, level, 4.5).maskedPixels();
  const size_t n_down = GroundMask(cam, down, 4.5).maskedPixels();
  EXPECT_NEAR(double(n_down - n_level) / cam.width(), 21.6, 1.5);
  // A camera on the ground (height 0): nothing masked, every event kept.
  const GroundMask none(cam, mountToTBaseCam(Vec3(0, 0, 0), 0, 0, 0), 4.5);
  EXPECT_EQ(none.maskedPixels(), 0u);
  EXPECT_TRUE(none.keeps({0, 100, 259, 1}));
  const EventVector events = {{0, 10, 250, 1}, {1, 10, 20, -1}, {2, 300, 255, 1}};
  EXPECT_EQ(none.filter(events).size(), 3u);
  const EventVector kept = GroundMask(cam, down, 4.5).filter(events);
  ASSERT_EQ(kept.size(), 1u);
  EXPECT_EQ(kept[0].t_ns, 1);
}

TEST(GroundMask, MasksTheLowParallaxWedgeAroundTheDirectionOfTravel) {
  // A level pinhole camera looking along base_link's x: a pixel's vertical and horizontal tangents
  // relative to the direction of travel are (y - cy) / fy and (x - cx) / fx, so with fx = fy the
  // wedge |phi| < k |theta| is |y - cy| < k |x - cx| in pixels.
  const CameraModel cam(test::syntheticCalibration(false));
  const double k = 0.5;
  const GroundMask wedge(cam, mountToTBaseCam(Vec3(1.5, 0.0, 1.4), 0, 0, 0), 0.0, k);
  size_t expected = 0;
  for (int y = 0; y < cam.height(); ++y)
    for (int x = 0; x < cam.width(); ++x) {
      const double dy = std::abs(y - 130.0), dx = std::abs(x - 173.0);
      const bool inside = dy < k * dx;
      expected += inside ? 1 : 0;
      if (std::abs(dy - k * dx) > 0.01) {
        ASSERT_EQ(wedge.keeps({0, uint16_t(x), uint16_t(y), 1}), !inside) << x << " " << y;
      }
    }
  EXPECT_NEAR(double(wedge.maskedPixels()), double(expected), 200.0);
  // Pitched 5 deg down, the wedge's apex (the focus of expansion) rises by fy tan(5 deg) = 21.9
  // rows: the pixel beside the centre on that row is masked, the image centre is kept.
  const GroundMask down(cam, mountToTBaseCam(Vec3(1.5, 0.0, 1.4), 0, 5.0 * kRadPerDeg, 0), 0.0, k);
  EXPECT_FALSE(down.keeps({0, 273, 108, 1}));
  EXPECT_TRUE(down.keeps({0, 273, 160, 1}));
  EXPECT_TRUE(down.keeps({0, 173, 130, 1}));
  // Both criteria at once: the union of the near ground and the wedge.
  const Pose3 mount = mountToTBaseCam(Vec3(1.5, 0.0, 1.4), 0, 0, 0);
  const size_t ground = GroundMask(cam, mount, 4.5).maskedPixels();
  const GroundMask both(cam, mount, 4.5, k);
  EXPECT_GT(both.maskedPixels(), ground);
  EXPECT_LT(both.maskedPixels(), ground + wedge.maskedPixels());
  EXPECT_FALSE(both.keeps({0, 173, 255, 1}));  // near ground straight ahead
  EXPECT_FALSE(both.keeps({0, 20, 131, 1}));   // the wedge, far left
}
