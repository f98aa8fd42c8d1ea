// ECD events.txt (`t x y polarity` lines): the whole-file reader and the streamed one.
#include "fuzz_file.h"
#include "vwe_vo/io/trajectory_io.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return vwe_vo_fuzz::readInput(".events.txt", data, size, [](const std::string& path) {
    const vwe_vo::EventVector all = vwe_vo::readEcdEvents(path, 346, 260);
    vwe_vo::EcdEventReader reader(path, 346, 260);
    vwe_vo::EventVector chunk;
    size_t n = 0;
    while (reader.read(3, &chunk) > 0) n += chunk.size();
    if (n != all.size()) __builtin_trap();  // the two readers must agree
  });
}
