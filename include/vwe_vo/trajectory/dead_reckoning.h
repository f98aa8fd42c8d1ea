// Dead reckoning of base_link from the front-end's arcs: the chain of constant-rate arcs, the one
// rule for the rates between two arcs (linear between their middles), and re-anchoring a dead
// reckoning on a refined spline. The front-end, the back-end and frontend_node all use these.
#pragma once

#include <cstdint>
#include <vector>

#include "vwe_vo/common/math.h"
#include "vwe_vo/trajectory/bspline.h"
#include "vwe_vo/trajectory/stamped_trajectory.h"

namespace vwe_vo {

/// Dead reckoning along one arc: the pose of base_link in odom at t_ns, given its pose
/// T_odom_Vr at the arc's reference time t_ref_ns.
Pose3 arcPropagate(const Pose3& T_odom_Vr, int64_t t_ref_ns, double omega, double v, int64_t t_ns);

/// Dead reckoning along a chain of arcs: starting from T_odom_base at t_start_ns, each
/// appended arc (omega, v) runs from the previous end time to its own end time. Poses before
/// the start or after the end extrapolate the first / last arc.
class ArcChain {
 public:
  ArcChain(const Pose3& T_odom_base_start, int64_t t_start_ns);
  /// Appends an arc from endTime() to t_end_ns; throws std::invalid_argument if
  /// t_end_ns < endTime().
  void append(double omega, double v, int64_t t_end_ns);
  Pose3 T_odom_base(int64_t t_ns) const;
  int64_t startTime() const { return t_start_ns_; }
  int64_t endTime() const { return segments_.empty() ? t_start_ns_ : segments_.back().t1_ns; }
  size_t numArcs() const { return segments_.size(); }

 private:
  struct Segment {
    int64_t t0_ns, t1_ns;
    double omega, v;
    Pose3 T_odom_V0;  // pose at t0_ns, the arc's reference
  };
  Pose3 T_odom_start_;
  int64_t t_start_ns_;
  std::vector<Segment> segments_;
};

/// Yaw rate [rad/s] and speed [m/s].
struct Rates {
  double omega = 0.0, v = 0.0;
};

/// The ramp rule: an arc is the mean rate over its window, i.e. the rate at its middle, so
/// between the middles of two arcs the rates are linear. Rates a fraction s in [0, 1] of the way
/// from a's middle to b's.
inline Rates rampRates(const Rates& a, const Rates& b, double s) {
  return {(1 - s) * a.omega + s * b.omega, (1 - s) * a.v + s * b.v};
}

/// Appends the ramp from `from` to `to` over [chain->endTime(), t_end_ns] as `pieces` constant
/// arcs of equal length, each at the ramp's rates at its middle.
void appendRamp(ArcChain* chain, const Rates& from, const Rates& to, int64_t t_end_ns, int pieces);

/// One front-end arc as dead reckoning sees it: its window, its middle and its rates.
struct TimedRates {
  int64_t t_start_ns = 0, t_ref_ns = 0, t_end_ns = 0;
  Rates rates;
};

/// The whole-sequence dead reckoning from the identity: rates ramping between the arcs' reference
/// times (rampRates), constant beyond the first and the last, integrated in steps of step_ns
/// (midpoint rule) from the first arc's start to the last arc's end; a pose at every step's end.
/// Empty without arcs or for step_ns <= 0.
Trajectory3 integrateRamps(const std::vector<TimedRates>& arcs, int64_t step_ns);

/// The back-end's incremental dead reckoning of the arcs as they arrive, in two views of the
/// same arcs from the identity at t_start_ns:
///  - steps(): each arc at its own rates over its own window. A pose there never changes once
///    its arc has arrived.
///  - ramped(): with interpolate_rates, the rates ramp between the arcs' middles (rampRates, in
///    kRampPieces constant pieces) and the chain ends at the newest arc's middle, going on at its
///    rates; the next arc appends the ramp from there, so poses behind the newest arc's middle are
///    final but the ones after it change. Standstills hold the pose. Without interpolate_rates it
///    equals steps(). The spline's initial fit and the back-end's poses beyond the refined
///    spline (Backend::planarPoseAt) follow this view.
class ArcDeadReckoning {
 public:
  static constexpr int kRampPieces = 8;
  ArcDeadReckoning(int64_t t_start_ns, bool interpolate_rates);
  /// An arc covering [from_ns, t_end_ns] (from_ns: the previous arc's end, or the first arc's
  /// start) with rates (zero in a standstill) and middle t_ref_ns. Throws std::invalid_argument
  /// if t_end_ns is before the end of the steps.
  void append(const Rates& rates, bool standstill, int64_t from_ns, int64_t t_ref_ns,
              int64_t t_end_ns);
  const ArcChain& steps() const { return steps_; }
  const ArcChain& ramped() const { return ramped_; }
  int64_t startTime() const { return steps_.startTime(); }

 private:
  bool interpolate_rates_;
  ArcChain steps_, ramped_;
  bool has_last_rates_ = false;  // ramped_ ends at the newest moving arc's middle
  Rates last_;
};

/// Re-anchoring: the rigid motion A with A * T_dead_reckoned = spline.T_odom_base(u). Composed
/// with a dead reckoning (A * T(t)) it puts the dead reckoning's pose at u onto the spline and
/// keeps its relative motion.
Pose3 anchorOnSplinePose(const BSpline& spline, double u, const Pose3& T_dead_reckoned);

/// The planar rigid motion that best maps a chain onto the spline over [t_end - span_s, t_end]
/// (least squares of 21 positions: their spread determines the heading far better than the
/// spline's tangent at its end), through the pose at t_end. Falls back to anchorOnSplinePose at
/// t_end over less than 50 ms or a spread of less than ~2 cm (heading unknown).
Pose3 fitAnchorOnSpline(const BSpline& spline, const ArcChain& chain, int64_t t_end_ns,
                        double span_s);

}  // namespace vwe_vo
