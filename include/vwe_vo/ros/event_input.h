// The sensor input every node shares: the calibration from camera_info, and one EventArray
// checked against the calibration's size and converted; what is refused or dropped is counted
// and warned about (throttled).
#pragma once

#include <atomic>
#include <cstddef>

#include <sensor_msgs/CameraInfo.h>

#include "vwe_vo/EventArray.h"
#include "vwe_vo/sensor/camera.h"
#include "vwe_vo/sensor/events.h"

namespace vwe_vo {

/// Counters a node keeps about the event packets it refused or trimmed.
struct EventPacketCounters {
  std::atomic<size_t>& empty;           // packets without events
  std::atomic<size_t>& wrong_size;      // packets whose width x height is not the calibration's
  std::atomic<size_t>& events_outside;  // events outside the packet's width x height
};

/// Counts an arriving packet against its publisher's header.seq: packets ROS dropped before the
/// callback (a full subscriber queue) are added to `lost` and warned about (throttled), naming
/// `node`. Call it first in the callback, for every packet. Returns the packets lost before this.
uint64_t countArrivingPacket(const std_msgs::Header& header, const char* node, SequenceGapCounter* sequence,
                             std::atomic<size_t>& lost);

/// Converts msg into *events if it is non-empty and width x height matches the calibration;
/// otherwise refuses it. Refusals and dropped events are counted and warned about, naming `node`
/// and both sizes. Returns false when nothing is left to process.
bool acceptEventPacket(const EventArray& msg, int width, int height, const char* node,
                       const EventPacketCounters& counters, EventVector* events);

/// The first valid camera_info becomes *calibration (sets *have_calibration, logs it, returns
/// true). Before that an invalid one is refused and the node keeps waiting; afterwards one of
/// another size is refused and the first is kept. Refusals are counted in `refused` and warned
/// about, naming `node`. Call it holding the lock that guards the calibration.
bool acceptCameraInfo(const sensor_msgs::CameraInfo& msg, const char* node, bool* have_calibration,
                      CameraCalibration* calibration, std::atomic<size_t>& refused);

}  // namespace vwe_vo
