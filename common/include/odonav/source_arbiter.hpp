#pragma once
// SourceArbiter: one stream of estimates out of several redundant producers (hot standby), without
// the middleware's help. Every estimate topic is SHARED (a reader of any vendor or a ROS 2 tool sees
// every producer's samples, each naming its source and priority); each consumer that wants one
// stream (dead reckoning, the recorder, the ground station) puts the samples of one key (vehicle)
// through one SourceArbiter, which delivers:
//
//   - the samples of the selected source: the highest-priority source that is live;
//   - in stamp order, each stamp once: a sample whose stamp is not after the last one delivered is
//     dropped (heartbeats repeat their stamp; another source's copy of an epoch already delivered);
//   - on a switch, the new source's samples from the stamp after the last one delivered on, which
//     it has been holding since (pending), so nothing is skipped or repeated; a stamp the selected
//     source never published but another did is filled from that other source.
//
// Live is decided in event time, never on the wall clock, so a replay at any speed arbitrates the
// same way: a source is live while its newest stamp is no more than silence_s behind the newest
// stamp of any source of the key. A producer that dies (or stalls) falls behind the others' stamps
// and loses the selection silence_s of event time later, which at real-time pace is silence_s plus
// one producer period after it stopped. Ties of priority keep the current selection; otherwise the
// smaller name wins (deterministic).
//
// Middleware-free and single-threaded: the caller serializes offer() calls (one worker thread, or
// one reader's listener thread).
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "odonav/printf_text.hpp"

namespace odonav {

struct SourceArbiterParams {
  /// A source whose newest stamp is more than this behind the newest stamp of any source is not
  /// live (event time, s). 0.3 s = three 10 Hz GNSS epochs: a switch about 0.4 s after a primary
  /// dies at real-time pace.
  double silence_s = 0.3;
  /// Samples held per non-selected source (those after the last delivered stamp). Bounds memory if
  /// a source runs far ahead; the oldest is dropped (counted) beyond it. 1000 = 100 s at 10 Hz.
  std::size_t max_pending_per_source = 1000;
};

/// One change of the selected source.
struct SourceSwitch {
  std::string from;  ///< empty for the first selection
  std::string to;
  double at_stamp_s = 0.0;  ///< the stamp of the sample that caused it
  /// Why, with the observed values: "'a' silent: newest t=12.3 s, 0.4 s behind t=12.7 s of 'b'
  /// (silence 0.3 s)", "'a' (priority 20) is live and outranks 'b' (priority 10)", "first source".
  std::string reason;
};

struct SourceArbiterCounters {
  std::uint64_t delivered = 0;         ///< samples handed on
  std::uint64_t filled = 0;            ///< of them: stamps the selected source lacked, from another source
  std::uint64_t repeated = 0;          ///< stamp equal to the last delivered one (heartbeats, other sources' copies)
  std::uint64_t superseded = 0;        ///< stamp before the last delivered one (a source that lagged behind)
  std::uint64_t pending_overflow = 0;  ///< held samples dropped beyond max_pending_per_source
  std::uint64_t not_finite = 0;        ///< stamp not finite: dropped
  std::uint64_t switches = 0;          ///< changes of the selected source, the first selection included
};

template <class Sample>
class SourceArbiter {
 public:
  explicit SourceArbiter(SourceArbiterParams params = {}) : params_(params) {}

  /// One received sample of `source` (its priority as published; higher wins) with its event-time
  /// stamp. Returns the samples to hand on now, oldest first (often none or one; several on a switch).
  std::vector<Sample> offer(const std::string& source, std::uint32_t priority, double stamp_s, const Sample& sample) {
    std::vector<Sample> out;
    if (!std::isfinite(stamp_s)) {
      ++counters_.not_finite;
      return out;
    }
    SourceState& s = sources_[source];
    s.priority = priority;
    if (!s.newest_s || stamp_s > *s.newest_s) s.newest_s = stamp_s;
    if (!newest_s_ || stamp_s > *newest_s_) newest_s_ = stamp_s;

    if (last_s_ && stamp_s <= *last_s_) {
      ++(stamp_s == *last_s_ ? counters_.repeated : counters_.superseded);
    } else {
      hold(s, stamp_s, sample);
    }
    select(source, stamp_s);
    deliver(out);
    return out;
  }

  /// The selected source, if any sample was offered.
  const std::optional<std::string>& selected() const { return selected_; }
  /// The stamp of the last sample handed on.
  std::optional<double> last_delivered_s() const { return last_s_; }
  const SourceArbiterCounters& counters() const { return counters_; }
  /// The last kSwitchesKept changes of the selected source, oldest first (the first selection
  /// included while kept; counters().switches counts them all).
  const std::vector<SourceSwitch>& switches() const { return switches_; }
  const SourceArbiterParams& params() const { return params_; }

 private:
  struct SourceState {
    std::uint32_t priority = 0;
    std::optional<double> newest_s;
    std::map<double, Sample> pending;  // stamps after last_s_, not yet delivered
  };

  void hold(SourceState& s, double stamp_s, const Sample& sample) {
    s.pending.insert_or_assign(stamp_s, sample);
    while (s.pending.size() > params_.max_pending_per_source) {
      s.pending.erase(s.pending.begin());
      ++counters_.pending_overflow;
    }
  }

  bool live(const SourceState& s) const { return s.newest_s && *s.newest_s >= *newest_s_ - params_.silence_s; }

  void select(const std::string& offered_by, double stamp_s) {
    const std::string* best = nullptr;
    const SourceState* best_state = nullptr;
    for (const auto& [name, s] : sources_) {
      if (!live(s)) continue;
      const bool better = best == nullptr || s.priority > best_state->priority ||
                          (s.priority == best_state->priority && selected_ && name == *selected_);
      if (better) {
        best = &name;
        best_state = &s;
      }
    }
    if (best == nullptr || (selected_ && *best == *selected_)) return;
    SourceSwitch sw;
    sw.from = selected_.value_or("");
    sw.to = *best;
    sw.at_stamp_s = stamp_s;
    sw.reason = switch_reason(sw.from, *best, offered_by);
    switches_.push_back(std::move(sw));
    if (switches_.size() > kSwitchesKept) switches_.erase(switches_.begin());
    ++counters_.switches;
    selected_ = *best;
  }

  std::string switch_reason(const std::string& from, const std::string& to, const std::string& offered_by) const {
    if (from.empty()) return "first source";
    const SourceState& f = sources_.at(from);
    const SourceState& t = sources_.at(to);
    if (!live(f)) {
      // Name the source that is ahead (the one whose stamp set the newest time).
      std::string ahead = offered_by;
      for (const auto& [name, s] : sources_)
        if (s.newest_s && *s.newest_s == *newest_s_) ahead = name;
      return "'" + from + "' silent: its newest t=" + fmt(*f.newest_s) + " s is " + fmt(*newest_s_ - *f.newest_s) +
             " s behind t=" + fmt(*newest_s_) + " s of '" + ahead + "' (silence " + fmt(params_.silence_s) + " s)";
    }
    return "'" + to + "' (priority " + std::to_string(t.priority) + ") is live and outranks '" + from + "' (priority " +
           std::to_string(f.priority) + ")";
  }

  static std::string fmt(double v) { return printf_text("%.6g", v); }

  /// Hands on the selected source's held samples in order; before each, any stamp between the last
  /// delivered one and it that another source holds (an epoch the selected source skipped). Then
  /// forgets every held sample at or before the last delivered stamp.
  void deliver(std::vector<Sample>& out) {
    if (!selected_) return;
    SourceState& sel = sources_.at(*selected_);
    while (!sel.pending.empty()) {
      const double next_s = sel.pending.begin()->first;
      while (const auto fill = earliest_other_before(next_s)) {
        out.push_back(std::move(fill->second));
        ++counters_.filled;
        advance(fill->first);
      }
      out.push_back(std::move(sel.pending.begin()->second));
      advance(next_s);
    }
  }

  std::optional<std::pair<double, Sample>> earliest_other_before(double before_s) const {
    std::optional<std::pair<double, Sample>> best;
    for (const auto& [name, s] : sources_) {
      if (name == *selected_ || s.pending.empty()) continue;
      const auto& first = *s.pending.begin();
      if (first.first < before_s && (!best || first.first < best->first)) best.emplace(first.first, first.second);
    }
    return best;
  }

  void advance(double delivered_s) {
    last_s_ = delivered_s;
    ++counters_.delivered;
    for (auto& [name, s] : sources_) s.pending.erase(s.pending.begin(), s.pending.upper_bound(delivered_s));
  }

  static constexpr std::size_t kSwitchesKept = 32;
  SourceArbiterParams params_;
  std::map<std::string, SourceState> sources_;
  std::optional<std::string> selected_;
  std::optional<double> newest_s_;
  std::optional<double> last_s_;
  SourceArbiterCounters counters_;
  std::vector<SourceSwitch> switches_;
};

/// One SourceArbiter per key (vehicle), for consumers of a whole fleet (the ground station).
template <class Sample>
class KeyedSourceArbiter {
 public:
  explicit KeyedSourceArbiter(SourceArbiterParams params = {}) : params_(params) {}
  std::vector<Sample> offer(const std::string& key, const std::string& source, std::uint32_t priority, double stamp_s,
                            const Sample& sample) {
    auto it = by_key_.find(key);
    if (it == by_key_.end()) it = by_key_.emplace(key, SourceArbiter<Sample>(params_)).first;
    return it->second.offer(source, priority, stamp_s, sample);
  }
  const SourceArbiter<Sample>* find(const std::string& key) const {
    const auto it = by_key_.find(key);
    return it == by_key_.end() ? nullptr : &it->second;
  }

 private:
  SourceArbiterParams params_;
  std::map<std::string, SourceArbiter<Sample>> by_key_;
};

}  // namespace odonav
