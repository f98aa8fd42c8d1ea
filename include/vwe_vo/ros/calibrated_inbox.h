// The hand-over between a node's ROS callbacks and its worker thread: a bounded queue of inputs
// that opens once the camera calibration is known (from ~calibration or the first valid
// camera_info), and the stop flag. Callbacks push; the worker waits for the calibration, then
// takes everything queued at once. Counting and warning about what was refused stay with the node.
#pragma once

#include <sensor_msgs/CameraInfo.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <mutex>

#include "vwe_vo/sensor/camera.h"
#include "vwe_vo/ros/event_input.h"

namespace vwe_vo {

template <typename T>
class CalibratedInbox {
 public:
  enum class Push { kQueued, kNoCalibration, kFull };

  /// A calibration known at start-up (~calibration): the inbox opens at once.
  void setCalibration(const CameraCalibration& calibration) {
    std::lock_guard<std::mutex> lock(mutex_);
    calibration_ = calibration;
    have_calibration_ = true;
    cv_.notify_all();
  }
  /// camera_info through acceptCameraInfo (the first valid one opens the inbox; another size is
  /// refused with an error). True if this message opened it.
  bool acceptCameraInfo(const sensor_msgs::CameraInfo& msg, const char* node, std::atomic<size_t>& refused) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!vwe_vo::acceptCameraInfo(msg, node, &have_calibration_, &calibration_, refused)) return false;
    cv_.notify_all();
    return true;
  }
  bool hasCalibration() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return have_calibration_;
  }
  /// The sensor size of the calibration; false while there is none.
  bool sensorSize(int* width, int* height) const {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!have_calibration_) return false;
    *width = calibration_.width;
    *height = calibration_.height;
    return true;
  }
  /// Queues `item` unless there is no calibration yet or max_size items wait already.
  Push push(T&& item, size_t max_size) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!have_calibration_) return Push::kNoCalibration;
    if (queue_.size() >= max_size) return Push::kFull;
    queue_.push_back(std::move(item));
    cv_.notify_one();
    return Push::kQueued;
  }

  /// Worker: blocks until the calibration is known; false if stopped first.
  bool waitForCalibration(CameraCalibration* calibration) {
    std::unique_lock<std::mutex> lock(mutex_);
    cv_.wait(lock, [this] { return stop_ || have_calibration_; });
    if (stop_) return false;
    *calibration = calibration_;
    return true;
  }
  /// Worker: everything queued (waiting up to `timeout` for something); false once stopped.
  bool takeAll(std::deque<T>* batch, std::chrono::milliseconds timeout) {
    std::unique_lock<std::mutex> lock(mutex_);
    cv_.wait_for(lock, timeout, [this] { return stop_ || !queue_.empty(); });
    if (stop_) return false;
    batch->clear();
    batch->swap(queue_);
    return true;
  }
  /// Wakes the worker for good (its waits return false).
  void stop() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      stop_ = true;
    }
    cv_.notify_all();
  }

 private:
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::deque<T> queue_;
  bool have_calibration_ = false;
  CameraCalibration calibration_;
  bool stop_ = false;
};

}  // namespace vwe_vo
