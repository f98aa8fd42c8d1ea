// The event input every node shares: one EventArray checked against the calibration's size and
// converted, with what is refused or dropped counted and warned about (throttled).
#pragma once

#include <atomic>
#include <cstddef>

#include "vwe_vo/EventArray.h"
#include "vwe_vo/core/events.h"

namespace vwe_vo {

/// Counters a node keeps about the event packets it refused or trimmed.
struct EventPacketCounters {
  std::atomic<size_t>& empty;           // packets without events
  std::atomic<size_t>& wrong_size;      // packets whose width x height is not the calibration's
  std::atomic<size_t>& events_outside;  // events outside the packet's width x height
};

/// Converts msg into *events if it is non-empty and width x height matches the calibration;
/// otherwise refuses it. Refusals and dropped events are counted and warned about, naming `node`
/// and both sizes. Returns false when nothing is left to process.
bool acceptEventPacket(const EventArray& msg, int width, int height, const char* node,
                       const EventPacketCounters& counters, EventVector* events);

}  // namespace vwe_vo
