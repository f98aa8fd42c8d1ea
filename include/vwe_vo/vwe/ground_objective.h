// The road as a view of the motion without depth to choose: the events of pixels that see the
// ground (base_link z = 0 under T_base_cam) are points of a known plane, so a trajectory puts
// each of them at one place in the reference view. Warped by the right trajectory the road's
// texture is sharp; a yaw-rate error turns it about the vehicle and blurs it, and no depth can
// take the error up, as it does for a facade seen at a grazing angle (docs/method.md). The
// price: the plane must be where the camera's pose says, to a tenth of a degree of pitch.
#pragma once

#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "vwe_vo/common/math.h"
#include "vwe_vo/sensor/camera.h"
#include "vwe_vo/sensor/events.h"
#include "vwe_vo/trajectory/trajectory_model.h"

namespace vwe_vo {

struct GroundObjectiveOptions {
  // The ground seen between these depths along the optical axis [m]: nearer, the body and the
  // image border; further, a pixel spans decimetres of road and walls at an intersection stand
  // where the plane would be (street_drive_flat's front-end windows, ground alone: 1.9 deg/s RMS
  // to 20 m, 0.4 to 7 m).
  double min_depth_m = 2.0;
  double max_depth_m = 7.0;
  double grid_scale = 1.0;       // image grid relative to the sensor
  int margin_px = 8;             // grid padding around the image [grid px]
  double pose_slice_s = 0.0005;  // events of a slice share one pose (as the VWE) [s]
  /// Throws std::invalid_argument naming the field by its key, section + "." + key.
  void validate(const std::string& section) const;
};

/// The ground plane n . X + h = 0 in a camera frame (n unit, h the camera's height above it).
struct GroundPlane {
  Vec3 n = -Vec3::UnitY();
  double h = 1.0;
};

/// Road events ready for many evaluations: their bearings, grouped by pose slice.
struct GroundEvents {
  std::vector<Eigen::Vector3f> bearings;  // camera frame, unit
  std::vector<int64_t> slice_times;       // the pose time of each slice [ns]
  std::vector<uint32_t> slice_begin;      // first bearing of each slice (+ one past the end)
  size_t size() const { return bearings.size(); }
};

class GroundObjective {
 public:
  GroundObjective(const GroundObjectiveOptions& options, const CameraModel& camera,
                  const Pose3& T_base_cam);
  /// Whether pixel (x, y) sees the untilted ground within [min_depth_m, max_depth_m].
  bool seesGround(int x, int y) const { return ground_[size_t(y) * width_ + x] != 0; }
  size_t groundPixels() const { return ground_pixels_; }
  /// The events of ground pixels, in order, into *out (its storage reused window after window).
  void groundEvents(const EventVector& events, EventVector* out) const;
  /// The events of ground pixels that `covers` (the model's time span) keeps, as GroundEvents.
  GroundEvents prepare(const EventVector& events, const TrajectoryModel& covers) const;
  /// The density per vote (VolumeOptions' kDensityPerVote: the mean of the image a vote meets,
  /// without its own weights) of the image of `events` in the reference view, each warped by
  /// `model` onto `plane` (the ground in the reference camera frame) and projected. Events of
  /// other pixels, or whose ray misses the plane, are left out. Leaves the image clear.
  double evaluate(const EventVector& events, const TrajectoryModel& model,
                  const GroundPlane& plane);
  /// The same for prepared events (prepare()): the poses of their slices from `model`.
  double evaluate(const GroundEvents& events, const TrajectoryModel& model,
                  const GroundPlane& plane);

 private:
  GroundObjectiveOptions options_;
  const CameraModel& camera_;
  int width_ = 0, height_ = 0;   // sensor
  int grid_w_ = 0, grid_h_ = 0;  // image grid
  float fx_, fy_, cx_, cy_;      // grid pinhole
  std::vector<uint8_t> ground_;  // per pixel: sees the ground in range
  size_t ground_pixels_ = 0;
  struct Vote {
    uint32_t idx;  // the grid cell at its upper left
    float ax, ay;  // its place within the four cells
  };
  std::vector<float> grid_;
  std::vector<Vote> votes_;  // of the evaluation under way (as many as its events)
};

}  // namespace vwe_vo
