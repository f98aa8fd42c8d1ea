// How a live front-end that falls behind its input keeps up: its windows vote fewer events first;
// whole windows are skipped only when even the cheapest windows cannot keep pace with the input.
// A burst of late input (a driver or a bag player that stalled on the CPU, then sent what it
// owed) makes a large backlog that thinned windows work off: it is no reason to skip.
#pragma once

#include <cstddef>
#include <deque>
#include <utility>

namespace vwe_vo {

struct BacklogPolicyOptions {
  double max_latency_s = 1.0;        // backlog [data s] beyond which windows may be skipped
  double window_s = 0.3;             // data per window [s]
  size_t max_thinning = 4;           // coarsest thinning of a window's events (1/max_thinning)
  double rate_horizon_s = 2.0;       // wall time over which the input's arrival rate is taken [s]
  double hard_latency_factor = 4.0;  // a backlog beyond this x max_latency_s is skipped regardless
  void validate() const;             // throws std::invalid_argument naming the option
};

class BacklogPolicy {
 public:
  BacklogPolicy() : BacklogPolicy(BacklogPolicyOptions()) {}
  explicit BacklogPolicy(const BacklogPolicyOptions& options);

  /// The newest event time [data s] received by wall time `wall_s` [s].
  void observeInput(double wall_s, double newest_data_s);
  /// One window estimated: `data_s` of events in `wall_s` of wall time (the node's whole pass).
  void observeWindow(double data_s, double wall_s);
  /// Forgets the rates (after a reset of the input).
  void reset();

  /// The thinning of the next window, from the current one: doubled while the backlog is above
  /// half of max_latency_s and the windows do not work it off within about max_latency_s (or the
  /// rates are not known), up to max_thinning; halved once the backlog is below one window.
  size_t nextThinning(double backlog_s, size_t current) const;
  /// True when windows must be skipped down to max_latency_s: the backlog is above it at the
  /// coarsest thinning and the windows are estimated slower than the input arrives (or the rates
  /// are not known yet), or the backlog is beyond hard_latency_factor x max_latency_s at any
  /// thinning (a bound on the latency and the memory).
  bool mustSkip(double backlog_s, size_t thinning) const;

  /// Data seconds arriving per wall second over the last rate_horizon_s; < 0 until known.
  double arrivalRate() const;
  /// Data seconds estimated per wall second of the recent windows (running mean); < 0 until known.
  double progressRate() const { return progress_; }

 private:
  BacklogPolicyOptions options_;
  std::deque<std::pair<double, double>> arrivals_;  // (wall s, newest data s), oldest first
  double progress_ = -1.0;
};

}  // namespace vwe_vo
