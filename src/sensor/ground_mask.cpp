#include "vwe_vo/sensor/ground_mask.h"

#include <cmath>
#include <limits>

namespace vwe_vo {

double groundDepthAlongAxis(const Vec3& f, const Pose3& T_base_cam) {
  const double height = T_base_cam.translation().z();
  const double down = (T_base_cam.linear() * f).z();  // the ray's slope in base_link (z up)
  if (!(height > 0) || !(down < -1e-9)) return std::numeric_limits<double>::quiet_NaN();
  return height / -down * f.z();
}

GroundMask::GroundMask(const CameraModel& camera, const Pose3& T_base_cam, double min_depth_m,
                       double min_parallax_slope) {
  const double height = T_base_cam.translation().z();
  const bool ground = height > 0 && min_depth_m > 0;
  if (!ground && !(min_parallax_slope > 0)) return;
  width_ = size_t(camera.width());
  masked_.assign(width_ * size_t(camera.height()), 0);
  const Eigen::Matrix3d R = T_base_cam.linear();
  for (int y = 0; y < camera.height(); ++y)
    for (int x = 0; x < camera.width(); ++x) {
      const Vec3 d = camera.bearing(x, y).cast<double>();
      const Vec3 b = R * d;  // in base_link: x forward (the direction of travel), z up
      bool mask = false;
      if (ground) {
        const double depth = groundDepthAlongAxis(d, T_base_cam);
        mask = depth > 0 && depth < min_depth_m;
      }
      if (min_parallax_slope > 0 && b.x() > 0 &&
          std::abs(b.z()) < min_parallax_slope * std::abs(b.y()))
        mask = true;
      if (mask) {
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
