// InputCallbackThread: the callbacks of the high-rate subscriptions run, in order, on the one
// input thread (not in the thread that delivers them), batched by its period, and a subscription
// removed while its callbacks wait never runs them.
#include <gtest/gtest.h>

#include <atomic>
#include <boost/make_shared.hpp>
#include <chrono>
#include <mutex>
#include <thread>
#include <vector>

#include "vwe_vo/ros/input_callback_thread.h"

namespace vwe_vo {
namespace {

/// Records the order and the threads of its calls.
struct Log {
  std::mutex mutex;
  std::vector<int> order;
  std::vector<std::thread::id> threads;
  size_t size() {
    std::lock_guard<std::mutex> lock(mutex);
    return order.size();
  }
};

class Recording : public ros::CallbackInterface {
 public:
  Recording(Log* log, int id) : log_(log), id_(id) {}
  CallResult call() override {
    std::lock_guard<std::mutex> lock(log_->mutex);
    log_->order.push_back(id_);
    log_->threads.push_back(std::this_thread::get_id());
    return Success;
  }

 private:
  Log* log_;
  int id_;
};

bool waitFor(Log* log, size_t n, std::chrono::seconds limit = std::chrono::seconds(10)) {
  const auto end = std::chrono::steady_clock::now() + limit;
  while (log->size() < n && std::chrono::steady_clock::now() < end)
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  return log->size() >= n;
}

TEST(InputCallbackThread, RunsEveryCallbackInOrderOnItsOwnThread) {
  InputCallbackThread input(std::chrono::milliseconds(2));
  Log log;
  constexpr int kN = 5000;
  for (int i = 0; i < kN; ++i)
    input.queue()->addCallback(boost::make_shared<Recording>(&log, i), 1);
  ASSERT_TRUE(waitFor(&log, kN));
  for (int i = 0; i < kN; ++i) ASSERT_EQ(log.order[size_t(i)], i);
  for (const std::thread::id& t : log.threads) {
    EXPECT_EQ(t, input.threadId());
    ASSERT_NE(t, std::this_thread::get_id());
  }
}

TEST(InputCallbackThread, TwoDeliveringThreadsLoseNothing) {
  InputCallbackThread input(std::chrono::milliseconds(1));
  Log log;
  constexpr int kPerThread = 20000;
  auto deliver = [&](int base) {
    for (int i = 0; i < kPerThread; ++i)
      input.queue()->addCallback(boost::make_shared<Recording>(&log, base + i), uint64_t(base));
  };
  std::thread a(deliver, 0), b(deliver, kPerThread);
  a.join();
  b.join();
  ASSERT_TRUE(waitFor(&log, 2 * kPerThread));
  std::vector<int> seen(2 * kPerThread, 0);
  for (int id : log.order) ++seen[size_t(id)];
  for (int s : seen) ASSERT_EQ(s, 1);  // each delivery ran exactly once
}

/// Adds a sentinel and returns once the thread has run it: the thread then waits a whole period.
void syncWithPass(InputCallbackThread* input, Log* log) {
  const size_t n = log->size();
  input->queue()->addCallback(boost::make_shared<Recording>(log, -1), 99);
  ASSERT_TRUE(waitFor(log, n + 1));
}

TEST(InputCallbackThread, BatchesByItsPeriod) {
  // Callbacks added while the thread waits run together at the end of its period, not one by one
  // as they arrive: the thread sleeps through a burst.
  InputCallbackThread input(std::chrono::milliseconds(2000));
  Log log;
  syncWithPass(&input, &log);
  for (int i = 0; i < 10; ++i)
    input.queue()->addCallback(boost::make_shared<Recording>(&log, i), 1);
  EXPECT_EQ(log.size(), 1u);  // the sentinel only
  ASSERT_TRUE(waitFor(&log, 11));
  for (int i = 0; i < 10; ++i) EXPECT_EQ(log.order[size_t(i) + 1], i);
}

TEST(InputCallbackThread, ARemovedOwnerIsNeverCalled) {
  InputCallbackThread input(std::chrono::milliseconds(2000));
  Log log;
  syncWithPass(&input, &log);
  input.queue()->addCallback(boost::make_shared<Recording>(&log, 1), 7);
  input.queue()->addCallback(boost::make_shared<Recording>(&log, 2), 8);
  input.queue()->removeByID(7);  // a subscriber shut down before its packet was taken
  ASSERT_TRUE(waitFor(&log, 2));
  syncWithPass(&input, &log);  // one more whole pass
  ASSERT_EQ(log.size(), 3u);
  EXPECT_EQ(log.order[1], 2);
}

TEST(InputCallbackThread, StopsPromptly) {
  const auto t0 = std::chrono::steady_clock::now();
  { InputCallbackThread input(std::chrono::seconds(60)); }
  EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(5));
}

}  // namespace
}  // namespace vwe_vo
