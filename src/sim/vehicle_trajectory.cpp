#include "vwe_vo/sim/vehicle_trajectory.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>

#include "vwe_vo/trajectory/ackermann_arc.h"

namespace vwe_vo {
namespace sim {

void VibrationOptions::validate() const {
  if (!(height_amplitude_m >= 0 && height_amplitude_m < 0.5))
    throw std::invalid_argument("vibration.height_amplitude_m must be in [0, 0.5)");
  if (!(pitch_amplitude_rad >= 0 && pitch_amplitude_rad < 0.5))
    throw std::invalid_argument("vibration.pitch_amplitude_rad must be in [0, 0.5)");
  if (!(roll_amplitude_rad >= 0 && roll_amplitude_rad < 0.5))
    throw std::invalid_argument("vibration.roll_amplitude_rad must be in [0, 0.5)");
  if (!(frequency_hz > 0 && frequency_hz < 200))
    throw std::invalid_argument("vibration.frequency_hz must be in (0, 200)");
}

bool ContinuousMotion::enabled() const {
  return !speed_sines.empty() || !speed_changes.empty() || !stops.empty() ||
         !curvature_sines.empty() || !lane_changes.empty() || !bends.empty();
}

void ContinuousMotion::validate() const {
  auto check = [](bool ok, const std::string& field, size_t i, const char* what) {
    if (!ok) throw std::invalid_argument("motion." + field + "[" + std::to_string(i) + "] " + what);
  };
  for (size_t i = 0; i < speed_sines.size(); ++i) {
    check(std::abs(speed_sines[i].relative_amplitude) < 1, "speed_sines", i,
          "relative_amplitude must be in (-1, 1)");
    check(speed_sines[i].period_s > 0, "speed_sines", i, "period_s must be > 0");
    check(std::isfinite(speed_sines[i].phase_rad), "speed_sines", i, "phase_rad must be finite");
  }
  for (size_t i = 0; i < speed_changes.size(); ++i) {
    check(speed_changes[i].duration_s > 0, "speed_changes", i, "duration_s must be > 0");
    check(std::isfinite(speed_changes[i].t_start_s), "speed_changes", i,
          "t_start_s must be finite");
    check(std::abs(speed_changes[i].relative_change) < 1, "speed_changes", i,
          "relative_change must be in (-1, 1)");
  }
  for (size_t i = 0; i < stops.size(); ++i) {
    check(std::isfinite(stops[i].t_start_s), "stops", i, "t_start_s must be finite");
    check(stops[i].brake_s > 0 && stops[i].go_s > 0 && stops[i].dwell_s >= 0, "stops", i,
          "needs brake_s > 0, go_s > 0, dwell_s >= 0");
  }
  for (size_t i = 0; i < curvature_sines.size(); ++i) {
    check(std::abs(curvature_sines[i].amplitude_per_m) < 1, "curvature_sines", i,
          "amplitude_per_m must be in (-1, 1)");
    check(curvature_sines[i].wavelength_m > 0, "curvature_sines", i, "wavelength_m must be > 0");
    check(std::isfinite(curvature_sines[i].phase_rad), "curvature_sines", i,
          "phase_rad must be finite");
  }
  for (size_t i = 0; i < lane_changes.size(); ++i) {
    check(lane_changes[i].length_m > 0, "lane_changes", i, "length_m must be > 0");
    check(std::isfinite(lane_changes[i].s_start_m) &&
              std::abs(lane_changes[i].lateral_m) < 0.5 * lane_changes[i].length_m,
          "lane_changes", i, "needs a finite s_start_m and |lateral_m| < length_m / 2");
  }
  for (size_t i = 0; i < bends.size(); ++i) {
    check(bends[i].clothoid_m > 0 && bends[i].arc_m >= 0, "bends", i,
          "needs clothoid_m > 0 and arc_m >= 0");
    check(std::isfinite(bends[i].s_start_m) && std::abs(bends[i].angle_rad) < 2 * kPi, "bends", i,
          "needs a finite s_start_m and |angle_rad| < 2 pi");
  }
}

void SuspensionOptions::validate() const {
  auto check = [](bool ok, const char* field, const char* what) {
    if (!ok) throw std::invalid_argument(std::string("suspension.") + field + " " + what);
  };
  check(road_gd_m3 >= 0 && road_gd_m3 < 1e-2, "road_gd_m3", "must be in [0, 1e-2)");
  check(road_n_min > 0 && road_n_max > road_n_min && road_n_max <= 100, "road_n_min",
        "and road_n_max need 0 < road_n_min < road_n_max <= 100");
  check(road_differential >= 0 && road_differential <= 4, "road_differential", "must be in [0, 4]");
  for (const RoadBump& b : bumps)
    check(std::isfinite(b.s_m) && b.length_m > 0 && std::abs(b.height_m) < 0.5 && b.side >= -1 &&
              b.side <= 1,
          "bumps", "need finite s_m, length_m > 0, |height_m| < 0.5, side in {-1, 0, 1}");
  check(wheelbase_m > 0 && wheelbase_m < 20, "wheelbase_m", "must be in (0, 20)");
  check(track_m > 0 && track_m < 10, "track_m", "must be in (0, 10)");
  check(heave_hz > 0 && heave_hz < 50, "heave_hz", "must be in (0, 50)");
  check(pitch_hz > 0 && pitch_hz < 50, "pitch_hz", "must be in (0, 50)");
  check(roll_hz > 0 && roll_hz < 50, "roll_hz", "must be in (0, 50)");
  check(damping_ratio > 0 && damping_ratio <= 2, "damping_ratio", "must be in (0, 2]");
  check(std::abs(pitch_per_g_rad) < 0.5, "pitch_per_g_rad", "must be in (-0.5, 0.5)");
  check(std::abs(roll_per_g_rad) < 0.5, "roll_per_g_rad", "must be in (-0.5, 0.5)");
}

void VehicleTrajectoryOptions::validate() const {
  if (!(table_step_s >= 1e-5 && table_step_s <= 0.01))
    throw std::invalid_argument("table_step_s must be in [1e-5, 0.01]");
  if (!(blend_s >= 0 && blend_s <= 10)) throw std::invalid_argument("blend_s must be in [0, 10]");
  if (!start_xyyaw.allFinite()) throw std::invalid_argument("start_xyyaw must be finite");
  vibration.validate();
  motion.validate();
  suspension.validate();
  if (suspension.enabled &&
      1.0 / table_step_s <
          20.0 * std::max({suspension.heave_hz, suspension.pitch_hz, suspension.roll_hz}))
    throw std::invalid_argument(
        "table_step_s too long for the suspension's natural frequencies (need 20 steps a period)");
}

namespace {
// 0 below -1/2, 1 above +1/2, C1-smooth and antisymmetric about 0 in between.
double smoothStep(double x) {
  if (x <= -0.5) return 0.0;
  if (x >= 0.5) return 1.0;
  const double s = x + 0.5;
  return s * s * (3.0 - 2.0 * s);
}

// 0 below 0, 1 above 1, a raised cosine in between (continuous first derivative at both ends
// of a velocity step: the acceleration is a half sine).
double raisedCosine(double x) {
  if (x <= 0.0) return 0.0;
  if (x >= 1.0) return 1.0;
  return 0.5 * (1.0 - std::cos(kPi * x));
}

constexpr double kGravity = 9.80665;  // standard gravity [m/s^2]

// A seeded road profile: a sum of cosines in distance whose variance per band follows the
// ISO 8608 displacement PSD Gd(n) = Gd(n0) (n / n0)^-2 (n0 = 0.1 cycles/m), log-spaced in n.
class RoadProfile {
 public:
  RoadProfile(double gd_m3, double n_min, double n_max, std::mt19937_64* rng) {
    constexpr int kComponents = 64;
    const double dlog = std::log(n_max / n_min) / (kComponents - 1);
    std::uniform_real_distribution<double> phase(0.0, 2.0 * kPi);
    for (int i = 0; i < kComponents; ++i) {
      const double n = n_min * std::exp(dlog * i);
      const double gd = gd_m3 * std::pow(n / 0.1, -2.0);
      // One-sided PSD: a cosine of amplitude A carries A^2 / 2 = Gd(n) dn of the variance.
      amplitude_.push_back(std::sqrt(2.0 * gd * n * dlog));
      k_.push_back(2.0 * kPi * n);
      phase_.push_back(phase(*rng));
    }
  }
  double height(double s_m) const {
    double h = 0.0;
    for (size_t i = 0; i < k_.size(); ++i) h += amplitude_[i] * std::cos(k_[i] * s_m + phase_[i]);
    return h;
  }

 private:
  std::vector<double> amplitude_, k_, phase_;
};

Mat3 suspensionRotation(double pitch, double roll) {
  return (Eigen::AngleAxisd(pitch, Vec3::UnitY()) * Eigen::AngleAxisd(roll, Vec3::UnitX()))
      .toRotationMatrix();
}
}  // namespace

double VehicleTrajectory::speedAt(double t_s) const {
  const double v = profileValue(t_s, true);
  const ContinuousMotion& m = options_.motion;
  if (!m.enabled()) return v;
  double factor = 1.0;
  for (const SpeedSine& q : m.speed_sines)
    factor += q.relative_amplitude * std::sin(2.0 * kPi * t_s / q.period_s + q.phase_rad);
  for (const SpeedChange& c : m.speed_changes)
    factor += c.relative_change * raisedCosine((t_s - c.t_start_s) / c.duration_s);
  for (const StopEvent& st : m.stops) {
    const double t_go = st.t_start_s + st.brake_s + st.dwell_s;
    if (t_s < t_go)
      factor *= 1.0 - raisedCosine((t_s - st.t_start_s) / st.brake_s);
    else
      factor *= raisedCosine((t_s - t_go) / st.go_s);
  }
  return v * std::max(0.0, factor);
}

double VehicleTrajectory::curvature(double s_m) const {
  const ContinuousMotion& m = options_.motion;
  double kappa = 0.0;
  for (const CurvatureSine& c : m.curvature_sines)
    kappa += c.amplitude_per_m * std::sin(2.0 * kPi * s_m / c.wavelength_m + c.phase_rad);
  for (const LaneChange& l : m.lane_changes) {
    const double x = (s_m - l.s_start_m) / l.length_m;
    // Lateral offset of the doublet (small angles): A L^2 / (2 pi).
    if (x > 0.0 && x < 1.0)
      kappa += 2.0 * kPi * l.lateral_m / (l.length_m * l.length_m) * std::sin(2.0 * kPi * x);
  }
  for (const Bend& b : m.bends) {
    const double k = b.angle_rad / (b.clothoid_m + b.arc_m);
    const double x = s_m - b.s_start_m;
    if (x <= 0.0) continue;
    if (x < b.clothoid_m)
      kappa += k * x / b.clothoid_m;
    else if (x < b.clothoid_m + b.arc_m)
      kappa += k;
    else if (x < 2.0 * b.clothoid_m + b.arc_m)
      kappa += k * (2.0 * b.clothoid_m + b.arc_m - x) / b.clothoid_m;
  }
  return kappa;
}

double VehicleTrajectory::yawRateAt(double t_s, double s_m) const {
  if (!options_.motion.enabled()) return profileValue(t_s, false);
  return profileValue(t_s, false) + speedAt(t_s) * curvature(s_m);
}

double VehicleTrajectory::profileValue(double t_s, bool want_v) const {
  double value = want_v ? segments_[0].v : segments_[0].omega;
  double boundary = segments_[0].duration_s;
  for (size_t i = 1; i < segments_.size(); ++i) {
    const double prev = want_v ? segments_[i - 1].v : segments_[i - 1].omega;
    const double next = want_v ? segments_[i].v : segments_[i].omega;
    const double w = options_.blend_s > 0 ? smoothStep((t_s - boundary) / options_.blend_s)
                                          : (t_s >= boundary ? 1.0 : 0.0);
    value += (next - prev) * w;
    boundary += segments_[i].duration_s;
  }
  return value;
}

VehicleTrajectory VehicleTrajectory::fromProfile(const std::vector<ProfileSegment>& segments,
                                                 const VehicleTrajectoryOptions& options) {
  options.validate();
  if (segments.empty()) throw std::invalid_argument("VehicleTrajectory: no profile segments");
  double total = 0.0;
  for (size_t i = 0; i < segments.size(); ++i) {
    const auto& s = segments[i];
    if (!(s.duration_s > 0) || !std::isfinite(s.v) || !std::isfinite(s.omega) || s.v < 0)
      throw std::invalid_argument("VehicleTrajectory: segment " + std::to_string(i) +
                                  " needs duration_s > 0, v >= 0 and finite omega");
    total += s.duration_s;
  }
  VehicleTrajectory tr;
  tr.segments_ = segments;
  tr.options_ = options;
  tr.step_ns_ = secToNs(options.table_step_s);
  tr.duration_ns_ = secToNs(total);
  const size_t n = static_cast<size_t>(tr.duration_ns_ / tr.step_ns_) + 2;
  tr.table_.resize(n);
  double x = options.start_xyyaw.x(), y = options.start_xyyaw.y(), yaw = options.start_xyyaw.z();
  const double h = nsToSec(tr.step_ns_);
  double dist = 0.0;
  for (size_t k = 0; k < n; ++k) {
    const double t = nsToSec(static_cast<int64_t>(k) * tr.step_ns_);
    Sample& s = tr.table_[k];
    s.x = x;
    s.y = y;
    s.yaw = yaw;
    s.s = dist;
    s.v = tr.speedAt(t);
    s.omega = tr.yawRateAt(t, dist);
    // Midpoint values: the arc over the step is accurate to O(h^3) per step.
    s.v_step = tr.speedAt(t + 0.5 * h);
    s.omega_step = tr.yawRateAt(t + 0.5 * h, dist + 0.5 * h * s.v_step);
    dist += s.v_step * h;
    const Vec2 d = arcT_Vr_Vt(s.omega_step, s.v_step, h).translation().head<2>();
    const double c = std::cos(yaw), sn = std::sin(yaw);
    x += c * d.x() - sn * d.y();
    y += sn * d.x() + c * d.y();
    yaw = wrapAngle(yaw + s.omega_step * h);
    if (static_cast<int64_t>(k) * tr.step_ns_ < tr.duration_ns_) tr.path_length_ += s.v_step * h;
  }
  if (options.suspension.enabled) tr.integrateSuspension();
  return tr;
}

void VehicleTrajectory::integrateSuspension() {
  const SuspensionOptions& o = options_.suspension;
  std::mt19937_64 rng(o.seed);
  const RoadProfile mean(o.road_gd_m3, o.road_n_min, o.road_n_max, &rng);
  const RoadProfile diff(o.road_gd_m3 * o.road_differential, o.road_n_min, o.road_n_max, &rng);
  // Height under the left (side +1) or right (-1) track at distance s.
  auto road = [&](double s_m, int side) {
    double z = mean.height(s_m) + 0.5 * side * diff.height(s_m);
    for (const RoadBump& b : o.bumps) {
      const double x = (s_m - b.s_m) / b.length_m;
      if ((b.side == 0 || b.side == side) && x > 0.0 && x < 1.0)
        z += b.height_m * 0.5 * (1.0 - std::cos(2.0 * kPi * x));
    }
    return z;
  };
  const double h = nsToSec(step_ns_);
  const double w[3] = {2 * kPi * o.heave_hz, 2 * kPi * o.pitch_hz, 2 * kPi * o.roll_hz};
  // Static attitude the body settles to: base_link at the rear axle, the front axle wheelbase_m
  // ahead.
  auto target = [&](size_t k, double u[3]) {
    const Sample& s = table_[k];
    const double t = nsToSec(static_cast<int64_t>(k) * step_ns_), e = 1e-4;
    const double a_long = (speedAt(t + e) - speedAt(t - e)) / (2 * e);
    const double a_lat = s.v * s.omega;
    const double rl = road(s.s, 1), rr = road(s.s, -1), fl = road(s.s + o.wheelbase_m, 1),
                 fr = road(s.s + o.wheelbase_m, -1);
    u[0] = 0.25 * (rl + rr + fl + fr);
    // Pitch > 0 is nose down (rotation about +y): front higher pitches up; braking dives.
    u[1] = 0.5 * ((rl + rr) - (fl + fr)) / o.wheelbase_m - o.pitch_per_g_rad * a_long / kGravity;
    // Roll > 0 raises the left side: left higher rolls positive; a left turn rolls the body out
    // (right).
    u[2] = 0.5 * ((rl + fl) - (rr + fr)) / o.track_m + o.roll_per_g_rad * a_lat / kGravity;
  };
  suspension_.resize(table_.size());
  double q[3], qd[3] = {0, 0, 0}, u[3];
  target(0, q);  // start settled
  for (size_t k = 0; k < table_.size(); ++k) {
    for (int c = 0; c < 3; ++c) suspension_[k].q[c] = q[c], suspension_[k].qd[c] = qd[c];
    target(k, u);
    // Damped second-order response, semi-implicit Euler (stable for w h << 1).
    for (int c = 0; c < 3; ++c) {
      qd[c] += h * (w[c] * w[c] * (u[c] - q[c]) - 2.0 * o.damping_ratio * w[c] * qd[c]);
      q[c] += h * qd[c];
    }
  }
  // Positions consistent with the rates for the cubic Hermite interpolation: with
  // q_k+1 - q_k = h (qd_k + qd_k+1) / 2 its second derivative is constant over each step
  // (the exact acceleration of the step) instead of swinging between 4 and -2 times it.
  for (size_t k = 1; k < suspension_.size(); ++k)
    for (int c = 0; c < 3; ++c)
      suspension_[k].q[c] =
          suspension_[k - 1].q[c] + 0.5 * h * (suspension_[k - 1].qd[c] + suspension_[k].qd[c]);
}

void VehicleTrajectory::suspensionAt(int64_t t_ns, double q[3], double qd[3], double qdd[3]) const {
  size_t k;
  double d;
  locate(t_ns, &k, &d);
  const double h = nsToSec(step_ns_), x = d / h, x2 = x * x, x3 = x2 * x;
  const SuspensionSample &a = suspension_[k], &b = suspension_[k + 1];
  for (int c = 0; c < 3; ++c) {
    const double p0 = a.q[c], m0 = a.qd[c] * h, p1 = b.q[c], m1 = b.qd[c] * h;
    q[c] = (2 * x3 - 3 * x2 + 1) * p0 + (x3 - 2 * x2 + x) * m0 + (-2 * x3 + 3 * x2) * p1 +
           (x3 - x2) * m1;
    qd[c] = ((6 * x2 - 6 * x) * p0 + (3 * x2 - 4 * x + 1) * m0 + (-6 * x2 + 6 * x) * p1 +
             (3 * x2 - 2 * x) * m1) /
            h;
    qdd[c] =
        ((12 * x - 6) * p0 + (6 * x - 4) * m0 + (-12 * x + 6) * p1 + (6 * x - 2) * m1) / (h * h);
  }
}

double VehicleTrajectory::distance(int64_t t_ns) const {
  if (!from_profile_)
    throw std::logic_error("VehicleTrajectory::distance: needs a profile trajectory");
  size_t k;
  double d;
  locate(t_ns, &k, &d);
  return table_[k].s + table_[k].v_step * d;
}

SuspensionState VehicleTrajectory::suspension(int64_t t_ns) const {
  if (suspension_.empty()) return {};
  double q[3], qd[3], qdd[3];
  suspensionAt(t_ns, q, qd, qdd);
  return {q[0], q[1], q[2]};
}

BaseKinematics VehicleTrajectory::kinematics(int64_t t_ns) const {
  const VibrationOptions& vib = options_.vibration;
  if (!from_profile_ || vib.height_amplitude_m > 0 || vib.pitch_amplitude_rad > 0 ||
      vib.roll_amplitude_rad > 0)
    throw std::logic_error(
        "VehicleTrajectory::kinematics: needs a profile trajectory without vibration");
  t_ns = std::clamp<int64_t>(t_ns, 0, duration_ns_);
  BaseKinematics out;
  out.T_odom_base = T_odom_base(t_ns);
  const double t = nsToSec(t_ns), s = distance(t_ns), e = 1e-4;
  const double v = speedAt(t), w = yawRateAt(t, s);
  // The profiles are smooth functions of time: central differences are exact to O(e^2).
  const double v_dot = (speedAt(t + e) - speedAt(t - e)) / (2 * e);
  const double w_dot = (yawRateAt(t + e, s + v * e) - yawRateAt(t - e, s - v * e)) / (2 * e);
  const double yaw = planar(t_ns).z();
  const Mat3 R_P = Eigen::AngleAxisd(yaw, Vec3::UnitZ()).toRotationMatrix();
  out.a_odom = R_P * Vec3(v_dot, v * w, 0.0);
  if (suspension_.empty()) {
    out.omega_B = Vec3(0, 0, w);
    out.alpha_B = Vec3(0, 0, w_dot);
    return out;
  }
  double q[3], qd[3], qdd[3];
  suspensionAt(t_ns, q, qd, qdd);
  // Body rotation R_s = R_y(pitch) R_x(roll) on the planar pose: body-frame rates.
  const Mat3 Rx_T = Eigen::AngleAxisd(-q[2], Vec3::UnitX()).toRotationMatrix();
  const Mat3 Rs_T = suspensionRotation(q[1], q[2]).transpose();
  const Vec3 omega_s = Rx_T * Vec3::UnitY() * qd[1] + Vec3::UnitX() * qd[2];
  const Vec3 alpha_s = Rx_T * Vec3::UnitY() * qdd[1] - qd[2] * qd[1] * (Rx_T * Vec3::UnitZ()) +
                       Vec3::UnitX() * qdd[2];
  const Vec3 z_B = Rs_T * Vec3::UnitZ();
  out.omega_B = z_B * w + omega_s;
  out.alpha_B = z_B * w_dot - omega_s.cross(z_B) * w + alpha_s;
  // Heave is along the vertical, which the planar rotation keeps.
  out.a_odom += Vec3(0, 0, qdd[0]);
  return out;
}

VehicleTrajectory VehicleTrajectory::fromTum(const Trajectory3& tum,
                                             const VehicleTrajectoryOptions& options) {
  options.validate();
  if (tum.size() < 2)
    throw std::invalid_argument("VehicleTrajectory: a TUM trajectory needs at least 2 poses");
  VehicleTrajectory tr;
  tr.from_profile_ = false;
  tr.options_ = options;
  const int64_t t0 = tum.front().t_ns;
  for (const auto& p : tum) tr.tum_.push_back({p.t_ns - t0, p.T});
  tr.duration_ns_ = tr.tum_.back().t_ns;
  for (size_t i = 1; i < tr.tum_.size(); ++i)
    tr.path_length_ +=
        (tr.tum_[i].T.translation() - tr.tum_[i - 1].T.translation()).head<2>().norm();
  return tr;
}

void VehicleTrajectory::locate(int64_t t_ns, size_t* k, double* d_s) const {
  t_ns = std::clamp<int64_t>(t_ns, 0, duration_ns_);
  *k = std::min(static_cast<size_t>(t_ns / step_ns_), table_.size() - 2);
  *d_s = nsToSec(t_ns - static_cast<int64_t>(*k) * step_ns_);
}

Vec3 VehicleTrajectory::planar(int64_t t_ns) const {
  if (!from_profile_) {
    Pose3 T;
    interpolateTrajectory(tum_, std::clamp<int64_t>(t_ns, 0, duration_ns_), &T);
    return Vec3(T.translation().x(), T.translation().y(), yawOf(T.linear()));
  }
  size_t k;
  double d;
  locate(t_ns, &k, &d);
  const Sample& s = table_[k];
  const Vec2 dp = arcT_Vr_Vt(s.omega_step, s.v_step, d).translation().head<2>();
  const double c = std::cos(s.yaw), sn = std::sin(s.yaw);
  return Vec3(s.x + c * dp.x() - sn * dp.y(), s.y + sn * dp.x() + c * dp.y(),
              wrapAngle(s.yaw + s.omega_step * d));
}

Pose3 VehicleTrajectory::T_odom_base(int64_t t_ns) const {
  if (!from_profile_) {
    Pose3 T;
    interpolateTrajectory(tum_, std::clamp<int64_t>(t_ns, 0, duration_ns_), &T);
    return T;
  }
  const Vec3 p = planar(t_ns);
  Pose3 T = planarPose(p.x(), p.y(), p.z());
  const VibrationOptions& vib = options_.vibration;
  if (!suspension_.empty()) {
    const SuspensionState b = suspension(t_ns);
    T = T * makePose(suspensionRotation(b.pitch_rad, b.roll_rad), Vec3(0, 0, b.heave_m));
  }
  if (vib.height_amplitude_m > 0 || vib.pitch_amplitude_rad > 0 || vib.roll_amplitude_rad > 0) {
    const double w = 2.0 * kPi * vib.frequency_hz * nsToSec(t_ns);
    // Two incommensurate tones per axis: irregular but smooth.
    const double z = vib.height_amplitude_m * (0.7 * std::sin(w) + 0.3 * std::sin(2.31 * w + 1.0));
    const double pitch =
        vib.pitch_amplitude_rad * (0.7 * std::sin(1.13 * w + 0.5) + 0.3 * std::sin(2.87 * w + 2.0));
    const double roll =
        vib.roll_amplitude_rad * (0.7 * std::sin(0.91 * w + 1.7) + 0.3 * std::sin(3.41 * w + 0.3));
    const Mat3 R =
        (Eigen::AngleAxisd(pitch, Vec3::UnitY()) * Eigen::AngleAxisd(roll, Vec3::UnitX()))
            .toRotationMatrix();
    T = T * makePose(R, Vec3(0, 0, z));
  }
  return T;
}

double VehicleTrajectory::speed(int64_t t_ns) const {
  if (from_profile_) return speedAt(nsToSec(std::clamp<int64_t>(t_ns, 0, duration_ns_)));
  const int64_t h = 5000000;
  const int64_t a = std::max<int64_t>(0, t_ns - h), b = std::min(duration_ns_, t_ns + h);
  if (b <= a) return 0.0;
  const Vec3 pa = planar(a), pb = planar(b);
  const Vec2 d = (pb - pa).head<2>();
  // Signed: forward along the mean heading.
  const double yaw = pa.z() + 0.5 * wrapAngle(pb.z() - pa.z());
  return (d.x() * std::cos(yaw) + d.y() * std::sin(yaw)) / dtSec(b, a);
}

double VehicleTrajectory::yawRate(int64_t t_ns) const {
  if (from_profile_) {
    t_ns = std::clamp<int64_t>(t_ns, 0, duration_ns_);
    return yawRateAt(nsToSec(t_ns), options_.motion.enabled() ? distance(t_ns) : 0.0);
  }
  const int64_t h = 5000000;
  const int64_t a = std::max<int64_t>(0, t_ns - h), b = std::min(duration_ns_, t_ns + h);
  if (b <= a) return 0.0;
  return wrapAngle(planar(b).z() - planar(a).z()) / dtSec(b, a);
}

Trajectory3 VehicleTrajectory::sample(int64_t step_ns) const {
  if (step_ns <= 0) throw std::invalid_argument("VehicleTrajectory::sample: step_ns must be > 0");
  Trajectory3 out;
  for (int64_t t = 0; t <= duration_ns_; t += step_ns) out.push_back({t, T_odom_base(t)});
  if (out.back().t_ns != duration_ns_) out.push_back({duration_ns_, T_odom_base(duration_ns_)});
  return out;
}

}  // namespace sim
}  // namespace vwe_vo
