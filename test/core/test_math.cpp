#include <gtest/gtest.h>

#include "vwe_vo/common/math.h"

using namespace vwe_vo;

TEST(Math, RotationAngleAccurateNearZeroAndPi) {
  for (double a : {1e-9, 1e-4, 0.3, 1.0, 3.0, kPi - 1e-6}) {
    const Mat3 R = Eigen::AngleAxisd(a, Vec3(1, 2, 3).normalized()).toRotationMatrix();
    EXPECT_NEAR(rotationAngle(R), a, 1e-9 * std::max(1.0, a)) << a;
  }
}

TEST(Math, WrapAngleAndYaw) {
  EXPECT_NEAR(wrapAngle(3 * kPi / 2), -kPi / 2, 1e-12);
  EXPECT_NEAR(wrapAngle(-3 * kPi / 2), kPi / 2, 1e-12);
  EXPECT_NEAR(wrapAngle(kPi), kPi, 1e-12);
  EXPECT_NEAR(yawOf(rotZ(0.7)), 0.7, 1e-12);
}

TEST(Math, OpticalFrameIsRightHandedAndLooksForward) {
  const Mat3 R = R_base_opticalFrame();
  EXPECT_NEAR(R.determinant(), 1.0, 1e-12);
  EXPECT_TRUE(R.col(2).isApprox(Vec3(1, 0, 0)));   // optical axis along base x
  EXPECT_TRUE(R.col(1).isApprox(Vec3(0, 0, -1)));  // image down = -z
}

TEST(Math, InterpolatePoseEndpointsAndMidpoint) {
  const Pose3 a = planarPose(0, 0, 0), b = planarPose(2, 4, 1.0);
  EXPECT_TRUE(interpolatePose(a, b, 0.0).isApprox(a));
  EXPECT_TRUE(interpolatePose(a, b, 1.0).isApprox(b));
  const Pose3 m = interpolatePose(a, b, 0.5);
  EXPECT_NEAR(yawOf(m.linear()), 0.5, 1e-12);
  EXPECT_TRUE(m.translation().isApprox(Vec3(1, 2, 0)));
}

TEST(Math, TimeConversionRoundTrip) {
  EXPECT_EQ(secToNs(1.5), 1500000000LL);
  EXPECT_EQ(secToNs(-0.25), -250000000LL);
  EXPECT_DOUBLE_EQ(dtSec(3000000000LL, 1000000000LL), 2.0);
}
