#include "vwe_vo/backend/backend_driver.h"

#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "vwe_vo/trajectory/dead_reckoning.h"

namespace vwe_vo {

namespace {
std::string format(const char* fmt, double a, double b = 0.0, double c = 0.0) {
  char buf[256];
  std::snprintf(buf, sizeof(buf), fmt, a, b, c);
  return buf;
}
}  // namespace

void BackendDriverOptions::validate() const {
  auto fail = [](const std::string& m) {
    throw std::invalid_argument("BackendDriverOptions: " + m);
  };
  if (!(odom_rate_hz > 0 && odom_rate_hz <= 1000)) fail("odom_rate_hz must be in (0, 1000] [Hz]");
  if (!(max_gap_s > 0) || !std::isfinite(max_gap_s))
    fail("max_gap_s must be positive and finite [s]");
}

BackendDriver::BackendDriver(Backend* backend, const BackendDriverOptions& options,
                             Callbacks callbacks)
    : backend_(backend), options_(options), callbacks_(std::move(callbacks)) {
  if (!backend_) throw std::invalid_argument("BackendDriver: the back-end is null");
  options_.validate();
  resets_seen_ = backend_->stats().resets;
}

void BackendDriver::afterReset(ResetCause cause, const std::string& why) {
  resets_seen_ = backend_->stats().resets;
  odometry_.reset();
  newest_arc_ns_ = -1;  // the next arc starts the back-end again
  if (callbacks_.reset) callbacks_.reset(cause, why);
}

void BackendDriver::reset(const std::string& why) {
  backend_->reset();
  newest_event_ns_ = -1;  // the events after a requested reset start afresh (no gap to them)
  afterReset(ResetCause::kRequested, why);
}

void BackendDriver::addEvents(const EventVector& events) {
  if (events.empty()) return;
  const int64_t first = events.front().t_ns;
  if (newest_event_ns_ >= 0 && dtSec(first, newest_event_ns_) > options_.max_gap_s) {
    ++stats_.gaps;
    backend_->reset();
    afterReset(ResetCause::kGap, format("no events for %.3f s (> max_gap_s %.3f s)",
                                        dtSec(first, newest_event_ns_), options_.max_gap_s));
  }
  const int64_t newest_before = newest_event_ns_;
  backend_->addEvents(events);
  if (backend_->stats().resets > resets_seen_) {
    ++stats_.loops;
    newest_event_ns_ = events.back().t_ns;
    afterReset(ResetCause::kLoop,
               format("event time jumped back by %.3f s (%.3f -> %.3f s; a looped bag?)",
                      dtSec(newest_before, first), nsToSec(newest_before), nsToSec(first)));
  } else {
    newest_event_ns_ = std::max(newest_event_ns_, events.back().t_ns);
  }
}

void BackendDriver::addArc(const ArcEstimate& arc, int64_t newest_pending_arc_ns) {
  ++stats_.arcs_in;
  const BackendOptions& bo = backend_->options();
  if (newest_arc_ns_ >= 0 && arc.t_end_ns <= newest_arc_ns_ &&
      arc.t_end_ns >= newest_arc_ns_ - secToNs(bo.max_backwards_jump_s)) {
    ++stats_.arcs_stale;
    return;
  }
  if (newest_arc_ns_ >= 0 && dtSec(arc.t_start_ns, newest_arc_ns_) > options_.max_gap_s) {
    ++stats_.gaps;
    const double gap = dtSec(arc.t_start_ns, newest_arc_ns_);
    backend_->reset();
    afterReset(ResetCause::kGap,
               format("no arcs for %.3f s (> max_gap_s %.3f s)", gap, options_.max_gap_s));
  }
  if (arc.status == ArcStatus::kLost || arc.status == ArcStatus::kLowEvents ||
      !std::isfinite(arc.omega) || !std::isfinite(arc.v))
    ++stats_.arcs_lost;  // no motion estimate: the back-end holds the last measured rates
  const int64_t newest_before = newest_arc_ns_;
  if (backend_->addArc(arc)) {
    ++stats_.loops;
    afterReset(ResetCause::kLoop,
               format("arc time jumped back to %.3f s (from %.3f s; a looped bag?)",
                      nsToSec(arc.t_end_ns), nsToSec(newest_before)));
  }
  newest_arc_ns_ = arc.t_end_ns;
  // The odometry of the new arc goes out first: it does not wait for the solver.
  const int64_t step = std::max<int64_t>(1, secToNs(1.0 / options_.odom_rate_hz));
  odometry_.advance(*backend_, step, [&](int64_t t_ns, const Pose3& T, double v, double omega) {
    if (callbacks_.odometry) callbacks_.odometry(t_ns, T, v, omega);
  });
  // A newer arc that would be due again is pending: one refinement covers both.
  if (newest_pending_arc_ns >= 0 &&
      dtSec(newest_pending_arc_ns, arc.t_end_ns) >= bo.update_interval_s)
    return;
  const int64_t from =
      backend_->hasSpline() ? backend_->processedUntil() : backend_->oldestArcTime();
  if (!backend_->process()) return;
  ++stats_.refinements;
  const double intervals = dtSec(backend_->processedUntil(), from) / bo.update_interval_s;
  const size_t merged = intervals >= 2.0 ? size_t(intervals) - 1 : 0;
  stats_.refinements_merged += merged;
  if (callbacks_.refinement) callbacks_.refinement(merged);
}

void BackendDriver::finish() {
  const size_t before = backend_->stats().updates;
  backend_->finish();
  if (backend_->stats().updates == before) return;
  ++stats_.refinements;
  if (callbacks_.refinement) callbacks_.refinement(0);
}

void FollowOptions::validate() const {
  if (!(min_speed_mps > 0) || !std::isfinite(min_speed_mps))
    throw std::invalid_argument(
        "FollowOptions: min_speed_mps must be positive and finite [m/s], got " +
        std::to_string(min_speed_mps));
}

FrontendFollower::FrontendFollower(const FollowOptions& options, bool speed_from_odometry)
    : options_((options.validate(), options)), speed_from_odometry_(speed_from_odometry) {}

void FrontendFollower::reset(int64_t t_ns) {
  T_anchor_ = Pose3::Identity();
  reset_ns_ = t_ns;
}

bool FrontendFollower::follow(const BSpline& spline, int64_t newest_event_ns, Frontend* frontend) {
  if (!options_.follow_backend || !frontend->hasPose()) return false;
  const double u = spline.validTo();
  const int64_t t_end = spline.epochNs() + secToNs(u);
  // A spline from before a reset (a looped bag) or beyond the dead reckoning is not used.
  if (spline.epochNs() < reset_ns_ || t_end > newest_event_ns) return false;
  T_anchor_ = anchorOnSplinePose(spline, u, frontend->T_odom_base(t_end));
  ++reanchors_;
  last_speed_ = spline.velocity(u).norm();
  last_t_ns_ = t_end;
  if (!speed_from_odometry_ && !spline.standstillAt(u) && std::isfinite(last_speed_) &&
      last_speed_ > options_.min_speed_mps) {
    frontend->setNominalSpeed(last_speed_, t_end);
    ++speeds_taken_;
  }
  return true;
}

}  // namespace vwe_vo
