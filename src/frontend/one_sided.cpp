#include "vwe_vo/frontend/one_sided.h"

#include <algorithm>
#include <stdexcept>

namespace vwe_vo {

void OneSidedOptions::validate(const VolumeOptions& normal, const std::string& section) const {
  auto fail = [&](const std::string& m) {
    throw std::invalid_argument(section + ".one_sided_" + m);
  };
  if (!(balance >= 0 && balance < 1)) fail("balance must be in [0, 1)");
  if (balance == 0) return;
  if (!(z_min_m > normal.z_min_m && (z_min_m < normal.z_max_m || normal.z_max_m < 0)))
    fail("z_min_m must be in (volume.z_min_m, volume.z_max_m) (any deeper one if z_max_m < 0)");
  if (!(min_depth_m > 0 && min_depth_m < 1e4)) fail("min_depth_m must be in (0, 1e4) m");
}

namespace {
/// Straight ahead of base_link in the camera frame; false if the camera does not look forward.
bool forwardDirection(const Pose3& T_base_cam, Vec3* d) {
  *d = T_base_cam.linear().transpose() * Vec3::UnitX();
  return d->z() > 1e-3;
}
}  // namespace

bool forwardPixel(const CameraModel& camera, const Pose3& T_base_cam, Vec2* pixel) {
  Vec3 d;
  return forwardDirection(T_base_cam, &d) && camera.project(d, pixel);
}

double sideBalance(const EventVector& events, const Vec2& pixel) {
  size_t left = 0, right = 0;
  for (const PixelEvent& e : events) {
    if (e.y >= pixel.y()) continue;
    if (e.x < pixel.x())
      ++left;
    else
      ++right;
  }
  const size_t most = std::max(left, right);
  return most == 0 ? 1.0 : double(std::min(left, right)) / double(most);
}

double oneSidedDepth(const ProjectiveVolume& volume, const std::vector<VolumeRay>& rays,
                     const Vec2& pixel) {
  size_t left = 0, right = 0;
  for (const VolumeRay& r : rays)
    if (r.v0 < pixel.y()) ++(r.u0 < pixel.x() ? left : right);
  const bool use_left = left >= right;
  std::vector<double> depths;
  depths.reserve(std::max(left, right));
  for (const VolumeRay& r : rays) {
    if (!(r.v0 < pixel.y()) || (r.u0 < pixel.x()) != use_left) continue;
    const double z = volume.peakDepth(r);
    if (z > 0) depths.push_back(z);
  }
  if (depths.empty()) return 0.0;
  const auto mid = depths.begin() + depths.size() / 2;
  std::nth_element(depths.begin(), mid, depths.end());
  return *mid;
}

OneSidedRule::OneSidedRule(const OneSidedOptions& options, const CameraModel& camera,
                           const Pose3& T_base_cam)
    : options_(options), T_base_cam_(T_base_cam) {
  enabled_ = options_.balance > 0 && forwardPixel(camera, T_base_cam_, &forward_pixel_);
}

VolumeOptions OneSidedRule::deeperPlanes(const VolumeOptions& normal) const {
  VolumeOptions deeper = normal;
  deeper.z_min_m = options_.z_min_m;
  return deeper;
}

bool OneSidedRule::oneSided(const EventVector& events) const {
  return enabled_ && sideBalance(events, forward_pixel_) < options_.balance;
}

bool OneSidedRule::deepEnough(VweObjective& normal, const EventVector& events,
                              const TrajectoryModel& model) const {
  ProjectiveVolume& volume = normal.volume();
  // Straight ahead in the volume's grid (the rays' (u0, v0) are directions in its undistorted
  // pinhole); enabled() means the camera looks forward.
  Vec3 d;
  forwardDirection(T_base_cam_, &d);
  const Vec2 forward(volume.fx() * d.x() / d.z() + volume.cx(),
                     volume.fy() * d.y() / d.z() + volume.cy());
  normal.voteOnly(events, model);
  const double depth = oneSidedDepth(volume, normal.lastRays(), forward);
  volume.clear(normal.lastRays());
  return depth >= options_.min_depth_m;
}

}  // namespace vwe_vo
