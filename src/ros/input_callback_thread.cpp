#include "vwe_vo/ros/input_callback_thread.h"

#include "vwe_vo/ros/process_priority.h"

namespace vwe_vo {

InputCallbackThread::InputCallbackThread(std::chrono::milliseconds period)
    : period_(period), thread_(&InputCallbackThread::run, this) {}

InputCallbackThread::~InputCallbackThread() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  cv_.notify_all();
  if (thread_.joinable()) thread_.join();
}

InputCallbackThread& InputCallbackThread::instance() {
  static InputCallbackThread thread;
  return thread;
}

void InputCallbackThread::run() {
  nameThisThread("vwe_vo_input");
  std::unique_lock<std::mutex> lock(mutex_);
  while (!stop_) {
    lock.unlock();
    queue_.callAvailable(ros::WallDuration(0.0));
    lock.lock();
    cv_.wait_for(lock, period_, [this] { return stop_; });
  }
}

}  // namespace vwe_vo
