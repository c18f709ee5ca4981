#pragma once
// Where and when a component's tasks (its readers' samples, operator commands) are executed: one at
// a time, in the order each posting thread posted them, with a tick after them and at least every
// tick period. Middleware-free (odonav::dds::ComponentRuntime owns one), so the rule is unit-tested
// without a participant.
#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <deque>
#include <functional>
#include <mutex>

namespace odonav {

class TaskDispatcher {
 public:
  /// kQueued: post() queues; run()'s thread executes the queue in batches, then ticks. The posting
  /// thread (a middleware listener) only copies, so a slow task (file I/O) never delays reception.
  /// kOnPost: while run() runs, post() executes the task at once on the posting thread, then the
  /// tick, under the dispatcher's mutex; run()'s thread only ticks every tick period. No thread
  /// wake-up per task: for tasks that are short and never block. Before run() and after it returns,
  /// tasks are queued as with kQueued (run() executes the ones posted before it; run_pending() the
  /// ones after: the drain).
  enum class Mode { kQueued, kOnPost };

  /// Set before run().
  void set_mode(Mode mode) { mode_ = mode; }
  Mode mode() const { return mode_; }

  /// Thread-safe. Executes or queues `task` as the mode says.
  void post(std::function<void()> task);
  /// Tasks waiting in the queue (0 with kOnPost while run() runs).
  std::size_t queue_depth() const;

  /// Executes tasks and ticks (see Mode) until stop_requested() returns true (checked at least
  /// every tick_period); returns then, leaving queued tasks queued. Tasks and ticks never overlap.
  void run(const std::function<bool()>& stop_requested, const std::function<void()>& tick,
           std::chrono::milliseconds tick_period);
  /// Executes every queued task on the calling thread (the drain, once nothing posts any more).
  void run_pending();

 private:
  void enqueue(std::function<void()> task);

  Mode mode_ = Mode::kQueued;
  std::mutex execute_mutex_;          // held while a task or the tick runs
  bool execute_on_post_ = false;      // kOnPost, under execute_mutex_: run() is running
  std::function<void()> after_task_;  // the tick, under execute_mutex_
  mutable std::mutex queue_mutex_;
  std::condition_variable queue_changed_;
  std::deque<std::function<void()>> queue_;
};

}  // namespace odonav
