// The IMU layer: attitude filter (known rotations, body rates by finite differences, x/y bias
// recovery), the gyro's yaw-rate prior (gradient against finite differences, bias recovery) and
// the bias filter.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <random>

#include "../common/prior_gradient_check.h"
#include "vwe_vo/backend/gyro_prior.h"
#include "vwe_vo/sensor/imu.h"

using namespace vwe_vo;

namespace {

constexpr double kG = 9.80665;

Mat3 rotZYX(double yaw, double pitch, double roll) {
  return (Eigen::AngleAxisd(yaw, Vec3::UnitZ()) * Eigen::AngleAxisd(pitch, Vec3::UnitY()) *
          Eigen::AngleAxisd(roll, Vec3::UnitX()))
      .toRotationMatrix();
}

Vec3 vee(const Mat3& W) {
  return Vec3(W(2, 1) - W(1, 2), W(0, 2) - W(2, 0), W(1, 0) - W(0, 1)) * 0.5;
}

// A vehicle driving a circle at v and yaw rate omega while its body rolls and pitches
// sinusoidally; the IMU at lever arm r in base_link, its samples at 1 kHz (white noise of the
// MPU-6150's densities, a constant gyro bias), body rates from central differences of R(t).
struct Motion {
  double v = 6.0, omega = 0.2;
  double roll_amp = 1.5 * kPi / 180, pitch_amp = 1.0 * kPi / 180;
  double roll_w = 0.9, pitch_w = 1.3;  // angular frequencies [rad/s]
  Vec3 lever_arm = Vec3(1.2, 0.0, 1.3);
  double pitch(double t) const { return pitch_amp * std::cos(pitch_w * t) + 0.01; }
  double roll(double t) const { return roll_amp * std::sin(roll_w * t) - 0.02; }
  Mat3 R(double t) const { return rotZYX(omega * t, pitch(t), roll(t)); }
  Vec3 omegaBody(double t) const {
    const double h = 1e-5;
    return vee(R(t).transpose() * (R(t + h) - R(t - h)) / (2 * h));
  }
  ImuSample sample(double t, const Vec3& bias, std::mt19937_64* rng) const {
    std::normal_distribution<double> n(0.0, 1.0);
    const double sg = 0.005 * kPi / 180 * std::sqrt(1000.0), sa = 400e-6 * kG * std::sqrt(1000.0);
    // Acceleration of the IMU's origin in odom: the circle's centripetal one plus the lever arm's,
    // by second central differences of its position.
    auto pos = [&](double s) {
      const double psi = omega * s;
      const Vec3 c(v / omega * std::sin(psi), v / omega * (1 - std::cos(psi)), 0.0);
      return Vec3(c + R(s) * lever_arm);
    };
    const double h = 1e-3;
    const Vec3 a = (pos(t + h) - 2 * pos(t) + pos(t - h)) / (h * h);
    ImuSample s;
    s.t_ns = secToNs(t);
    s.gyro = omegaBody(t) + bias;
    s.accel = R(t).transpose() * (a + Vec3(0, 0, kG));
    for (int i = 0; i < 3; ++i) s.gyro(i) += sg * n(*rng), s.accel(i) += sa * n(*rng);
    return s;
  }
};

}  // namespace

TEST(Imu, EulerYawRateMatchesFiniteDifferencesOfTheYaw) {
  const Motion m;
  for (double t : {0.3, 1.7, 4.2}) {
    const Vec3 w = m.omegaBody(t);
    const double pitch = m.pitch_amp * std::cos(1.3 * t) + 0.01;
    const double roll = m.roll_amp * std::sin(0.9 * t) - 0.02;
    // d yaw / dt = omega exactly.
    EXPECT_NEAR(eulerYawRate(w, roll, pitch), m.omega, 1e-7) << t;
    // Not the body z rate: the tilt's own rates mix in.
    EXPECT_GT(std::abs(w.z() - m.omega), 1e-6) << t;
  }
}

TEST(Imu, TiltRotationAndRotatedSamples) {
  Tilt t;
  t.roll = 0.03, t.pitch = -0.02;
  EXPECT_TRUE(t.rotation().isApprox(rotZYX(0, -0.02, 0.03), 1e-12));
  ImuFusionOptions o;
  o.T_cam_imu_quaternion_xyzw = {0.0, 0.0, std::sin(0.25), std::cos(0.25)};
  o.validate();
  ImuSample s;
  s.gyro = Vec3(0.1, 0.2, 0.3);
  s.accel = Vec3(0, 0, kG);
  const Pose3 T_base_imu = o.T_cam_imu();
  const ImuSample r = rotateImuSample(s, T_base_imu);
  EXPECT_TRUE(r.gyro.isApprox(Eigen::AngleAxisd(0.5, Vec3::UnitZ()) * s.gyro, 1e-12));
  EXPECT_NEAR(r.accel.z(), kG, 1e-12);
}

TEST(Imu, OptionsValidationNamesTheKey) {
  ImuFusionOptions o;
  o.T_cam_imu_quaternion_xyzw = {0, 0, 0, 2};
  try {
    o.validate();
    FAIL() << "a non-unit quaternion was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("imu.T_cam_imu.quaternion_xyzw"), std::string::npos);
  }
  o = ImuFusionOptions();
  o.bias_sigma_min_deg_s = 1.0;  // above bias_sigma_deg_s
  EXPECT_THROW(o.validate(), std::invalid_argument);
}

// A static, tilted IMU with x/y gyro biases: the filter finds the tilt and the biases.
TEST(Imu, AttitudeFilterRecoversAStaticTiltAndTheXYGyroBias) {
  ImuFusionOptions o;
  AttitudeFilter f(o, Vec3::Zero());
  const Mat3 R = rotZYX(0.4, -2.0 * kPi / 180, 3.0 * kPi / 180);
  const Vec3 bias(0.3 * kPi / 180, -0.4 * kPi / 180, 0.0);
  std::mt19937_64 rng(3);
  std::normal_distribution<double> n(0.0, 1.0);
  double first_err = 0, early_err = 0;
  for (int k = 0; k <= 120000; ++k) {
    ImuSample s;
    s.t_ns = int64_t(k) * 1000000;
    s.gyro = bias + 0.005 * kPi / 180 * std::sqrt(1000.0) * Vec3(n(rng), n(rng), n(rng));
    s.accel = R.transpose() * Vec3(0, 0, kG) + 0.12 * Vec3(n(rng), n(rng), n(rng));
    f.add(s, VehicleMotion());
    const double err =
        std::hypot(f.tilt().roll - 3.0 * kPi / 180, f.tilt().pitch + 2.0 * kPi / 180);
    if (k == 1000) first_err = err;  // the first tilt, from 1 s of specific force
    if (k >= 5000 && k <= 10000) early_err = std::max(early_err, err);
  }
  std::printf("[imu] static tilt error: first %.3f deg, 5-10 s at most %.3f deg\n",
              first_err * kDegPerRad, early_err * kDegPerRad);
  // One 1 kHz sample is 0.7 deg off (0.12 m/s^2 of noise; measured 1.4 here), 1000 average to
  // 0.02 deg (measured 0.022).
  EXPECT_LT(first_err * kDegPerRad, 0.06);
  // The unknown bias (0.5 deg/s) pulls the tilt by bias x the proportional time constant until
  // the integral has it: measured 0.07 deg at most over 5-10 s (0.38 with both time constants at
  // their final values from the start, 0.19 with only the integral's growing).
  EXPECT_LT(early_err * kDegPerRad, 0.12);
  EXPECT_NEAR(f.tilt().roll, 3.0 * kPi / 180, 0.01 * kPi / 180);
  EXPECT_NEAR(f.tilt().pitch, -2.0 * kPi / 180, 0.01 * kPi / 180);
  EXPECT_NEAR(f.bias().x(), bias.x(), 0.01 * kPi / 180);
  EXPECT_NEAR(f.bias().y(), bias.y(), 0.01 * kPi / 180);
}

// Driving a circle while the body rolls and pitches: with the centripetal and lever-arm
// accelerations removed the tilt follows the truth; without the compensation the roll is off by
// the centripetal angle atan(v omega / g).
TEST(Imu, AttitudeFilterFollowsAMovingBodyWithItsAccelerationRemoved) {
  const Motion m;
  const Vec3 bias(0.2 * kPi / 180, -0.3 * kPi / 180, 0.1 * kPi / 180);
  ImuFusionOptions o;
  AttitudeFilter comp(o, m.lever_arm), raw(o, Vec3::Zero());
  comp.setYawBias(bias.z());
  raw.setYawBias(bias.z());
  std::mt19937_64 rng(5);
  VehicleMotion vm;
  vm.v = m.v, vm.omega = m.omega;
  double se = 0.0, se_raw = 0.0;
  int n = 0;
  for (int k = 0; k <= 60000; ++k) {
    const double t = k * 1e-3;
    const ImuSample s = m.sample(t, bias, &rng);
    comp.add(s, vm);
    raw.add(s, VehicleMotion());
    if (t < 30.0) continue;  // converged (bias integral)
    se += std::pow(comp.tilt().roll - m.roll(t), 2) + std::pow(comp.tilt().pitch - m.pitch(t), 2);
    se_raw += std::pow(raw.tilt().roll - m.roll(t), 2);
    ++n;
  }
  const double rms_deg = std::sqrt(se / n) * 180 / kPi;
  const double rms_raw_deg = std::sqrt(se_raw / n) * 180 / kPi;
  std::printf("[imu] moving body: tilt RMS %.4f deg (uncompensated roll %.2f deg)\n", rms_deg,
              rms_raw_deg);
  EXPECT_LT(rms_deg, 0.045) << rms_deg;        // measured 0.031
  EXPECT_GT(rms_raw_deg, 5.0) << rms_raw_deg;  // atan(1.2 / 9.81) = 7 deg
  EXPECT_NEAR(comp.bias().x(), bias.x(), 0.02 * kPi / 180);
  EXPECT_NEAR(comp.bias().y(), bias.y(), 0.02 * kPi / 180);
}

// A car's body rides at 1-1.5 Hz: its pitching moves an IMU 1.4 m above the pitch axis by
// tenths of m/s^2 forward and back, which the specific force of a fraction of a ride period takes
// for degrees of tilt. Started at any phase, the first tilt averages over the ride, and the
// early seconds stay near the truth.
TEST(Imu, AttitudeFilterStartedOnARidingBodyGetsItsFirstTiltRight) {
  Motion m;
  m.v = 8.0, m.omega = 0.05;
  m.pitch_amp = 0.5 * kPi / 180, m.pitch_w = 2 * kPi * 1.4;
  m.roll_amp = 0.4 * kPi / 180, m.roll_w = 2 * kPi * 1.5;
  m.lever_arm = Vec3(1.5, 0.0, 1.4);
  const Vec3 bias(0.2 * kPi / 180, -0.3 * kPi / 180, 0.1 * kPi / 180);
  ImuFusionOptions o;
  o.attitude_time_constant_s = 3.0;  // car.yaml's
  VehicleMotion vm;
  vm.v = m.v, vm.omega = m.omega;
  double worst_first = 0.0, worst_rms = 0.0;
  for (double t0 = 0.0; t0 < 0.7; t0 += 0.1) {  // one ride period of phases
    AttitudeFilter f(o, m.lever_arm);
    f.setYawBias(bias.z());
    std::mt19937_64 rng(11);
    double first = -1.0, se = 0.0;
    int n = 0;
    for (int k = 0; k <= 10000; ++k) {
      const double t = t0 + k * 1e-3;
      f.add(m.sample(t, bias, &rng), vm);
      if (!f.initialised()) continue;
      // The first tilt against the ride's mean (the offsets of Motion's pitch and roll).
      if (first < 0) first = std::hypot(f.tilt().pitch - 0.01, f.tilt().roll + 0.02);
      se += std::pow(f.tilt().roll - m.roll(t), 2) + std::pow(f.tilt().pitch - m.pitch(t), 2);
      ++n;
    }
    worst_first = std::max(worst_first, first);
    worst_rms = std::max(worst_rms, std::sqrt(se / n));
  }
  std::printf(
      "[imu] riding start: first tilt off by %.3f deg, tilt RMS over 10 s %.3f deg (worst phase)\n",
      worst_first * kDegPerRad, worst_rms * kDegPerRad);
  // Measured 0.16 and 0.34 deg; from 0.1 s of specific force 1.16 and 0.37, from 1 s without
  // the lever arm's mean dw x r 1.51 and 0.44.
  EXPECT_LT(worst_first * kDegPerRad, 0.4);
  EXPECT_LT(worst_rms * kDegPerRad, 0.4);
}

TEST(Imu, TiltHistoryInterpolatesAndHoldsAtTheEnds) {
  TiltHistory h(5000000);
  Tilt a, b;
  a.roll = 0.01, b.roll = 0.03;
  h.add(0, a);
  h.add(1000000, b);  // within the step: ignored
  h.add(10000000, b);
  EXPECT_NEAR(h.at(5000000).roll, 0.02, 1e-12);
  EXPECT_NEAR(h.at(-5).roll, 0.01, 1e-12);
  EXPECT_NEAR(h.at(20000000).roll, 0.03, 1e-12);
}

namespace {

// A planar spline whose yaw rate varies (0.1 + 0.07 sin 2t rad/s) at 1 m/s, 3.2 s.
std::shared_ptr<BSpline> curvedSpline() {
  std::vector<int64_t> t;
  std::vector<Vec2> p;
  Vec2 c(0, 0);
  double psi = 0.0;
  const double dt = 0.001;
  for (double s = 0; s <= 3.2 + 1e-9; s += dt) {
    t.push_back(secToNs(s));
    p.push_back(c);
    const double w = 0.1 + 0.07 * std::sin(2.0 * s);
    c += dt * Vec2(std::cos(psi + 0.5 * w * dt), std::sin(psi + 0.5 * w * dt));
    psi += w * dt;
  }
  BSplineFitOptions o;
  o.knot_spacing_s = 0.3;
  return std::make_shared<BSpline>(fitBSpline(t, p, o));
}

std::vector<GyroRatePrior::Bin> gyroBins(const BSpline& s, double bias) {
  std::vector<GyroRatePrior::Bin> bins;
  for (double u = 0.3; u + 0.05 <= 3.0; u += 0.05)
    bins.push_back({u, u + 0.05, wrapAngle(s.heading(u + 0.05) - s.heading(u)) / 0.05 + bias});
  return bins;
}

}  // namespace

TEST(Imu, GyroPriorRecoversABiasAndIsFlatOnTheTruth) {
  auto spline = curvedSpline();
  const double b = 0.3 * kPi / 180, nd = 0.005 * kPi / 180;
  // A wide bias prior: the bias comes from the gyro against the spline.
  const GyroRatePrior wide(spline, 4, gyroBins(*spline, b), 1e-3, nd, 0.0, 10 * kPi / 180);
  EXPECT_GT(wide.numBins(), 30u);
  EXPECT_NEAR(wide.measuredBias(), b, 1e-9);
  EXPECT_NEAR(wide.bias(), b, 1e-4 * b);
  EXPECT_LT(wide.evaluate(nullptr), 1e-6);
  // A tight prior at zero holds the bias there and the residuals cost.
  const GyroRatePrior tight(spline, 4, gyroBins(*spline, b), 1e-3, nd, 0.0, 1e-4 * kPi / 180);
  EXPECT_NEAR(tight.bias(), 0.0, 0.01 * b);
  // weight * (bin / nd^2) * b^2 = 1e-3 * 0.05 * (0.3 / 0.005)^2 (bias held at 0).
  EXPECT_NEAR(tight.evaluate(nullptr), 0.18, 0.005);
}

TEST(Imu, GyroPriorModelSpreadWeighsTheBinsAgainstTheBiasPrior) {
  auto spline = curvedSpline();
  const double b = 0.3 * kPi / 180, nd = 0.005 * kPi / 180, model = 0.1 * kPi / 180;
  const double sigma_b = 0.005 * kPi / 180;
  const auto bins = gyroBins(*spline, b);
  const GyroRatePrior white(spline, 4, bins, 1e-3, nd, 0.0, sigma_b);
  const GyroRatePrior floored(spline, 4, bins, 1e-3, nd, 0.0, sigma_b, 0.05, model);
  const double k = double(white.numBins());
  ASSERT_EQ(floored.numBins(), white.numBins());
  // The closed-form bias: the bins' information k / sigma_k^2 against the prior's 1 / sigma_b^2.
  auto expected = [&](double var_k) {
    return b * (k / var_k) / (k / var_k + 1.0 / (sigma_b * sigma_b));
  };
  EXPECT_NEAR(white.bias(), expected(nd * nd / 0.05), 1e-6 * b);
  EXPECT_NEAR(floored.bias(), expected(nd * nd / 0.05 + model * model), 1e-6 * b);
  // White noise alone the bins outweigh a tight prior (0.73 b); with the model spread the prior
  // holds the bias (0.11 b).
  EXPECT_GT(white.bias(), 0.65 * b);
  EXPECT_LT(floored.bias(), 0.17 * b);
  // No held standstill in this spline: the measured bias is the gyro against the spline.
  EXPECT_EQ(floored.numStandstillBins(), 0u);
  EXPECT_EQ(floored.measuredBiasBins(), floored.numBins());
  EXPECT_NEAR(floored.measuredBias(), b, 1e-9);
}

// A held standstill is made of whole front-end windows whose event rate fell: its first window
// may still turn. Only bins kStillMargin_s inside it measure the bias from the gyro alone.
TEST(Imu, GyroPriorMeasuresTheBiasOnlyWellInsideAStandstill) {
  auto spline = curvedSpline();
  spline->setStandstills({{1.0, 3.0}});
  const double b = 0.3 * kPi / 180, nd = 0.005 * kPi / 180, turning = 0.6 * kPi / 180;
  auto binsUntil = [&](double u_end) {
    std::vector<GyroRatePrior::Bin> bins;
    for (int k = 0; 0.3 + 0.05 * (k + 1) <= u_end + 1e-9; ++k) {
      const double u = 0.3 + 0.05 * k;
      const double rate = u < 1.0 - 1e-9
                              ? wrapAngle(spline->heading(u + 0.05) - spline->heading(u)) / 0.05
                          : u < 1.2 - 1e-9 ? turning  // the stop's first 0.2 s
                                           : 0.0;
      bins.push_back({u, u + 0.05, rate + b});
    }
    return bins;
  };
  // 0.4 s into the stop: 8 held bins, half of them turning, none well inside: no standstill
  // measurement (the median of the held bins would be 0.3 deg/s off).
  const GyroRatePrior early(spline, 4, binsUntil(1.4), 1e-3, nd, 0.0, 10 * kPi / 180);
  EXPECT_EQ(early.numStandstillBins(), 8u);
  EXPECT_FALSE(early.measuresStandstill());
  EXPECT_EQ(early.measuredBiasBins(), early.numBins());
  // 0.8 s into it: the bins from 1.3 s measure the bias, the turning start left out.
  const GyroRatePrior later(spline, 4, binsUntil(1.8), 1e-3, nd, 0.0, 10 * kPi / 180);
  EXPECT_TRUE(later.measuresStandstill());
  EXPECT_EQ(later.measuredBiasBins(), 10u);
  EXPECT_NEAR(later.measuredBias(), b, 1e-12);
}

TEST(Imu, GyroPriorGradientMatchesCentralFiniteDifferences) {
  auto spline = curvedSpline();
  const int first_free = 4;
  const double nd = 0.005 * kPi / 180;
  const GyroRatePrior prior(spline, first_free, gyroBins(*spline, 0.2 * kPi / 180), 1e-3, nd,
                            0.1 * kPi / 180, 0.1 * kPi / 180);
  test::expectPriorGradientMatchesCentralDifferences(spline.get(), first_free, prior, 0.003, 1e-5);
}

TEST(Imu, GyroBiasFilterDownWeighsFarMeasurementsByHuber) {
  // Within huber_k spreads of the estimate a measurement keeps its full weight.
  GyroBiasFilter near(1e9, 0.5, 0.02, 10.0, 1.0), plain(1e9, 0.5, 0.02, 10.0);
  near.add(1.0, 0.0, 1.0);
  plain.add(1.0, 0.0, 1.0);
  EXPECT_NEAR(near.bias(), 1.0 / 5.0, 1e-12);  // prior information 4, the measurement's 1
  EXPECT_DOUBLE_EQ(near.bias(), plain.bias());
  // Further, it keeps huber_k * spread / |r| of it; the spread is its own and the prior's.
  GyroBiasFilter far(1e9, 0.5, 0.02, 10.0, 1.0);
  far.add(3.0, 0.0, 1.0);
  const double w = std::sqrt(1.0 + 0.25) / 3.0;
  EXPECT_NEAR(far.bias(), 3.0 * w / (4.0 + w), 1e-12);
  EXPECT_NEAR(far.sigma(), 1.0 / std::sqrt(4.0 + w), 1e-12);
  EXPECT_EQ(far.refused(), 0u);
  // A run of windows pulled one way by 1.8 among ones around the truth (0.2, spread 1): the
  // estimate stays nearer the truth than the plain weighted mean.
  GyroBiasFilter huber(1e9, 0.5, 0.02, 10.0, 1.0), mean(1e9, 0.5, 0.02, 10.0);
  const double m[] = {0.9, -0.5, 0.6, -0.2, -1.6, -1.6, -1.6, 0.4, 0.7, -0.1, 0.3, 0.5, 0.2, 0.6};
  for (double x : m) huber.add(x, 1.0, 1.0), mean.add(x, 1.0, 1.0);
  EXPECT_LT(std::abs(huber.bias() - 0.2), std::abs(mean.bias() - 0.2) - 0.03);
}

TEST(Imu, GyroBiasFilterWeighsByInformationThenForgetsSlowly) {
  GyroBiasFilter f(20.0, 0.5, 0.02, 1.0);
  EXPECT_DOUBLE_EQ(f.sigma(), 0.5);
  f.add(1.0, 0.0, 0.1);
  f.add(3.0, 0.0, 0.1);
  // Two equal measurements against the prior at 0 (spread 0.5): their mean, pulled by 1 / 51.
  EXPECT_NEAR(f.bias(), 2.0 * 200.0 / 204.0, 1e-12);
  EXPECT_NEAR(f.sigma(), 1.0 / std::sqrt(204.0), 1e-12);
  // A precise measurement (a standstill) outweighs them.
  f.add(1.5, 0.0, 0.01);
  EXPECT_NEAR(f.bias(), (2.0 * 200.0 / 204.0 * 204.0 + 1.5 * 1e4) / 10204.0, 1e-12);
  EXPECT_TRUE(f.add(2.0, 1.0, 0.1));
  EXPECT_FALSE(f.add(5.0, 1.0, 0.1));  // a jump: refused
  EXPECT_FALSE(f.add(2.0, 1.0, 0.0));  // no spread: refused
  EXPECT_EQ(f.refused(), 2u);
  for (int k = 0; k < 1000; ++k) f.add(2.0 * std::exp(-0.01 * k), 1.0, 0.1);
  EXPECT_NEAR(f.bias(), 0.0, 0.01);  // follows with the lag of tau (2 exp(-10) x 20 = 1.8e-3)
  // The information of tau / dt measurements: 1 / (0.1^2 (1 - exp(-1 / 20))).
  EXPECT_NEAR(f.sigma(), 0.1 * std::sqrt(1.0 - std::exp(-0.05)), 1e-9);
}
