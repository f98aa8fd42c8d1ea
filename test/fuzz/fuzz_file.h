// The readers take paths: each input goes to one file per fuzzing process (in /dev/shm when
// there is one), rewritten for every run.
#pragma once

#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <stdexcept>
#include <string>

namespace vwe_vo_fuzz {

inline std::string inputPath(const char* suffix) {
  const char* dir = access("/dev/shm", W_OK) == 0 ? "/dev/shm" : "/tmp";
  return std::string(dir) + "/vwe_vo_fuzz_" + std::to_string(getpid()) + suffix;
}

/// Writes the fuzz input to `path`.
inline void writeInput(const std::string& path, const uint8_t* data, size_t size) {
  FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) throw std::logic_error("fuzz: cannot write " + path);
  if (size && std::fwrite(data, 1, size, f) != size)
    throw std::logic_error("fuzz: short write " + path);
  std::fclose(f);
}

/// Runs read(path) on the input; the reader may refuse it with an exception, never crash.
template <typename Read>
int readInput(const char* suffix, const uint8_t* data, size_t size, Read read) {
  static const std::string path = inputPath(suffix);
  writeInput(path, data, size);
  try {
    read(path);
  } catch (const std::exception&) {
  }
  return 0;
}

}  // namespace vwe_vo_fuzz
