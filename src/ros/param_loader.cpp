#include "vwe_vo/ros/param_loader.h"

#include <ros/console.h>

#include <algorithm>

namespace vwe_vo {

std::vector<std::string> ParamLoader::unknownKeys() const {
  std::vector<std::string> names, unknown;
  if (!pnh_.getParamNames(names)) return unknown;
  const std::string prefix = pnh_.getNamespace() + "/";
  for (const std::string& name : names) {
    if (name.compare(0, prefix.size(), prefix) != 0) continue;
    const std::string key =
        name.substr(prefix.size(), name.find('/', prefix.size()) - prefix.size());
    if (std::find(keys_.begin(), keys_.end(), key) == keys_.end() &&
        std::find(unknown.begin(), unknown.end(), key) == unknown.end())
      unknown.push_back(key);
  }
  return unknown;
}

void ParamLoader::finish() const {
  for (const std::string& key : unknownKeys()) {
    std::string known;
    for (const std::string& k : keys_) known += (known.empty() ? "" : ", ") + k;
    ROS_WARN("%s: unknown private parameter ~%s ignored (known: %s)", node_.c_str(), key.c_str(),
             known.c_str());
  }
  std::string values;
  for (const auto& [key, format] : values_)
    values += (values.empty() ? "" : " ") + key + "=" + format();
  ROS_INFO("%s: parameters: %s", node_.c_str(), values.c_str());
}

}  // namespace vwe_vo
