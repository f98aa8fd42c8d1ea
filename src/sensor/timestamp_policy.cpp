#include "vwe_vo/sensor/timestamp_policy.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "vwe_vo/common/math.h"

namespace vwe_vo {
namespace {
std::string format(const char* f, double a, double b = 0, double c = 0) {
  char buf[256];
  std::snprintf(buf, sizeof(buf), f, a, b, c);
  return buf;
}
}  // namespace

void TimestampPolicyOptions::validate(const std::string& section) const {
  const auto fail = [&](const std::string& m) { throw std::invalid_argument(section + "." + m); };
  if (!(std::isfinite(max_backward_jump_s) && max_backward_jump_s >= 0))
    fail("max_backward_jump_s must be finite and >= 0 [s]");
  if (!(std::isfinite(max_gap_s) && max_gap_s >= 0))
    fail("max_gap_s must be finite and >= 0 (0: never) [s]");
  if (max_gap_s > 0 && max_gap_s <= max_backward_jump_s)
    fail("max_gap_s must be 0 or larger than max_backward_jump_s");
  if (!(std::isfinite(warn_interval_s) && warn_interval_s >= 0))
    fail("warn_interval_s must be finite and >= 0 [s]");
}

const char* toString(TimestampAction action) {
  switch (action) {
    case TimestampAction::kPass:
      return "pass";
    case TimestampAction::kAbsorb:
      return "absorb";
    case TimestampAction::kReset:
      return "reset";
  }
  return "?";
}

TimestampPolicy::TimestampPolicy(const TimestampPolicyOptions& options) : options_(options) {
  options_.validate();
}

void TimestampPolicy::restart() {
  newest_ns_ = -1;
}

TimestampAction TimestampPolicy::process(const EventVector& in, EventVector* out) {
  out->clear();
  ++stats_.packets;
  stats_.events_in += in.size();
  if (in.empty()) return TimestampAction::kPass;
  const int64_t max_back_ns = secToNs(options_.max_backward_jump_s);
  TimestampAction action = TimestampAction::kPass;
  size_t begin = 0;
  // A long silence: the first event far after the newest.
  if (newest_ns_ >= 0 && in.front().t_ns > newest_ns_) {
    const double gap_s = dtSec(in.front().t_ns, newest_ns_);
    stats_.largest_gap_s = std::max(stats_.largest_gap_s, gap_s);
    if (options_.max_gap_s > 0 && gap_s > options_.max_gap_s) {
      ++stats_.resets, ++stats_.resets_gap;
      last_event_ = format(
          "events resume %.3f s after the newest (> input.max_gap_s %.3g s): reset at t = %.6f s",
          gap_s, options_.max_gap_s, nsToSec(in.front().t_ns));
      pending_reset_ = last_event_;
      newest_ns_ = -1;
      action = TimestampAction::kReset;
    }
  }
  // The last event that goes back by more than max_backward_jump_s starts the packet afresh.
  int64_t running = newest_ns_;
  for (size_t i = 0; i < in.size(); ++i) {
    const int64_t t = in[i].t_ns;
    if (running >= 0 && t < running - max_back_ns) {
      const double jump_s = dtSec(running, t);
      ++stats_.resets, ++stats_.resets_backward;
      stats_.events_dropped_at_reset += i - begin;
      last_event_ = format(
          "events jump back %.3f s (> input.max_backward_jump_s %.3g s): reset at t = %.6f s",
          jump_s, options_.max_backward_jump_s, nsToSec(t));
      pending_reset_ = last_event_;
      action = TimestampAction::kReset;
      begin = i;
      running = t;
    } else {
      running = std::max(running, t);
    }
  }
  if (action == TimestampAction::kReset) newest_ns_ = -1;
  // Events before `begin` are gone; from it on, drop each event older than the newest.
  int64_t newest = newest_ns_;
  int64_t oldest_late = -1;
  size_t absorbed = 0;
  out->reserve(in.size() - begin);
  for (size_t i = begin; i < in.size(); ++i) {
    const PixelEvent& e = in[i];
    if (newest >= 0 && e.t_ns < newest) {
      ++absorbed;
      if (oldest_late < 0 || e.t_ns < oldest_late) oldest_late = e.t_ns;
      // Jump measured against the newest when the packet came in (or the running newest inside it).
      const double jump_s = dtSec(newest, e.t_ns);
      pending_largest_s_ = std::max(pending_largest_s_, jump_s);
      stats_.largest_backward_jump_s = std::max(stats_.largest_backward_jump_s, jump_s);
      continue;
    }
    newest = e.t_ns;
    out->push_back(e);
  }
  newest_ns_ = newest;
  stats_.events_out += out->size();
  if (absorbed > 0) {
    ++stats_.backward_jumps;
    stats_.events_absorbed += absorbed;
    ++pending_jumps_;
    pending_events_ += absorbed;
    if (action == TimestampAction::kPass) {
      action = TimestampAction::kAbsorb;
      last_event_ = format(
          "%.0f of %.0f events up to %.3f s older than the newest dropped (<= "
          "input.max_backward_jump_s)",
          double(absorbed), double(in.size()), dtSec(newest, oldest_late));
    }
  }
  return action;
}

std::string TimestampPolicy::takeWarning() {
  std::string w;
  if (!pending_reset_.empty()) {
    w = pending_reset_;
    pending_reset_.clear();
  }
  if (pending_jumps_ == 0 || newest_ns_ < 0) return w;
  if (last_warning_ns_ >= 0 && newest_ns_ >= last_warning_ns_ &&
      dtSec(newest_ns_, last_warning_ns_) < options_.warn_interval_s)
    return w;
  if (!w.empty()) w += "\n";
  w += takeSummary();
  return w;
}

std::string TimestampPolicy::takeSummary() {
  if (pending_jumps_ == 0) return "";
  const std::string s =
      format(
          "%.0f backward timestamp jump(s) up to %.1f ms absorbed: %.0f out-of-order events "
          "dropped",
          double(pending_jumps_), pending_largest_s_ * 1e3, double(pending_events_)) +
      (newest_ns_ >= 0 ? format(" (by t = %.3f s)", nsToSec(newest_ns_)) : std::string());
  pending_jumps_ = pending_events_ = 0;
  pending_largest_s_ = 0;
  last_warning_ns_ = newest_ns_;
  return s;
}

}  // namespace vwe_vo
