// The calibration of the tests' synthetic camera: a DAVIS346's 346 x 260 sensor with a 250 px
// focal length (~70 deg horizontal field of view), optionally with the strong barrel distortion
// of a small wide-angle lens, so that undistortion is exercised; and the shipped DAVIS346
// calibration. Header-only, not core.
#pragma once

#include <string>

#include "vwe_vo/io/config.h"
#include "vwe_vo/sensor/camera.h"

namespace vwe_vo {
namespace test {

inline CameraCalibration syntheticCalibration(bool distorted) {
  CameraCalibration c;
  c.width = 346;
  c.height = 260;
  c.fx = c.fy = 250;
  c.cx = 173;
  c.cy = 130;
  if (distorted) c.distortion = {-0.3, 0.1, 0, 0, 0};
  return c;
}

/// The shipped DAVIS346 calibration (config/davis346.yaml), loaded once. Needs VWE_VO_SOURCE_DIR.
inline const CameraModel& davis346Camera() {
  static const CameraModel cam(
      loadCameraCalibrationYaml(std::string(VWE_VO_SOURCE_DIR) + "/config/davis346.yaml"));
  return cam;
}

}  // namespace test
}  // namespace vwe_vo
