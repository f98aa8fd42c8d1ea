#include "vwe_vo/ros/event_input.h"

#include <ros/console.h>

#include "vwe_vo/ros/conversions.h"

namespace vwe_vo {

bool acceptEventPacket(const EventArray& msg, int width, int height, const char* node,
                       const EventPacketCounters& counters, EventVector* events) {
  events->clear();
  if (msg.events.empty()) {
    ++counters.empty;
    ROS_WARN_THROTTLE(10, "%s: empty EventArray ignored (%zu so far)", node, counters.empty.load());
    return false;
  }
  if (int(msg.width) != width || int(msg.height) != height) {
    ++counters.wrong_size;
    ROS_ERROR_THROTTLE(5, "%s: EventArray is %ux%u but the calibration is %dx%d: packet refused (%zu so far)", node,
                       msg.width, msg.height, width, height, counters.wrong_size.load());
    return false;
  }
  EventConversionStats stats;
  eventsFromMsg(msg, events, &stats);
  if (stats.dropped > 0) {
    counters.events_outside += stats.dropped;
    ROS_WARN_THROTTLE(10, "%s: %zu events outside the %dx%d sensor dropped (%zu so far)", node, stats.dropped,
                      width, height, counters.events_outside.load());
  }
  return !events->empty();
}

}  // namespace vwe_vo
