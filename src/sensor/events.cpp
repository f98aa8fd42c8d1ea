#include "vwe_vo/sensor/events.h"

#include <algorithm>

namespace vwe_vo {

bool EventBuffer::push(const PixelEvent& e) {
  if (!events_.empty() && e.t_ns < events_.back().t_ns) {
    ++out_of_order_;
    return false;
  }
  events_.push_back(e);
  return true;
}

size_t EventBuffer::push(const EventVector& events) {
  size_t accepted = 0;
  for (const PixelEvent& e : events) accepted += push(e) ? 1 : 0;
  return accepted;
}

size_t EventBuffer::lowerBound(int64_t t_ns) const {
  const auto it = std::lower_bound(events_.begin(), events_.end(), t_ns,
                                   [](const PixelEvent& e, int64_t t) { return e.t_ns < t; });
  return static_cast<size_t>(it - events_.begin());
}

EventVector EventBuffer::window(int64_t t0_ns, int64_t t1_ns) const {
  const size_t i0 = lowerBound(t0_ns), i1 = lowerBound(t1_ns);
  if (i1 <= i0) return {};
  return EventVector(events_.begin() + i0, events_.begin() + i1);
}

EventVector EventBuffer::windowByCount(int64_t t0_ns, size_t count) const {
  const size_t i0 = lowerBound(t0_ns);
  const size_t i1 = std::min(events_.size(), i0 + count);
  return EventVector(events_.begin() + i0, events_.begin() + i1);
}

void EventBuffer::dropBefore(int64_t t_ns) {
  events_.erase(events_.begin(), events_.begin() + lowerBound(t_ns));
}

void EventBuffer::clear() {
  events_.clear();
}

uint64_t SequenceGapCounter::observe(uint32_t seq) {
  uint64_t gap = 0;
  if (has_last_ && seq > last_) {
    gap = uint64_t(seq - last_ - 1);
  } else if (has_last_ && seq < last_) {
    ++restarts_;
  }
  has_last_ = true;
  last_ = seq;
  missed_ += gap;
  return gap;
}

}  // namespace vwe_vo
