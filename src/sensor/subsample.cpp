#include "vwe_vo/sensor/subsample.h"

#include <algorithm>

namespace vwe_vo {

double subsamplePhase(uint64_t seed, double stride) {
  uint64_t z = seed + 0x9e3779b97f4a7c15ULL;
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  z ^= z >> 31;
  return double(z >> 11) / double(1ULL << 53) * stride;
}

EventVector subsampleEvents(const EventVector& events, size_t max_events, uint64_t seed) {
  if (max_events == 0 || events.size() <= max_events) return events;
  return subsampleRange(events, 0, events.size(), max_events, seed);
}

EventVector subsampleEventsPerTimeSlice(const EventVector& events, int64_t t0_ns, int64_t t1_ns,
                                        size_t max_events, int bins, uint64_t seed) {
  if (bins <= 1 || t1_ns <= t0_ns) return subsampleEvents(events, max_events, seed);
  EventVector out;
  out.reserve(max_events);
  const size_t per_bin = std::max<size_t>(1, max_events / size_t(bins));
  size_t begin = 0;
  for (int b = 0; b < bins; ++b) {
    const int64_t edge = t0_ns + (t1_ns - t0_ns) * (b + 1) / bins;
    size_t end = begin;
    while (end < events.size() && (events[end].t_ns < edge || b == bins - 1)) ++end;
    const EventVector kept = subsampleRange(events, begin, end, per_bin, seed + uint64_t(b));
    out.insert(out.end(), kept.begin(), kept.end());
    begin = end;
  }
  return out;
}

}  // namespace vwe_vo
