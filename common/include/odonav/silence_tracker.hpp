#pragma once
// Edge detection of silence: one event when something goes silent and one when its data returns,
// however often the silence is reported. Used for the DDS deadline (Fast DDS 2.9 calls
// on_requested_deadline_missed once per deadline period for every silent instance, for as long as
// it stays silent, docs/DDS.md §4) and for silent peers (odonav/peer_tracker.hpp). No DDS here.
#include <mutex>
#include <set>

namespace odonav {

/// Tracks which keys (anything ordered: a DDS InstanceHandle_t, a writer id) are silent.
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

}  // namespace odonav

namespace odonav::dds {
using odonav::SilenceTracker;
}  // namespace odonav::dds
