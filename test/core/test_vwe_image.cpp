// The VWE image: sharper (a higher peak and more contrast) with the true arc than with a wrong one.
#include <gtest/gtest.h>

#include "../common/synthetic_events.h"
#include "../common/test_camera.h"
#include "vwe_vo/io/config.h"
#include "vwe_vo/trajectory/ackermann_arc.h"
#include "vwe_vo/vwe/vwe_image.h"

using namespace vwe_vo;

namespace {
const CameraModel& camera() {
  return test::davis346Camera();
}
double imageVariance(const cv::Mat& m) {
  cv::Scalar mean, stddev;
  cv::meanStdDev(m, mean, stddev);
  return stddev[0] * stddev[0];
}
}  // namespace

TEST(VweImage, TrueArcIsSharperThanAWrongOne) {
  const double w = 20.0 / kDegPerRad;
  const AckermannArcModel truth(w, 0.4, secToNs(2.0), defaultTBaseCam());
  const EventVector events = synthetic::randomPointEvents(camera(), truth, 8000, 5, 0.15, 300);
  VweImageRenderer renderer(camera(), VolumeOptions());
  const AckermannArcModel wrong(w + 15.0 / kDegPerRad, 0.4, secToNs(2.0), defaultTBaseCam());
  const cv::Mat good = renderer.maxProjection(events, truth),
                bad = renderer.maxProjection(events, wrong);
  EXPECT_EQ(good.rows, renderer.height());
  EXPECT_EQ(good.cols, renderer.width());
  double max_good = 0, max_bad = 0;
  cv::minMaxLoc(good, nullptr, &max_good);
  cv::minMaxLoc(bad, nullptr, &max_bad);
  EXPECT_GT(max_good, max_bad);
  EXPECT_GT(imageVariance(good), 1.2 * imageVariance(bad));
}

TEST(VweImage, Mono8ScalesTheMaximumTo255AndEmptyIsBlack) {
  const AckermannArcModel truth(0.1, 0.4, secToNs(2.0), defaultTBaseCam());
  VweImageRenderer renderer(camera(), VolumeOptions());
  const cv::Mat empty = renderer.render(EventVector(), truth);
  EXPECT_EQ(empty.type(), CV_8U);
  EXPECT_EQ(cv::countNonZero(empty), 0);
  const EventVector events = synthetic::randomPointEvents(camera(), truth, 3000, 7, 0.15, 200);
  const cv::Mat image = renderer.render(events, truth);
  double lo = 0, hi = 0;
  cv::minMaxLoc(image, &lo, &hi);
  EXPECT_EQ(hi, 255.0);
  EXPECT_EQ(lo, 0.0);
  // Rendering twice gives the same image: the volume is left clear.
  EXPECT_EQ(cv::countNonZero(image != renderer.render(events, truth)), 0);
}
