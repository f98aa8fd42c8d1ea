#include "vwe_vo/frontend/ground_yaw.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "vwe_vo/sensor/subsample.h"
#include "vwe_vo/trajectory/ackermann_arc.h"

namespace vwe_vo {

void GroundYawOptions::validate(const std::string& section) const {
  auto fail = [&](const std::string& m) { throw std::invalid_argument(section + "." + m); };
  if (!(weight >= 0 && weight <= 1)) fail("weight must be in [0, 1] (0: off)");
  objective.validate(section);
  if (max_events < 100) fail("max_events must be at least 100");
  if (min_events > max_events) fail("min_events must not exceed max_events");
  if (!(step_rad_s > 0)) fail("step_rad_s must be positive");
  if (!(half_range_rad_s >= step_rad_s && half_range_rad_s <= 1.0))
    fail("half_range_rad_s must be in [step_rad_s, 1] rad/s");
  if (!(std::abs(pitch_per_g_rad) <= 0.5)) fail("pitch_per_g_rad must be in [-0.5, 0.5]");
  if (!(pitch_step_deg > 0)) fail("pitch_step_deg must be positive");
  if (!(pitch_half_range_deg >= 0 && pitch_half_range_deg <= 5))
    fail("pitch_half_range_deg must be in [0, 5] deg");
  if (!(pitch_rate_step_deg_s > 0)) fail("pitch_rate_step_deg_s must be positive");
  if (!(pitch_rate_half_range_deg_s >= 0 && pitch_rate_half_range_deg_s <= 30))
    fail("pitch_rate_half_range_deg_s must be in [0, 30] deg/s");
  if (pitch_rounds < 0 || pitch_rounds > 10) fail("pitch_rounds must be in [0, 10]");
  if (num_threads < 1 || num_threads > 64) fail("num_threads must be in [1, 64]");
}

namespace {
Pose3 pitched(double pitch) {
  Pose3 T = Pose3::Identity();
  T.linear() = Eigen::AngleAxisd(pitch, Vec3::UnitY()).toRotationMatrix();
  return T;
}
}  // namespace

PitchedArcModel::PitchedArcModel(double omega, double v, int64_t t_ref_ns, const Pose3& T_base_cam,
                                 double pitch, double pitch_rate)
    : omega_(omega),
      v_(v),
      t_ref_ns_(t_ref_ns),
      T_base_cam_(T_base_cam),
      pitch_(pitch),
      pitch_rate_(pitch_rate) {
  T_ref_inv_ = T_ground_cam(t_ref_ns).inverse();
}

Pose3 PitchedArcModel::T_ground_cam(int64_t t_ns) const {
  const double dt = dtSec(t_ns, t_ref_ns_);
  return arcT_Vr_Vt(omega_, v_, dt) * pitched(pitch_ + pitch_rate_ * dt) * T_base_cam_;
}

Pose3 PitchedArcModel::T_Cr_Ct(int64_t t_ns, PoseJacobian* jac) const {
  if (jac) throw std::logic_error("PitchedArcModel: poses only");
  return T_ref_inv_ * T_ground_cam(t_ns);
}

GroundPlane PitchedArcModel::groundInReference() const {
  // z = 0 of the road frame: e_z . (R X + t) = 0 for X in the reference camera.
  const Pose3 T = T_ref_inv_.inverse();
  GroundPlane plane;
  plane.n = T.linear().transpose() * Vec3::UnitZ();
  plane.h = T.translation().z();
  return plane;
}

GroundYaw::GroundYaw(const GroundYawOptions& options, const CameraModel& camera,
                     const Pose3& T_base_cam)
    : options_(options), T_base_cam_(T_base_cam), pool_(options.num_threads) {
  options_.validate("frontend.ground");
  for (int i = 0; i < pool_.numThreads(); ++i)
    objectives_.push_back(
        std::make_unique<GroundObjective>(options_.objective, camera, T_base_cam));
}

std::vector<double> GroundYaw::evaluate(const std::vector<Params>& params) {
  std::vector<double> f(params.size());
  pool_.run(int(params.size()), [&](int i, int thread) {
    const Params& p = params[size_t(i)];
    const PitchedArcModel model(p.omega, v_, t_ref_ns_, T_base_cam_, p.pitch, p.pitch_rate);
    f[size_t(i)] = objectives_[size_t(thread)]->evaluate(events_, model, model.groundInReference());
  });
  evaluations_ += int(params.size());
  return f;
}

GroundYawEstimate GroundYaw::estimate(const EventVector& events, int64_t t0_ns, int64_t t1_ns,
                                      int64_t t_ref_ns, double v, double dv, double omega_center,
                                      uint64_t seed) {
  GroundYawEstimate out;
  evaluations_ = 0;
  const EventVector road = objectives_.front()->groundEvents(events);
  if (road.size() < options_.min_events) return out;
  constexpr int kTimeSlices = 10;
  const PitchedArcModel everywhere(0.0, v, t_ref_ns, T_base_cam_, 0.0, 0.0);
  events_ = objectives_.front()->prepare(
      subsampleEventsPerTimeSlice(road, t0_ns, t1_ns, options_.max_events, kTimeSlices, seed),
      everywhere);
  t_ref_ns_ = t_ref_ns;
  v_ = v;
  constexpr double kGravity = 9.80665;  // [m/s^2]
  const double dive = -options_.pitch_per_g_rad * dv / kGravity;
  Params best{omega_center, dive, 0.0};
  double best_f = -1.0;
  // Points of one coordinate c in [lo, hi] every step, the others at best; the best kept.
  auto search = [&](double Params::*c, double center, double half, double step) {
    const int k = std::max(1, int(std::floor(half / step + 1e-9)));
    std::vector<Params> ps;
    for (int i = -k; i <= k; ++i) {
      Params p = best;
      p.*c = center + i * step;
      ps.push_back(p);
    }
    const std::vector<double> f = evaluate(ps);
    const size_t i = size_t(std::max_element(f.begin(), f.end()) - f.begin());
    if (f[i] > best_f) best_f = f[i], best = ps[i];
    return std::make_pair(ps, f);
  };
  // The yaw rate coarse (four fine steps) over the range, then fine around the best.
  const double fine = options_.step_rad_s;
  search(&Params::omega, omega_center, options_.half_range_rad_s, 4 * fine);
  search(&Params::omega, best.omega, 3 * fine, fine);
  for (int r = 0; r < options_.pitch_rounds; ++r) {
    search(&Params::pitch, dive, options_.pitch_half_range_deg * kRadPerDeg,
           options_.pitch_step_deg * kRadPerDeg);
    search(&Params::pitch_rate, 0.0, options_.pitch_rate_half_range_deg_s * kRadPerDeg,
           options_.pitch_rate_step_deg_s * kRadPerDeg);
    search(&Params::omega, best.omega, 8 * fine, fine);
  }
  // The parabola's vertex through the best yaw rate and its neighbours.
  const auto [ps, f] = search(&Params::omega, best.omega, fine, fine);
  double omega = best.omega;
  const double curvature = f[0] - 2 * f[1] + f[2];
  if (curvature < 0)
    omega = ps[1].omega + fine * std::clamp(0.5 * (f[0] - f[2]) / curvature, -1.0, 1.0);
  out.valid = true;
  out.omega = omega;
  out.pitch = best.pitch;
  out.pitch_rate = best.pitch_rate;
  out.contrast = best_f;
  out.events = events_.size();
  out.evaluations = evaluations_;
  return out;
}

}  // namespace vwe_vo
