#pragma once
// A vector that one thread appends to (a DDS reader's callback) while another reads copies of it:
// for the tests and benchmarks that collect what a topic delivers.
#include <cstddef>
#include <mutex>
#include <optional>
#include <utility>
#include <vector>

namespace odonav::test {

/// Thread-safe append-only list: push_back from any thread, copy() and size() from any other.
template <class T>
class LockedVector {
 public:
  void push_back(T value) {
    std::lock_guard<std::mutex> lock(mutex_);
    values_.push_back(std::move(value));
  }
  /// The values so far, in the order they were appended.
  std::vector<T> copy() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return values_;
  }
  std::size_t size() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return values_.size();
  }
  /// The last value appended, if any.
  std::optional<T> last() const {
    std::lock_guard<std::mutex> lock(mutex_);
    if (values_.empty()) return std::nullopt;
    return values_.back();
  }

 private:
  mutable std::mutex mutex_;
  std::vector<T> values_;
};

}  // namespace odonav::test
