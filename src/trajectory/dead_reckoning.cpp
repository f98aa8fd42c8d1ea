#include "vwe_vo/trajectory/dead_reckoning.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "vwe_vo/trajectory/ackermann_arc.h"

namespace vwe_vo {

Pose3 arcPropagate(const Pose3& T_odom_Vr, int64_t t_ref_ns, double omega, double v, int64_t t_ns) {
  return T_odom_Vr * arcT_Vr_Vt(omega, v, dtSec(t_ns, t_ref_ns));
}

ArcChain::ArcChain(const Pose3& T_odom_base_start, int64_t t_start_ns)
    : T_odom_start_(T_odom_base_start), t_start_ns_(t_start_ns) {}

void ArcChain::append(double omega, double v, int64_t t_end_ns) {
  const int64_t t0 = endTime();
  if (t_end_ns < t0) {
    throw std::invalid_argument("ArcChain::append: t_end_ns " + std::to_string(t_end_ns) +
                                " is before the chain's end time " + std::to_string(t0));
  }
  const Pose3 T_odom_V0 = segments_.empty()
                              ? T_odom_start_
                              : arcPropagate(segments_.back().T_odom_V0, segments_.back().t0_ns,
                                             segments_.back().omega, segments_.back().v, t0);
  segments_.push_back({t0, t_end_ns, omega, v, T_odom_V0});
}

Pose3 ArcChain::T_odom_base(int64_t t_ns) const {
  if (segments_.empty()) return T_odom_start_;
  // The first segment whose end is at or after t (the last one for t beyond the end).
  const auto it = std::lower_bound(segments_.begin(), segments_.end() - 1, t_ns,
                                   [](const Segment& s, int64_t t) { return s.t1_ns < t; });
  const Segment& s = *it;
  return arcPropagate(s.T_odom_V0, s.t0_ns, s.omega, s.v, t_ns);
}

void appendRamp(ArcChain* chain, const Rates& from, const Rates& to, int64_t t_end_ns, int pieces) {
  if (pieces < 1)
    throw std::invalid_argument("appendRamp: pieces " + std::to_string(pieces) + " < 1");
  const int64_t t0 = chain->endTime();
  for (int k = 0; k < pieces; ++k) {
    const Rates r = rampRates(from, to, (k + 0.5) / pieces);
    chain->append(r.omega, r.v, t0 + (t_end_ns - t0) * (k + 1) / pieces);
  }
}

Trajectory3 integrateRamps(const std::vector<TimedRates>& arcs, int64_t step_ns) {
  Trajectory3 out;
  if (arcs.empty() || step_ns <= 0) return out;
  // Rates at time t: ramping between consecutive reference times, constant beyond the ends.
  size_t k = 0;
  auto ratesAt = [&](int64_t t) {
    while (k + 1 < arcs.size() && arcs[k + 1].t_ref_ns <= t) ++k;
    const TimedRates& a = arcs[k];
    if (t <= a.t_ref_ns || k + 1 >= arcs.size()) return a.rates;
    const TimedRates& b = arcs[k + 1];
    return rampRates(a.rates, b.rates, double(t - a.t_ref_ns) / double(b.t_ref_ns - a.t_ref_ns));
  };
  const int64_t t0 = arcs.front().t_start_ns, t1 = arcs.back().t_end_ns;
  // One constant arc per step, at the rates of the step's middle (midpoint rule: second order).
  ArcChain chain(Pose3::Identity(), t0);
  out.push_back({t0, chain.T_odom_base(t0)});
  for (int64_t t = t0; t < t1;) {
    const int64_t tn = std::min(t1, t + step_ns);
    const Rates r = ratesAt(t + (tn - t) / 2);
    chain.append(r.omega, r.v, tn);
    out.push_back({tn, chain.T_odom_base(tn)});
    t = tn;
  }
  return out;
}

ArcDeadReckoning::ArcDeadReckoning(int64_t t_start_ns, bool interpolate_rates)
    : interpolate_rates_(interpolate_rates),
      steps_(Pose3::Identity(), t_start_ns),
      ramped_(Pose3::Identity(), t_start_ns) {}

void ArcDeadReckoning::append(const Rates& rates, bool standstill, int64_t from_ns,
                              int64_t t_ref_ns, int64_t t_end_ns) {
  steps_.append(rates.omega, rates.v, t_end_ns);
  if (!interpolate_rates_) {
    ramped_.append(rates.omega, rates.v, t_end_ns);
  } else if (standstill) {
    // The moving arc before keeps its rates to its end; the standstill holds the pose.
    if (has_last_rates_ && from_ns > ramped_.endTime())
      ramped_.append(last_.omega, last_.v, from_ns);
    ramped_.append(0.0, 0.0, t_end_ns);
    has_last_rates_ = false;
  } else {
    const int64_t t_ref = std::clamp(t_ref_ns, std::max(from_ns, ramped_.endTime()), t_end_ns);
    if (!has_last_rates_) {
      if (from_ns > ramped_.endTime()) ramped_.append(0.0, 0.0, from_ns);  // after a standstill
      ramped_.append(rates.omega, rates.v, t_ref);
    } else {
      appendRamp(&ramped_, last_, rates, t_ref, kRampPieces);
      // Empty: beyond its end the chain goes on at the arc's rates.
      ramped_.append(rates.omega, rates.v, t_ref);
    }
    last_ = rates;
    has_last_rates_ = true;
  }
}

Pose3 anchorOnSplinePose(const BSpline& spline, double u, const Pose3& T_dead_reckoned) {
  return spline.T_odom_base(u) * T_dead_reckoned.inverse();
}

Pose3 fitAnchorOnSpline(const BSpline& spline, const ArcChain& chain, int64_t t_end_ns,
                        double span_s) {
  const Pose3 T_end =
      anchorOnSplinePose(spline, spline.toSplineTime(t_end_ns), chain.T_odom_base(t_end_ns));
  const int64_t t_from = std::max({t_end_ns - secToNs(span_s), chain.startTime(),
                                   spline.epochNs() + secToNs(spline.validFrom())});
  constexpr int kSamples = 21;
  if (t_end_ns - t_from < secToNs(0.05)) return T_end;
  std::vector<Vec2> q(kSamples), p(kSamples);
  Vec2 qc = Vec2::Zero(), pc = Vec2::Zero();
  for (int k = 0; k < kSamples; ++k) {
    const int64_t t = t_from + (t_end_ns - t_from) * k / (kSamples - 1);
    q[k] = chain.T_odom_base(t).translation().head<2>();
    p[k] = spline.position(spline.toSplineTime(t));
    qc += q[k] / kSamples;
    pc += p[k] / kSamples;
  }
  double sxx = 0, sxy = 0, spread = 0;  // H = sum (q - qc)(p - pc)^T
  for (int k = 0; k < kSamples; ++k) {
    const Vec2 a = q[k] - qc, b = p[k] - pc;
    sxx += a.dot(b);
    sxy += a.x() * b.y() - a.y() * b.x();
    spread += a.squaredNorm();
  }
  if (spread / kSamples < 0.02 * 0.02) return T_end;  // moved less than ~2 cm: heading unknown
  const double theta = std::atan2(sxy, sxx);
  const Eigen::Rotation2Dd R(theta);
  // Position: through the pose at t_end (continuity there), rotation from the fit.
  const Vec2 q_end = chain.T_odom_base(t_end_ns).translation().head<2>();
  const Vec2 t = spline.position(spline.toSplineTime(t_end_ns)) - R * q_end;
  return makePose(rotZ(theta), Vec3(t.x(), t.y(), 0.0));
}

}  // namespace vwe_vo
