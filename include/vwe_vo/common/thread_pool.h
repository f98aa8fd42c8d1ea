// A small pool of long-lived worker threads for data-parallel loops in the core (the voting
// kernels). One pool per component; no thread is created per call or per message.
#pragma once

#include <condition_variable>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace vwe_vo {

class ThreadPool {
 public:
  /// num_threads <= 0 means std::thread::hardware_concurrency(). One thread runs inline.
  explicit ThreadPool(int num_threads = 0);
  ~ThreadPool();
  ThreadPool(const ThreadPool&) = delete;
  ThreadPool& operator=(const ThreadPool&) = delete;

  int numThreads() const { return num_threads_; }

  /// Runs fn(chunk, thread_index) for chunk in [0, num_chunks) on all threads and returns when
  /// all are done. Chunks are handed out dynamically. Not reentrant.
  void run(int num_chunks, const std::function<void(int chunk, int thread)>& fn);

 private:
  void workerLoop(int thread_index);
  void drain(int thread_index);

  int num_threads_;
  std::vector<std::thread> workers_;
  std::mutex mutex_;  // guards everything below
  std::condition_variable work_cv_, done_cv_;
  const std::function<void(int, int)>* fn_ = nullptr;
  int num_chunks_ = 0, next_chunk_ = 0, busy_ = 0;
  long generation_ = 0;
  bool stop_ = false;
};

}  // namespace vwe_vo
