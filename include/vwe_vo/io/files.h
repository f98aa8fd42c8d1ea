// File-system helpers shared by the tools and the offline runner, and the one lookup of the
// package's config folder (installed, in a catkin workspace's source tree, or named by
// VWE_VO_CONFIG_DIR).
#pragma once

#include <string>

namespace vwe_vo {

bool fileExists(const std::string& path);

/// Creates the directory and its parents (like mkdir -p); throws naming the path on failure.
void makeDirs(const std::string& path);

/// The folder holding vwe_vo.yaml and davis346.yaml. Searched in this order:
/// $VWE_VO_CONFIG_DIR; the install space next to the executable (lib/vwe_vo/.. ->
/// share/vwe_vo/config); every package path in $ROS_PACKAGE_PATH whose package.xml names
/// vwe_vo; the source tree of the catkin workspace the executable was built in
/// (devel/lib/vwe_vo -> src/vwe_vo/config); ./config. Throws listing every place it looked.
std::string defaultConfigDir();

}  // namespace vwe_vo
