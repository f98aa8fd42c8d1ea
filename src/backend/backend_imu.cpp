// The Backend's IMU fusion (Backend::enableImu): attitude filter, gyro prior, yaw-rate bias.
#include "backend_imu.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <vector>

namespace vwe_vo {

void Backend::enableImu(const ImuFusionOptions& options, const Pose3& T_cam_imu) {
  options.validate();
  imu_ = std::make_unique<Imu>(options, Pose3(T_base_cam_ * T_cam_imu));
  imu_->stats.yaw_bias_sigma_rad_s = imu_->bias.sigma();
}

const BackendImuStats& Backend::imuStats() const {
  imu_->stats.attitude = imu_->attitude.stats();
  imu_->stats.gyro_bias_base = imu_->attitude.bias();
  imu_->stats.tilt_in_pose = tiltInPose();
  return imu_->stats;
}

void Backend::addImu(const ImuSample& sample) {
  if (!imu_) return;
  ++imu_->stats.samples_in;
  if (!sample.gyro.allFinite() || !sample.accel.allFinite() || sample.t_ns < imu_->newest_ns) {
    ++imu_->stats.samples_dropped;
    return;
  }
  imu_->newest_ns = sample.t_ns;
  imu_->pending.push_back(rotateImuSample(sample, imu_->T_base_imu));
  // Bounded while no arcs arrive: what the arcs will never reach (older than the window) goes.
  const int64_t keep_ns = secToNs(options_.window_s + options_.update_interval_s + 5.0);
  while (imu_->pending.front().t_ns < sample.t_ns - keep_ns) imu_->pending.pop_front();
  if (dead_reckoning_) advanceImu();
}

Tilt Backend::tiltAt(int64_t t_ns) const {
  if (imu_) return imu_->tilts.at(t_ns);
  return tiltInPose() ? accelerationTiltAt(t_ns) : Tilt();
}

Pose3 Backend::withTilt(int64_t t_ns, const Pose3& T_planar) const {
  if (imu_ && imu_->tilts.empty()) return T_planar;
  Pose3 T = T_planar;
  T.linear() = T_planar.linear() * tiltAt(t_ns).rotation();
  return T;
}

int64_t Backend::accelerationSpan_ns() const {
  int64_t diff_ns = 100000000;
  if (!arcs_.empty()) diff_ns = std::max(diff_ns, arcs_.back().t_end_ns - arcs_.back().t_start_ns);
  return diff_ns;
}

bool Backend::vehicleMotionAt(int64_t t_ns, int64_t diff_ns, VehicleMotion* motion) const {
  if (!dead_reckoning_) return false;
  Pose3 T;
  double v = 0, w = 0, va = 0, vb = 0, unused = 0;
  const int64_t a = std::max(dead_reckoning_->startTime(), t_ns - diff_ns),
                b = std::min(newest_arc_ns_, t_ns + diff_ns);
  if (!planarPoseAt(t_ns, &T, &v, &w) || !planarPoseAt(a, &T, &va, &unused) ||
      !planarPoseAt(b, &T, &vb, &unused))
    return false;
  const double dt = dtSec(b, a);
  motion->v = v;
  motion->omega = w;
  motion->dv = dt > 0 ? (vb - va) / dt : 0.0;
  return true;
}

Tilt Backend::accelerationTiltAt(int64_t t_ns) const {
  // The quasi-static response of the suspension (its ride frequencies, ~1-1.5 Hz on a car, are
  // faster than the braking and steering): a pitch and a roll proportional to the longitudinal
  // and lateral accelerations.
  constexpr double kGravity = 9.80665;  // [m/s^2]
  Tilt tilt;
  VehicleMotion m;
  if (!vehicleMotionAt(t_ns, accelerationSpan_ns(), &m)) return tilt;
  tilt.pitch = -options_.pitch_per_g_deg / kDegPerRad * m.dv / kGravity;
  tilt.roll = options_.roll_per_g_deg / kDegPerRad * m.v * m.omega / kGravity;
  return tilt;
}

std::function<Mat3(int64_t)> Backend::tiltTable(int64_t t0_ns, int64_t t1_ns) const {
  constexpr int64_t kStep_ns = 10000000;  // the suspension's motion is slower than 100 Hz
  auto table = std::make_shared<TiltHistory>(kStep_ns, t1_ns - t0_ns + 2 * kStep_ns);
  for (int64_t t = t0_ns; t < t1_ns + kStep_ns; t += kStep_ns) table->add(t, tiltAt(t));
  return [table](int64_t t_ns) { return table->at(t_ns).rotation(); };
}

namespace {

/// The Euler yaw rate of a base_link sample, its x/y gyro bias removed (the z bias is the
/// back-end's) [rad/s].
double yawRateOf(const ImuSample& s, const Vec3& xy_bias, const Tilt& tilt) {
  const Vec3 gyro(s.gyro.x() - xy_bias.x(), s.gyro.y() - xy_bias.y(), s.gyro.z());
  return eulerYawRate(gyro, tilt.roll, tilt.pitch);
}

/// The first pending sample after t_ns.
std::deque<ImuSample>::const_iterator firstAfter(const std::deque<ImuSample>& pending,
                                                 int64_t t_ns) {
  return std::upper_bound(pending.begin(), pending.end(), t_ns,
                          [](int64_t t, const ImuSample& s) { return t < s.t_ns; });
}

}  // namespace

void Backend::advanceImu(bool to_newest) {
  Imu& m = *imu_;
  const int64_t t0 = dead_reckoning_ ? dead_reckoning_->startTime() : -1;
  constexpr int64_t kMotionStep_ns = 10000000;  // vehicle motion refreshed every 10 ms
  // dv: a central difference over at least 0.2 s, and over at least one arc on each side: the
  // arcs' speeds are constant per window, and a shorter difference across their steps gives
  // spikes of acceleration (a car braking at 0.3 g showed pitch errors of 2-3 deg). The attitude
  // filter runs that far behind the newest arc, so the difference is central: cut at the newest
  // arc, it lagged the car's braking and accelerating into pitch (street_drive with the IMU:
  // estimated pitch varying 0.96 deg RMS against the car's 0.24, tilt RPE 0.72 -> 0.28 deg/s).
  const int64_t diff_ns = accelerationSpan_ns();
  // The gyro's yaw rates (the back-end's prior) up to the newest arc, with the newest tilt; the
  // tilt moves little in diff_ns, and the Euler yaw rate barely depends on it.
  const Tilt tilt = m.attitude.tilt();
  for (auto it = firstAfter(m.pending, m.yaw_rates_until_ns);
       it != m.pending.end() && it->t_ns <= newest_arc_ns_; ++it) {
    m.yaw_rates.push_back({it->t_ns, yawRateOf(*it, m.attitude.bias(), tilt)});
    m.yaw_rates_until_ns = it->t_ns;
  }
  const int64_t attitude_until = to_newest ? newest_arc_ns_ : newest_arc_ns_ - diff_ns;
  while (!m.pending.empty() && m.pending.front().t_ns <= attitude_until) {
    const ImuSample s = m.pending.front();
    m.pending.pop_front();
    if (t0 >= 0 && s.t_ns >= t0 && (m.motion_ns < 0 || s.t_ns >= m.motion_ns + kMotionStep_ns)) {
      // The spline's (or the arcs') speed and yaw rate, with a central difference for dv; the
      // yaw rate is replaced by the gyro's below.
      vehicleMotionAt(s.t_ns, diff_ns, &m.motion);
      m.motion_ns = s.t_ns;
    }
    // The centripetal acceleration v omega with the gyro's yaw rate (bias removed): the
    // spline's is the events' estimate, degrees per second off along facades, which the
    // compensation would turn into roll.
    if (m.attitude.initialised()) {
      const Vec3& bias = m.attitude.bias();
      const Tilt tilt_before = m.attitude.tilt();
      m.motion.omega = eulerYawRate(s.gyro - bias, tilt_before.roll, tilt_before.pitch);
    }
    m.attitude.add(s, (t0 >= 0 && s.t_ns >= t0) ? m.motion : VehicleMotion());
    // Until the filter has its first tilt the history stays empty; it then holds that tilt
    // back over the samples that gave it.
    if (m.attitude.initialised()) m.tilts.add(s.t_ns, m.attitude.tilt());
  }
  const int64_t keep_ns = secToNs(options_.window_s + options_.update_interval_s + 1.0);
  while (!m.yaw_rates.empty() && m.yaw_rates.front().t_ns < newest_arc_ns_ - keep_ns)
    m.yaw_rates.pop_front();
}

std::unique_ptr<SplinePrior> Backend::makeGyroPrior(double u_window, double u_new, int first_free) {
  Imu& m = *imu_;
  if (m.options.gyro_prior_weight == 0.0 || m.yaw_rates.empty()) return nullptr;
  const double bin = m.options.gyro_bin_s;
  std::vector<GyroRatePrior::Bin> bins;
  auto it = m.yaw_rates.begin();
  for (double ua = u_window; ua + bin <= u_new + 1e-9; ua += bin) {
    const int64_t ta = spline_->epochNs() + secToNs(ua), tb = ta + secToNs(bin);
    while (it != m.yaw_rates.end() && it->t_ns < ta) ++it;
    double sum = 0.0;
    size_t n = 0;
    int64_t first = -1, last = -1;
    for (auto jt = it; jt != m.yaw_rates.end() && jt->t_ns < tb; ++jt, ++n) {
      sum += jt->rate;
      if (first < 0) first = jt->t_ns;
      last = jt->t_ns;
    }
    // Only bins the samples cover (at least 80 % of their length, two samples).
    if (n < 2 || dtSec(last, first) < 0.8 * bin * (double(n) - 1.0) / double(n)) continue;
    bins.push_back({ua, ua + bin, sum / double(n)});
  }
  if (bins.empty()) return nullptr;
  auto prior =
      std::make_unique<GyroRatePrior>(spline_, first_free, bins, m.options.gyro_prior_weight,
                                      m.options.gyro_noise_density_deg_s / kDegPerRad,
                                      m.bias.bias(), m.options.bias_sigma_min_deg_s / kDegPerRad,
                                      0.05, m.options.gyro_model_sigma_deg_s / kDegPerRad);
  m.stats.prior_bins += prior->numBins();
  return prior;
}

bool Backend::gyroMeanYawRate(int64_t a_ns, int64_t b_ns, double* omega) const {
  const Imu& m = *imu_;
  const Tilt tilt = m.attitude.tilt();
  double sum = 0.0;
  int n = 0;
  int64_t first = -1, last = -1;
  for (auto it = firstAfter(m.pending, a_ns - 1); it != m.pending.end() && it->t_ns <= b_ns; ++it) {
    sum += yawRateOf(*it, m.attitude.bias(), tilt);
    ++n;
    if (first < 0) first = it->t_ns;
    last = it->t_ns;
  }
  if (n < 2 || dtSec(last, first) < 0.8 * dtSec(b_ns, a_ns)) return false;
  *omega = sum / n - m.bias.bias();
  return true;
}

void Backend::updateGyroBias(const GyroRatePrior& gyro, int64_t t_new_ns,
                             double events_offset_rad_s) {
  Imu& m = *imu_;
  if (gyro.numBins() == 0) return;
  const double dt = m.last_bias_update_ns < 0 ? 0.0 : dtSec(t_new_ns, m.last_bias_update_ns);
  // In a held standstill the gyro alone measures the bias, to its white noise over the still
  // bins. Moving, the window's events do: the gyro against the spline (which the solve holds at
  // the gyro less the estimate) turned by the yaw-rate offset its volumes prefer, to about
  // bias_window_sigma_deg_s. The spline's offset alone measured the estimate it was held to: the
  // first window's error stayed for good (street_drive started at 2.3 s: 0.54 deg/s off).
  const double bin = m.options.gyro_bin_s, nd = m.options.gyro_noise_density_deg_s / kDegPerRad;
  double measured = gyro.measuredBias(), var = 0.0;
  if (gyro.measuresStandstill()) {
    var = nd * nd / (double(gyro.numStillBins()) * bin);
  } else {
    if (!std::isfinite(events_offset_rad_s)) return;
    measured -= events_offset_rad_s;
    const double sigma = m.options.bias_window_sigma_deg_s / kDegPerRad;
    var = sigma * sigma;
  }
  if (!m.bias.add(measured, dt, std::sqrt(var))) ++m.stats.bias_refused;
  m.last_bias_update_ns = t_new_ns;
  ++m.stats.bias_updates;
  m.stats.yaw_bias_rad_s = m.bias.bias();
  m.stats.yaw_bias_sigma_rad_s = m.bias.sigma();
  m.attitude.setYawBias(m.bias.bias());
}

}  // namespace vwe_vo
