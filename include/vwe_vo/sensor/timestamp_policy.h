// The one rule for event timestamps that go back or jump ahead, applied at the input before
// the front-end and the back-end see the events, so that they only ever get time-ordered data.
// Drivers glitch (a DAVIS driver sends a packet stamped ~0.1 s in the past now and then), bags
// loop and drivers restart: small backward jumps are absorbed, large ones and long silences reset.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

#include "vwe_vo/sensor/events.h"

namespace vwe_vo {

/// The YAML `input:` section (one key for the whole pipeline; the front-end's and back-end's own
/// max_backwards_jump_s guards are set from max_backward_jump_s so that they agree).
struct TimestampPolicyOptions {
  double max_backward_jump_s = 0.5;  // events at most this far behind the newest are dropped [s];
                                     // further back resets (a looped bag, a restarted driver)
  double max_gap_s = 2.0;        // a packet starting this far after the newest resets [s]; 0: never
  double warn_interval_s = 1.0;  // at most one warning per this much data time [s]
  /// Throws std::invalid_argument naming the field by its YAML key, section + "." + key.
  void validate(const std::string& section = "input") const;
};

/// What the input does with one packet.
enum class TimestampAction {
  kPass,    // every event in order: hand the packet on as it is
  kAbsorb,  // some events older than the newest handed on were dropped; hand on the rest
  kReset,   // a large backward jump or a long gap: reset the estimators, then hand on the rest
};
const char* toString(TimestampAction action);

struct TimestampPolicyStats {
  size_t packets = 0, events_in = 0, events_out = 0;
  size_t backward_jumps = 0;   // packets with events older than the newest handed on (absorbed)
  size_t events_absorbed = 0;  // events dropped because they were older than the newest
  size_t resets = 0, resets_backward = 0, resets_gap = 0;
  size_t events_dropped_at_reset = 0;  // events of a resetting packet before its jump point
  double largest_backward_jump_s = 0;  // largest absorbed jump (newest - oldest event of a packet)
  double largest_gap_s = 0;            // largest forward step between packets
};

/// Takes the packets in arrival order and returns, for each, what to do and the events to hand
/// on: always non-decreasing in time across all packets since the last reset.
///
/// Out-of-order events are dropped, not merged back into order: the front-end has usually cut
/// its window over that time already (re-inserting would need re-running it), and a glitching
/// driver's stamps are wrong rather than late, so merging would put events at the wrong time.
/// Events stamped exactly at the newest time pass (a sensor emits many events per microsecond),
/// so a duplicated packet leaves those few events doubled and drops the rest.
class TimestampPolicy {
 public:
  explicit TimestampPolicy(const TimestampPolicyOptions& options = {});

  /// Filters `in` into `out` (cleared first; may not alias `in`). A jump back by more than
  /// max_backward_jump_s inside the packet is a reset: the events before it are dropped and
  /// counted, the ones from it on handed on. A packet whose first event is more than max_gap_s
  /// after the newest is a reset too.
  TimestampAction process(const EventVector& in, EventVector* out);
  /// Forgets the newest time (the caller reset for its own reasons); counters stay.
  void restart();

  const TimestampPolicyStats& stats() const { return stats_; }
  const TimestampPolicyOptions& options() const { return options_; }
  /// Newest time handed on since the last reset (-1: none).
  int64_t newestNs() const { return newest_ns_; }
  /// One line about the last packet that was not passed as it was (empty if none yet).
  const std::string& lastEvent() const { return last_event_; }

  /// A warning to print, throttled by data time: resets always and at once; absorbed jumps at
  /// most once per warn_interval_s of data, summing those since the previous warning. Empty when
  /// there is nothing to say.
  std::string takeWarning();
  /// The absorbed jumps not yet warned about, as one line (empty if none): for the end of a run.
  std::string takeSummary();

 private:
  TimestampPolicyOptions options_;
  TimestampPolicyStats stats_;
  int64_t newest_ns_ = -1;
  std::string last_event_;
  // Throttling: jumps since the last warning and the data time of that warning.
  std::string pending_reset_;
  size_t pending_jumps_ = 0, pending_events_ = 0;
  double pending_largest_s_ = 0;
  int64_t last_warning_ns_ = -1;
};

}  // namespace vwe_vo
