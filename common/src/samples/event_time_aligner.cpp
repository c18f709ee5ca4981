// Event-time alignment of input streams (see odonav/event_time_aligner.hpp).
#include "odonav/event_time_aligner.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "odonav/consumer_rules.hpp"

namespace odonav {

namespace {
constexpr double kInf = std::numeric_limits<double>::infinity();

// The largest double below g: "complete for every time < g" as a process_until watermark.
double just_below(double g) { return std::nextafter(g, -kInf); }

// estimate_applies_from_s (consumer_rules.hpp), also for the infinite watermarks.
double applies(double t_s, double hold_off_s) {
  return std::isfinite(t_s) ? estimate_applies_from_s(t_s, hold_off_s) : t_s;
}

void check_hold_off(const std::string& name, double hold_off_s) {
  if (!std::isfinite(hold_off_s) || hold_off_s < 0.0) {
    std::ostringstream m;
    m << "EventTimeAligner: stream '" << name << "': hold_off_s must be finite and >= 0, got " << hold_off_s;
    throw std::invalid_argument(m.str());
  }
}
}  // namespace

const char* to_string(SampleAdmission admission) {
  switch (admission) {
    case SampleAdmission::kAccepted: return "accepted";
    case SampleAdmission::kLate: return "late";
    case SampleAdmission::kRepeated: return "repeated";
    case SampleAdmission::kBackwards: return "backwards";
    case SampleAdmission::kInvalid: return "invalid";
  }
  return "unknown";
}

EventTimeAligner::EventTimeAligner(double max_wait_s, double start_s, double in_flight_max_wait_s)
    : max_wait_s_(max_wait_s),
      in_flight_max_wait_s_(in_flight_max_wait_s == 0.0 ? max_wait_s : in_flight_max_wait_s),
      start_s_(start_s),
      processed_s_(-kInf) {
  if (!std::isfinite(max_wait_s) || !(max_wait_s > 0.0)) {
    std::ostringstream m;
    m << "EventTimeAligner: max_wait_s must be finite and > 0, got " << max_wait_s;
    throw std::invalid_argument(m.str());
  }
  if (!std::isfinite(in_flight_max_wait_s_) || in_flight_max_wait_s_ < max_wait_s) {
    std::ostringstream m;
    m << "EventTimeAligner: in_flight_max_wait_s must be finite and >= max_wait_s (" << max_wait_s << "), got "
      << in_flight_max_wait_s;
    throw std::invalid_argument(m.str());
  }
  if (!std::isfinite(start_s)) throw std::invalid_argument("EventTimeAligner: start_s must be finite");
}

EventTimeAligner::StreamId EventTimeAligner::add_stream(const std::string& name, double hold_off_s) {
  check_hold_off(name, hold_off_s);
  Stream s;
  s.name = name;
  s.hold_off_s = hold_off_s;
  streams_.push_back(std::move(s));
  return streams_.size() - 1;
}

EventTimeAligner::StreamId EventTimeAligner::add_paced_stream(const std::string& name, StreamId pacing,
                                                              double hold_off_s) {
  check_hold_off(name, hold_off_s);
  if (pacing >= streams_.size() || streams_[pacing].pacing) {
    throw std::invalid_argument("EventTimeAligner::add_paced_stream('" + name +
                                "'): the pacing stream must be a plain stream declared before");
  }
  Stream s;
  s.name = name;
  s.hold_off_s = hold_off_s;
  s.pacing = pacing;
  streams_.push_back(std::move(s));
  const StreamId id = streams_.size() - 1;
  streams_[pacing].followers.push_back(id);
  return id;
}

EventTimeAligner::Stream& EventTimeAligner::stream_at(StreamId id) {
  if (id >= streams_.size()) throw std::out_of_range("EventTimeAligner: unknown stream id " + std::to_string(id));
  return streams_[id];
}

const EventTimeAligner::Stream& EventTimeAligner::stream_at(StreamId id) const {
  if (id >= streams_.size()) throw std::out_of_range("EventTimeAligner: unknown stream id " + std::to_string(id));
  return streams_[id];
}

void EventTimeAligner::prune_pacing_stamps(Stream& pacing) {
  // A follower's next non-late sample is stamped at a pacing epoch after its own last stamp and
  // applying after the processed watermark: an epoch older than that for every follower can never
  // be needed again.
  auto needed = [&](double g) {
    for (StreamId f : pacing.followers) {
      const Stream& follower = streams_[f];
      if (g > follower.last_t_s.value_or(-kInf) && applies(g, follower.hold_off_s) > processed_s_) return true;
    }
    return false;
  };
  while (!pacing.pacing_stamps.empty() && !needed(pacing.pacing_stamps.front())) pacing.pacing_stamps.pop_front();
}

SampleAdmission EventTimeAligner::on_sample(StreamId id, double t_s, double now_s) {
  Stream& s = stream_at(id);
  // Any sample, good or not, proves the producer alive.
  s.last_arrival_s = now_s;
  s.in_flight_held = false;
  if (s.absent) {
    s.absent = false;
    s.behind_since_s.reset();
  }
  if (!std::isfinite(t_s)) {
    ++s.counts.invalid;
    return SampleAdmission::kInvalid;
  }
  if (s.last_t_s && t_s < *s.last_t_s) {
    ++s.counts.backwards;
    return SampleAdmission::kBackwards;
  }
  if (s.last_t_s && t_s == *s.last_t_s) {
    ++s.counts.repeated;
    return SampleAdmission::kRepeated;
  }
  if (s.pacing && s.last_t_s) {
    const Stream& pacing = streams_[*s.pacing];
    for (double g : pacing.pacing_stamps)
      if (g > *s.last_t_s && g < t_s) ++s.counts.skipped_pacing_epochs;
  }
  s.last_t_s = t_s;
  // A declaration counts once everything it says was published has been received.
  while (!s.pending_declarations.empty() && s.pending_declarations.front().second <= t_s) {
    s.declared_through_s = std::max(s.declared_through_s, s.pending_declarations.front().first);
    s.pending_declarations.pop_front();
  }
  if (!s.followers.empty()) {
    s.pacing_stamps.push_back(t_s);
    prune_pacing_stamps(s);
  }
  if (s.pacing) prune_pacing_stamps(streams_[*s.pacing]);
  if (applies(t_s, s.hold_off_s) <= processed_s_) {
    ++s.counts.late;
    return SampleAdmission::kLate;
  }
  ++s.counts.accepted;
  return SampleAdmission::kAccepted;
}

void EventTimeAligner::declare_published(StreamId id, double complete_through_s, std::optional<double> last_stamp_s) {
  Stream& s = stream_at(id);
  if (std::isnan(complete_through_s) || (last_stamp_s && !std::isfinite(*last_stamp_s))) return;
  if (complete_through_s <= s.declared_through_s) return;
  if (!last_stamp_s || (s.last_t_s && *s.last_t_s >= *last_stamp_s)) {
    s.declared_through_s = complete_through_s;
    return;
  }
  // Counts once the stream has shown its last stamp (on_sample).
  if (s.pending_declarations.empty() || complete_through_s > s.pending_declarations.back().first)
    s.pending_declarations.emplace_back(complete_through_s, *last_stamp_s);
}

double EventTimeAligner::raw_watermark_of(const Stream& s) const {
  return std::max(s.last_t_s.value_or(-kInf), s.declared_through_s);
}

double EventTimeAligner::watermark_of(const Stream& s, bool with_hold_off) const {
  const double h = with_hold_off ? s.hold_off_s : 0.0;
  const double own = s.last_t_s.value_or(-kInf);
  if (!s.pacing) return applies(raw_watermark_of(s), h);
  const Stream& pacing = streams_[*s.pacing];
  // The next sample applies from applies(g) of a pacing epoch g > own: complete below that. Taken
  // below applies(g) itself (not applies(below g)), which rounding could make equal to it.
  for (double g : pacing.pacing_stamps)
    if (g > own) return std::max(applies(own, h), just_below(applies(g, h)));
  // No pacing epoch after our last one is known: complete up to the pacing stream's own watermark,
  // or for good while the pacing stream is absent (nothing new can be produced upstream).
  if (pacing.absent) return kInf;
  return applies(std::max(own, raw_watermark_of(pacing)), h);
}

std::optional<double> EventTimeAligner::advance(double now_s) {
  // Absence: silent for longer than max wait while another present stream is ahead, compared on
  // the streams' own stamps: a hold-off puts a stream's watermark ahead of the odometer in normal
  // operation, which must not make the odometer "behind" when the data simply ends.
  std::vector<double> wm(streams_.size());
  for (std::size_t i = 0; i < streams_.size(); ++i) wm[i] = watermark_of(streams_[i], false);
  for (std::size_t i = 0; i < streams_.size(); ++i) {
    Stream& s = streams_[i];
    if (s.absent || wm[i] == kInf) {
      s.behind_since_s.reset();
      continue;
    }
    bool others_ahead = false;
    for (std::size_t j = 0; j < streams_.size(); ++j)
      if (j != i && !streams_[j].absent && std::isfinite(wm[j]) && wm[j] > wm[i]) others_ahead = true;
    if (!others_ahead) {
      s.behind_since_s.reset();
      continue;
    }
    if (!s.behind_since_s) s.behind_since_s = now_s;
    const double silent_since = std::max(s.last_arrival_s.value_or(start_s_), *s.behind_since_s);
    const double silent_for = now_s - silent_since;
    if (silent_for <= max_wait_s_) continue;
    if (!s.pending_declarations.empty() && silent_for <= in_flight_max_wait_s_) {
      // Its producer declared samples it has not shown: they are on their way.
      if (!s.in_flight_held) {
        s.in_flight_held = true;
        ++s.counts.in_flight_waits;
      }
      continue;
    }
    s.absent = true;
    s.behind_since_s.reset();
    ++s.counts.absent_events;
  }
  // Absence of a pacing stream can lift its followers' watermarks.
  for (std::size_t i = 0; i < streams_.size(); ++i) wm[i] = watermark_of(streams_[i], true);

  double w = kInf;
  bool any = false;
  for (std::size_t i = 0; i < streams_.size(); ++i) {
    if (streams_[i].absent || wm[i] == kInf) continue;
    w = std::min(w, wm[i]);
    any = true;
  }
  // Hold-off waits: an estimate stream (paced) or one with a hold-off that is the minimum while
  // another is ahead.
  for (std::size_t i = 0; i < streams_.size(); ++i) {
    Stream& s = streams_[i];
    if (!(s.hold_off_s > 0.0 || s.pacing) || s.absent || wm[i] == kInf) {
      s.holding_back = false;
      continue;
    }
    bool others_ahead = false;
    for (std::size_t j = 0; j < streams_.size(); ++j)
      if (j != i && !streams_[j].absent && std::isfinite(wm[j]) && wm[j] > wm[i]) others_ahead = true;
    const bool holding = any && wm[i] == w && others_ahead;
    if (holding && !s.holding_back) ++s.counts.hold_off_waits;
    s.holding_back = holding;
  }
  if (!any || !std::isfinite(w) || !(w > processed_s_)) return std::nullopt;
  processed_s_ = w;
  for (Stream& s : streams_)
    if (!s.followers.empty()) prune_pacing_stamps(s);
  return w;
}

EventTimeAligner::StreamStatus EventTimeAligner::status(StreamId id, double now_s) const {
  const Stream& s = stream_at(id);
  StreamStatus out = s.counts;
  out.name = s.name;
  out.last_t_s = s.last_t_s;
  out.watermark_s = watermark_of(s);
  out.absent = s.absent;
  out.hold_off_s = s.hold_off_s;
  out.in_flight = !s.pending_declarations.empty();
  out.silent_for_s = now_s - s.last_arrival_s.value_or(start_s_);
  return out;
}

}  // namespace odonav
