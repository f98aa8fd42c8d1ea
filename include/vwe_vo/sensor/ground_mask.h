// Pixels whose line of sight meets the ground nearer than a volume's first plane. Whatever such
// a pixel sees lies nearer still (the ground behind it is hidden), so its events cannot focus in
// any plane of the volume; their rays are spread over the nearest planes at every yaw rate and
// pull the contrast's peak towards the rates that smear them least (street_drive, a car's camera
// 1.4 m up: the 0.3 s windows' peaks 2.4 deg/s RMS from the true yaw rate with them, 1.1 without).
// Optionally also the pixels of the low-parallax wedge beside the horizon row, whose events cannot
// pin the yaw rate either (FrontendOptions::parallax_mask_slope): one mask, one pass per window.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "vwe_vo/common/math.h"
#include "vwe_vo/sensor/camera.h"
#include "vwe_vo/sensor/events.h"

namespace vwe_vo {

/// The depth along the camera's optical axis at which the bearing f (camera frame) meets the
/// ground, the plane z = 0 of base_link under T_base_cam; NaN where it does not (a ray at or above
/// the horizon, a camera at or below the ground). Negative for a ray behind the camera.
double groundDepthAlongAxis(const Vec3& f, const Pose3& T_base_cam);

class GroundMask {
 public:
  /// Keeps every pixel.
  GroundMask() = default;
  /// Masks the pixels whose ray meets the ground, the plane z = 0 of base_link, at a depth along
  /// the camera's optical axis below min_depth_m (0: none). A camera at or below the ground masks
  /// none of these. With min_parallax_slope k > 0 it also masks the pixels whose bearing b in
  /// base_link (x the direction of travel, z up) points forward with |b_z| < k |b_y|: the wedge
  /// around the horizon row beside the focus of expansion, where a yaw-rate error is absorbed
  /// by depth (FrontendOptions::parallax_mask_slope).
  GroundMask(const CameraModel& camera, const Pose3& T_base_cam, double min_depth_m,
             double min_parallax_slope = 0.0);
  bool keeps(const PixelEvent& e) const {
    return masked_.empty() || !masked_[size_t(e.y) * width_ + e.x];
  }
  /// Pixels masked, of width x height.
  size_t maskedPixels() const { return num_masked_; }
  /// The events of `events` it keeps, in order.
  EventVector filter(const EventVector& events) const;

 private:
  std::vector<uint8_t> masked_;  // row-major, 1: masked; empty: keeps everything
  size_t width_ = 0;
  size_t num_masked_ = 0;
};

}  // namespace vwe_vo
