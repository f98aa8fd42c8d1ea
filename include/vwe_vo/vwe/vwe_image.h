// An image of the Volume of Warped Events for people to look at: the window's events warped by
// a trajectory estimate and voted into a VWE; per grid pixel the maximum over depth planes.
// A good estimate gives sharp edges, a wrong one smears them. ROS-free (OpenCV only).
#pragma once

#include <opencv2/core.hpp>

#include "vwe_vo/sensor/camera.h"
#include "vwe_vo/sensor/events.h"
#include "vwe_vo/trajectory/trajectory_model.h"
#include "vwe_vo/vwe/projective_volume.h"
#include "vwe_vo/vwe/vwe_objective.h"

namespace vwe_vo {

class VweImageRenderer {
 public:
  /// Owns its own volume (grid and voting threads per `options`); `camera` must outlive it.
  VweImageRenderer(const CameraModel& camera, const VolumeOptions& options);

  /// CV_32F image of the grid size (volume width x height, margins included): per pixel the
  /// maximum over depth planes of the VWE of `events` warped by `model`. Zero where no ray voted.
  cv::Mat maxProjection(const EventVector& events, const TrajectoryModel& model);
  /// maxProjection() scaled to CV_8U: 0 = no votes, 255 = the image's maximum.
  cv::Mat render(const EventVector& events, const TrajectoryModel& model);

  int width() const { return volume_.width(); }
  int height() const { return volume_.height(); }

 private:
  ProjectiveVolume volume_;
  VweObjective objective_;
};

}  // namespace vwe_vo
