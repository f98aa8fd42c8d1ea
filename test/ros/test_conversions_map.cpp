// Conversions of the mapping and trajectory messages: SplineTrajectory round trip and its
// validation, PointCloud2 of map points, Image of an OpenCV matrix.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <string>

#include "vwe_vo/ros/conversions.h"

namespace {
vwe_vo::BSpline testSpline() {
  using vwe_vo::Vec2;
  std::vector<Vec2> cps = {Vec2(0, 0), Vec2(0.2, 0.05), Vec2(0.5, 0.2), Vec2(0.9, 0.5),
                           Vec2(1.2, 0.9)};
  return vwe_vo::BSpline(3, vwe_vo::BSpline::clampedUniformKnots(3, 5, 0.0, 2.0), cps,
                         vwe_vo::secToNs(100.25));
}
/// The message of the std::invalid_argument convert() throws, or "no exception".
template <typename F>
std::string refusal(F&& convert) {
  try {
    convert();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "no exception";
}
}  // namespace

TEST(Conversions, SplineRoundTripEvaluatesIdentically) {
  vwe_vo::BSpline spline = testSpline();
  spline.setMinSpeed(0.5);  // the heading near u = 0 comes from a faster tangent
  const vwe_vo::SplineTrajectory msg = vwe_vo::splineToMsg(spline, 2, "odom");
  EXPECT_EQ(msg.header.frame_id, "odom");
  EXPECT_EQ(msg.first_free_control_point, 2u);
  EXPECT_EQ(msg.knots.size(), 9u);
  EXPECT_EQ(vwe_vo::toNs(msg.valid_from), vwe_vo::secToNs(100.25));
  EXPECT_EQ(vwe_vo::toNs(msg.valid_to), vwe_vo::secToNs(102.25));
  const vwe_vo::BSpline back = vwe_vo::splineFromMsg(msg);
  EXPECT_EQ(back.epochNs(), spline.epochNs());
  EXPECT_EQ(back.minSpeed(), 0.5);
  for (double u = 0.0; u <= 2.0; u += 0.1) {
    EXPECT_EQ(back.position(u), spline.position(u));
    EXPECT_EQ(back.heading(u), spline.heading(u));
  }
}

TEST(Conversions, SplineTiltSamplesRoundTrip) {
  // The body's tilt rides along with the spline: samples relative to the knot epoch, linear between
  // them and held outside; none for a planar body.
  vwe_vo::SplineTrajectory msg = vwe_vo::splineToMsg(testSpline(), 0, "odom");
  EXPECT_TRUE(vwe_vo::tiltFromMsg(msg).empty());
  const int64_t t0 = vwe_vo::secToNs(100.5);
  for (int k = 0; k < 5; ++k) {
    vwe_vo::Tilt tilt;
    tilt.roll = 0.01 * k;
    tilt.pitch = -0.02 * k;
    vwe_vo::addTiltToMsg(t0 + k * 20000000LL, tilt, &msg);
  }
  ASSERT_EQ(msg.tilt_t.size(), 5u);
  EXPECT_DOUBLE_EQ(msg.tilt_t[1], 0.27);  // seconds since the epoch 100.25 s
  const vwe_vo::TiltHistory tilts = vwe_vo::tiltFromMsg(msg);
  EXPECT_NEAR(tilts.at(t0 + 30000000LL).roll, 0.015, 1e-12);  // halfway between samples 1 and 2
  EXPECT_NEAR(tilts.at(t0 + 30000000LL).pitch, -0.03, 1e-12);
  EXPECT_NEAR(tilts.at(t0 - vwe_vo::secToNs(1.0)).roll, 0.0, 1e-12);     // held before the first
  EXPECT_NEAR(tilts.at(t0 + vwe_vo::secToNs(1.0)).pitch, -0.08, 1e-12);  // and after the last
  const auto message = [](const vwe_vo::SplineTrajectory& m) {
    return refusal([&] { vwe_vo::tiltFromMsg(m); });
  };
  vwe_vo::SplineTrajectory m = msg;
  m.tilt_pitch.pop_back();
  EXPECT_NE(message(m).find("5 tilt_t but 5 tilt_roll and 4 tilt_pitch"), std::string::npos)
      << message(m);
  m = msg;
  m.tilt_roll[2] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_NE(message(m).find("tilt sample 2 is not finite"), std::string::npos) << message(m);
  m = msg;
  m.tilt_t[3] = m.tilt_t[2];
  EXPECT_NE(message(m).find("tilt_t[3]"), std::string::npos) << message(m);
  m = msg;
  m.tilt_t[4] = 1e191;  // would overflow the nanoseconds
  EXPECT_NE(message(m).find("tilt_t[4]"), std::string::npos) << message(m);
}

TEST(Conversions, SplineFromMsgNamesTheBadField) {
  const vwe_vo::SplineTrajectory good = vwe_vo::splineToMsg(testSpline(), 0, "odom");
  const auto message = [](const vwe_vo::SplineTrajectory& m) {
    return refusal([&] { vwe_vo::splineFromMsg(m); });
  };
  vwe_vo::SplineTrajectory m = good;
  m.degree = 0;
  EXPECT_NE(message(m).find("degree"), std::string::npos) << message(m);
  m = good;
  m.degree = 9;
  EXPECT_NE(message(m).find("degree"), std::string::npos) << message(m);
  m = good;
  m.knots.pop_back();
  EXPECT_NE(message(m).find("knots has 8 entries"), std::string::npos) << message(m);
  m = good;
  m.min_speed = -1.0;
  EXPECT_NE(message(m).find("min_speed"), std::string::npos) << message(m);
  m = good;
  m.control_y.pop_back();
  EXPECT_NE(message(m).find("control_y"), std::string::npos) << message(m);
  m = good;
  m.control_x[1] = std::nan("");
  EXPECT_NE(message(m).find("control point 1 is not finite"), std::string::npos) << message(m);
  m = good;
  m.knots[4] = std::numeric_limits<double>::infinity();
  EXPECT_NE(message(m).find("knots[4]"), std::string::npos) << message(m);
  m = good;
  std::swap(m.knots[4], m.knots[5]);
  EXPECT_NE(message(m).find("knots"), std::string::npos) << message(m);
}

TEST(Conversions, CloudToMsgKeepsFinitePointsAsXyzIntensity) {
  std::vector<vwe_vo::MapPoint> points(3);
  points[0].p = Eigen::Vector3f(1, 2, 3);
  points[0].confidence = 7;
  points[1].p = Eigen::Vector3f(std::nanf(""), 0, 0);
  points[2].p = Eigen::Vector3f(-1, 0.5f, 2);
  points[2].confidence = 4;
  const sensor_msgs::PointCloud2 msg = vwe_vo::cloudToMsg(points, "odom", vwe_vo::secToNs(3.0));
  EXPECT_EQ(msg.header.frame_id, "odom");
  EXPECT_EQ(msg.width, 2u);
  EXPECT_EQ(msg.height, 1u);
  ASSERT_EQ(msg.data.size(), 2u * msg.point_step);
  float v[4];
  std::memcpy(v, &msg.data[msg.point_step], sizeof(v));
  EXPECT_EQ(v[0], -1.0f);
  EXPECT_EQ(v[1], 0.5f);
  EXPECT_EQ(v[2], 2.0f);
  EXPECT_EQ(v[3], 4.0f);
}

TEST(Conversions, ImageToMsgCopiesRows) {
  cv::Mat bgr(4, 5, CV_8UC3, cv::Scalar(1, 2, 3));
  bgr.at<cv::Vec3b>(3, 4) = cv::Vec3b(9, 8, 7);
  const sensor_msgs::Image msg = vwe_vo::imageToMsg(bgr, 0, "davis");
  EXPECT_EQ(msg.encoding, "bgr8");
  EXPECT_EQ(msg.step, 15u);
  EXPECT_EQ(msg.data.back(), 7);
  EXPECT_THROW(vwe_vo::imageToMsg(cv::Mat(2, 2, CV_32F), 0, "davis"), std::invalid_argument);
}
