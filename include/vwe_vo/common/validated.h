// validated(options): the options after validate() has accepted them, for member initialisers
// that must refuse bad options before anything is built from them.
#pragma once

namespace vwe_vo {

/// Calls options.validate() (which throws std::invalid_argument naming the bad field) and
/// returns options.
template <typename Options>
const Options& validated(const Options& options) {
  options.validate();
  return options;
}

}  // namespace vwe_vo
