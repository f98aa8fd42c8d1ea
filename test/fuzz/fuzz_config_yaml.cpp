// The pipeline configuration (config/vwe_vo.yaml): every section, T_base_cam, the calibration path.
#include "fuzz_file.h"
#include "vwe_vo/io/config.h"
#include "vwe_vo/io/options_yaml.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return vwe_vo_fuzz::readInput(".config.yaml", data, size, [](const std::string& path) {
    vwe_vo::loadPipelineConfig(path, std::string(VWE_VO_SOURCE_DIR) + "/config/davis346.yaml");
  });
}
