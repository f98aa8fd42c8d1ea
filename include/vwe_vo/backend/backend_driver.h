// The one orchestration of the back-end, shared by backend_node (live) and OfflinePipeline: it
// takes events and arcs in arrival order, applies the gap, looped-data and stale-arc rules,
// publishes the continuous odometry of each arc before the refinement it triggers, and decides
// when to refine. FrontendFollower is the other half of the loop: what the front-end takes from a
// refined spline (frontend_node live, OfflinePipeline offline). ROS-free.
#pragma once

#include <cstdint>
#include <functional>
#include <string>

#include "vwe_vo/backend/backend.h"
#include "vwe_vo/frontend/frontend.h"
#include "vwe_vo/trajectory/bspline.h"

namespace vwe_vo {

struct BackendDriverOptions {
  double odom_rate_hz = 20.0;  // rate of the continuous odometry (/vwe/odom, odom.tum) [Hz]
  double max_gap_s = 2.0;      // events or arcs this far apart reset the back-end [s]
  void validate() const;       // throws std::invalid_argument naming the field
};

struct BackendDriverStats {
  size_t arcs_in = 0;
  size_t arcs_stale = 0;  // not newer than the newest arc (and no jump back): ignored
  size_t arcs_lost = 0;   // LOST / LOW_EVENTS / non-finite: the back-end holds the last rates
  size_t gaps = 0;        // resets after a gap in the events or the arcs
  size_t loops = 0;       // resets after the time jumped back (a looped bag)
  size_t refinements = 0;
  size_t refinements_merged = 0;  // update intervals folded into a later refinement
};

/// Drives a Backend. Processing rule: one refinement check per arc, in arrival order, after the
/// arc's odometry went out. A caller that already holds newer arcs (a batch: it fell behind)
/// passes the newest one's end; a refinement due at an arc is then deferred while an arc ending at
/// least update_interval_s later is pending (that one would be due again), so one refinement
/// covers the batch instead of a queue of refinements the CPU cannot afford. When the caller keeps
/// up (pending arcs less than update_interval_s apart) this is exactly one check per arc.
class BackendDriver {
 public:
  enum class ResetCause { kGap, kLoop, kRequested };
  struct Callbacks {
    /// A pose of the continuous odometry (ContinuousOdometry), every 1 / odom_rate_hz.
    std::function<void(int64_t t_ns, const Pose3& T_odom_base, double v, double omega)> odometry;
    /// After each refinement (the spline: backend().spline()); merged: update intervals this one
    /// covers beyond the first (0 when keeping up).
    std::function<void(size_t merged)> refinement;
    /// After a reset (the odometry restarts at the identity), with a sentence saying why.
    std::function<void(ResetCause cause, const std::string& why)> reset;
  };

  /// backend must outlive the driver; only the driver may feed it.
  BackendDriver(Backend* backend, const BackendDriverOptions& options, Callbacks callbacks);

  /// Time-ordered events. After a gap of more than max_gap_s, or when they jump back by more than
  /// the back-end's max_backwards_jump_s (a looped bag), the back-end is reset first.
  void addEvents(const EventVector& events);
  /// One arc. Stale arcs (ending at or before the newest arc, less than max_backwards_jump_s back)
  /// are ignored; one starting more than max_gap_s after the newest, or ending more than
  /// max_backwards_jump_s before it, resets the back-end. newest_pending_arc_ns: the end of the
  /// newest arc the caller holds but has not added yet (-1: none); see the processing rule.
  void addArc(const ArcEstimate& arc, int64_t newest_pending_arc_ns = -1);
  /// Extends and refines up to the newest arc (end of data).
  void finish();
  /// Resets the back-end and the odometry (e.g. after the back-end failed).
  void reset(const std::string& why);

  const Backend& backend() const { return *backend_; }
  const BackendDriverStats& stats() const { return stats_; }
  const BackendDriverOptions& options() const { return options_; }

 private:
  void afterReset(ResetCause cause, const std::string& why);

  Backend* backend_;
  BackendDriverOptions options_;
  Callbacks callbacks_;
  ContinuousOdometry odometry_;
  int64_t newest_event_ns_ = -1, newest_arc_ns_ = -1;
  size_t resets_seen_ = 0;  // backend_->stats().resets already reported
  BackendDriverStats stats_;
};

/// How the front-end follows the back-end (frontend_node's ~follow_backend; vwe_vo_offline).
struct FollowOptions {
  bool follow_backend =
      true;  // re-anchor on each refined spline and, without odometry, take its speed
  double min_speed_mps =
      0.05;               // the spline's speed is taken only above this (not in a standstill) [m/s]
  void validate() const;  // throws std::invalid_argument naming the field
};

/// The front-end following the back-end: on each refined spline it re-anchors the front-end's
/// dead reckoning on the spline's end (anchor() maps the front-end's odom onto the back-end's)
/// and, unless the front-end has its speed from odometry, sets the front-end's nominal speed to
/// the spline's speed there.
class FrontendFollower {
 public:
  explicit FrontendFollower(const FollowOptions& options = FollowOptions(),
                            bool speed_from_odometry = false);
  /// The front-end was reset at data time t_ns (looped data): the anchor is the identity again and
  /// splines starting before t_ns are ignored.
  void reset(int64_t t_ns);
  /// Follows a refined spline at its end u = validTo(). Returns false (nothing changes) if
  /// following is off, the front-end has no pose yet, the spline starts before the last reset or
  /// ends after newest_event_ns (beyond the dead reckoning). The speed is taken if it is finite,
  /// above min_speed_mps and u is not in a standstill.
  bool follow(const BSpline& spline, int64_t newest_event_ns, Frontend* frontend);
  /// Whether follow() can change the front-end's arcs (it sets the nominal speed).
  bool changesArcs() const { return options_.follow_backend && !speed_from_odometry_; }
  const Pose3& anchor() const { return T_anchor_; }
  /// The front-end's dead reckoning at t_ns in the back-end's odom.
  Pose3 anchoredPose(const Frontend& frontend, int64_t t_ns) const {
    return T_anchor_ * frontend.T_odom_base(t_ns);
  }
  size_t reanchors() const { return reanchors_; }
  size_t speedsTaken() const { return speeds_taken_; }
  /// The spline's speed at the last re-anchoring (taken or not) [m/s].
  double lastSpeed() const { return last_speed_; }
  int64_t lastTime() const { return last_t_ns_; }

 private:
  FollowOptions options_;
  bool speed_from_odometry_;
  Pose3 T_anchor_ = Pose3::Identity();
  int64_t reset_ns_ = -1;
  size_t reanchors_ = 0, speeds_taken_ = 0;
  double last_speed_ = 0.0;
  int64_t last_t_ns_ = -1;
};

}  // namespace vwe_vo
