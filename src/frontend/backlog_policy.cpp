#include "vwe_vo/frontend/backlog_policy.h"

#include <algorithm>
#include <stdexcept>

namespace vwe_vo {

void BacklogPolicyOptions::validate() const {
  if (!(max_latency_s > 0)) throw std::invalid_argument("backlog: max_latency_s must be > 0 [s]");
  if (!(window_s > 0)) throw std::invalid_argument("backlog: window_s must be > 0 [s]");
  if (max_thinning < 1) throw std::invalid_argument("backlog: max_thinning must be >= 1");
  if (!(rate_horizon_s > 0)) throw std::invalid_argument("backlog: rate_horizon_s must be > 0 [s]");
  if (!(hard_latency_factor >= 1))
    throw std::invalid_argument("backlog: hard_latency_factor must be >= 1");
}

BacklogPolicy::BacklogPolicy(const BacklogPolicyOptions& options) : options_(options) {
  options_.validate();
}

void BacklogPolicy::observeInput(double wall_s, double newest_data_s) {
  if (!arrivals_.empty() && newest_data_s < arrivals_.back().second) arrivals_.clear();
  arrivals_.emplace_back(wall_s, newest_data_s);
  // Keep one sample at or before the horizon, so the rate always spans it once it can.
  while (arrivals_.size() > 2 && arrivals_[1].first <= wall_s - options_.rate_horizon_s)
    arrivals_.pop_front();
}

void BacklogPolicy::observeWindow(double data_s, double wall_s) {
  if (!(data_s > 0) || !(wall_s > 0)) return;
  const double rate = data_s / wall_s;
  constexpr double kWeight = 0.25;  // a running mean over the last ~4 windows
  progress_ = progress_ < 0 ? rate : (1 - kWeight) * progress_ + kWeight * rate;
}

void BacklogPolicy::reset() {
  arrivals_.clear();
  progress_ = -1.0;
}

double BacklogPolicy::arrivalRate() const {
  if (arrivals_.size() < 2) return -1.0;
  const double wall = arrivals_.back().first - arrivals_.front().first;
  if (wall < 0.5 * options_.rate_horizon_s) return -1.0;
  return (arrivals_.back().second - arrivals_.front().second) / wall;
}

size_t BacklogPolicy::nextThinning(double backlog_s, size_t current) const {
  current = std::max<size_t>(1, current);
  if (backlog_s < options_.window_s) return std::max<size_t>(1, current / 2);
  if (backlog_s <= 0.5 * options_.max_latency_s) return current;
  // Coarser only while the windows do not work the backlog off within about max_latency_s of
  // wall time: every halving of a window's events costs accuracy.
  const double arrival = arrivalRate();
  const bool draining =
      current > 1 && arrival >= 0 && progress_ >= arrival + backlog_s / options_.max_latency_s;
  return draining ? current : std::min(2 * current, options_.max_thinning);
}

bool BacklogPolicy::mustSkip(double backlog_s, size_t thinning) const {
  if (backlog_s > options_.hard_latency_factor * options_.max_latency_s) return true;
  if (backlog_s <= options_.max_latency_s || thinning < options_.max_thinning) return false;
  const double arrival = arrivalRate();
  if (arrival < 0 || progress_ < 0) return true;
  return progress_ < arrival;
}

}  // namespace vwe_vo
