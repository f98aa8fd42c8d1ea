#include "vwe_vo/frontend/ground_yaw.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <utility>

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
  if (!(std::abs(roll_per_g_rad) <= 0.5)) fail("roll_per_g_rad must be in [-0.5, 0.5]");
  if (pitch_rounds < 0 || pitch_rounds > 20) fail("pitch_rounds must be in [0, 20]");
  if (num_threads < 1 || num_threads > 64) fail("num_threads must be in [1, 64]");
}

PitchedArcModel::PitchedArcModel(double omega, double v, int64_t t_ref_ns, const Pose3& T_base_cam,
                                 double pitch, double pitch_rate, double roll)
    : omega_(omega),
      v_(v),
      t_ref_ns_(t_ref_ns),
      T_base_cam_(T_base_cam),
      pitch_(pitch),
      pitch_rate_(pitch_rate),
      roll_(roll) {
  T_ref_inv_ = T_ground_cam(t_ref_ns).inverse();
}

Pose3 PitchedArcModel::T_ground_cam(int64_t t_ns) const {
  // arc(t) Ry(pitch(t)) Rx(roll) T_base_cam as 3x3 products (once per pose slice of every
  // evaluation, rather than 4x4 transforms): each rotation mixes two columns.
  const double dt = dtSec(t_ns, t_ref_ns_);
  const Pose3 A = arcT_Vr_Vt(omega_, v_, dt);
  Mat3 M = A.linear();
  auto mix = [&M](int i, int j, double angle) {  // M times the rotation taking e_i towards e_j
    const double c = std::cos(angle), s = std::sin(angle);
    const Vec3 mi = M.col(i), mj = M.col(j);
    M.col(i) = c * mi + s * mj;
    M.col(j) = c * mj - s * mi;
  };
  mix(2, 0, pitch_ + pitch_rate_ * dt);  // Ry = [c 0 s; 0 1 0; -s 0 c]
  if (roll_ != 0.0) mix(1, 2, roll_);    // Rx
  return makePose(M * T_base_cam_.linear(), M * T_base_cam_.translation() + A.translation());
}

Pose3 PitchedArcModel::T_Cr_Ct(int64_t t_ns, PoseJacobian* jac) const {
  if (jac) throw std::logic_error("PitchedArcModel: poses only");
  const Pose3 T = T_ground_cam(t_ns);
  return makePose(T_ref_inv_.linear() * T.linear(),
                  T_ref_inv_.linear() * T.translation() + T_ref_inv_.translation());
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
    const PitchedArcModel model(p.omega, v_, t_ref_ns_, T_base_cam_, p.pitch, p.pitch_rate, p.roll);
    f[size_t(i)] = objectives_[size_t(thread)]->evaluate(events_, model, model.groundInReference());
  });
  evaluations_ += int(params.size());
  return f;
}

GroundYawEstimate GroundYaw::estimate(const EventVector& events, int64_t t0_ns, int64_t t1_ns,
                                      int64_t t_ref_ns, double v, double dv, double omega_center,
                                      uint64_t seed, double omega_prior) {
  GroundYawEstimate out;
  evaluations_ = 0;
  objectives_.front()->groundEvents(events, &road_);
  if (road_.size() < options_.min_events) return out;
  constexpr int kTimeSlices = 10;
  const PitchedArcModel everywhere(0.0, v, t_ref_ns, T_base_cam_, 0.0, 0.0);
  events_ = objectives_.front()->prepare(
      subsampleEventsPerTimeSlice(road_, t0_ns, t1_ns, options_.max_events, kTimeSlices, seed),
      everywhere);
  t_ref_ns_ = t_ref_ns;
  v_ = v;
  constexpr double kGravity = 9.80665;  // [m/s^2]
  const double dive = -options_.pitch_per_g_rad * dv / kGravity;
  auto lean = [&](double omega) { return options_.roll_per_g_rad * v * omega / kGravity; };
  Params best{omega_center, dive, 0.0, lean(omega_center)};
  double best_f = -1.0;
  std::pair<std::vector<Params>, std::vector<double>> last_omega;  // the last yaw-rate search
  // Points of one coordinate c within center +- half every step, the others at best; the best
  // kept. Over four or more steps each side every second point first, then the best one's two
  // neighbours (the contrast is smooth over two steps: a third fewer evaluations).
  auto search = [&](double Params::*c, double center, double half, double step) {
    const int k = std::max(1, int(std::floor(half / step + 1e-9)));
    const int stride = k >= 4 ? 2 : 1;
    const Params base = best;
    auto at = [&](int i) {
      Params p = base;
      p.*c = center + i * step;
      return p;
    };
    std::vector<Params> ps;
    std::vector<int> index;
    for (int i = -k; i <= k; i += stride) ps.push_back(at(i)), index.push_back(i);
    std::vector<double> f = evaluate(ps);
    size_t b = size_t(std::max_element(f.begin(), f.end()) - f.begin());
    if (stride > 1) {
      std::vector<Params> more;
      std::vector<int> more_index;
      for (int i : {index[b] - 1, index[b] + 1})
        if (i >= -k && i <= k) more.push_back(at(i)), more_index.push_back(i);
      const std::vector<double> g = evaluate(more);
      for (size_t j = 0; j < g.size(); ++j)
        ps.push_back(more[j]), index.push_back(more_index[j]), f.push_back(g[j]);
      b = size_t(std::max_element(f.begin(), f.end()) - f.begin());
    }
    if (f[b] > best_f) best_f = f[b], best = ps[b];
    if (c == &Params::omega) last_omega = {std::move(ps), std::move(f)};
  };
  // The yaw rate coarse (four fine steps) over the range, then fine around the best. Where the
  // VWE's yaw rate jumped away from the previous window's (a full scan that found a spurious peak:
  // a near corner, a facade seen edge-on), the range around the previous one is searched too, and
  // the road's contrast chooses.
  const double fine = options_.step_rad_s, half = options_.half_range_rad_s;
  search(&Params::omega, omega_center, half, 4 * fine);
  if (std::abs(omega_prior - omega_center) > half) {  // false for NaN
    const double near_center = best_f;
    search(&Params::omega, omega_prior, half, 4 * fine);
    if (best_f > near_center) {  // the lean of the yaw rate found
      best.roll = lean(best.omega);
      best_f = -1.0;
    }
  }
  search(&Params::omega, best.omega, 3 * fine, fine);
  // Pitch, pitch rate and yaw rate in turn until none of them moves: on the road an error of the
  // pitch is nearly undone by one of the pitch rate of the same sign (~2.5 deg/s per deg), so the
  // best lies along a ridge that each search climbs by a step or two (two rounds stopped short of
  // it on a pitching body). A search whose points and other coordinates are as at its last run
  // would find the same point: it is skipped (the yaw rate's points follow its best, so a move of
  // its own runs it again).
  int moves = 0, pitch_seen = -1, rate_seen = -1, omega_seen = -1;
  auto searchIfMoved = [&](int* seen, double Params::*c, double center, double half, double step) {
    if (*seen == moves) return;
    const double before = best.*c;
    search(c, center, half, step);
    const bool moved = best.*c != before;
    moves += moved;
    *seen = moved && c == &Params::omega ? -1 : moves;
  };
  for (int r = 0; r < options_.pitch_rounds; ++r) {
    const int moves_before = moves;
    searchIfMoved(&pitch_seen, &Params::pitch, dive, options_.pitch_half_range_deg * kRadPerDeg,
                  options_.pitch_step_deg * kRadPerDeg);
    searchIfMoved(&rate_seen, &Params::pitch_rate, 0.0,
                  options_.pitch_rate_half_range_deg_s * kRadPerDeg,
                  options_.pitch_rate_step_deg_s * kRadPerDeg);
    searchIfMoved(&omega_seen, &Params::omega, best.omega, 8 * fine, fine);
    if (r > 0 && moves == moves_before) break;
  }
  // The yaw rate at the vertex of the parabola fitted (least squares) to the last yaw-rate search,
  // which ran at the final pitch and pitch rate around the best: over +-8 steps it averages the
  // contrast's ripple, which moves the best point of a broad peak (28 street_drive windows, 12
  // subsamples each: 0.19 deg/s RMS apart, the 3-point parabola through the best point 0.22).
  double omega = best.omega, curvature = 0.0;
  {
    Eigen::Matrix3d AtA = Eigen::Matrix3d::Zero();
    Eigen::Vector3d Atf = Eigen::Vector3d::Zero();
    double lo = 0.0, hi = 0.0;
    for (size_t i = 0; i < last_omega.first.size(); ++i) {
      const double x = (last_omega.first[i].omega - best.omega) / fine;
      const Eigen::Vector3d r(1.0, x, x * x);
      AtA += r * r.transpose();
      Atf += r * (last_omega.second[i] / best_f);
      lo = std::min(lo, x), hi = std::max(hi, x);
    }
    const Eigen::Vector3d q = AtA.ldlt().solve(Atf);
    if (last_omega.first.size() >= 3 && q[2] < 0 && q.allFinite()) {
      omega = best.omega + fine * std::clamp(-q[1] / (2 * q[2]), lo, hi);
      curvature = -2 * q[2] / (fine * fine);
    }
  }
  out.valid = true;
  out.omega = omega;
  out.pitch = best.pitch;
  out.pitch_rate = best.pitch_rate;
  out.roll = best.roll;
  out.contrast = best_f;
  out.curvature = curvature;
  out.apart = std::abs(omega - omega_center) > half;
  out.near_prior = std::abs(omega - omega_prior) <= half;  // false for NaN
  out.events = events_.size();
  out.evaluations = evaluations_;
  return out;
}

double GroundYaw::share(const GroundYawEstimate& road) const {
  if (!road.valid || !(road.curvature > 0)) return 0.0;
  if (road.apart) return road.near_prior ? 1.0 : 0.0;
  return options_.weight;
}

}  // namespace vwe_vo
