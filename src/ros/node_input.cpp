#include "vwe_vo/ros/node_input.h"

#include <ros/console.h>

#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "vwe_vo/ros/conversions.h"

namespace vwe_vo {

const char* inputKindName(InputKind kind) {
  switch (kind) {
    case InputKind::kEvents:
      return "events";
    case InputKind::kImu:
      return "imu";
    case InputKind::kOdometry:
      return "odom";
    case InputKind::kTrajectory:
      return "trajectory";
    case InputKind::kArc:
      return "arc";
    case InputKind::kFrame:
      return "frame";
  }
  return "?";
}

NodeInputBase::NodeInputBase(std::string node) : node_(std::move(node)) {
  bound_.fill(std::numeric_limits<size_t>::max());
  overflow_.fill(Overflow::kRefuseNewest);
  used_.fill(false);
  queued_.fill(0);
}

void NodeInputBase::setBound(InputKind kind, size_t bound, Overflow overflow) {
  if (bound < 1)
    throw std::invalid_argument(node_ + ": the input bound of " + inputKindName(kind) +
                                " must be >= 1");
  std::lock_guard<std::mutex> lock(mutex_);
  bound_[size_t(kind)] = bound;
  overflow_[size_t(kind)] = overflow;
  used_[size_t(kind)] = true;
}

void NodeInputBase::setTimestampPolicy(const TimestampPolicyOptions& options) {
  TimestampPolicy policy(options);  // validates, naming the input. key
  std::lock_guard<std::mutex> order(events_mutex_);
  timestamp_policy_ = policy;
}

void NodeInputBase::setCalibration(const CameraCalibration& calibration) {
  std::lock_guard<std::mutex> lock(mutex_);
  calibration_ = calibration;
  have_calibration_ = true;
  cv_.notify_all();
}

bool NodeInputBase::acceptCameraInfo(const sensor_msgs::CameraInfo& msg) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (have_calibration_) {
    if (int(msg.width) != calibration_.width || int(msg.height) != calibration_.height) {
      ++counters_.camera_info_refused;
      ROS_ERROR_THROTTLE(
          10,
          "%s: camera_info is %ux%u but the calibration in use is %dx%d: refused, keeping the "
          "first (%zu refused so far)",
          node_.c_str(), msg.width, msg.height, calibration_.width, calibration_.height,
          counters_.camera_info_refused);
    }
    return false;
  }
  try {
    calibration_ = calibrationFromMsg(msg);
  } catch (const std::invalid_argument& e) {
    ++counters_.camera_info_refused;
    ROS_WARN_THROTTLE(
        5, "%s: camera_info refused: %s; still waiting for a valid one (%zu refused so far)",
        node_.c_str(), e.what(), counters_.camera_info_refused);
    return false;
  }
  have_calibration_ = true;
  ROS_INFO("%s: calibration from camera_info: %dx%d, fx %.2f fy %.2f cx %.2f cy %.2f",
           node_.c_str(), calibration_.width, calibration_.height, calibration_.fx, calibration_.fy,
           calibration_.cx, calibration_.cy);
  size_t before = 0;
  for (const InputKindCounters& k : counters_.kinds) before += k.before_calibration;
  if (before > 0)
    ROS_INFO("%s: %zu inputs before the calibration were ignored", node_.c_str(), before);
  cv_.notify_all();
  return true;
}

bool NodeInputBase::hasCalibration() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return have_calibration_;
}

bool NodeInputBase::acceptEventPacket(const EventArray& msg, EventVector* events,
                                      std::string* reset_why) {
  events->clear();
  reset_why->clear();
  int width = 0, height = 0;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    InputKindCounters& c = counters_.kinds[size_t(InputKind::kEvents)];
    used_[size_t(InputKind::kEvents)] = true;
    ++c.in;
    const uint64_t gap = packet_sequence_.observe(msg.header.seq);
    if (gap > 0) {
      counters_.packets_lost += gap;
      ROS_WARN_THROTTLE(
          10,
          "%s: %lu event packets never reached the node (gap in header.seq before %u: the "
          "subscriber queue overflowed, the node is too slow for the data); %zu lost so far",
          node_.c_str(), static_cast<unsigned long>(gap), msg.header.seq, counters_.packets_lost);
    }
    if (!have_calibration_) {
      ++c.before_calibration;
      return false;
    }
    if (msg.events.empty()) {
      ++c.refused;
      ++counters_.packets_empty;
      ROS_WARN_THROTTLE(10, "%s: empty EventArray ignored (%zu so far)", node_.c_str(),
                        counters_.packets_empty);
      return false;
    }
    width = calibration_.width;
    height = calibration_.height;
    if (int(msg.width) != width || int(msg.height) != height) {
      ++c.refused;
      ++counters_.packets_wrong_size;
      ROS_ERROR_THROTTLE(
          5, "%s: EventArray is %ux%u but the calibration is %dx%d: packet refused (%zu so far)",
          node_.c_str(), msg.width, msg.height, width, height, counters_.packets_wrong_size);
      return false;
    }
  }
  // The conversion runs outside the lock: the worker may take its batch meanwhile.
  EventConversionStats stats;
  eventsFromMsg(msg, events, &stats);
  if (stats.dropped > 0) {
    size_t outside = 0;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      counters_.events_outside += stats.dropped;
      outside = counters_.events_outside;
    }
    ROS_WARN_THROTTLE(10, "%s: %zu events outside the %dx%d sensor dropped (%zu so far)",
                      node_.c_str(), stats.dropped, width, height, outside);
  }
  if (events->empty()) return false;
  // The timestamp policy, in arrival order (the caller holds events_mutex_ when it queues).
  EventVector ordered;
  const TimestampAction action = timestamp_policy_.process(*events, &ordered);
  events->swap(ordered);
  if (action == TimestampAction::kReset) *reset_why = timestamp_policy_.lastEvent();
  const std::string warning = timestamp_policy_.takeWarning();
  {
    std::lock_guard<std::mutex> lock(mutex_);
    counters_.timestamps = timestamp_policy_.stats();
    if (action == TimestampAction::kReset) counters_.last_reset = *reset_why;
  }
  if (!warning.empty()) {
    std::istringstream lines(warning);
    for (std::string line; std::getline(lines, line);)
      ROS_WARN("%s: %s%s", node_.c_str(), line.c_str(),
               line.find("reset at") != std::string::npos ? " (the node resets)" : "");
  }
  return !events->empty();
}

void NodeInputBase::countRefused(InputKind kind, bool queued) {
  std::lock_guard<std::mutex> lock(mutex_);
  used_[size_t(kind)] = true;
  if (!queued) ++counters_.kinds[size_t(kind)].in;
  ++counters_.kinds[size_t(kind)].refused;
}

void NodeInputBase::countBeforeCalibration(InputKind kind) {
  std::lock_guard<std::mutex> lock(mutex_);
  used_[size_t(kind)] = true;
  ++counters_.kinds[size_t(kind)].in;
  ++counters_.kinds[size_t(kind)].before_calibration;
}

NodeInputCounters NodeInputBase::counters() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return counters_;
}

std::string NodeInputBase::statusLine() const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::ostringstream s;
  for (size_t k = 0; k < kNumInputKinds; ++k) {
    if (!used_[k]) continue;
    const InputKindCounters& c = counters_.kinds[k];
    s << inputKindName(InputKind(k)) << " in=" << c.in;
    if (InputKind(k) == InputKind::kEvents)
      s << " lost=" << counters_.packets_lost << " empty=" << counters_.packets_empty
        << " wrong_size=" << counters_.packets_wrong_size
        << " outside=" << counters_.events_outside;
    s << " refused=" << c.refused << " before_calibration=" << c.before_calibration
      << " dropped=" << c.dropped;
    if (overflow_[k] == Overflow::kReplaceOldest) s << " superseded=" << c.superseded;
    s << "; ";
  }
  s << "camera_info refused=" << counters_.camera_info_refused;
  if (used_[size_t(InputKind::kEvents)]) {
    const TimestampPolicyStats& t = counters_.timestamps;
    s << "; overload thinned=" << counters_.events_thinned
      << " episodes=" << counters_.thinning_episodes << " keep=1/" << counters_.thinning
      << " max_queued=" << counters_.max_queued_events << "; timestamps jumps=" << t.backward_jumps
      << " late=" << t.events_absorbed
      << " largest_jump_ms=" << std::lround(t.largest_backward_jump_s * 1e3)
      << " resets=" << t.resets << " resets_backward=" << t.resets_backward
      << " resets_gap=" << t.resets_gap;
    if (!counters_.last_reset.empty()) s << " last_reset=\"" << counters_.last_reset << "\"";
  }
  return s.str();
}

bool NodeInputBase::waitForCalibration(CameraCalibration* calibration) {
  std::unique_lock<std::mutex> lock(mutex_);
  cv_.wait(lock, [this] { return stop_ || have_calibration_; });
  if (stop_) return false;
  *calibration = calibration_;
  return true;
}

void NodeInputBase::stop() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  cv_.notify_all();
}

NodeInputBase::Push NodeInputBase::admitLocked(InputKind kind, size_t size) {
  const size_t k = size_t(kind);
  used_[k] = true;
  InputKindCounters& c = counters_.kinds[k];
  if (kind != InputKind::kEvents) ++c.in;
  if (!have_calibration_) {
    ++c.before_calibration;
    return Push::kNoCalibration;
  }
  if (queued_[k] == 0 || queued_[k] + size <= bound_[k]) return Push::kQueued;
  if (overflow_[k] != Overflow::kRefuseNewest) return Push::kQueuedDroppedOldest;
  ++c.dropped;
  return Push::kFull;
}

void NodeInputBase::stepThinningLocked() {
  counters_.thinning *= 2;
  ++counters_.thinning_episodes;
  ROS_WARN_THROTTLE(5,
                    "%s: events queue full (%zu events), the worker cannot keep up: events "
                    "thinned to 1/%zu, evenly in time (%zu thinned so far)",
                    node_.c_str(), bound_[size_t(InputKind::kEvents)], counters_.thinning,
                    counters_.events_thinned);
}

void NodeInputBase::thinArrivalLocked(EventVector* events) {
  const size_t t = counters_.thinning;
  if (t <= 1) return;
  // Every t-th event, the phase running on across packets: the same fraction of every slice.
  size_t kept = 0;
  for (size_t i = 0; i < events->size(); ++i)
    if ((thin_phase_ + i) % t == 0) (*events)[kept++] = (*events)[i];
  thin_phase_ = (thin_phase_ + events->size()) % t;
  if (kept == 0) kept = 1;  // a packet keeps at least one event (and a reset it carries)
  counters_.events_thinned += events->size() - kept;
  events->resize(kept);
}

void NodeInputBase::recoverThinningLocked(size_t taken_events) {
  if (counters_.thinning > 1 && taken_events < bound_[size_t(InputKind::kEvents)] / 4) {
    counters_.thinning /= 2;
    ROS_INFO_THROTTLE(5, "%s: the worker caught up: events thinned to 1/%zu", node_.c_str(),
                      counters_.thinning);
  }
}

void NodeInputBase::warnDropped(InputKind kind) {
  size_t dropped = 0, bound = 0;
  Overflow overflow;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    dropped = counters_.kinds[size_t(kind)].dropped;
    bound = bound_[size_t(kind)];
    overflow = overflow_[size_t(kind)];
  }
  const char* unit = kind == InputKind::kEvents ? "events" : "messages";
  if (kind == InputKind::kEvents)
    ROS_WARN_THROTTLE(5,
                      "%s: events queue full (%zu events) at the coarsest thinning (1/%zu), the "
                      "worker cannot keep up: oldest packets dropped (%zu so far)",
                      node_.c_str(), bound, kMaxThinning, dropped);
  else if (overflow != Overflow::kRefuseNewest)
    ROS_WARN_THROTTLE(
        5, "%s: %s queue full (%zu %s), the worker cannot keep up: oldest dropped (%zu so far)",
        node_.c_str(), inputKindName(kind), bound, unit, dropped);
  else
    ROS_WARN_THROTTLE(
        5, "%s: %s queue full (%zu %s), the worker cannot keep up: newest dropped (%zu so far)",
        node_.c_str(), inputKindName(kind), bound, unit, dropped);
}

}  // namespace vwe_vo
