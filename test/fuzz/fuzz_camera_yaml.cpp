// The CameraInfo-style calibration YAML (config/davis346.yaml).
#include "fuzz_file.h"
#include "vwe_vo/sensor/camera.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return vwe_vo_fuzz::readInput(".camera.yaml", data, size, [](const std::string& path) {
    const vwe_vo::CameraCalibration c = vwe_vo::loadCameraCalibrationYaml(path);
    vwe_vo::CameraModel camera(c);  // an accepted calibration must make a camera
    (void)camera;
  });
}
