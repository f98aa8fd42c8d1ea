// Events as the core sees them (no ROS types) and a time-ordered buffer that hands out windows
// by event count or by duration.
#pragma once

#include <cstddef>
#include <cstdint>
#include <deque>
#include <vector>

namespace vwe_vo {

/// One event (PixelEvent, not to be confused with the message vwe_vo::Event): pixel (x, y) on the
/// sensor, time in int64 nanoseconds, polarity (+1 ON, -1 OFF).
struct PixelEvent {
  int64_t t_ns = 0;
  uint16_t x = 0;
  uint16_t y = 0;
  int8_t polarity = 1;
};

using EventVector = std::vector<PixelEvent>;

/// A time-ordered store of events. push() refuses events older than the newest one held
/// (it returns false and counts them); the caller decides whether that means a reset.
class EventBuffer {
 public:
  /// Appends one event. Returns false (and counts it as out of order) if t_ns < newest time.
  bool push(const PixelEvent& e);
  /// Appends many; returns how many were accepted.
  size_t push(const EventVector& events);

  /// Events with t in [t0_ns, t1_ns), in time order.
  EventVector window(int64_t t0_ns, int64_t t1_ns) const;
  /// The `count` events that start at the first event with t >= t0_ns (fewer if not held).
  EventVector windowByCount(int64_t t0_ns, size_t count) const;
  /// Index of the first event with t >= t_ns.
  size_t lowerBound(int64_t t_ns) const;

  /// Drops every event with t < t_ns.
  void dropBefore(int64_t t_ns);
  void clear();

  size_t size() const { return events_.size(); }
  bool empty() const { return events_.empty(); }
  const PixelEvent& operator[](size_t i) const { return events_[i]; }
  int64_t oldestTime() const { return events_.front().t_ns; }
  int64_t newestTime() const { return events_.back().t_ns; }
  /// Events refused by push() because they went back in time.
  size_t outOfOrderCount() const { return out_of_order_; }

 private:
  std::deque<PixelEvent> events_;
  size_t out_of_order_ = 0;
};

/// Messages lost before a subscriber saw them, from gaps in a publisher's sequence numbers (ROS
/// drops the oldest message silently when a subscriber's queue is full; roscpp numbers each
/// publisher's messages in header.seq and rosbag keeps the recorded numbers). A number that goes
/// back (a restarted driver, a looped bag) starts counting afresh; a repeated one (messages left
/// unnumbered) counts nothing.
class SequenceGapCounter {
 public:
  /// Returns how many numbers were skipped before seq (0 when it follows the previous one).
  uint64_t observe(uint32_t seq);
  uint64_t missed() const { return missed_; }
  uint64_t restarts() const { return restarts_; }

 private:
  bool has_last_ = false;
  uint32_t last_ = 0;
  uint64_t missed_ = 0, restarts_ = 0;
};

}  // namespace vwe_vo
