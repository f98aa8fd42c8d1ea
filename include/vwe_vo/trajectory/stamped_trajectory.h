// A trajectory as time-stamped poses (ground truth, TUM files, dead-reckoned odometry) and its
// interpolation at any time between the samples.
#pragma once

#include <cstdint>
#include <vector>

#include "vwe_vo/common/math.h"

namespace vwe_vo {

struct StampedPose {
  int64_t t_ns = 0;
  Pose3 T = Pose3::Identity();  // e.g. T_odom_base
};
using Trajectory3 = std::vector<StampedPose>;

/// Pose at t by interpolation between the neighbouring samples (slerp); false if t is outside
/// [front, back] of the (time-sorted) trajectory.
bool interpolateTrajectory(const Trajectory3& trajectory, int64_t t_ns, Pose3* T);

}  // namespace vwe_vo
