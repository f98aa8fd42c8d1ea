// The event camera's geometry: pinhole + plumb_bob (k1 k2 p1 p2 k3) as in ROS CameraInfo.
// Precomputes the undistorted unit bearing of every pixel once; projects 3D points back to
// distorted pixels. Invalid calibrations are refused with a message naming the field.
#pragma once

#include <Eigen/Core>
#include <array>
#include <string>
#include <vector>

#include "vwe_vo/common/math.h"

namespace vwe_vo {

struct CameraCalibration {
  int width = 0;                                      // sensor width [px]
  int height = 0;                                     // sensor height [px]
  double fx = 0, fy = 0, cx = 0, cy = 0;              // intrinsics [px]
  std::array<double, 5> distortion{{0, 0, 0, 0, 0}};  // plumb_bob k1 k2 p1 p2 k3
  std::string camera_name = "davis";
  /// Throws std::invalid_argument naming the bad field (size, focal length, centre, distortion).
  void validate() const;
};

/// Reads a ROS camera_calibration YAML (image_width, image_height, camera_matrix.data,
/// distortion_model: plumb_bob, distortion_coefficients.data). Throws naming file and field.
CameraCalibration loadCameraCalibrationYaml(const std::string& path);

class CameraModel {
 public:
  /// Validates the calibration (throws std::invalid_argument) and builds the bearing table.
  explicit CameraModel(const CameraCalibration& calibration);

  const CameraCalibration& calibration() const { return calib_; }
  int width() const { return calib_.width; }
  int height() const { return calib_.height; }
  bool inside(int x, int y) const {
    return x >= 0 && y >= 0 && x < calib_.width && y < calib_.height;
  }

  /// Unit bearing (camera optical frame, z forward) of pixel (x, y), undistorted. Precomputed.
  const Eigen::Vector3f& bearing(int x, int y) const { return bearings_[y * calib_.width + x]; }
  /// Bearing of a sub-pixel position (undistorts on the fly; slower than the table).
  Vec3 bearingAt(double u, double v) const;

  /// Distorted pixel of a point in the camera frame; false if z <= 0.
  bool project(const Vec3& p_C, Vec2* uv) const;
  /// Applies the plumb_bob distortion to normalised undistorted coordinates (x/z, y/z).
  Vec2 distortNormalized(const Vec2& xn) const;
  /// Inverse of distortNormalized (iterative), for normalised distorted coordinates.
  Vec2 undistortNormalized(const Vec2& xd) const;

 private:
  CameraCalibration calib_;
  std::vector<Eigen::Vector3f> bearings_;
};

}  // namespace vwe_vo
