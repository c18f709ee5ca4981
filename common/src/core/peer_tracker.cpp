#include "odonav/peer_tracker.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "odonav/printf_text.hpp"

namespace odonav {

PeerTracker::PeerTracker(double silence_s) : silence_s_(silence_s) {
  if (!std::isfinite(silence_s) || silence_s <= 0.0)
    throw std::invalid_argument("odonav::PeerTracker: silence_s must be finite and > 0, got " +
                                std::to_string(silence_s));
}

void PeerTracker::matched(const std::string& stream, const std::string& writer_id, const std::string& peer,
                          double now_s) {
  std::lock_guard<std::mutex> lock(mutex_);
  auto [it, inserted] = writers_.try_emplace(writer_id);
  it->second.stream = stream;
  it->second.peer = peer;
  if (inserted) it->second.since_s = now_s;
}

void PeerTracker::unmatched(const std::string& writer_id) {
  std::lock_guard<std::mutex> lock(mutex_);
  writers_.erase(writer_id);
  reported_.on_data(writer_id);  // forgotten: a later writer with this id starts clean
}

void PeerTracker::heard(const std::string& writer_id, double now_s) {
  std::lock_guard<std::mutex> lock(mutex_);
  auto it = writers_.find(writer_id);
  if (it == writers_.end()) return;
  it->second.since_s = std::max(it->second.since_s, now_s);
  it->second.ever_heard = true;
}

std::vector<PeerTracker::SilentPeer> PeerTracker::silent_locked(double now_s) const {
  std::vector<SilentPeer> out;
  bool someone_alive = false;
  for (const auto& [id, w] : writers_) {
    const double quiet = now_s - w.since_s;
    if (quiet >= silence_s_)
      out.push_back({w.stream, w.peer, quiet});
    else if (w.ever_heard)
      someone_alive = true;
  }
  if (!someone_alive) return {};
  std::stable_sort(out.begin(), out.end(),
                   [](const SilentPeer& a, const SilentPeer& b) { return a.silent_s > b.silent_s; });
  return out;
}

std::vector<PeerTracker::SilentPeer> PeerTracker::silent(double now_s) const {
  std::lock_guard<std::mutex> lock(mutex_);
  return silent_locked(now_s);
}

std::optional<std::string> PeerTracker::reason(double now_s) const {
  const std::vector<SilentPeer> s = silent(now_s);
  if (s.empty()) return std::nullopt;
  std::string r =
      "no " + s.front().stream + " from " + s.front().peer + " for " + printf_text("%.1f", s.front().silent_s) + " s";
  if (s.size() > 1) r += ", and " + std::to_string(s.size() - 1) + " more silent";
  return r;
}

std::vector<PeerTracker::Edge> PeerTracker::edges(double now_s) {
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<Edge> out;
  const bool any_silent = !silent_locked(now_s).empty();  // someone else alive, someone silent
  for (const auto& [id, w] : writers_) {
    const double quiet = now_s - w.since_s;
    if (any_silent && quiet >= silence_s_) {
      if (reported_.on_deadline_missed(id)) out.push_back({{w.stream, w.peer, quiet}, true});
    } else if (quiet < silence_s_ && reported_.on_data(id)) {
      out.push_back({{w.stream, w.peer, quiet}, false});
    }
  }
  return out;
}

std::size_t PeerTracker::matched_count() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return writers_.size();
}

std::string stream_name_of_topic(const std::string& topic_name) {
  static const std::string kPrefix = "rt/odonav/";
  if (topic_name.compare(0, kPrefix.size(), kPrefix) == 0) return topic_name.substr(kPrefix.size());
  return topic_name;
}

}  // namespace odonav
