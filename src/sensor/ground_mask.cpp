#include "vwe_vo/sensor/ground_mask.h"

namespace vwe_vo {

GroundMask::GroundMask(const CameraModel& camera, const Pose3& T_base_cam, double min_depth_m) {
  const double height = T_base_cam.translation().z();
  if (!(height > 0) || !(min_depth_m > 0)) return;
  width_ = size_t(camera.width());
  masked_.assign(width_ * size_t(camera.height()), 0);
  const Eigen::Matrix3d R = T_base_cam.linear();
  for (int y = 0; y < camera.height(); ++y)
    for (int x = 0; x < camera.width(); ++x) {
      const Vec3 d = camera.bearing(x, y).cast<double>();
      const double down = (R * d).z();  // metres of height lost per unit of ray length
      if (!(down < 0) || !(d.z() > 0)) continue;
      const double depth = height / -down * d.z();  // along the optical axis, where it lands
      if (depth < min_depth_m) {
        masked_[size_t(y) * width_ + size_t(x)] = 1;
        ++num_masked_;
      }
    }
  if (num_masked_ == 0) masked_.clear();
}

EventVector GroundMask::filter(const EventVector& events) const {
  if (masked_.empty()) return events;
  EventVector out;
  out.reserve(events.size());
  for (const PixelEvent& e : events)
    if (keeps(e)) out.push_back(e);
  return out;
}

}  // namespace vwe_vo
