#include "vwe_vo/sim/imu_simulator.h"

#include <cmath>
#include <stdexcept>
#include <string>

namespace vwe_vo {
namespace sim {

double ImuOptions::gyroSigma() const {
  return gyro_noise_density * std::sqrt(rate_hz);
}
double ImuOptions::accelSigma() const {
  return accel_noise_density * std::sqrt(rate_hz);
}

void ImuOptions::validate() const {
  auto check = [](bool ok, const char* field, const char* what) {
    if (!ok) throw std::invalid_argument(std::string("ImuOptions.") + field + " " + what);
  };
  check(rate_hz > 0 && rate_hz <= 10000, "rate_hz", "must be in (0, 10000]");
  check(gyro_noise_density >= 0 && gyro_noise_density < 1, "gyro_noise_density",
        "must be in [0, 1)");
  check(accel_noise_density >= 0 && accel_noise_density < 10, "accel_noise_density",
        "must be in [0, 10)");
  check(gyro_bias_max >= 0 && gyro_bias_max < 1, "gyro_bias_max", "must be in [0, 1)");
  check(gravity > 0 && gravity < 20, "gravity", "must be in (0, 20)");
}

ImuSimulator::ImuSimulator(const VehicleTrajectory& trajectory, const Pose3& T_base_cam,
                           const ImuOptions& options)
    : trajectory_(trajectory), T_base_cam_(T_base_cam), options_(options), rng_(options.seed) {
  options_.validate();
  period_ns_ = secToNs(1.0 / options_.rate_hz);
  std::uniform_real_distribution<double> u(-options_.gyro_bias_max, options_.gyro_bias_max);
  gyro_bias_.x() = u(rng_);
  gyro_bias_.y() = u(rng_);
  gyro_bias_.z() = u(rng_);
}

ImuSample ImuSimulator::truth(int64_t t_ns) const {
  const BaseKinematics k = trajectory_.kinematics(t_ns);
  const Mat3& R_odom_base = k.T_odom_base.linear();
  const Mat3& R_base_cam = T_base_cam_.linear();
  const Vec3& r_B = T_base_cam_.translation();
  // Camera origin p_C = p_B + R_B r: a_C = a_B + R_B (alpha x r + omega x (omega x r)).
  const Vec3 a_C =
      k.a_odom + R_odom_base * (k.alpha_B.cross(r_B) + k.omega_B.cross(k.omega_B.cross(r_B)));
  ImuSample s;
  s.t_ns = t_ns;
  s.gyro = R_base_cam.transpose() * k.omega_B;
  // Specific force: R^T (a - g) with g = (0, 0, -gravity) in odom (z up).
  s.accel = (R_odom_base * R_base_cam).transpose() * (a_C + Vec3(0, 0, options_.gravity));
  return s;
}

ImuSample ImuSimulator::measure(int64_t t_ns) {
  ImuSample s = truth(t_ns);
  const double sg = options_.gyroSigma(), sa = options_.accelSigma();
  for (int i = 0; i < 3; ++i) s.gyro(i) += gyro_bias_(i) + sg * n01_(rng_);
  for (int i = 0; i < 3; ++i) s.accel(i) += sa * n01_(rng_);
  return s;
}

}  // namespace sim
}  // namespace vwe_vo
