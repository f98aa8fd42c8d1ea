// Helpers of the tests that check error messages. Header-only, not core.
#pragma once

#include <gtest/gtest.h>

#include <stdexcept>
#include <string>

namespace vwe_vo {
namespace test {

/// The message of the std::runtime_error that f throws ("no exception" otherwise).
template <typename F>
std::string errorOf(F f) {
  try {
    f();
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "no exception";
}

inline void expectContains(const std::string& text, const std::string& part) {
  EXPECT_NE(text.find(part), std::string::npos) << "'" << text << "' lacks '" << part << "'";
}

}  // namespace test
}  // namespace vwe_vo
