#pragma once
// Shared by the calibration, identification and dead-reckoning nodes; library odonav_node_support
// (common/dds/node), which joins the DDS layer (odonav_dds) and the event-time aligner
// (odonav_samples) so that odonav_dds itself stays free of the estimation libraries:
// - sensor messages -> core samples (header stamp -> seconds with the layer's time helpers);
// - NodeInput: one input stream through the EventTimeAligner into a core, counting every sample
//   that is not fed (late, backwards, refused by the core) instead of crashing;
// - health counters and reasons of the inputs;
// - EstimatePublisher: writes a node's estimates and republishes the last one as a heartbeat
//   when nothing was published for a second (the estimate topics' 1 s deadline contract,
//   idl/README.md, and the liveness signal consumers' maximum waits rely on), or for the period
//   the node gives (the scale factor's 300 ms deadline);
// - BurstThrottle: the pause that lets a KEEP_LAST history drain during a burst of writes;
// - the options every node adds to its core's own, and the core's construction (a parameter it
//   rejects is a configuration error);
// - the estimation commands (reset, freeze, unfreeze) of the estimating nodes.
#include <spdlog/spdlog.h>

#include <chrono>
#include <cmath>
#include <cstdint>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "odonav/config.hpp"
#include "odonav/dds/endpoints.hpp"
#include "odonav/dds/health.hpp"
#include "odonav/dds/time.hpp"
#include "odonav/event_time_aligner.hpp"
#include "odonav/frames.hpp"
#include "odonav/msg/Command.h"
#include "odonav/msg/GnssFix.h"
#include "odonav/msg/InsAttitude.h"
#include "odonav/msg/Misalignment.h"
#include "odonav/msg/Odometer.h"
#include "odonav/msg/ScaleFactor.h"
#include "odonav/published_estimates.hpp"
#include "odonav/sensor_samples.hpp"
#include "odonav/stream_buffers.hpp"

namespace odonav::dds {

// ---- messages -> samples (frames and units: idl/README.md; samples: sensor_samples.hpp) ----

/// Odometer message -> sample: t_s = header stamp (s), raw pulses, direction (-1, 0, +1 as sent;
/// the core rejects other values). Throws std::invalid_argument for a non-normalized stamp.
OdometerSample odometer_sample_from(const odonav::msg::Odometer& m);

/// GnssFix message -> sample: degrees -> radians, ENU velocity (m/s), accuracies (-1 = unknown ->
/// absent), fix quality (a fix the producer marked not valid is taken as fix 0, invalid).
GnssSample gnss_sample_from(const odonav::msg::GnssFix& m);

/// InsAttitude message -> sample (radians; velocity only when velocity_valid).
InsSample ins_sample_from(const odonav::msg::InsAttitude& m);

/// Misalignment message -> what its consumers use (published_estimates.hpp); t_s: its stamp (s),
/// converted by the caller.
PublishedMisalignment published_misalignment_from(const odonav::msg::Misalignment& m, double t_s);

/// ScaleFactor message -> what its consumers use (published_estimates.hpp); t_s: its stamp (s).
PublishedScaleFactor published_scale_factor_from(const odonav::msg::ScaleFactor& m, double t_s);

// ---- options and the core ----

/// Adds what a sensor-consuming node takes beside its core's own options, in this order:
/// --lever-arm (lever_arm_option.hpp), --use-ins (default true; help "the vehicle has an INS;
/// false = degraded mode (<degraded_mode>), as odonav-offline does for a dataset without ins.csv"),
/// --state-dir and --checkpoint-every-s (restart_policy.hpp; checkpoint_file names the file in the
/// help, e.g. "calibration-<vehicle>.ckpt").
void add_sensor_node_options(Options& options, const std::string& degraded_mode, const std::string& checkpoint_file);

/// Constructs a node's core from its parameters; a parameter the core rejects
/// (std::invalid_argument) becomes a ConfigError "<what> parameters: <why>", so the process exits 2
/// as for a bad flag.
template <class Core, class... Args>
Core make_node_core(const std::string& what, Args&&... args) {
  try {
    return Core(std::forward<Args>(args)...);
  } catch (const std::invalid_argument& e) {
    throw ConfigError(what + " parameters: " + e.what());
  }
}

/// The QoS profile of a node's sensor readers: after a restore from a checkpoint (restored_t_s
/// set) topics::kSensorReplayReaderProfile, TRANSIENT_LOCAL, so the producers hand over their
/// history (30 s) and the downtime is processed (logged with the restored time); on a fresh start
/// topics::kSensorReaderProfile, reading from the moment the reader matched.
const char* sensor_reader_profile(const std::optional<double>& restored_t_s);

// ---- inputs ----

/// One input stream of a node. Not thread-safe: the node runs it one task at a time.
struct NodeInput {
  std::string name;                   ///< stream name in counters and reasons ("gnss", ...).
  EventTimeAligner::StreamId id = 0;  ///< its stream in the node's aligner.
  bool estimate = false;              ///< an estimate topic: repeated stamps are heartbeats.
  /// Estimate input only: samples stamped before the last one taken. A producer restarted from its
  /// checkpoint republishes the epochs between the checkpoint and its last output before the
  /// restart, with the same values (it resumes exactly): they were applied already and are dropped
  /// as repeats, counted here, not as problems.
  uint64_t republished = 0;
  uint64_t refused = 0;                       ///< refused by the core or with a bad stamp.
  uint64_t dropped_invalid = 0;               ///< dropped by the node before the aligner (e.g. INS not valid).
  std::string last_problem;                   ///< why the last sample was not fed, in words.
  std::optional<double> last_problem_wall_s;  ///< when (steady clock, s).
  uint64_t problems = 0;                      ///< samples not fed for any reason but heartbeats.

  /// Records a sample that was not fed, with the reason (logged, rate-limited).
  void note_problem(const std::string& why, double now_s);
};

/// Passes one sample stamped `stamp` through the aligner and, if accepted, to feed(t_s) (which
/// adds it to the core(s)). Never throws on input: bad stamps, late or backwards samples, and
/// samples the core refuses (StreamInputError / std::invalid_argument) are counted on `in`.
template <class Feed>
SampleAdmission admit_sample(EventTimeAligner& aligner, NodeInput& in, const builtin_interfaces::msg::Time& stamp,
                             double now_s, Feed&& feed) {
  double t_s = 0.0;
  try {
    t_s = to_seconds(stamp);
  } catch (const std::invalid_argument& e) {
    ++in.refused;
    in.note_problem(e.what(), now_s);
    return SampleAdmission::kInvalid;
  }
  const SampleAdmission a = aligner.on_sample(in.id, t_s, now_s);
  std::ostringstream why;
  why.precision(15);
  switch (a) {
    case SampleAdmission::kAccepted: try { feed(t_s);
      } catch (const std::invalid_argument& e) {  // StreamInputError and parameter checks
        ++in.refused;
        in.note_problem(e.what(), now_s);
      }
      return a;
    case SampleAdmission::kRepeated:
      if (in.estimate) return a;  // heartbeat of a live producer
      why << "time did not increase (t=" << t_s << " s, as the previous sample)";
      break;
    case SampleAdmission::kBackwards:
      if (in.estimate) {
        ++in.republished;
        if (in.republished == 1 || in.republished % 1000 == 0)
          spdlog::info(
              "{}: estimate of t={:.3f} s is older than the last one taken: republished by a producer "
              "resuming from its checkpoint, already applied ({} so far)",
              in.name, t_s, in.republished);
        return a;
      }
      why << "time went backwards (t=" << t_s << " s)";
      break;
    case SampleAdmission::kLate:
      why << "late: t=" << t_s << " s is not after what was already processed (" << aligner.processed_s() << " s)";
      break;
    case SampleAdmission::kInvalid: why << "time stamp is not finite"; break;
  }
  in.note_problem(why.str(), now_s);
  return a;
}

/// Appends "<name>_in", "<name>_late", "<name>_rejected", "<name>_absent_events",
/// "<name>_silent_s" for one input (and "<name>_in_flight_waits" when the component waits longer for
/// samples in flight).
void append_input_counters(HealthCounters& c, const EventTimeAligner& aligner, const NodeInput& in, double now_s);

/// "no gnss for 12 s" for the first of `inputs` that is absent now, else nullopt.
std::optional<std::string> absent_reason(const EventTimeAligner& aligner, const std::vector<const NodeInput*>& inputs,
                                         double now_s);

/// "waiting for gnss" for the first of `inputs` that never delivered a sample, else nullopt.
std::optional<std::string> waiting_reason(const EventTimeAligner& aligner, const std::vector<const NodeInput*>& inputs,
                                          double now_s);

/// "rejected 12 ins samples: time went backwards ..." when one of `inputs` had a sample not fed
/// within the last recent_s seconds (steady clock), else nullopt.
std::optional<std::string> rejection_reason(const std::vector<const NodeInput*>& inputs, double now_s,
                                            double recent_s = 10.0);

// ---- outputs ----

/// Sleeps 2 ms every 100 writes. A burst of writes (catching up after a wait, the drain at stop)
/// larger than a KEEP_LAST history would overwrite samples the transport has not delivered yet:
/// the pause lets it drain. Call after_write() after each write of one writer.
class BurstThrottle {
 public:
  static constexpr uint64_t kWritesPerPause = 100;
  static constexpr std::chrono::milliseconds kPause{2};

  void after_write() {
    if (++writes_ % kWritesPerPause == 0) std::this_thread::sleep_for(kPause);
  }
  /// Writes counted so far.
  uint64_t writes() const { return writes_; }

 private:
  uint64_t writes_ = 0;
};

/// Writes one estimate topic; republishes the last estimate (same stamp: consumers see a repeat,
/// i.e. a heartbeat) when nothing was written for heartbeat_period_s of wall clock.
template <class T>
class EstimatePublisher {
 public:
  /// heartbeat_period_s: steady clock (s, > 0). settings: per-process writer settings on top of the
  /// profile (ownership strength, TRANSIENT persistence; endpoints.hpp), none by default.
  EstimatePublisher(const Participant& participant, const std::string& topic_name, const std::string& qos_profile,
                    double heartbeat_period_s = 1.0, const WriterSettings& settings = {})
      : writer_(participant, topic_name, qos_profile, settings), heartbeat_period_s_(heartbeat_period_s) {}

  /// Writes a new estimate at now_s (steady clock, s). A refusal by the middleware is counted and
  /// logged, never thrown: the next estimate is written anyway.
  void publish(const T& message, double now_s) {
    if (!writer_.write(message)) {
      ++write_failures_;
      spdlog::warn("{}: write refused by the middleware ({} so far)", writer_.topic_name(), write_failures_);
    }
    last_ = message;
    last_write_s_ = now_s;
    ++published_;
    throttle_.after_write();
  }
  /// Republishes the last estimate if the period has passed since the last write.
  void heartbeat_if_due(double now_s) {
    if (!last_ || now_s - last_write_s_ < heartbeat_period_s_) return;
    writer_.write(*last_);
    last_write_s_ = now_s;
    ++heartbeats_;
  }
  Writer<T>& writer() { return writer_; }
  uint64_t published() const { return published_; }
  uint64_t heartbeats() const { return heartbeats_; }
  uint64_t write_failures() const { return write_failures_; }
  const std::optional<T>& last() const { return last_; }

 private:
  Writer<T> writer_;
  double heartbeat_period_s_;
  std::optional<T> last_;
  double last_write_s_ = 0.0;
  uint64_t published_ = 0;
  uint64_t heartbeats_ = 0;
  uint64_t write_failures_ = 0;
  BurstThrottle throttle_;
};

/// What an estimating node (calibration, identification) replies to an accepted reset, freeze and
/// unfreeze.
struct EstimationCommandReplies {
  const char* reset;
  const char* freeze;
  const char* unfreeze;
};

/// Runs COMMAND_RESET_ESTIMATION, COMMAND_FREEZE_ESTIMATION and COMMAND_UNFREEZE_ESTIMATION on
/// core (its reset(), freeze(), unfreeze()) and returns the accepted acknowledgement with the node's
/// reply; nullopt for any other command kind, which the node answers itself.
template <class Core>
std::optional<CommandAck> run_estimation_command(const odonav::msg::Command& c, Core& core,
                                                 const EstimationCommandReplies& replies) {
  using namespace odonav::msg;
  switch (c.command()) {
    case COMMAND_RESET_ESTIMATION:
      core.reset();
      return CommandAck{c.command_id(), COMMAND_RESULT_ACCEPTED, replies.reset};
    case COMMAND_FREEZE_ESTIMATION:
      core.freeze();
      return CommandAck{c.command_id(), COMMAND_RESULT_ACCEPTED, replies.freeze};
    case COMMAND_UNFREEZE_ESTIMATION:
      core.unfreeze();
      return CommandAck{c.command_id(), COMMAND_RESULT_ACCEPTED, replies.unfreeze};
    default: return std::nullopt;
  }
}

}  // namespace odonav::dds
