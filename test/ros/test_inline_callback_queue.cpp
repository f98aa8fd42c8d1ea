// InlineCallbackQueue: the callbacks of the high-rate subscriptions run in the delivering thread,
// and one that another thread is running is retried, never dropped.
#include <gtest/gtest.h>

#include <atomic>
#include <boost/make_shared.hpp>
#include <chrono>
#include <mutex>
#include <thread>
#include <vector>

#include "vwe_vo/ros/inline_callback_queue.h"

namespace vwe_vo {
namespace {

/// Answers TryAgain `busy` times, then runs (Success), recording the thread that ran it.
class CountingCallback : public ros::CallbackInterface {
 public:
  explicit CountingCallback(int busy) : busy_(busy) {}
  CallResult call() override {
    ++calls;
    if (busy_ > 0) {
      --busy_;
      return TryAgain;
    }
    ran_in = std::this_thread::get_id();
    ++runs;
    return Success;
  }
  int calls = 0, runs = 0;
  std::thread::id ran_in;

 private:
  int busy_;
};

TEST(InlineCallbackQueue, RunsEachCallbackAtOnceInTheAddingThread) {
  auto cb = boost::make_shared<CountingCallback>(0);
  InlineCallbackQueue::instance()->addCallback(cb, 1);
  EXPECT_EQ(cb->runs, 1);
  EXPECT_EQ(cb->calls, 1);
  EXPECT_EQ(cb->ran_in, std::this_thread::get_id());
  InlineCallbackQueue::instance()->addCallback(cb, 1);
  EXPECT_EQ(cb->runs, 2);
}

TEST(InlineCallbackQueue, RetriesACallbackThatIsBusyUntilItRuns) {
  auto cb = boost::make_shared<CountingCallback>(3);
  InlineCallbackQueue::instance()->addCallback(cb, 7);
  EXPECT_EQ(cb->calls, 4);
  EXPECT_EQ(cb->runs, 1);
}

TEST(InlineCallbackQueue, InvalidIsNotRetried) {
  struct Gone : ros::CallbackInterface {
    int calls = 0;
    CallResult call() override {
      ++calls;
      return Invalid;
    }
  };
  auto cb = boost::make_shared<Gone>();
  InlineCallbackQueue::instance()->addCallback(cb, 2);
  EXPECT_EQ(cb->calls, 1);
}

/// A subscription's queue as roscpp runs it without concurrent callbacks: a call that finds the
/// callback running in another thread answers TryAgain. Its first run holds on until another
/// thread has found it busy, so that the retry is exercised.
class NonReentrant : public ros::CallbackInterface {
 public:
  CallResult call() override {
    std::unique_lock<std::mutex> lock(running_, std::try_to_lock);
    if (!lock.owns_lock()) {
      ++busy;
      return TryAgain;
    }
    const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(10);
    while (runs.load() == 0 && busy.load() == 0 && std::chrono::steady_clock::now() < give_up)
      std::this_thread::yield();
    const int n = runs.load();
    std::this_thread::yield();  // widen the window in which the other thread finds it busy
    runs.store(n + 1);          // not atomic as a whole: only correct without overlap
    return Success;
  }
  std::atomic<int> runs{0}, busy{0};

 private:
  std::mutex running_;
};

TEST(InlineCallbackQueue, TwoDeliveringThreadsLoseNothing) {
  auto cb = boost::make_shared<NonReentrant>();
  constexpr int kPerThread = 20000;
  auto deliver = [&] {
    for (int i = 0; i < kPerThread; ++i) InlineCallbackQueue::instance()->addCallback(cb, 3);
  };
  std::thread a(deliver), b(deliver);
  a.join();
  b.join();
  EXPECT_GT(cb->busy.load(), 0);               // the other thread did find it running
  EXPECT_EQ(cb->runs.load(), 2 * kPerThread);  // and every delivery still ran exactly once
}

TEST(InlineCallbackQueue, RemoveByIdIsHarmless) {
  InlineCallbackQueue::instance()->removeByID(1);  // nothing is ever queued
  auto cb = boost::make_shared<CountingCallback>(0);
  InlineCallbackQueue::instance()->addCallback(cb, 1);
  EXPECT_EQ(cb->runs, 1);
}

}  // namespace
}  // namespace vwe_vo
