// The input of every node: the hand-over between its ROS callbacks and its worker thread. It opens
// once the camera calibration is known (~calibration, or the first valid camera_info), checks and
// converts event packets (size against the calibration, events outside the sensor, header.seq
// gaps), puts the event stamps through the pipeline's one timestamp policy
// (sensor/timestamp_policy, the YAML input: section, as the offline runner does), bounds the queue
// per input kind (event packets by their total events, every other kind by its own message count,
// so that event packets never starve the IMU, odometry or trajectories), thins the queued events
// when the worker falls behind (the overload policy below), counts everything refused, thinned or
// dropped per kind, and formats those counters for the node's status line.
//
// Overload policy (docs/method.md, "Overload"): an event packet that would take the queue past its
// bound thins the queue instead of being dropped: every queued packet keeps every second event
// (time-uniform: the same fraction of every time slice, so no data time is lost and nothing
// downstream sees a gap), and packets arriving afterwards are thinned to the same fraction, halved
// again while the queue does not fit, down to 1 / kMaxThinning. The fraction doubles back each
// time the worker has drained the queue below a quarter of its bound. Only a queue that is full at
// 1 / kMaxThinning drops its oldest packets (counted as dropped). Memory stays below the bound:
// at most bound x sizeof(PixelEvent) (16 bytes) queued, plus one packet being converted.
#pragma once

#include <sensor_msgs/CameraInfo.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <mutex>
#include <string>
#include <utility>

#include "vwe_vo/EventArray.h"
#include "vwe_vo/sensor/camera.h"
#include "vwe_vo/sensor/events.h"
#include "vwe_vo/sensor/subsample.h"
#include "vwe_vo/sensor/timestamp_policy.h"

namespace vwe_vo {

/// What a node receives. Each kind has its own bound and counters.
enum class InputKind { kEvents, kImu, kOdometry, kTrajectory, kArc, kFrame };
constexpr size_t kNumInputKinds = 6;
/// "events", "imu", "odom", "trajectory", "arc", "frame" (the keys of the status line).
const char* inputKindName(InputKind kind);

/// What happens to an input that finds its kind's queue full.
enum class Overflow {
  kRefuseNewest,   // the arriving input is dropped (a stream the worker must see in order)
  kDropOldest,     // the oldest queued input of the kind goes (a live stream: frames)
  kReplaceOldest,  // as kDropOldest, but expected (only the newest matters): counted as
                   // superseded, not as lost, and not warned about
};

/// The coarsest thinning of the overload policy: at least 1 event in 8 is kept. The front-end's
/// standstill test counts events per second (frontend.standstill_event_rate_hz, 30 kev/s): at 1/8
/// a scene of 240 kev/s or more still moves, and a DAVIS346 in a lit scene gives 1-5 Mev/s.
constexpr size_t kMaxThinning = 8;

/// A worker takes its input at most this often (NodeInput::takeAll): 10 ms of latency against a
/// 0.15-0.3 s front-end window, for ~100 instead of ~1000 wake-ups per second and node.
constexpr std::chrono::milliseconds kGatherPeriod(10);

/// The subscriber queue of /dvs/events [packets]: 5 s of a driver's 1 kHz packets, 2.5 s of a bag
/// played at rate 2. The callbacks only move packets into the node's queue (bounded by events,
/// above); this one absorbs a burst from a publisher that stalled, instead of dropping it.
constexpr uint32_t kEventPacketQueue = 5000;

/// The counters of one input kind.
struct InputKindCounters {
  size_t in = 0;                  // messages that reached the callback
  size_t refused = 0;             // refused by a check or the conversion
  size_t before_calibration = 0;  // arrived while there was no calibration yet
  size_t dropped = 0;             // lost to a full queue (refused or pushed out)
  size_t superseded = 0;          // replaced by a newer one (Overflow::kReplaceOldest): not lost
};

/// Everything counted at the input (a snapshot).
struct NodeInputCounters {
  std::array<InputKindCounters, kNumInputKinds> kinds;
  size_t packets_lost = 0;        // event packets ROS dropped before the callback (header.seq gaps)
  size_t packets_empty = 0;       // event packets without events (counted in refused)
  size_t packets_wrong_size = 0;  // width x height not the calibration's (counted in refused)
  size_t events_outside = 0;      // events outside the packet's width x height, dropped
  size_t camera_info_refused = 0;   // invalid camera_info, or one of another size than the first
  size_t events_thinned = 0;        // events removed by the overload policy's thinning
  size_t thinning_episodes = 0;     // times the queue filled and the thinning stepped up
  size_t thinning = 1;              // the current fraction kept is 1 / thinning
  size_t max_queued_events = 0;     // the largest number of queued events seen
  TimestampPolicyStats timestamps;  // the timestamp policy's counters
  std::string last_reset;           // why the policy last reset (empty: never)
  const InputKindCounters& operator[](InputKind kind) const { return kinds[size_t(kind)]; }
};

/// The part of NodeInput that does not depend on the node's queued type.
class NodeInputBase {
 public:
  enum class Push { kQueued, kNoCalibration, kFull, kQueuedDroppedOldest };

  /// `node` names the node in every warning.
  explicit NodeInputBase(std::string node);
  NodeInputBase(const NodeInputBase&) = delete;
  NodeInputBase& operator=(const NodeInputBase&) = delete;

  /// The bound of a kind's queue: for kEvents the number of events in queued packets, for every
  /// other kind the number of queued messages. Unbounded until set. Call before the callbacks run.
  void setBound(InputKind kind, size_t bound, Overflow overflow = Overflow::kRefuseNewest);

  /// The timestamp policy's options (the YAML input: section; defaults otherwise). Call before the
  /// callbacks run; throws std::invalid_argument naming the input. key.
  void setTimestampPolicy(const TimestampPolicyOptions& options);

  /// A calibration known at start-up (~calibration): the input opens at once.
  void setCalibration(const CameraCalibration& calibration);
  /// The camera_info callback. The first valid message opens the input (logged, with the number of
  /// inputs ignored before it); before that an invalid one is refused; afterwards one of another
  /// size is refused and the first kept. Refusals are counted and warned about. True if it opened.
  bool acceptCameraInfo(const sensor_msgs::CameraInfo& msg);
  bool hasCalibration() const;

  /// The first half of the event-packet callback: counts the packet and any header.seq gap before
  /// it, refuses it without a calibration, when empty or when its width x height is not the
  /// calibration's, and converts it (events outside the sensor dropped). All counted and warned
  /// about (throttled). Then the timestamp policy: events older than the newest are dropped and
  /// counted, a large jump back or a long gap sets *reset_why (the worker resets its estimator
  /// before these events); jumps and resets are warned about (jumps throttled by data time). False
  /// when nothing is left to queue.
  bool acceptEventPacket(const EventArray& msg, EventVector* events, std::string* reset_why);

  /// A message of `kind` the node's own check or conversion refused: counted as refused, and as
  /// in unless it had been queued (`queued`: refused by the worker after push()).
  void countRefused(InputKind kind, bool queued = false);
  /// A message of `kind` that arrived before the calibration and is not queued (counted).
  void countBeforeCalibration(InputKind kind);

  NodeInputCounters counters() const;
  /// The counters as one line of `key=value` fields, e.g. "events in=120 lost=0 empty=3
  /// wrong_size=0 outside=15 before_calibration=0 dropped=0; odom in=60 refused=0 ...; camera_info
  /// refused=0". Kinds the node never bounded nor received are left out.
  std::string statusLine() const;

  /// Worker: blocks until the calibration is known; false if stopped first.
  bool waitForCalibration(CameraCalibration* calibration);
  /// Wakes the worker for good (its waits return false).
  void stop();

 protected:
  /// The overload policy (mutex_ held): thins an arriving packet to the current fraction (every
  /// k-th event, the phase running on across packets; counted).
  void thinArrivalLocked(EventVector* events);
  /// Halves the fraction kept (counted, warned about, throttled).
  void stepThinningLocked();
  /// After the worker took its batch (mutex_ held): the fraction recovers.
  void recoverThinningLocked(size_t taken_events);
  /// Counts an arrival (event packets are counted by acceptEventPacket) and decides whether it may
  /// be queued; the caller holds mutex_. `size` is the item's weight against its kind's bound
  /// (events for kEvents, 1 otherwise); an item alone in its kind's queue always fits. Returns
  /// kFull when the item must be refused, kQueuedDroppedOldest when the caller must first drop
  /// the oldest queued items of the kind until queued_[kind] + size fits.
  Push admitLocked(InputKind kind, size_t size);
  void warnDropped(InputKind kind);

  const std::string node_;
  mutable std::mutex mutex_;  // guards everything below and the derived class's queue
  std::condition_variable cv_;
  bool stop_ = false;
  bool have_calibration_ = false;
  CameraCalibration calibration_;
  std::array<size_t, kNumInputKinds> bound_;
  std::array<Overflow, kNumInputKinds> overflow_;
  std::array<bool, kNumInputKinds> used_;
  std::array<size_t, kNumInputKinds> queued_;  // weight queued per kind
  NodeInputCounters counters_;
  SequenceGapCounter packet_sequence_;  // header.seq of the event packets
  // Event packets go through the policy and into the queue in arrival order (events_mutex_ is
  // taken before mutex_).
  std::mutex events_mutex_;
  TimestampPolicy timestamp_policy_;  // guarded by events_mutex_
  size_t thin_phase_ = 0;             // the arrivals' thinning phase (mutex_)
};

/// The node's queue of T (its own tagged input struct), on top of NodeInputBase.
template <typename T>
class NodeInput : public NodeInputBase {
 public:
  using NodeInputBase::NodeInputBase;

  /// Queues `item` of `kind` (weight `size` against the kind's bound: its events for kEvents)
  /// unless there is no calibration yet or the kind's queue is full (then by its Overflow).
  Push push(InputKind kind, T&& item, size_t size = 1) {
    bool warn = false;
    Push result;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      result = admitLocked(kind, size);
      if (result == Push::kFull) {
        warn = true;
      } else if (result != Push::kNoCalibration) {
        const bool was_empty = queue_.empty();
        if (result == Push::kQueuedDroppedOldest) {
          warn = overflow_[size_t(kind)] == Overflow::kDropOldest;
          for (auto it = queue_.begin();
               it != queue_.end() && queued_[size_t(kind)] + size > bound_[size_t(kind)];) {
            if (it->kind == kind) {
              queued_[size_t(kind)] -= it->size;
              InputKindCounters& c = counters_.kinds[size_t(kind)];
              ++(overflow_[size_t(kind)] == Overflow::kReplaceOldest ? c.superseded : c.dropped);
              it = queue_.erase(it);
            } else {
              ++it;
            }
          }
        }
        queue_.push_back(Slot{kind, size, std::move(item)});
        queued_[size_t(kind)] += size;
        if (was_empty) cv_.notify_one();  // otherwise the worker was woken already
      }
    }
    if (warn) warnDropped(kind);
    return result;
  }

  /// The whole event-packet callback: acceptEventPacket, then queues make(events) (a T with the
  /// members `EventVector events` and `std::string reset_why`, set from the timestamp policy) as
  /// kEvents weighted by its events, under the overload policy. True if queued.
  template <typename Make>
  bool pushEventPacket(const EventArray& msg, Make&& make) {
    std::lock_guard<std::mutex> order(events_mutex_);
    EventVector events;
    std::string reset_why;
    if (!acceptEventPacket(msg, &events, &reset_why)) return false;
    bool warn = false;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      constexpr size_t k = size_t(InputKind::kEvents);
      if (!have_calibration_) return false;  // (the calibration cannot go away; for clarity)
      const bool was_empty = queue_.empty();
      thinArrivalLocked(&events);
      // Overflow: everything queued and the arrival keep every second event, until it fits.
      while (queued_[k] > 0 && queued_[k] + events.size() > bound_[k] &&
             counters_.thinning < kMaxThinning) {
        stepThinningLocked();
        for (Slot& s : queue_) {
          if (s.kind != InputKind::kEvents) continue;
          const size_t removed = keepEverySecond(&s.item.events);
          s.size -= removed;
          queued_[k] -= removed;
          counters_.events_thinned += removed;
        }
        counters_.events_thinned += keepEverySecond(&events);
      }
      // A queue still full at the coarsest thinning: the oldest packets go.
      for (auto it = queue_.begin();
           it != queue_.end() && queued_[k] > 0 && queued_[k] + events.size() > bound_[k];) {
        if (it->kind == InputKind::kEvents) {
          queued_[k] -= it->size;
          ++counters_.kinds[k].dropped;
          it = queue_.erase(it);
          warn = true;
        } else {
          ++it;
        }
      }
      const size_t n = events.size();
      T item = make(std::move(events));
      item.reset_why = std::move(reset_why);
      queue_.push_back(Slot{InputKind::kEvents, n, std::move(item)});
      queued_[k] += n;
      counters_.max_queued_events = std::max(counters_.max_queued_events, queued_[k]);
      if (was_empty) cv_.notify_one();  // otherwise the worker was woken already
    }
    if (warn) warnDropped(InputKind::kEvents);
    return true;
  }

  /// Worker: everything queued, in arrival order (waiting up to `timeout` for something); false
  /// once stopped. A take within kGatherPeriod of the previous one first waits out the rest of
  /// that period, so that a stream of small packets (a driver's 1 kHz) wakes the worker about
  /// once per period instead of once per packet.
  bool takeAll(std::deque<T>* batch, std::chrono::milliseconds timeout) {
    std::deque<Slot> slots;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      cv_.wait_for(lock, timeout, [this] { return stop_ || !queue_.empty(); });
      if (!queue_.empty())
        cv_.wait_until(lock, last_take_ + kGatherPeriod, [this] { return stop_; });
      if (stop_) return false;
      if (!queue_.empty()) last_take_ = std::chrono::steady_clock::now();
      slots.swap(queue_);
      recoverThinningLocked(queued_[size_t(InputKind::kEvents)]);
      queued_.fill(0);
    }
    batch->clear();
    for (Slot& s : slots) batch->push_back(std::move(s.item));
    return true;
  }

 private:
  struct Slot {
    InputKind kind;
    size_t size;
    T item;
  };
  std::deque<Slot> queue_;                             // guarded by mutex_
  std::chrono::steady_clock::time_point last_take_{};  // of a non-empty batch (mutex_)
};

}  // namespace vwe_vo
