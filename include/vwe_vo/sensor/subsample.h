// Deterministic subsampling of event windows, for what votes fewer events than it is given
// (the front-end's and back-end's volumes, the front-end node's window).
#pragma once

#include <cstddef>
#include <cstdint>

#include "vwe_vo/sensor/events.h"

namespace vwe_vo {

/// Deterministic uniform subsampling to at most max_events (every k-th event on a fractional
/// stride, the phase chosen from seed). Returns the input unchanged if it is small enough.
EventVector subsampleEvents(const EventVector& events, size_t max_events, uint64_t seed);
/// Subsampling that gives every one of `bins` equal time slices of [t0, t1) the same budget
/// (max_events / bins, all of a slice's events when it has fewer): the VWE then weighs time, not
/// event count, so a window whose motion changes is not pulled towards its busiest part.
EventVector subsampleEventsPerTimeSlice(const EventVector& events, int64_t t0_ns, int64_t t1_ns,
                                        size_t max_events, int bins, uint64_t seed);

}  // namespace vwe_vo
