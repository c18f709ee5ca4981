#pragma once
// Edge detection of the DDS deadline: Fast DDS 2.9 calls on_requested_deadline_missed once per
// deadline period for every silent instance, for as long as it stays silent (docs/DDS.md §4).
// Users want one event when an instance goes silent and one when its data returns.
#include <mutex>
#include <set>

namespace odonav::dds {

/// Tracks which instances (Key: anything ordered, e.g. a DDS InstanceHandle_t) are silent.
/// Thread-safe: the deadline and the data paths run on different middleware threads.
template <class Key>
class SilenceTracker {
 public:
  /// A deadline was missed for `key`. Returns true only on the edge (the instance was not already
  /// silent): the caller reports "went silent" exactly then.
  bool on_deadline_missed(const Key& key) {
    std::lock_guard<std::mutex> lock(mutex_);
    return silent_.insert(key).second;
  }

  /// Data arrived for `key`. Returns true only if the instance was silent: "data returned".
  bool on_data(const Key& key) {
    std::lock_guard<std::mutex> lock(mutex_);
    return silent_.erase(key) > 0;
  }

  /// Whether `key` is silent now.
  bool is_silent(const Key& key) const {
    std::lock_guard<std::mutex> lock(mutex_);
    return silent_.count(key) > 0;
  }

 private:
  mutable std::mutex mutex_;
  std::set<Key> silent_;
};

}  // namespace odonav::dds
