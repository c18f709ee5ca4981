// TaskDispatcher: where a component's tasks run, in what order, and never two at once.
#include "odonav/task_dispatcher.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <mutex>
#include <thread>
#include <vector>

namespace {

using odonav::TaskDispatcher;
using namespace std::chrono_literals;

// Runs the dispatcher on its own thread until stop is set; tick counts ticks and checks that no
// task or tick overlaps another.
struct Harness {
  TaskDispatcher dispatcher;
  std::atomic<bool> stop{false};
  std::atomic<int> inside{0};
  std::atomic<int> overlaps{0};
  std::atomic<int> ticks{0};
  std::thread runner;
  std::thread::id runner_id;

  void enter() {
    if (inside.fetch_add(1) != 0) ++overlaps;
    std::this_thread::sleep_for(50us);  // widen the window an overlap would need
    inside.fetch_sub(1);
  }
  void start() {
    runner = std::thread([this] {
      runner_id = std::this_thread::get_id();
      dispatcher.run([this] { return stop.load(); },
                     [this] {
                       enter();
                       ++ticks;
                     },
                     5ms);
    });
  }
  void finish() {
    stop = true;
    runner.join();
  }
};

TEST(TaskDispatcher, OnPostExecutesOnThePostingThreadInOrderAndNeverBesideAnotherTaskOrTick) {
  Harness h;
  h.dispatcher.set_mode(TaskDispatcher::Mode::kOnPost);
  std::mutex order_mutex;
  std::vector<int> early;  // posted before run(): queued, then executed by run() first, in order
  for (int i = 0; i < 3; ++i) h.dispatcher.post([&, i] { early.push_back(i); });
  EXPECT_EQ(h.dispatcher.queue_depth(), 3u);
  h.start();
  while (h.ticks.load() == 0) std::this_thread::sleep_for(1ms);
  EXPECT_EQ(early, (std::vector<int>{0, 1, 2}));
  EXPECT_EQ(h.dispatcher.queue_depth(), 0u);

  // Two posting threads (two listener threads), 300 tasks each, while run() ticks every 5 ms.
  constexpr int kTasks = 300;
  std::vector<int> seen[2];
  std::atomic<int> on_other_thread{0};
  const int ticks_before = h.ticks.load();
  auto poster = [&](int p) {
    const auto me = std::this_thread::get_id();
    for (int i = 0; i < kTasks; ++i) {
      h.dispatcher.post([&, p, i, me] {
        h.enter();
        if (std::this_thread::get_id() != me) ++on_other_thread;
        std::lock_guard<std::mutex> lock(order_mutex);
        seen[p].push_back(i);
      });
      EXPECT_EQ(h.dispatcher.queue_depth(), 0u);  // executed, not queued
    }
  };
  std::thread a(poster, 0), b(poster, 1);
  a.join();
  b.join();
  const int ticks_after_posts = h.ticks.load();
  h.finish();

  EXPECT_EQ(on_other_thread.load(), 0);
  EXPECT_EQ(h.overlaps.load(), 0);
  for (const auto& s : seen) {
    ASSERT_EQ(s.size(), static_cast<std::size_t>(kTasks));
    for (int i = 0; i < kTasks; ++i) EXPECT_EQ(s[i], i);
  }
  // A tick follows every task executed on post (and the timer adds its own).
  EXPECT_GE(ticks_after_posts - ticks_before, 2 * kTasks);

  // After run() returned, tasks queue again for the drain.
  int drained = 0;
  h.dispatcher.post([&] { ++drained; });
  EXPECT_EQ(drained, 0);
  EXPECT_EQ(h.dispatcher.queue_depth(), 1u);
  h.dispatcher.run_pending();
  EXPECT_EQ(drained, 1);
}

TEST(TaskDispatcher, QueuedExecutesOnTheRunningThreadInOrderAndTicksAfterBatches) {
  Harness h;
  h.dispatcher.set_mode(TaskDispatcher::Mode::kQueued);
  h.start();
  std::vector<int> seen;
  std::atomic<int> on_runner{0};
  constexpr int kTasks = 500;
  for (int i = 0; i < kTasks; ++i)
    h.dispatcher.post([&, i] {
      h.enter();
      if (std::this_thread::get_id() == h.runner_id) ++on_runner;
      seen.push_back(i);
    });
  while (h.dispatcher.queue_depth() > 0) std::this_thread::sleep_for(1ms);
  // The last batch may still be executing: a tick follows it.
  const int ticks = h.ticks.load();
  while (h.ticks.load() == ticks) std::this_thread::sleep_for(1ms);
  h.finish();
  EXPECT_EQ(h.overlaps.load(), 0);
  EXPECT_EQ(on_runner.load(), kTasks);
  ASSERT_EQ(seen.size(), static_cast<std::size_t>(kTasks));
  for (int i = 0; i < kTasks; ++i) EXPECT_EQ(seen[i], i);
}

TEST(TaskDispatcher, OnPostTicksOnTheTimerWhenNothingIsPosted) {
  Harness h;
  h.dispatcher.set_mode(TaskDispatcher::Mode::kOnPost);
  h.start();
  // Maximum waits and health depend on ticks without input: at least a few in generous time.
  const auto deadline = std::chrono::steady_clock::now() + 10s;
  while (h.ticks.load() < 4 && std::chrono::steady_clock::now() < deadline) std::this_thread::sleep_for(1ms);
  h.finish();
  EXPECT_GE(h.ticks.load(), 4);
}

}  // namespace
