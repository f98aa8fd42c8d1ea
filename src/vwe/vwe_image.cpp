#include "vwe_vo/vwe/vwe_image.h"

#include <algorithm>

#include "vwe_vo/common/validated.h"

namespace vwe_vo {

VweImageRenderer::VweImageRenderer(const CameraModel& camera, const VolumeOptions& options)
    : volume_(validated(options), camera.width(), camera.height(), camera.calibration().fx,
              camera.calibration().fy, camera.calibration().cx, camera.calibration().cy),
      objective_(camera, &volume_) {}

cv::Mat VweImageRenderer::maxProjection(const EventVector& events, const TrajectoryModel& model) {
  cv::Mat image(volume_.height(), volume_.width(), CV_32F, cv::Scalar(0.0f));
  if (events.empty()) return image;
  objective_.voteOnly(events, model);
  for (int l = 0; l < volume_.numPlanes(); ++l)
    for (int y = 0; y < volume_.height(); ++y) {
      float* row = image.ptr<float>(y);
      for (int x = 0; x < volume_.width(); ++x) row[x] = std::max(row[x], volume_.at(x, y, l));
    }
  volume_.clear(objective_.lastRays());
  return image;
}

cv::Mat VweImageRenderer::render(const EventVector& events, const TrajectoryModel& model) {
  const cv::Mat image = maxProjection(events, model);
  double max_value = 0.0;
  cv::minMaxLoc(image, nullptr, &max_value);
  cv::Mat out;
  image.convertTo(out, CV_8U, max_value > 0 ? 255.0 / max_value : 0.0);
  return out;
}

}  // namespace vwe_vo
