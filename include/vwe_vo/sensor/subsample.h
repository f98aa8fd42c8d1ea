// Deterministic subsampling of event windows, for what votes fewer events than it is given
// (the front-end's and back-end's volumes, the front-end node's window).
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>

#include "vwe_vo/sensor/events.h"

namespace vwe_vo {

/// Keeps every second event of `events` (a vector or deque of events, in time order), in place,
/// from the second: the overload policies' halving, evenly in time (the first and the last
/// events keep their times within one event). Returns how many went.
template <typename Events>
size_t keepEverySecond(Events* events) {
  const size_t n = events->size();
  if (n < 2) return 0;
  size_t kept = 0;
  for (size_t i = 1; i < n; i += 2) (*events)[kept++] = (*events)[i];
  events->resize(kept);
  return n - kept;
}

/// Deterministic uniform subsampling to at most max_events (every k-th event on a fractional
/// stride, the phase chosen from seed). Returns the input unchanged if it is small enough.
EventVector subsampleEvents(const EventVector& events, size_t max_events, uint64_t seed);

/// The phase in [0, stride) subsampleEvents starts at for `seed` (a splitmix64 hash of it).
double subsamplePhase(uint64_t seed, double stride);

/// subsampleEvents of the events [begin, end) of any indexable sequence (an EventBuffer), copying
/// only the events it keeps: the same events as subsampleEvents of that range copied out.
template <typename Events>
EventVector subsampleRange(const Events& events, size_t begin, size_t end, size_t max_events,
                           uint64_t seed) {
  EventVector out;
  if (end <= begin) return out;
  const size_t n = end - begin;
  if (max_events == 0 || n <= max_events) {
    out.reserve(n);
    for (size_t i = begin; i < end; ++i) out.push_back(events[i]);
    return out;
  }
  out.reserve(max_events);
  const double stride = double(n) / double(max_events);
  const double phase = subsamplePhase(seed, stride);
  for (size_t k = 0; k < max_events; ++k)
    out.push_back(events[begin + std::min(n - 1, size_t(phase + double(k) * stride))]);
  return out;
}
/// Subsampling that gives every one of `bins` equal time slices of [t0, t1) the same budget
/// (max_events / bins, all of a slice's events when it has fewer): the VWE then weighs time, not
/// event count, so a window whose motion changes is not pulled towards its busiest part.
EventVector subsampleEventsPerTimeSlice(const EventVector& events, int64_t t0_ns, int64_t t1_ns,
                                        size_t max_events, int bins, uint64_t seed);

}  // namespace vwe_vo
