#include "vwe_vo/trajectory/stamped_trajectory.h"

#include <algorithm>

namespace vwe_vo {

bool interpolateTrajectory(const Trajectory3& traj, int64_t t_ns, Pose3* T) {
  if (traj.empty() || t_ns < traj.front().t_ns || t_ns > traj.back().t_ns) return false;
  const auto it = std::lower_bound(traj.begin(), traj.end(), t_ns,
                                   [](const StampedPose& p, int64_t t) { return p.t_ns < t; });
  if (it->t_ns == t_ns) {
    *T = it->T;
    return true;
  }
  const StampedPose& b = *it;
  const StampedPose& a = *(it - 1);
  *T = interpolatePose(a.T, b.T,
                       static_cast<double>(t_ns - a.t_ns) / static_cast<double>(b.t_ns - a.t_ns));
  return true;
}

}  // namespace vwe_vo
