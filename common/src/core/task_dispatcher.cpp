// Task execution of a component (task_dispatcher.hpp).
#include "odonav/task_dispatcher.hpp"

#include <thread>
#include <utility>

namespace odonav {

void TaskDispatcher::post(std::function<void()> task) {
  if (mode_ == Mode::kOnPost) {
    // Decide and queue under one lock: a task queued after run() drained the queue, or after it
    // returned and before the drain, would otherwise wait until the drain at shutdown.
    std::lock_guard<std::mutex> execute(execute_mutex_);
    if (execute_on_post_) {
      task();
      if (after_task_) after_task_();
    } else {
      enqueue(std::move(task));
    }
    return;
  }
  enqueue(std::move(task));
}

void TaskDispatcher::enqueue(std::function<void()> task) {
  {
    std::lock_guard<std::mutex> lock(queue_mutex_);
    queue_.push_back(std::move(task));
  }
  queue_changed_.notify_one();
}

std::size_t TaskDispatcher::queue_depth() const {
  std::lock_guard<std::mutex> lock(queue_mutex_);
  return queue_.size();
}

void TaskDispatcher::run(const std::function<bool()>& stop_requested, const std::function<void()>& tick,
                         std::chrono::milliseconds tick_period) {
  if (mode_ == Mode::kOnPost) {
    {
      // What was posted before run() goes first, in order; from then on post() executes.
      std::lock_guard<std::mutex> execute(execute_mutex_);
      run_pending();
      if (tick) tick();
      after_task_ = tick;
      execute_on_post_ = true;
    }
    while (!stop_requested()) {
      std::this_thread::sleep_for(tick_period);
      std::lock_guard<std::mutex> execute(execute_mutex_);
      if (tick) tick();
    }
    std::lock_guard<std::mutex> execute(execute_mutex_);
    execute_on_post_ = false;  // from now on tasks queue, for the drain
    after_task_ = nullptr;
    return;
  }
  auto next_tick = std::chrono::steady_clock::now();
  while (!stop_requested()) {
    std::deque<std::function<void()>> batch;
    {
      std::unique_lock<std::mutex> lock(queue_mutex_);
      queue_changed_.wait_until(lock, next_tick, [&] { return !queue_.empty(); });
      // Bounded batches keep ticks (watermarks, health) regular under a flood of samples.
      for (int i = 0; i < 256 && !queue_.empty(); ++i) {
        batch.push_back(std::move(queue_.front()));
        queue_.pop_front();
      }
    }
    std::lock_guard<std::mutex> execute(execute_mutex_);
    for (auto& task : batch) task();
    if (tick) tick();
    next_tick = std::chrono::steady_clock::now() + tick_period;
  }
}

void TaskDispatcher::run_pending() {
  while (true) {
    std::function<void()> task;
    {
      std::lock_guard<std::mutex> lock(queue_mutex_);
      if (queue_.empty()) return;
      task = std::move(queue_.front());
      queue_.pop_front();
    }
    task();
  }
}

}  // namespace odonav
