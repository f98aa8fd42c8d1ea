#include "vwe_vo/ros/event_input.h"

#include <ros/console.h>

#include "vwe_vo/ros/conversions.h"

namespace vwe_vo {

uint64_t countArrivingPacket(const std_msgs::Header& header, const char* node, SequenceGapCounter* sequence,
                             std::atomic<size_t>& lost) {
  const uint64_t gap = sequence->observe(header.seq);
  if (gap > 0) {
    lost += gap;
    ROS_WARN_THROTTLE(10,
                      "%s: %lu event packets never reached the node (gap in header.seq before %u: the subscriber "
                      "queue overflowed, the node is too slow for the data); %zu lost so far",
                      node, static_cast<unsigned long>(gap), header.seq, lost.load());
  }
  return gap;
}

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

bool acceptCameraInfo(const sensor_msgs::CameraInfo& msg, const char* node, bool* have_calibration,
                      CameraCalibration* calibration, std::atomic<size_t>& refused) {
  if (*have_calibration) {
    if (int(msg.width) != calibration->width || int(msg.height) != calibration->height) {
      ++refused;
      ROS_ERROR_THROTTLE(10,
                         "%s: camera_info is %ux%u but the calibration in use is %dx%d: refused, keeping the "
                         "first (%zu refused so far)",
                         node, msg.width, msg.height, calibration->width, calibration->height, refused.load());
    }
    return false;
  }
  try {
    *calibration = calibrationFromMsg(msg);
  } catch (const std::invalid_argument& e) {
    ++refused;
    ROS_WARN_THROTTLE(5, "%s: camera_info refused: %s; still waiting for a valid one (%zu refused so far)", node,
                      e.what(), refused.load());
    return false;
  }
  *have_calibration = true;
  ROS_INFO("%s: calibration from camera_info: %dx%d, fx %.2f fy %.2f cx %.2f cy %.2f", node, calibration->width,
           calibration->height, calibration->fx, calibration->fy, calibration->cx, calibration->cy);
  return true;
}

}  // namespace vwe_vo
