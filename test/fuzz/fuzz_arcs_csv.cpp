// The front-end's arcs.csv as vwe_vo_eval reads it.
#include "fuzz_file.h"
#include "vwe_vo/eval/evaluation.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return vwe_vo_fuzz::readInput(".arcs.csv", data, size,
                                [](const std::string& path) { vwe_vo::readArcsCsv(path); });
}
