// The DAVIS346's IMU (InvenSense MPU-6150) as the estimator uses it: its mount T_cam_imu and the
// fusion options (YAML section imu:), samples rotated into base_link, and the attitude filter that
// gives the body's pitch and roll from gyro and accelerometer. ROS-free.
#pragma once

#include <cstdint>
#include <deque>
#include <string>
#include <vector>

#include "vwe_vo/common/math.h"
#include "vwe_vo/io/trajectory_io.h"

namespace vwe_vo {

struct ImuFusionOptions {
  // T_cam_imu maps IMU-frame vectors into the camera's optical frame. The DAVIS346 reports its
  // IMU in the camera's frame (the simulator and the ECD layout likewise): the identity.
  std::vector<double> T_cam_imu_translation = {0.0, 0.0, 0.0};           // [m]
  std::vector<double> T_cam_imu_quaternion_xyzw = {0.0, 0.0, 0.0, 1.0};  // unit quaternion
  // MPU-6150 product specification (PS-MPU-6150A, rev. 4.2): gyro rate noise spectral density
  // 0.005 deg/s/sqrt(Hz). Weights the gyro's yaw rate against the spline's.
  double gyro_noise_density_deg_s = 0.005;  // [deg/s/sqrt(Hz)]
  // Added in quadrature to each bin's white noise: what the spline cannot follow within a bin and
  // the bias's drift between filter and solve. Without it a 0.05 s bin's sigma (0.022 deg/s) makes
  // the gyro's shape override the volumes and leaves the bias free to take any yaw-rate offset.
  double gyro_model_sigma_deg_s = 0.1;  // [deg/s]
  double gyro_prior_weight = 1e-3;     // the gyro's yaw rate vs the normalised VWE, per bin and per
                                       // (residual / its noise)^2 (0: off) [1]
  double gyro_bin_s = 0.05;            // the gyro is compared with the spline's mean yaw rate over
                                       // bins of this length [s]
  double bias_time_constant_s = 20.0;  // slow filter of the refined windows' yaw-rate bias [s]
  double bias_sigma_deg_s = 0.5;       // prior spread of the yaw-rate bias before any estimate (the
                                       // simulated DAVIS's bound) [deg/s]
  double bias_sigma_min_deg_s = 0.005;  // each window's solve holds the bias at the filter's
                                        // estimate to this (a window's own fit let its events'
                                        // offset through); the filter's spread is at least this
  double bias_max_jump_deg_s = 1.5;     // a window's bias further from the estimate is refused:
                                        // past the offset scan's reach (+-2 window spreads)
  double bias_huber_k = 1.0;  // a window's bias further than this many spreads (its own and the
                              // filter's in quadrature) is down-weighted (Huber; 0: off) [1]
  // Moving, each refined window measures the bias as the gyro's offset from the yaw rate its
  // volumes prefer: the spline's new part is turned by yaw-rate offsets of +-1 and +-2 times
  // this and the contrast's peak found by a parabola. It is also the measurement's spread: the
  // events of one window place the yaw rate about this well (car.yaml: a street's facades pull
  // single windows by up to a few deg/s) [deg/s].
  double bias_window_sigma_deg_s = 0.5;
  double attitude_time_constant_s = 1.0;        // accelerometer correction of pitch and roll [s]
  double attitude_bias_time_constant_s = 10.0;  // integral (x/y gyro bias) of that correction [s]
  double max_accel_error_mps2 = 2.0;  // compensated specific force this far from |g|: the sample
                                      // does not correct the attitude [m/s^2]
  double gravity_mps2 = 9.80665;      // [m/s^2]
  /// Throws std::invalid_argument naming the field by its YAML key, section + "." + key.
  void validate(const std::string& section = "imu") const;
  Pose3 T_cam_imu() const;
};

/// A sample with gyro and specific force rotated into base_link (T_base_imu's rotation; the lever
/// arm is the attitude filter's).
ImuSample rotateImuSample(const ImuSample& s, const Pose3& T_base_imu);

/// Euler (Z-Y-X) yaw rate of base_link [rad/s] from its body rates w_base and roll, pitch.
double eulerYawRate(const Vec3& w_base, double roll, double pitch);

/// Roll (about x) and pitch (about y) of base_link w.r.t. gravity: R_odom_base = Rz(yaw) Ry(pitch)
/// Rx(roll).
struct Tilt {
  double roll = 0.0, pitch = 0.0;  // [rad]
  Mat3 rotation() const;           // Ry(pitch) Rx(roll)
};

/// The motion of base_link the accelerometer also measures, from the back-end's trajectory.
struct VehicleMotion {
  double v = 0.0;      // forward speed [m/s]
  double dv = 0.0;     // its derivative [m/s^2]
  double omega = 0.0;  // yaw rate [rad/s]
};

struct AttitudeStats {
  size_t samples = 0;
  size_t corrections_skipped = 0;  // |compensated specific force| too far from g
  size_t out_of_order = 0;         // older than the previous sample: dropped
  size_t gaps = 0;                 // more than 0.1 s after the previous one: integrated over 0
};

/// Complementary filter on SO(3) (Mahony, Hamel, Pflimlin, "Nonlinear complementary filters on
/// the special orthogonal group", IEEE TAC 2008, passive form with bias estimation): the
/// bias-corrected gyro integrates the attitude; the accelerometer, with the vehicle's own
/// acceleration removed (longitudinal dv, centripetal v * omega, and the IMU's lever arm
/// w x (w x r) + dw x r, dw from the gyro low-passed over kRateFilter_s), measures the direction of
/// gravity, which pulls the attitude with gain 1 / attitude_time_constant_s and estimates the x/y
/// gyro bias with an integral gain 1 / (attitude_time_constant_s * attitude_bias_time_constant_s).
/// The z bias (unobservable from gravity on level ground) is the back-end's (setYawBias). Yaw is
/// integrated but unused. The tilt starts from the mean specific force of the first
/// kInitWindow_s, the lever arm's mean dw x r (the change of the gyro over the window) removed: a
/// window as long as a car's slowest ride period (1-1.5 Hz, Gillespie, Fundamentals of Vehicle
/// Dynamics, ch. 5), whose pitching moves an IMU 1.4 m above the axle by tenths of m/s^2, and long
/// against the accelerometer's noise (one 1 kHz sample of an MPU-6150 class accelerometer is 0.7
/// deg off). Both time constants grow with the time since that first tilt: the proportional one
/// from a quarter of attitude_time_constant_s to it (over 4 of them), the integral's from 4 times
/// the proportional one (critically damped) to attitude_bias_time_constant_s, so an unknown bias
/// stops pulling the tilt off within seconds instead of tens of seconds.
class AttitudeFilter {
 public:
  static constexpr double kRateFilter_s = 0.05;  // low-pass of the gyro for dw [s]
  static constexpr double kInitWindow_s = 1.0;   // specific force averaged for the first tilt [s]
  /// lever_arm: the IMU's position in base_link [m].
  AttitudeFilter(const ImuFusionOptions& options, const Vec3& lever_arm);
  /// One sample in base_link (rotateImuSample), in time order, with the vehicle's motion then.
  void add(const ImuSample& s_base, const VehicleMotion& motion);
  bool initialised() const { return initialised_; }
  Tilt tilt() const;
  int64_t time() const { return t_ns_; }
  /// Gyro bias estimate in base_link [rad/s]: x, y from gravity, z as set.
  const Vec3& bias() const { return bias_; }
  void setYawBias(double bz) { bias_.z() = bz; }
  const AttitudeStats& stats() const { return stats_; }
  void reset();

 private:
  ImuFusionOptions options_;
  Vec3 lever_arm_;
  bool initialised_ = false;
  int64_t t_ns_ = 0;
  Mat3 R_ = Mat3::Identity();  // R_odom_base (yaw integrated, unused)
  Vec3 bias_ = Vec3::Zero();
  Vec3 w_lp_ = Vec3::Zero();          // low-passed gyro (angular acceleration for the lever arm)
  Vec3 g_init_sum_ = Vec3::Zero();    // specific force summed over the first kInitWindow_s
  int init_samples_ = 0;              // samples in g_init_sum_
  Vec3 w_init_first_ = Vec3::Zero();  // gyro at the window's first sample
  int64_t t_start_ns_ = -1;           // first sample
  int64_t t_first_tilt_ns_ = -1;      // end of the first kInitWindow_s: the gains' schedule starts
  AttitudeStats stats_;
};

/// Tilt history for the published poses: one entry every `step_ns`, linear in between, held
/// before the first and after the newest; entries older than max_age_ns behind the newest are
/// dropped.
class TiltHistory {
 public:
  explicit TiltHistory(int64_t step_ns = 5000000, int64_t max_age_ns = int64_t(3600) * 1000000000);
  void add(int64_t t_ns, const Tilt& tilt);
  bool empty() const { return entries_.empty(); }
  Tilt at(int64_t t_ns) const;
  int64_t newestTime() const { return entries_.empty() ? -1 : entries_.back().t_ns; }
  void clear() { entries_.clear(); }

 private:
  struct Entry {
    int64_t t_ns;
    Tilt tilt;
  };
  int64_t step_ns_, max_age_ns_;
  std::deque<Entry> entries_;
};

}  // namespace vwe_vo
