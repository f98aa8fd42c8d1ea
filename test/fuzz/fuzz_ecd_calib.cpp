// ECD calib.txt (`fx fy cx cy k1 k2 p1 p2 k3`) and extrinsics.txt (one pose line).
#include "fuzz_file.h"
#include "vwe_vo/io/trajectory_io.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  vwe_vo_fuzz::readInput(".calib.txt", data, size,
                         [](const std::string& path) { vwe_vo::readEcdCalibration(path); });
  return vwe_vo_fuzz::readInput(".pose.txt", data, size,
                                [](const std::string& path) { vwe_vo::readPoseLine(path); });
}
