// The IMU's state inside the Backend (Backend::enableImu); private to src/backend.
#pragma once

#include <deque>
#include <memory>

#include "vwe_vo/backend/backend.h"
#include "vwe_vo/backend/gyro_prior.h"
#include "vwe_vo/sensor/imu.h"

namespace vwe_vo {

struct Backend::Imu {
  Imu(const ImuFusionOptions& o, const Pose3& T_base_imu_)
      : options(o),
        T_base_imu(T_base_imu_),
        attitude(o, T_base_imu_.translation()),
        bias(o.bias_time_constant_s, o.bias_sigma_deg_s / kDegPerRad,
             o.bias_sigma_min_deg_s / kDegPerRad, o.bias_max_jump_deg_s / kDegPerRad,
             o.bias_huber_k) {}
  /// After a reset of the back-end: the samples and the attitude start again, the bias (a property
  /// of the sensor) is kept.
  void reset() {
    pending.clear();
    yaw_rates.clear();
    yaw_rates_until_ns = -1;
    attitude.reset();
    tilts.clear();
    motion_ns = -1;
  }
  struct YawRate {
    int64_t t_ns;
    double rate;  // Euler yaw rate of the gyro (x/y bias removed, z bias not) [rad/s]
  };
  ImuFusionOptions options;
  Pose3 T_base_imu;
  std::deque<ImuSample> pending;  // in base_link, not yet in the attitude filter
  int64_t newest_ns = -1;
  std::deque<YawRate> yaw_rates;    // of the last window (GyroRatePrior bins)
  int64_t yaw_rates_until_ns = -1;  // the newest sample in yaw_rates
  AttitudeFilter attitude;
  TiltHistory tilts;
  GyroBiasFilter bias;
  int64_t last_bias_update_ns = -1;
  // The vehicle's motion for the accelerometer, refreshed every 10 ms.
  int64_t motion_ns = -1;
  VehicleMotion motion;
  BackendImuStats stats;
};

}  // namespace vwe_vo
