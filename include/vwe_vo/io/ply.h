// PLY files of point clouds (the EMVS map) for common viewers.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "vwe_vo/mapping/emvs.h"

namespace vwe_vo {

/// A cloud for writePly: rgb and confidence are optional (empty or one per point).
struct PlyCloud {
  std::vector<Eigen::Vector3f> xyz;
  std::vector<std::array<uint8_t, 3>> rgb;
  std::vector<float> confidence;
};
PlyCloud toPlyCloud(const std::vector<MapPoint>& points);

/// Binary little-endian PLY: x y z float, then red green blue uchar and/or confidence float.
/// Throws std::invalid_argument on size mismatch and std::runtime_error naming the file.
void writePly(const std::string& path, const PlyCloud& cloud);

}  // namespace vwe_vo
