#pragma once
// Event-time alignment of a component's separately arriving input streams, middleware-free,
// so a component's outputs depend on the data's time stamps, not on arrival order or replay speed.
//
// A component receives each input stream on its own (DDS topics, in increasing event time per
// stream, but in any interleaving across streams and with any delay). Its cores (sample builder,
// calibrator, dead reckoner) need process_until(w) with the contract "every input stamped <= w has
// been added". This class decides w:
//
//   w = min over the PRESENT input streams of their watermark (the latest stamp received),
//
// so an epoch is processed only when every input has reached it, whatever the scheduling or the
// replay speed. A stream that has been silent (no sample, wall clock) for longer than max_wait_s
// while the others are ahead of it is declared ABSENT: it no longer holds w back, and the event is
// counted. When it speaks again it is present again; its samples stamped at or before what was
// already processed are LATE: counted and dropped (never fed: the cores require increasing time).
//
// Paced streams. An estimate stream (misalignment, scale factor) carries one sample per epoch of
// another stream the component also receives (GNSS): its stamps are a subset of the pacing
// stream's stamps. So once the pacing stream has shown an epoch g after the paced stream's last
// stamp b, the paced stream is complete for every time < g (its next sample is stamped >= g):
//   watermark(paced) = max(b, the largest double below g)       if a pacing stamp g > b is known,
//                    = max(b, watermark(pacing))                 otherwise,
// and +infinity (not limiting) while the pacing stream is absent and the paced stream has caught
// up with it (nothing new can be produced upstream without new pacing epochs). This is what keeps
// a consumer deterministic while the producer runs, and lets it go on through GNSS outages.
//
// Hold-off. A stream declared with a hold-off h >= 0 (consumer_rules.hpp, estimate_applies_from_s)
// feeds its core with samples that apply from t + h, not from their stamp t: its watermark, its
// lateness and the comparison with the other streams are all taken at t + h. An estimate stream
// with hold-off h therefore limits the consumer's watermark w only until the estimates of the
// epochs <= w - h are in, which in normal operation arrived long before. When such a stream is
// what holds w back (its producer is later than the hold-off), the wait is bounded by max_wait_s
// as any other and counted (hold_off_waits: one per episode).
//
// Declared completeness. Topics have no mutual order, so the producer of a pacing stream (the
// gateway, for GNSS) may declare on another stream's samples (each odometer sample) "every sample
// stamped <= C has been published, the last one stamped L" (declare_published). Once the pacing
// stream has shown L, it is complete up to C although its next sample is not there yet: a consumer
// then knows, at an odometer time t, every GNSS epoch <= t and waits only for their estimates.
//
// Samples in flight. A stream whose producer has declared samples published (declare_published)
// that it has not shown yet is not silent for lack of data: they are on their way (a restarted
// consumer's history hand-over, a loaded link). Such a stream is declared absent only after
// in_flight_max_wait_s of silence (>= max_wait_s; a component that may wait for exact results, the
// identification and the calibration, sets the producers' history length, kInFlightMaxWait_s),
// and each time this longer wait held a stream that max_wait_s would have dropped is counted
// (in_flight_waits). A component whose outputs must stay fresh (dead reckoning) keeps max_wait_s.
//
// Repeated stamps. A sample stamped exactly like the stream's previous one is a REPEAT: a producer's
// heartbeat (an estimate republished so that its readers know it is alive) or a duplicate. It
// refreshes the stream's liveness and is not fed.
//
// Clock: every call takes now_s, a monotonic wall clock in seconds supplied by the caller (the
// component's steady clock; a test's fake clock), so this class never reads a clock itself.
// Not thread-safe: its owner calls it one task at a time.
#include <cstddef>
#include <cstdint>
#include <deque>
#include <limits>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace odonav {

/// The in-flight wait of the components that wait for exact results: the producers' history (30 s of
/// sensor samples), beyond which the data would be lost anyway.
inline constexpr double kInFlightMaxWait_s = 30.0;

/// What on_sample decided for one sample.
enum class SampleAdmission {
  kAccepted,   ///< feed it to the core.
  kLate,       ///< stamped at or before what was already processed (the stream was absent): drop.
  kRepeated,   ///< same stamp as the stream's previous sample (heartbeat or duplicate): drop.
  kBackwards,  ///< stamped before the stream's previous sample: time went backwards: drop.
  kInvalid,    ///< stamp not finite: drop.
};
/// "accepted", "late", "repeated", "backwards", "invalid".
const char* to_string(SampleAdmission admission);

/// One input of a consumer component, as its core declares it (calibration_inputs,
/// identification_inputs, dead_reckoning_inputs): the DDS node subscribes and aligns it so
/// (EventTimeNode), and odonav-offline declares it to the component's aligner so (OfflinePipeline).
/// One list serves both, so the two transports decide alike when the component may process.
struct ComponentInput {
  std::string name;         ///< the stream: "odometer", "gnss", "ins", "misalignment", "scale_factor"
  bool required = false;    ///< a sensor stream the component cannot work without (Health WARN when absent)
  std::string paced_by;     ///< empty, or the input declared before whose epochs pace this estimate stream
  double hold_off_s = 0.0;  ///< samples apply from their stamp (or pacing epoch) + hold-off (s)
};

class EventTimeAligner {
 public:
  using StreamId = std::size_t;

  /// What a component reports about one input stream (health counters and reasons).
  struct StreamStatus {
    std::string name;
    std::optional<double> last_t_s;  ///< latest stamp seen (s, event time), accepted or late.
    double watermark_s = 0.0;        ///< complete up to this (s); -inf before anything, +inf see above.
    bool absent = false;             ///< declared absent and not heard since.
    double silent_for_s = 0.0;       ///< wall time since its last sample (or since start) (s).
    uint64_t accepted = 0;
    uint64_t late = 0;
    uint64_t repeated = 0;
    uint64_t backwards = 0;
    uint64_t invalid = 0;
    uint64_t absent_events = 0;  ///< times it was declared absent.
    /// Paced streams: pacing epochs skipped between two consecutive samples (a sample lost upstream
    /// or in transit). 0 for other streams.
    uint64_t skipped_pacing_epochs = 0;
    /// Paced streams and streams with a hold-off: times this stream was the one holding the
    /// watermark back while another present stream was ahead (its samples later than the
    /// hold-off), one per episode.
    uint64_t hold_off_waits = 0;
    double hold_off_s = 0.0;  ///< its hold-off (s).
    /// Samples declared published by its producer and not received yet (see "Samples in flight").
    bool in_flight = false;
    /// Times the in-flight wait kept it present past max_wait_s, one per episode.
    uint64_t in_flight_waits = 0;
  };

  /// max_wait_s: how long (s, wall clock, finite, > 0) a stream may be silent while others are
  /// ahead before it is declared absent. start_s: the wall clock now (s, finite): silence of a stream
  /// that never spoke counts from here. in_flight_max_wait_s: the same for a stream with samples in
  /// flight (finite, >= max_wait_s; 0 = max_wait_s). Throws std::invalid_argument naming the bad value.
  EventTimeAligner(double max_wait_s, double start_s, double in_flight_max_wait_s = 0.0);

  /// Declares an input stream (name: for status and messages, e.g. "gnss"). Before the first sample.
  /// hold_off_s: see "Hold-off" (finite, >= 0; else std::invalid_argument).
  StreamId add_stream(const std::string& name, double hold_off_s = 0.0);
  /// Declares a stream whose stamps are a subset of `pacing`'s stamps (one sample per pacing epoch
  /// at most). `pacing` must be a plain stream (add_stream). Throws std::invalid_argument otherwise.
  StreamId add_paced_stream(const std::string& name, StreamId pacing, double hold_off_s = 0.0);

  /// The producer of `stream` declares that every sample stamped <= complete_through_s (s) has been
  /// published, the last one stamped last_stamp_s (nullopt: none yet). Non-finite or decreasing
  /// declarations are ignored (a declaration only ever adds knowledge). Throws std::out_of_range for
  /// an unknown stream id.
  void declare_published(StreamId stream, double complete_through_s, std::optional<double> last_stamp_s);

  /// One sample of `stream` stamped t_s (s, event time) arrived at now_s (s, wall clock).
  /// Any sample (also late or repeated) proves the stream alive: an absent stream becomes present.
  /// Throws std::out_of_range for an unknown stream id (a programming error, not an input error).
  SampleAdmission on_sample(StreamId stream, double t_s, double now_s);

  /// Re-evaluates absence at now_s (s, wall clock) and returns the new watermark (s, event time) if
  /// it moved past the processed one; the caller then calls process_until(*result) on its core(s)
  /// and the returned value becomes the processed watermark. nullopt: nothing new to process.
  /// Never returns +infinity (the end of data is the component's finish(), not a watermark).
  std::optional<double> advance(double now_s);

  /// The processed watermark (s): -inf until the first advance() that returned a value.
  double processed_s() const { return processed_s_; }
  /// Status of one stream at now_s (s, wall clock).
  StreamStatus status(StreamId stream, double now_s) const;
  std::size_t stream_count() const { return streams_.size(); }
  double max_wait_s() const { return max_wait_s_; }
  double in_flight_max_wait_s() const { return in_flight_max_wait_s_; }

 private:
  struct Stream {
    std::string name;
    std::optional<StreamId> pacing;   ///< set for paced streams.
    std::vector<StreamId> followers;  ///< paced streams that this one paces.
    std::optional<double> last_t_s;
    std::deque<double> pacing_stamps;  ///< pacing streams: own stamps newer than some follower's last.
    std::optional<double> last_arrival_s;
    std::optional<double> behind_since_s;  ///< wall time since when others are ahead of it.
    double hold_off_s = 0.0;
    /// declare_published: complete up to here (the declarations whose last stamp has been seen) ...
    double declared_through_s = -std::numeric_limits<double>::infinity();
    /// ... and the declarations waiting for their last stamp: (complete through, last stamp).
    std::deque<std::pair<double, double>> pending_declarations;
    bool holding_back = false;    ///< hold-off streams: limited the last watermark.
    bool in_flight_held = false;  ///< kept present by the in-flight wait (counted once).
    bool absent = false;
    StreamStatus counts;  ///< counters only (name etc. filled by status()).
  };
  Stream& stream_at(StreamId id);
  const Stream& stream_at(StreamId id) const;
  /// Complete up to here in the stream's own stamps (declarations included).
  double raw_watermark_of(const Stream& s) const;
  /// The watermark in consumer time (hold-off applied), or in the stream's own stamps.
  double watermark_of(const Stream& s, bool with_hold_off = true) const;
  void prune_pacing_stamps(Stream& pacing);

  double max_wait_s_;
  double in_flight_max_wait_s_;
  double start_s_;
  double processed_s_;
  std::vector<Stream> streams_;
};

}  // namespace odonav
