// ECD imu.txt (`t ax ay az gx gy gz`).
#include "fuzz_file.h"
#include "vwe_vo/io/trajectory_io.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return vwe_vo_fuzz::readInput(".imu.txt", data, size,
                                [](const std::string& path) { vwe_vo::readEcdImu(path); });
}
