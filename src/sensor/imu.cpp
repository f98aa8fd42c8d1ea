#include "vwe_vo/sensor/imu.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace vwe_vo {

void ImuFusionOptions::validate(const std::string& section) const {
  auto fail = [&](const std::string& m) { throw std::invalid_argument(section + "." + m); };
  if (T_cam_imu_translation.size() != 3) fail("T_cam_imu.translation must have 3 entries");
  for (double v : T_cam_imu_translation)
    if (!(std::isfinite(v) && std::abs(v) <= 10)) fail("T_cam_imu.translation must be within 10 m");
  if (T_cam_imu_quaternion_xyzw.size() != 4) fail("T_cam_imu.quaternion_xyzw must have 4 entries");
  double n2 = 0.0;
  for (double v : T_cam_imu_quaternion_xyzw) n2 += v * v;
  if (!(std::abs(std::sqrt(n2) - 1.0) <= 1e-3))
    fail("T_cam_imu.quaternion_xyzw must be a unit quaternion");
  if (!(gyro_noise_density_deg_s > 0 && gyro_noise_density_deg_s < 10))
    fail("gyro_noise_density_deg_s must be in (0, 10) deg/s/sqrt(Hz)");
  if (!(gyro_model_sigma_deg_s >= 0 && gyro_model_sigma_deg_s <= 10))
    fail("gyro_model_sigma_deg_s must be in [0, 10] deg/s");
  if (!(gyro_prior_weight >= 0 && std::isfinite(gyro_prior_weight)))
    fail("gyro_prior_weight must be >= 0");
  if (!(gyro_bin_s >= 0.002 && gyro_bin_s <= 1)) fail("gyro_bin_s must be in [0.002, 1] s");
  if (!(bias_time_constant_s > 0 && bias_time_constant_s <= 1e5))
    fail("bias_time_constant_s must be in (0, 1e5] s");
  if (!(bias_sigma_deg_s > 0 && bias_sigma_deg_s <= 100))
    fail("bias_sigma_deg_s must be in (0, 100] deg/s");
  if (!(bias_sigma_min_deg_s > 0 && bias_sigma_min_deg_s <= bias_sigma_deg_s))
    fail("bias_sigma_min_deg_s must be in (0, bias_sigma_deg_s] deg/s");
  if (!(bias_max_jump_deg_s > 0 && bias_max_jump_deg_s <= 100))
    fail("bias_max_jump_deg_s must be in (0, 100] deg/s");
  if (!(bias_huber_k >= 0 && bias_huber_k <= 100)) fail("bias_huber_k must be in [0, 100]");
  if (!(bias_window_sigma_deg_s > 0 && bias_window_sigma_deg_s <= 10))
    fail("bias_window_sigma_deg_s must be in (0, 10] deg/s");
  if (!(attitude_time_constant_s > 0.01 && attitude_time_constant_s <= 1000))
    fail("attitude_time_constant_s must be in (0.01, 1000] s");
  if (!(attitude_bias_time_constant_s > 0.01 && attitude_bias_time_constant_s <= 1e5))
    fail("attitude_bias_time_constant_s must be in (0.01, 1e5] s");
  if (!(max_accel_error_mps2 > 0 && max_accel_error_mps2 <= 100))
    fail("max_accel_error_mps2 must be in (0, 100] m/s^2");
  if (!(gravity_mps2 > 1 && gravity_mps2 < 20)) fail("gravity_mps2 must be in (1, 20) m/s^2");
}

Pose3 ImuFusionOptions::T_cam_imu() const {
  const std::vector<double>& q = T_cam_imu_quaternion_xyzw;
  const std::vector<double>& t = T_cam_imu_translation;
  const Quat quat = Quat(q.at(3), q.at(0), q.at(1), q.at(2)).normalized();
  return makePose(quat.toRotationMatrix(), Vec3(t.at(0), t.at(1), t.at(2)));
}

ImuSample rotateImuSample(const ImuSample& s, const Pose3& T_base_imu) {
  ImuSample out = s;
  out.gyro = T_base_imu.linear() * s.gyro;
  out.accel = T_base_imu.linear() * s.accel;
  return out;
}

double eulerYawRate(const Vec3& w, double roll, double pitch) {
  // Z-Y-X Euler rates: psi' = (sin(roll) w_y + cos(roll) w_z) / cos(pitch).
  return (std::sin(roll) * w.y() + std::cos(roll) * w.z()) / std::cos(pitch);
}

Mat3 Tilt::rotation() const {
  return (Eigen::AngleAxisd(pitch, Vec3::UnitY()) * Eigen::AngleAxisd(roll, Vec3::UnitX()))
      .toRotationMatrix();
}

// ---------------------------------------------------------------------------------------------

AttitudeFilter::AttitudeFilter(const ImuFusionOptions& options, const Vec3& lever_arm)
    : options_(options), lever_arm_(lever_arm) {
  options_.validate();
}

void AttitudeFilter::reset() {
  initialised_ = false;
  R_.setIdentity();
  w_lp_.setZero();
  g_init_sum_.setZero();
  init_samples_ = 0;
  t_start_ns_ = -1;
  t_first_tilt_ns_ = -1;
  const double bz = bias_.z();
  bias_.setZero();
  bias_.z() = bz;
}

Tilt AttitudeFilter::tilt() const {
  Tilt t;
  t.pitch = -std::asin(std::max(-1.0, std::min(1.0, R_(2, 0))));
  t.roll = std::atan2(R_(2, 1), R_(2, 2));
  return t;
}

void AttitudeFilter::add(const ImuSample& s, const VehicleMotion& m) {
  if (!s.gyro.allFinite() || !s.accel.allFinite()) return;
  if (initialised_ && s.t_ns < t_ns_) {
    ++stats_.out_of_order;
    return;
  }
  ++stats_.samples;
  const Vec3 w = s.gyro - bias_;
  // The angular acceleration: the derivative of the low-passed gyro, (w - w_lp) / tau.
  const double dt_lp = initialised_ ? std::min(dtSec(s.t_ns, t_ns_), 0.1) : 0.0;
  if (!initialised_) w_lp_ = w;
  w_lp_ += std::min(1.0, dt_lp / kRateFilter_s) * (w - w_lp_);
  const Vec3 dw = (w - w_lp_) / kRateFilter_s;
  // Specific force expected without gravity, in base_link: the vehicle's acceleration in its
  // heading frame (dv forward, v omega to the left) tilted into the body, plus the lever arm's.
  const Vec3 a_heading(m.dv, m.v * m.omega, 0.0);
  const Tilt tilt_now = tilt();
  const Vec3 a_body = tilt_now.rotation().transpose() * a_heading + w.cross(w.cross(lever_arm_)) +
                      dw.cross(lever_arm_);
  const Vec3 g_meas = s.accel - a_body;  // = R^T (0, 0, g)
  const double g = options_.gravity_mps2;
  if (!initialised_) {
    // dw is 0 here (w_lp_ = w): over the window, the mean of the lever arm's dw x r is the
    // change of w over its length, which the first tilt subtracts from the mean specific force.
    if (t_start_ns_ < 0 || s.t_ns < t_start_ns_)
      t_start_ns_ = s.t_ns, g_init_sum_.setZero(), init_samples_ = 0, w_init_first_ = w;
    g_init_sum_ += g_meas;
    ++init_samples_;
    t_ns_ = s.t_ns;
    const double window = dtSec(s.t_ns, t_start_ns_);
    if (window < kInitWindow_s) return;
    const Vec3 dw_mean = (w - w_init_first_) / window;
    const Vec3 f = (g_init_sum_ / double(init_samples_) - dw_mean.cross(lever_arm_)).normalized();
    Tilt t0;
    t0.roll = std::atan2(f.y(), f.z());
    t0.pitch = std::atan2(-f.x(), std::hypot(f.y(), f.z()));
    R_ = t0.rotation();
    initialised_ = true;
    t_first_tilt_ns_ = s.t_ns;
    return;
  }
  double dt = dtSec(s.t_ns, t_ns_);
  if (dt > 0.1) {
    ++stats_.gaps;
    dt = 0.0;
  }
  t_ns_ = s.t_ns;
  Vec3 e = Vec3::Zero();
  if (std::abs(g_meas.norm() - g) <= options_.max_accel_error_mps2) {
    const Vec3 v_meas = g_meas.normalized();
    const Vec3 v_est = R_.transpose() * Vec3::UnitZ();
    e = v_meas.cross(v_est);
  } else {
    ++stats_.corrections_skipped;
  }
  // Both time constants grow with the time since the first tilt: the proportional one from a
  // quarter of attitude_time_constant_s, the integral one from 4 times that (critically damped) up
  // to attitude_bias_time_constant_s.
  const double elapsed = dtSec(s.t_ns, t_first_tilt_ns_),
               tau_final = options_.attitude_time_constant_s;
  const double tau = std::clamp(0.25 * elapsed, 0.25 * tau_final, tau_final);
  const double kp = 1.0 / tau;
  const double tau_b =
      std::clamp(elapsed, std::min(4.0 * tau, options_.attitude_bias_time_constant_s),
                 options_.attitude_bias_time_constant_s);
  const double ki = kp / tau_b;
  // The z bias is the back-end's: gravity observes it only through the tilt.
  bias_.x() -= ki * e.x() * dt;
  bias_.y() -= ki * e.y() * dt;
  const Vec3 w_corr = w + kp * e;
  const double angle = w_corr.norm() * dt;
  if (angle > 0) R_ = R_ * Eigen::AngleAxisd(angle, w_corr.normalized()).toRotationMatrix();
  // Re-orthonormalise (drift of the repeated products).
  const Eigen::Quaterniond q(R_);
  R_ = q.normalized().toRotationMatrix();
}

// ---------------------------------------------------------------------------------------------

TiltHistory::TiltHistory(int64_t step_ns, int64_t max_age_ns)
    : step_ns_(std::max<int64_t>(1, step_ns)), max_age_ns_(max_age_ns) {}

void TiltHistory::add(int64_t t_ns, const Tilt& tilt) {
  if (!entries_.empty() && t_ns < entries_.back().t_ns + step_ns_) return;
  entries_.push_back({t_ns, tilt});
  while (entries_.front().t_ns < t_ns - max_age_ns_) entries_.pop_front();
}

Tilt TiltHistory::at(int64_t t_ns) const {
  if (entries_.empty()) return Tilt();
  if (t_ns <= entries_.front().t_ns) return entries_.front().tilt;
  if (t_ns >= entries_.back().t_ns) return entries_.back().tilt;
  // Uniform-ish spacing: binary search.
  size_t lo = 0, hi = entries_.size() - 1;
  while (hi - lo > 1) {
    const size_t mid = (lo + hi) / 2;
    (entries_[mid].t_ns <= t_ns ? lo : hi) = mid;
  }
  const Entry &a = entries_[lo], &b = entries_[hi];
  const double f = double(t_ns - a.t_ns) / double(b.t_ns - a.t_ns);
  Tilt t;
  t.roll = a.tilt.roll + f * (b.tilt.roll - a.tilt.roll);
  t.pitch = a.tilt.pitch + f * (b.tilt.pitch - a.tilt.pitch);
  return t;
}

}  // namespace vwe_vo
