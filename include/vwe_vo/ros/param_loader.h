// Reads a node's private parameters once at start-up into its options struct: every key falls
// back to the struct's own value (the single default), private parameters the node does not know
// are warned about (a typo is not silently ignored), and every value in use is logged once.
#pragma once

#include <ros/node_handle.h>

#include <functional>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

namespace vwe_vo {

class ParamLoader {
 public:
  /// `node` names the node in the log.
  ParamLoader(const ros::NodeHandle& pnh, std::string node) : pnh_(pnh), node_(std::move(node)) {}

  /// *value = ~key if it is set, else unchanged (the struct's default): pnh.param(key, v, v).
  /// *value must outlive finish(), which logs it as it is then.
  template <typename T>
  void read(const std::string& key, T* value) {
    pnh_.param(key, *value, *value);
    keys_.push_back(key);
    values_.emplace_back(key, [value] {
      std::ostringstream s;
      s << std::boolalpha << *value;
      return s.str();
    });
  }

  /// Private parameters (under the node's namespace) that no read() asked for, by their first
  /// name component.
  std::vector<std::string> unknownKeys() const;
  /// Warns about unknownKeys() and logs every value read in one line (`key=value ...`).
  void finish() const;

 private:
  ros::NodeHandle pnh_;
  std::string node_;
  std::vector<std::string> keys_;
  std::vector<std::pair<std::string, std::function<std::string()>>> values_;
};

}  // namespace vwe_vo
