#include "node/ground_node.hpp"

#include <fastdds/dds/publisher/qos/DataWriterQos.hpp>
#include <fastdds/rtps/common/SerializedPayload.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <cmath>
#include <condition_variable>
#include <mutex>
#include <optional>
#include <random>
#include <stdexcept>
#include <thread>

#include "core/recording.hpp"
#include "core/ros2msg_schema.hpp"
#include "node/topic_types.hpp"
#include "odonav/dds/component.hpp"
#include "odonav/dds/time.hpp"
#include "odonav/dds/types.hpp"

namespace odonav::ground {

namespace msg = odonav::msg;
using dds::Reader;

namespace {

double stamp_of(const std_msgs::msg::Header& h) {
  try {
    return dds::to_seconds(h.stamp());
  } catch (const std::invalid_argument&) {
    return std::nan("");  // a bad peer's stamp: shown as unknown, never a crash
  }
}

HealthView view_of(const msg::Health& h) {
  HealthView v;
  v.vehicle_id = h.vehicle_id();
  v.component = h.component();
  v.stamp_s = stamp_of(h.header());
  v.state = static_cast<std::uint32_t>(h.state());
  v.level = static_cast<std::uint32_t>(h.level());
  v.reason = h.reason();
  for (const auto& c : h.counters()) v.counters.emplace_back(c.name(), c.value());
  v.last_command_id = h.last_command_id();
  v.last_command_result = static_cast<std::uint32_t>(h.last_command_result());
  v.last_command_detail = h.last_command_detail();
  return v;
}

ScaleFactorView view_of(const msg::ScaleFactor& s) {
  ScaleFactorView v;
  v.vehicle_id = s.vehicle_id();
  v.stamp_s = stamp_of(s.header());
  v.k_m_per_pulse = s.k_m_per_pulse();
  v.sigma_m_per_pulse = s.sigma_m_per_pulse();
  v.forgetting_factor = s.forgetting_factor();
  v.window_fill = s.window_fill();
  v.estimator = s.estimator();
  v.converged = s.converged();
  v.frozen = s.frozen();
  v.samples_accepted = s.samples_accepted();
  v.samples_rejected = s.samples_rejected();
  v.source = s.source();
  return v;
}

MisalignmentView view_of(const msg::Misalignment& m) {
  MisalignmentView v;
  v.vehicle_id = m.vehicle_id();
  v.stamp_s = stamp_of(m.header());
  v.heading_rad = m.heading_rad();
  v.pitch_rad = m.pitch_rad();
  v.heading_std_rad = m.heading_std_rad();
  v.pitch_std_rad = m.pitch_std_rad();
  v.samples_used = m.samples_used();
  v.converged = m.converged();
  v.state = static_cast<std::uint32_t>(m.state());
  return v;
}

DeadReckoningView view_of(const msg::DeadReckoning& d) {
  DeadReckoningView v;
  v.vehicle_id = d.vehicle_id();
  v.stamp_s = stamp_of(d.header());
  v.latitude_deg = d.latitude_deg();
  v.longitude_deg = d.longitude_deg();
  v.distance_m = d.distance_m();
  v.k_m_per_pulse = d.k_m_per_pulse();
  v.k_source = static_cast<std::uint32_t>(d.k_source());
  v.gnss_valid = d.gnss_valid();
  v.horizontal_error_m = d.horizontal_error_m();
  v.error_percent_distance = d.error_percent_distance();
  return v;
}

GnssView view_of(const msg::GnssFix& g) {
  GnssView v;
  v.vehicle_id = g.vehicle_id();
  v.stamp_s = stamp_of(g.header());
  v.valid = g.valid();
  v.fix_quality = g.fix_quality();
  v.speed_mps = std::hypot(g.velocity_east_mps(), g.velocity_north_mps());
  return v;
}

std::uint64_t unix_now_ns() {
  return static_cast<std::uint64_t>(
      std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
          .count());
}

OfferedQos offered_qos(const dds::Participant& participant, const std::string& writer_profile) {
  eprosima::fastdds::dds::DataWriterQos qos;
  OfferedQos o;
  if (participant.core()->publisher().get_datawriter_qos_from_profile(writer_profile, qos) !=
      eprosima::fastrtps::types::ReturnCode_t::RETCODE_OK) {
    throw std::runtime_error("odonav-ground: no data_writer QoS profile '" + writer_profile + "' in " +
                             participant.qos_file());
  }
  o.reliable = qos.reliability().kind == eprosima::fastdds::dds::RELIABLE_RELIABILITY_QOS;
  o.transient_local = qos.durability().kind == eprosima::fastdds::dds::TRANSIENT_LOCAL_DURABILITY_QOS;
  o.keep_all = qos.history().kind == eprosima::fastdds::dds::KEEP_ALL_HISTORY_QOS;
  o.depth = qos.history().depth;
  const auto& period = qos.deadline().period;
  if (!(period == eprosima::fastrtps::c_TimeInfinite)) o.deadline_s = period.to_ns() * 1e-9;
  return o;
}

}  // namespace

// ---- FleetMonitor ----

FleetMonitor::FleetMonitor(const dds::Participant& participant, FleetState& state, std::function<double()> clock) {
  FleetState* s = &state;
  auto now = clock;
  readers_.push_back(std::make_unique<Reader<msg::Health>>(
      participant, topics::kHealth.name, topics::kHealthReaderProfile,
      [s, now](const msg::Health& h) { s->on_health(view_of(h), now()); },
      [s](const msg::Health& last, bool silent) {
        s->on_silence(last.vehicle_id(), Stream::kHealth, last.component(), silent);
      }));
  readers_.push_back(std::make_unique<Reader<msg::ScaleFactor>>(
      participant, topics::kScaleFactor.name, topics::kEstimateReaderProfile,
      [s, now](const msg::ScaleFactor& m) { s->on_scale_factor(view_of(m), now()); },
      [s](const msg::ScaleFactor& last, bool silent) {
        s->on_silence(last.vehicle_id(), Stream::kScaleFactor, "", silent);
      }));
  readers_.push_back(std::make_unique<Reader<msg::Misalignment>>(
      participant, topics::kMisalignment.name, topics::kEstimateReaderProfile,
      [s, now](const msg::Misalignment& m) { s->on_misalignment(view_of(m), now()); },
      [s](const msg::Misalignment& last, bool silent) {
        s->on_silence(last.vehicle_id(), Stream::kMisalignment, "", silent);
      }));
  const char* best_effort = topics::kGroundBestEffortReaderProfile;
  readers_.push_back(std::make_unique<Reader<msg::DeadReckoning>>(
      participant, topics::kDeadReckoning.name, best_effort,
      [s, now](const msg::DeadReckoning& m) { s->on_dead_reckoning(view_of(m), now()); }));
  readers_.push_back(std::make_unique<Reader<msg::GnssFix>>(
      participant, topics::kGnssFix.name, best_effort,
      [s, now](const msg::GnssFix& m) { s->on_gnss(view_of(m), now()); }));
  readers_.push_back(std::make_unique<Reader<msg::Odometer>>(
      participant, topics::kOdometer.name, best_effort,
      [s, now](const msg::Odometer& m) { s->on_arrival(m.vehicle_id(), Stream::kOdometer, now()); }));
  readers_.push_back(std::make_unique<Reader<msg::InsAttitude>>(
      participant, topics::kInsAttitude.name, best_effort,
      [s, now](const msg::InsAttitude& m) { s->on_arrival(m.vehicle_id(), Stream::kInsAttitude, now()); }));
}

FleetMonitor::~FleetMonitor() {
  readers_.clear();  // each Reader closes itself first: no callback into the FleetState afterwards
}

// ---- TopicRecorder ----

TopicRecorder::TopicRecorder(const dds::Participant& participant, McapWriter& writer,
                             const std::vector<topics::TopicSpec>& topic_list, bool best_effort) {
  const MsgLibrary& library = embedded_msg_library();
  std::map<std::string, std::uint16_t> schema_ids;
  for (const topics::TopicSpec& spec : topic_list) {
    auto schema = schema_ids.find(spec.ros_type_name);
    if (schema == schema_ids.end()) {
      const std::uint16_t id = writer.add_schema(spec.ros_type_name, "ros2msg", ros2msg_schema(library, spec.ros_type_name));
      schema = schema_ids.emplace(spec.ros_type_name, id).first;
    }
    const std::string profile = recording_reader_profile(spec, best_effort);
    const std::string ros_topic = std::string(spec.name).substr(2);  // "rt/odonav/x" -> "/odonav/x"
    const std::uint16_t channel = writer.add_channel(
        schema->second, ros_topic, "cdr", channel_metadata(spec, offered_qos(participant, spec.writer_profile), profile));
    McapWriter* out = &writer;
    std::atomic<std::uint64_t>* failures = &failures_;
    with_message_type_of(topic_id_of(spec), [&](auto prototype, auto /*topic id*/) {
      using T = decltype(prototype);
      auto on_data = [out, failures, channel, ros_topic](const T& sample) {
        // Serialized again with the generated type support: the CDR bytes (encapsulation header
        // first) that Fast DDS puts on the wire for this sample.
        typename dds::DdsType<T>::PubSubType type;
        T copy = sample;
        eprosima::fastrtps::rtps::SerializedPayload_t payload(type.getSerializedSizeProvider(&copy)());
        const std::uint64_t t = unix_now_ns();
        try {
          if (!type.serialize(&copy, &payload)) throw std::runtime_error("serialization failed");
          out->write_message(channel, t, t, payload.data, payload.length);
        } catch (const std::exception& e) {
          if ((*failures)++ == 0) spdlog::error("record: sample of {} not written: {}", ros_topic, e.what());
        }
      };
      readers_.push_back(std::make_unique<Reader<T>>(participant, spec.name, profile, on_data));
    });
  }
}

TopicRecorder::~TopicRecorder() { stop(); }

void TopicRecorder::stop() { readers_.clear(); }

std::size_t TopicRecorder::matched_topics() const {
  std::size_t n = 0;
  for (const auto& r : readers_) n += r->matched_writers() > 0 ? 1 : 0;
  return n;
}

// ---- commands ----

msg::CommandKind parse_command_kind(const std::string& name) {
  if (name == "reset") return msg::COMMAND_RESET_ESTIMATION;
  if (name == "set-k") return msg::COMMAND_SET_K;
  if (name == "freeze") return msg::COMMAND_FREEZE_ESTIMATION;
  if (name == "unfreeze") return msg::COMMAND_UNFREEZE_ESTIMATION;
  if (name == "release-k") return msg::COMMAND_RELEASE_K;
  // The former name of wire value 0, which dead reckoning took as "release the commanded K": refused
  // rather than mapped, so a script written for the old meaning is not silently given the new one.
  if (name == "reset-calibration") {
    throw std::invalid_argument(
        "'reset-calibration' is no longer a command: use 'reset' (the addressed estimator restarts) or, "
        "for odonav-dead-reckoning, 'release-k' (follow the identified K again)");
  }
  throw std::invalid_argument("unknown command '" + name + "' (valid: reset, set-k VALUE, freeze, unfreeze, release-k)");
}

std::string command_kind_name(msg::CommandKind kind) {
  switch (kind) {
    case msg::COMMAND_RESET_ESTIMATION: return "reset";
    case msg::COMMAND_SET_K: return "set-k";
    case msg::COMMAND_FREEZE_ESTIMATION: return "freeze";
    case msg::COMMAND_UNFREEZE_ESTIMATION: return "unfreeze";
    case msg::COMMAND_RELEASE_K: return "release-k";
  }
  return "command" + std::to_string(static_cast<int>(kind));
}

CommandReply send_command(const dds::Participant& participant, const CommandRequest& request) {
  if (!(request.timeout_s > 0.0) || !std::isfinite(request.timeout_s)) {
    throw std::invalid_argument("--timeout-s must be finite and > 0");
  }
  std::random_device random;
  std::uint32_t id = 0;
  while (id == 0) id = random();

  std::mutex mutex;
  std::condition_variable changed;
  std::optional<msg::Health> latest;  // the target's latest Health
  Reader<msg::Health> health(participant, topics::kHealth.name, topics::kHealthReaderProfile,
                             [&](const msg::Health& h) {
                               if (h.vehicle_id() != request.vehicle_id || h.component() != request.component) return;
                               {
                                 std::lock_guard<std::mutex> lock(mutex);
                                 latest = h;
                               }
                               changed.notify_all();
                             });
  dds::Writer<msg::Command> writer(participant, topics::kCommand.name, topics::kCommand.writer_profile);

  const auto deadline =
      std::chrono::steady_clock::now() + std::chrono::microseconds(static_cast<long long>(request.timeout_s * 1e6));
  CommandReply reply;
  reply.command_id = id;
  // 1. The target exists (its Health is seen) and a command reader is matched. Commands are
  // VOLATILE: one written before the target's reader matched would be lost.
  {
    std::unique_lock<std::mutex> lock(mutex);
    if (!changed.wait_until(lock, deadline, [&] { return latest.has_value(); })) {
      reply.detail = "no Health from component '" + request.component + "' of vehicle '" + request.vehicle_id +
                     "' (is it running, on this domain?)";
      return reply;
    }
  }
  if (!writer.wait_for_matched(1, std::chrono::duration_cast<std::chrono::milliseconds>(
                                      deadline - std::chrono::steady_clock::now()))) {
    reply.detail = "no reader of " + std::string(topics::kCommand.name) + " matched";
    return reply;
  }
  // Readers of one participant are discovered together; a short grace lets the target's own command
  // reader match when another participant's matched first.
  std::this_thread::sleep_for(std::chrono::milliseconds(300));

  msg::Command command;
  command.header(dds::make_header(dds::unix_now_s(), ""));
  command.vehicle_id(request.vehicle_id);
  command.target_component(request.component);
  command.command(request.kind);
  command.value(request.kind == msg::COMMAND_SET_K ? request.value : 0.0);
  command.command_id(id);
  if (!writer.write(command)) {
    reply.detail = "the middleware refused to write the command";
    return reply;
  }
  spdlog::debug("command {} sent: {} to {}/{}", id, command_kind_name(request.kind), request.vehicle_id,
                request.component);
  // 2. The acknowledgement: the target's Health carrying our id.
  std::unique_lock<std::mutex> lock(mutex);
  if (!changed.wait_until(lock, deadline, [&] { return latest && latest->last_command_id() == id; })) {
    reply.detail = "no acknowledgement of command " + std::to_string(id) + " in the Health of '" + request.component +
                   "' within " + std::to_string(request.timeout_s) + " s";
    return reply;
  }
  reply.outcome = latest->last_command_result() == msg::COMMAND_RESULT_ACCEPTED ? CommandOutcome::kAccepted
                                                                                : CommandOutcome::kRejected;
  reply.detail = latest->last_command_detail();
  return reply;
}

}  // namespace odonav::ground
