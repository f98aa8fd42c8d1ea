// One thread per process for the callbacks of the high-rate subscriptions (/dvs/events,
// /dvs/imu), which only check a message and hand it to the node's worker (NodeInput). It takes
// whatever arrived every kInputPeriod, so a driver's 1 kHz packets cost ~200 wake-ups per second
// for all nodes of a process together. Through a nodelet manager's own queues each packet wakes
// the manager's queue thread and one of its worker threads for every subscribing nodelet (on
// street_long ~18000 context switches per second, which on a small or virtualised computer cost
// more CPU than the callbacks). Running the callbacks in roscpp's network thread instead starves
// every other socket of the process when the input outruns the CPU (the nodelet bonds broke at
// street_long played at rate 2): here the network thread only reads, and a thread that falls
// behind leaves the packets in the subscriber's queue (kEventPacketQueue), as before.
#pragma once

#include <ros/callback_queue.h>
#include <ros/node_handle.h>
#include <ros/subscribe_options.h>

#include <boost/shared_ptr.hpp>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <string>
#include <thread>

namespace vwe_vo {

/// How often the input thread takes what arrived: 5 ms of latency against the workers' own
/// kGatherPeriod (10 ms) and a 0.15-0.3 s front-end window.
constexpr std::chrono::milliseconds kInputPeriod(5);

/// A callback queue served by its own thread every `period` (callAvailable, then a wait).
class InputCallbackThread {
 public:
  explicit InputCallbackThread(std::chrono::milliseconds period = kInputPeriod);
  ~InputCallbackThread();  // stops and joins the thread
  InputCallbackThread(const InputCallbackThread&) = delete;
  InputCallbackThread& operator=(const InputCallbackThread&) = delete;

  ros::CallbackQueue* queue() { return &queue_; }
  std::thread::id threadId() const { return thread_.get_id(); }
  /// The process's one instance, started at its first use.
  static InputCallbackThread& instance();

 private:
  void run();

  const std::chrono::milliseconds period_;
  ros::CallbackQueue queue_;
  std::mutex mutex_;
  std::condition_variable cv_;
  bool stop_ = false;
  std::thread thread_;  // last: starts once the members above exist
};

/// nh.subscribe(topic, queue_size, callback, obj) with the callback run by the input thread.
template <typename M, typename C>
ros::Subscriber subscribeInput(ros::NodeHandle& nh, const std::string& topic, uint32_t queue_size,
                               void (C::*callback)(const boost::shared_ptr<const M>&), C* obj) {
  ros::SubscribeOptions options;
  options.template init<M>(
      topic, queue_size,
      [obj, callback](const boost::shared_ptr<const M>& msg) { (obj->*callback)(msg); });
  options.callback_queue = InputCallbackThread::instance().queue();
  return nh.subscribe(options);
}

}  // namespace vwe_vo
