#pragma once
// Which discovered producers are silent. A component's readers report each matched writer (with the
// name of the participant that owns it), each sample and each unmatch; the tracker says which
// writers have sent nothing for `silence_s` while another writer of the component was heard within
// that time. That is a peer that is discovered but cut off (a transport that stopped delivering,
// a stalled or frozen process still holding its lease, a killed one until its lease expires),
// as opposed to a pause of the whole data flow (end of data, everything stopped), which is not a
// peer's fault and is reported by the inputs' own checks.
// Clock: any monotonic seconds the caller drives (the steady clock in the nodes). No DDS here.
// Thread-safe: readers report from middleware threads, the component asks from its worker.
#include <cstddef>
#include <cstdint>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "odonav/silence_tracker.hpp"

namespace odonav {

class PeerTracker {
 public:
  /// One matched writer that is silent.
  struct SilentPeer {
    std::string stream;  ///< what it publishes, e.g. "odometer"
    std::string peer;    ///< the participant that owns it, e.g. "odonav-gateway"
    double silent_s;     ///< since its last sample, or since it was matched if it never sent one
  };
  /// An edge: a writer went silent (silent = true) or was heard again after being reported silent.
  struct Edge {
    SilentPeer who;
    bool silent;
  };

  /// silence_s: finite, > 0. Throws std::invalid_argument otherwise.
  explicit PeerTracker(double silence_s = 2.0);

  /// A writer of `stream` owned by participant `peer` was matched at now_s (a repeat match of a
  /// known writer only renames it).
  void matched(const std::string& stream, const std::string& writer_id, const std::string& peer, double now_s);
  /// The writer is gone (unmatched: it left, its lease expired, or we closed the reader).
  void unmatched(const std::string& writer_id);
  /// A sample of the writer arrived at now_s. Unknown writers (a sample racing its match) are
  /// ignored.
  void heard(const std::string& writer_id, double now_s);

  /// The matched writers silent for >= silence_s at now_s, longest silence first; empty unless some
  /// other writer was heard within silence_s of now_s.
  std::vector<SilentPeer> silent(double now_s) const;
  /// "no odometer from odonav-gateway for 2.3 s" for the longest silent writer (", and N more"
  /// when there are others), or nothing.
  std::optional<std::string> reason(double now_s) const;
  /// The writers that went silent or came back since the last call (each silence once: edge
  /// detected), for a log line per event.
  std::vector<Edge> edges(double now_s);

  std::size_t matched_count() const;
  double silence_s() const { return silence_s_; }

 private:
  struct Writer {
    std::string stream;
    std::string peer;
    double since_s = 0.0;  // last sample, or the match when none
    bool ever_heard = false;
  };
  std::vector<SilentPeer> silent_locked(double now_s) const;

  double silence_s_;
  mutable std::mutex mutex_;
  std::map<std::string, Writer> writers_;  // writer id -> writer
  SilenceTracker<std::string> reported_;   // writers reported silent by edges()
};

/// "rt/odonav/gnss/fix" -> "gnss/fix": the name of a stream as health reasons give it.
std::string stream_name_of_topic(const std::string& topic_name);

}  // namespace odonav
