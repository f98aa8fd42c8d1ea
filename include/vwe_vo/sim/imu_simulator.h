// A DAVIS346-like IMU (InvenSense MPU-6150 class): gyro and accelerometer in the camera frame
// (T_cam_imu = identity) from the exact derivatives of the simulated 6-DoF motion, with gravity,
// white noise from the datasheet's noise densities and a constant seeded gyro bias.
#pragma once

#include <cstdint>
#include <random>

#include "vwe_vo/common/math.h"
#include "vwe_vo/io/trajectory_io.h"
#include "vwe_vo/sim/vehicle_trajectory.h"

namespace vwe_vo {
namespace sim {

struct ImuOptions {
  double rate_hz = 1000.0;  // sample rate [Hz] (the DAVIS driver publishes the MPU's 1 kHz)
  // MPU-6150 product specification (PS-MPU-6150A, rev. 4.2): gyro rate noise spectral density
  // 0.005 deg/s/sqrt(Hz), accelerometer noise power spectral density 400 ug/sqrt(Hz).
  double gyro_noise_density = 0.005 * kPi / 180.0;  // [rad/s/sqrt(Hz)]
  double accel_noise_density = 400e-6 * 9.80665;    // [m/s^2/sqrt(Hz)]
  double gyro_bias_max =
      0.5 * kPi / 180.0;     // per-axis constant bias, uniform in [-max, max] [rad/s]
  double gravity = 9.80665;  // [m/s^2]
  uint64_t seed = 1;
  /// Standard deviations of one sample: density * sqrt(rate) (white noise sampled at rate_hz).
  double gyroSigma() const;
  double accelSigma() const;
  void validate() const;
};

class ImuSimulator {
 public:
  ImuSimulator(const VehicleTrajectory& trajectory, const Pose3& T_base_cam,
               const ImuOptions& options = {});
  /// Noise-free angular velocity and specific force R_odom_cam^T (a - g) in the camera frame at t.
  ImuSample truth(int64_t t_ns) const;
  /// The next measurement (truth + bias + noise); call with increasing times.
  ImuSample measure(int64_t t_ns);
  const Vec3& gyroBias() const { return gyro_bias_; }
  int64_t periodNs() const { return period_ns_; }

 private:
  const VehicleTrajectory& trajectory_;
  Pose3 T_base_cam_;
  ImuOptions options_;
  Vec3 gyro_bias_;
  int64_t period_ns_;
  std::mt19937_64 rng_;
  std::normal_distribution<double> n01_{0.0, 1.0};
};

}  // namespace sim
}  // namespace vwe_vo
