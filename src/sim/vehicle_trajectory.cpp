#include "vwe_vo/sim/vehicle_trajectory.h"

#include <algorithm>
#include <cmath>
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

void VehicleTrajectoryOptions::validate() const {
  if (!(table_step_s >= 1e-5 && table_step_s <= 0.01))
    throw std::invalid_argument("table_step_s must be in [1e-5, 0.01]");
  if (!(blend_s >= 0 && blend_s <= 10)) throw std::invalid_argument("blend_s must be in [0, 10]");
  if (!start_xyyaw.allFinite()) throw std::invalid_argument("start_xyyaw must be finite");
  vibration.validate();
}

namespace {
// 0 below -1/2, 1 above +1/2, C1-smooth and antisymmetric about 0 in between.
double smoothStep(double x) {
  if (x <= -0.5) return 0.0;
  if (x >= 0.5) return 1.0;
  const double s = x + 0.5;
  return s * s * (3.0 - 2.0 * s);
}
}  // namespace

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
  for (size_t k = 0; k < n; ++k) {
    const double t = nsToSec(static_cast<int64_t>(k) * tr.step_ns_);
    Sample& s = tr.table_[k];
    s.x = x;
    s.y = y;
    s.yaw = yaw;
    s.v = tr.profileValue(t, true);
    s.omega = tr.profileValue(t, false);
    // Midpoint values: the arc over the step is accurate to O(h^3) per step.
    s.v_step = tr.profileValue(t + 0.5 * h, true);
    s.omega_step = tr.profileValue(t + 0.5 * h, false);
    const Vec2 d = arcT_Vr_Vt(s.omega_step, s.v_step, h).translation().head<2>();
    const double c = std::cos(yaw), sn = std::sin(yaw);
    x += c * d.x() - sn * d.y();
    y += sn * d.x() + c * d.y();
    yaw = wrapAngle(yaw + s.omega_step * h);
    if (static_cast<int64_t>(k) * tr.step_ns_ < tr.duration_ns_) tr.path_length_ += s.v_step * h;
  }
  return tr;
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
  if (from_profile_) return profileValue(nsToSec(std::clamp<int64_t>(t_ns, 0, duration_ns_)), true);
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
  if (from_profile_)
    return profileValue(nsToSec(std::clamp<int64_t>(t_ns, 0, duration_ns_)), false);
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
