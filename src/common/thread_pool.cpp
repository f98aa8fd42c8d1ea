#include "vwe_vo/common/thread_pool.h"

namespace vwe_vo {

ThreadPool::ThreadPool(int num_threads) {
  num_threads_ = num_threads > 0 ? num_threads : std::max(1u, std::thread::hardware_concurrency());
  for (int i = 1; i < num_threads_; ++i) workers_.emplace_back(&ThreadPool::workerLoop, this, i);
}

ThreadPool::~ThreadPool() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  work_cv_.notify_all();
  for (auto& w : workers_) w.join();
}

void ThreadPool::drain(int thread_index) {
  std::unique_lock<std::mutex> lock(mutex_);
  while (next_chunk_ < num_chunks_) {
    const int chunk = next_chunk_++;
    lock.unlock();
    (*fn_)(chunk, thread_index);
    lock.lock();
  }
}

void ThreadPool::workerLoop(int thread_index) {
  long seen = 0;
  while (true) {
    {
      std::unique_lock<std::mutex> lock(mutex_);
      work_cv_.wait(lock, [&] { return stop_ || generation_ != seen; });
      if (stop_) return;
      seen = generation_;
      ++busy_;
    }
    drain(thread_index);
    {
      std::lock_guard<std::mutex> lock(mutex_);
      --busy_;
    }
    done_cv_.notify_all();
  }
}

void ThreadPool::run(int num_chunks, const std::function<void(int, int)>& fn) {
  if (num_chunks <= 0) return;
  if (workers_.empty() || num_chunks == 1) {
    for (int c = 0; c < num_chunks; ++c) fn(c, 0);
    return;
  }
  {
    std::lock_guard<std::mutex> lock(mutex_);
    fn_ = &fn;
    num_chunks_ = num_chunks;
    next_chunk_ = 0;
    ++generation_;
  }
  work_cv_.notify_all();
  drain(0);
  std::unique_lock<std::mutex> lock(mutex_);
  done_cv_.wait(lock, [&] { return busy_ == 0 && next_chunk_ >= num_chunks_; });
  fn_ = nullptr;
}

}  // namespace vwe_vo
