// Subscriptions whose callback runs in the thread that delivers the message: roscpp's network
// thread for a message from another process, the publisher's thread for one from the same
// process. For callbacks that only check a message and hand it to the node's worker (NodeInput),
// at the rate of a DAVIS driver's event packets (1 kHz): through a nodelet manager each packet
// otherwise wakes the manager's queue thread and one of its worker threads for every subscribing
// nodelet, ~6000 context switches per second for three nodelets, and on a small or virtualised
// computer those wake-ups cost more CPU than the callbacks themselves.
// Such a callback must not block, and must not subscribe to or unsubscribe from its own topic
// (roscpp holds the subscription's lock while it runs).
#pragma once

#include <ros/callback_queue_interface.h>
#include <ros/node_handle.h>
#include <ros/subscribe_options.h>

#include <boost/shared_ptr.hpp>
#include <cstdint>
#include <string>

namespace vwe_vo {

/// A callback queue that calls each callback as it is added. A callback another thread is
/// running (call() returns TryAgain) is retried until it has run: nothing is dropped.
class InlineCallbackQueue : public ros::CallbackQueueInterface {
 public:
  void addCallback(const ros::CallbackInterfacePtr& callback, uint64_t owner_id = 0) override;
  void removeByID(uint64_t /*owner_id*/) override {}  // nothing is ever queued
  /// The process's one instance (it holds no state).
  static InlineCallbackQueue* instance();
};

/// nh.subscribe(topic, queue_size, callback, obj) with the callback run inline (above).
template <typename M, typename C>
ros::Subscriber subscribeInline(ros::NodeHandle& nh, const std::string& topic, uint32_t queue_size,
                                void (C::*callback)(const boost::shared_ptr<const M>&), C* obj) {
  ros::SubscribeOptions options;
  options.template init<M>(
      topic, queue_size,
      [obj, callback](const boost::shared_ptr<const M>& msg) { (obj->*callback)(msg); });
  options.callback_queue = InlineCallbackQueue::instance();
  return nh.subscribe(options);
}

}  // namespace vwe_vo
