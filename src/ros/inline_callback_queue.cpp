#include "vwe_vo/ros/inline_callback_queue.h"

#include <thread>

namespace vwe_vo {

void InlineCallbackQueue::addCallback(const ros::CallbackInterfacePtr& callback,
                                      uint64_t /*owner_id*/) {
  // TryAgain: the subscription's callback is running in another thread (two publishers
  // delivering at once); it finishes soon and this message is then taken.
  for (;;) {
    if (callback->ready() && callback->call() != ros::CallbackInterface::TryAgain) return;
    std::this_thread::yield();
  }
}

InlineCallbackQueue* InlineCallbackQueue::instance() {
  static InlineCallbackQueue queue;
  return &queue;
}

}  // namespace vwe_vo
