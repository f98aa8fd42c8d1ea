// TUM trajectories (`t x y z qx qy qz qw`).
#include "fuzz_file.h"
#include "vwe_vo/io/trajectory_io.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return vwe_vo_fuzz::readInput(".tum", data, size,
                                [](const std::string& path) { vwe_vo::readTum(path); });
}
