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
#include <type_traits>

#include "odonav/ground/recording.hpp"
#include "odonav/ground/ros2msg_schema.hpp"
#include "odonav/ground/standard_channels.hpp"
#include "node/topic_types.hpp"
#include "odonav/dds/component.hpp"
#include "odonav/dds/output_messages.hpp"
#include "odonav/dds/time.hpp"
#include "odonav/dds/types.hpp"
#include "odonav/geodesy.hpp"
#include "odonav/source_arbiter.hpp"

namespace odonav::ground {

namespace msg = odonav::msg;
using dds::Reader;

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

namespace {
/// The row of an estimate message by the one field table (odonav/dds/output_messages.hpp); a bad
/// peer's stamp gives t_s NaN (shown as unknown, never a crash) and keeps the rest of the message.
template <class Msg>
auto row_of_any_stamp(const Msg& m) {
  try {
    return dds::row_of(m);
  } catch (const std::invalid_argument&) {
    Msg without_stamp = m;
    without_stamp.header().stamp(builtin_interfaces::msg::Time());
    auto row = dds::row_of(without_stamp);
    row.t_s = std::nan("");
    return row;
  }
}
}  // namespace

ScaleFactorView view_of(const msg::ScaleFactor& s) {
  return {s.vehicle_id(), row_of_any_stamp(s), s.frozen(), s.source()};
}

MisalignmentView view_of(const msg::Misalignment& m) { return {m.vehicle_id(), row_of_any_stamp(m)}; }

DeadReckoningView view_of(const msg::DeadReckoning& d) {
  DeadReckoningView v;
  v.vehicle_id = d.vehicle_id();
  v.row = row_of_any_stamp(d);
  v.row.lon_rad = normalize_lon_rad(v.row.lon_rad);  // shown in [-180, 180) whoever sent it
  v.origin_latitude_deg = d.origin_latitude_deg();
  v.origin_longitude_deg = normalize_lon_deg(d.origin_longitude_deg());
  v.origin_height_m = d.origin_height_m();
  v.gnss_valid = d.gnss_valid();
  return v;
}

NavigationPositionView view_of(const msg::NavigationPosition& n) {
  NavigationPositionView v{n.vehicle_id(), row_of_any_stamp(n)};
  v.row.lon_rad = normalize_lon_rad(v.row.lon_rad);
  return v;
}

GnssView view_of(const msg::GnssFix& g) {
  GnssView v;
  v.vehicle_id = g.vehicle_id();
  v.stamp_s = stamp_of(g.header());
  v.valid = g.valid();
  v.fix_quality = g.fix_quality();
  v.speed_mps = std::hypot(g.velocity_east_mps(), g.velocity_north_mps());
  v.latitude_deg = g.latitude_deg();
  v.longitude_deg = normalize_lon_deg(g.longitude_deg());
  v.height_m = g.height_m();
  v.position_std_m = g.position_std_m();
  return v;
}

namespace {

std::uint64_t unix_now_ns() {
  return static_cast<std::uint64_t>(
      std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
          .count());
}

/// The samples `arbiter` hands on for `m` (its vehicle's stream), plus the heartbeats (repeated last
/// stamp) of the followed source, as a single writer's reader saw them; a stamp that is no time is
/// passed through for the consumer to refuse, as before.
std::vector<msg::ScaleFactor> arbitrated(KeyedSourceArbiter<msg::ScaleFactor>& arbiter, const msg::ScaleFactor& m) {
  double t_s = 0.0;
  try {
    t_s = dds::to_seconds(m.header().stamp());
  } catch (const std::invalid_argument&) {
    return {m};
  }
  std::vector<msg::ScaleFactor> out = arbiter.offer(m.vehicle_id(), m.source(), m.source_priority(), t_s, m);
  const SourceArbiter<msg::ScaleFactor>* a = arbiter.find(m.vehicle_id());
  if (out.empty() && a != nullptr && a->selected() == m.source() && a->last_delivered_s() == t_s) out.push_back(m);
  return out;
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

namespace {
/// One FleetMonitor reader of Msg on `topic` with the data_reader profile `profile`: each sample goes
/// to `on` with its arrival time (steady clock, s, from `now`), then to the tap as topic `id`;
/// on_silence (may be null) hears the reader's deadline edges.
template <class Msg, class On>
std::unique_ptr<dds::detail::ReaderBase> fleet_reader(const dds::Participant& participant, const char* topic,
                                                      const char* profile, topics::TopicId id,
                                                      const std::function<double()>& now, const SampleTap& tap, On on,
                                                      typename Reader<Msg>::SilenceCallback on_silence = nullptr) {
  return std::make_unique<Reader<Msg>>(
      participant, topic, profile,
      [now, tap, id, on](const Msg& m) {
        on(m, now());
        if (tap) tap(id, &m);
      },
      std::move(on_silence));
}
}  // namespace

FleetMonitor::FleetMonitor(const dds::Participant& participant, FleetState& state, std::function<double()> clock,
                           SampleTap tap) {
  FleetState* s = &state;
  auto now = clock;
  using topics::TopicId;
  readers_.push_back(fleet_reader<msg::Health>(
      participant, topics::kHealth.name, topics::kHealthReaderProfile, TopicId::kHealth, now, tap,
      [s](const msg::Health& h, double t_s) { s->on_health(view_of(h), t_s); },
      [s](const msg::Health& last, bool silent) {
        s->on_silence(last.vehicle_id(), Stream::kHealth, last.component(), silent);
      }));
  // One K stream per vehicle out of its identification instances (hot standby), as dead reckoning
  // follows them; the reader's callbacks never run concurrently, so the arbiter needs no lock.
  auto k_arbiter = std::make_shared<KeyedSourceArbiter<msg::ScaleFactor>>();
  readers_.push_back(std::make_unique<Reader<msg::ScaleFactor>>(
      participant, topics::kScaleFactor.name, topics::kGroundEstimateReaderProfile,
      [s, now, tap, k_arbiter](const msg::ScaleFactor& m) {
        for (const auto& k : arbitrated(*k_arbiter, m)) {
          s->on_scale_factor(view_of(k), now());
          if (tap) tap(TopicId::kScaleFactor, &k);
        }
      },
      [s](const msg::ScaleFactor& last, bool silent) {
        s->on_silence(last.vehicle_id(), Stream::kScaleFactor, "", silent);
      }));
  readers_.push_back(fleet_reader<msg::Misalignment>(
      participant, topics::kMisalignment.name, topics::kGroundEstimateReaderProfile, TopicId::kMisalignment, now, tap,
      [s](const msg::Misalignment& m, double t_s) { s->on_misalignment(view_of(m), t_s); },
      [s](const msg::Misalignment& last, bool silent) {
        s->on_silence(last.vehicle_id(), Stream::kMisalignment, "", silent);
      }));
  const char* best_effort = topics::kGroundBestEffortReaderProfile;
  readers_.push_back(fleet_reader<msg::DeadReckoning>(
      participant, topics::kDeadReckoning.name, best_effort, TopicId::kDeadReckoning, now, tap,
      [s](const msg::DeadReckoning& m, double t_s) { s->on_dead_reckoning(view_of(m), t_s); }));
  readers_.push_back(fleet_reader<msg::NavigationPosition>(
      participant, topics::kNavigationPosition.name, best_effort, TopicId::kNavigationPosition, now, tap,
      [s](const msg::NavigationPosition& m, double t_s) { s->on_navigation(view_of(m), t_s); }));
  readers_.push_back(
      fleet_reader<msg::GnssFix>(participant, topics::kGnssFix.name, best_effort, TopicId::kGnssFix, now, tap,
                                 [s](const msg::GnssFix& m, double t_s) { s->on_gnss(view_of(m), t_s); }));
  readers_.push_back(fleet_reader<msg::Odometer>(
      participant, topics::kOdometer.name, best_effort, TopicId::kOdometer, now, tap,
      [s](const msg::Odometer& m, double t_s) { s->on_arrival(m.vehicle_id(), Stream::kOdometer, t_s); }));
  readers_.push_back(fleet_reader<msg::InsAttitude>(
      participant, topics::kInsAttitude.name, best_effort, TopicId::kInsAttitude, now, tap,
      [s](const msg::InsAttitude& m, double t_s) { s->on_arrival(m.vehicle_id(), Stream::kInsAttitude, t_s); }));
  if (tap) {
    readers_.push_back(std::make_unique<Reader<msg::Command>>(
        participant, topics::kCommand.name, best_effort, [tap](const msg::Command& m) { tap(TopicId::kCommand, &m); }));
  }
}

FleetMonitor::~FleetMonitor() {
  readers_.clear();  // each Reader closes itself first: no callback into the FleetState afterwards
}

// ---- TopicRecorder ----

/// The standard channels of a recording (core/standard_channels.hpp): NavSatFix per vehicle from
/// NavigationPosition, DeadReckoning and GnssFix, DiagnosticArray per vehicle from Health (with STALE from the Health
/// reader's deadline and age, as the monitor shows it). Channels are added as vehicles appear.
class TopicRecorder::Standard {
 public:
  Standard(McapWriter& writer, bool navsat, bool diagnostics) : writer_(writer) {
    const MsgLibrary& library = embedded_msg_library();
    if (navsat) navsat_schema_ = writer.add_schema(kNavSatFixType, "ros2msg", ros2msg_schema(library, kNavSatFixType));
    if (diagnostics) {
      diagnostics_schema_ =
          writer.add_schema(kDiagnosticArrayType, "ros2msg", ros2msg_schema(library, kDiagnosticArrayType));
    }
  }
  void on_dead_reckoning(const DeadReckoningView& v, std::uint64_t t_ns) {
    const auto bytes = encode_cdr(navsat_from_dead_reckoning(v));
    writer_.write_message(channel_of(v.vehicle_id, DerivedChannel::kNavSatDeadReckoning), t_ns, t_ns, bytes.data(),
                          bytes.size());
    ++messages_;
  }
  void on_navigation(const NavigationPositionView& v, std::uint64_t t_ns) {
    const auto bytes = encode_cdr(navsat_from_navigation(v));
    writer_.write_message(channel_of(v.vehicle_id, DerivedChannel::kNavSatNavigation), t_ns, t_ns, bytes.data(),
                          bytes.size());
    ++messages_;
  }
  void on_gnss(const GnssView& v, std::uint64_t t_ns) {
    const auto bytes = encode_cdr(navsat_from_gnss(v));
    writer_.write_message(channel_of(v.vehicle_id, DerivedChannel::kNavSatGnss), t_ns, t_ns, bytes.data(),
                          bytes.size());
    ++messages_;
  }
  std::uint64_t messages() const { return messages_; }
  FleetState& fleet() { return fleet_; }
  void write_diagnostics(double now_s, std::uint64_t t_ns) {
    for (const VehicleSnapshot& v : fleet_.snapshot(now_s).vehicles) {
      if (v.components.empty()) continue;
      const auto bytes = encode_cdr(diagnostics_from(v));
      writer_.write_message(channel_of(v.vehicle_id, DerivedChannel::kDiagnostics), t_ns, t_ns, bytes.data(),
                            bytes.size());
      ++messages_;
    }
  }

 private:
  std::uint16_t channel_of(const std::string& vehicle, DerivedChannel kind) {
    std::lock_guard<std::mutex> lock(mutex_);
    const auto key = std::make_pair(vehicle, kind);
    auto it = channels_.find(key);
    if (it != channels_.end()) return it->second;
    const std::uint16_t schema = kind == DerivedChannel::kDiagnostics ? diagnostics_schema_ : navsat_schema_;
    const char* source = kind == DerivedChannel::kDiagnostics        ? topics::kHealth.name
                         : kind == DerivedChannel::kNavSatGnss       ? topics::kGnssFix.name
                         : kind == DerivedChannel::kNavSatNavigation ? topics::kNavigationPosition.name
                                                                     : topics::kDeadReckoning.name;
    const std::uint16_t id = writer_.add_channel(schema, derived_topic(vehicle, kind), "cdr",
                                                 {{"odonav_derived_from", source}, {"odonav_vehicle_id", vehicle}});
    channels_.emplace(key, id);
    return id;
  }

  McapWriter& writer_;
  std::uint16_t navsat_schema_ = 0, diagnostics_schema_ = 0;
  FleetState fleet_;
  std::mutex mutex_;
  std::map<std::pair<std::string, DerivedChannel>, std::uint16_t> channels_;
  std::atomic<std::uint64_t> messages_{0};
};

TopicRecorder::TopicRecorder(const dds::Participant& participant, McapWriter& writer,
                             const std::vector<topics::TopicSpec>& topic_list, bool best_effort) {
  const MsgLibrary& library = embedded_msg_library();
  bool navsat = false, diagnostics = false;
  for (const topics::TopicSpec& spec : topic_list) {
    const auto id = topic_id_of(spec);
    navsat = navsat || id == topics::TopicId::kDeadReckoning || id == topics::TopicId::kGnssFix ||
             id == topics::TopicId::kNavigationPosition;
    diagnostics = diagnostics || id == topics::TopicId::kHealth;
  }
  standard_ = std::make_unique<Standard>(writer, navsat, diagnostics);
  Standard* standard = standard_.get();
  std::map<std::string, std::uint16_t> schema_ids;
  for (const topics::TopicSpec& spec : topic_list) {
    auto schema = schema_ids.find(spec.ros_type_name);
    if (schema == schema_ids.end()) {
      const std::uint16_t id =
          writer.add_schema(spec.ros_type_name, "ros2msg", ros2msg_schema(library, spec.ros_type_name));
      schema = schema_ids.emplace(spec.ros_type_name, id).first;
    }
    const std::string profile = recording_reader_profile(spec, best_effort);
    const std::string ros_topic = std::string(spec.name).substr(2);  // "rt/odonav/x" -> "/odonav/x"
    const std::uint16_t channel =
        writer.add_channel(schema->second, ros_topic, "cdr",
                           channel_metadata(spec, offered_qos(participant, spec.writer_profile), profile));
    McapWriter* out = &writer;
    std::atomic<std::uint64_t>* failures = &failures_;
    with_message_type_of(topic_id_of(spec), [&](auto prototype, auto /*topic id*/) {
      using T = decltype(prototype);
      auto on_data = [out, failures, channel, ros_topic, standard](const T& sample) {
        // Serialized again with the generated type support: the CDR bytes (encapsulation header
        // first) that Fast DDS puts on the wire for this sample.
        typename dds::DdsType<T>::PubSubType type;
        T copy = sample;
        eprosima::fastrtps::rtps::SerializedPayload_t payload(type.getSerializedSizeProvider(&copy)());
        const std::uint64_t t = unix_now_ns();
        try {
          if (!type.serialize(&copy, &payload)) throw std::runtime_error("serialization failed");
          out->write_message(channel, t, t, payload.data, payload.length);
          if constexpr (std::is_same_v<T, msg::DeadReckoning>) standard->on_dead_reckoning(view_of(sample), t);
          if constexpr (std::is_same_v<T, msg::NavigationPosition>) standard->on_navigation(view_of(sample), t);
          if constexpr (std::is_same_v<T, msg::GnssFix>) standard->on_gnss(view_of(sample), t);
          if constexpr (std::is_same_v<T, msg::Health>)
            standard->fleet().on_health(view_of(sample), dds::steady_now_s());
        } catch (const std::exception& e) {
          if ((*failures)++ == 0) spdlog::error("record: sample of {} not written: {}", ros_topic, e.what());
        }
      };
      if constexpr (std::is_same_v<T, msg::Health>) {
        // Health's deadline marks a silent component STALE in the recorded diagnostics, as live.
        readers_.push_back(std::make_unique<Reader<T>>(
            participant, spec.name, profile, on_data, [standard](const msg::Health& last, bool silent) {
              standard->fleet().on_silence(last.vehicle_id(), Stream::kHealth, last.component(), silent);
            }));
      } else if constexpr (std::is_same_v<T, msg::ScaleFactor>) {
        // The recording holds one K stream per vehicle, as dead reckoning and odonav-recorder
        // follow it (the highest-priority live identification; nothing skipped on a switch).
        auto arbiter = std::make_shared<KeyedSourceArbiter<msg::ScaleFactor>>();
        readers_.push_back(std::make_unique<Reader<T>>(participant, spec.name, profile, [on_data, arbiter](const T& m) {
          for (const auto& k : arbitrated(*arbiter, m)) on_data(k);
        }));
      } else {
        readers_.push_back(std::make_unique<Reader<T>>(participant, spec.name, profile, on_data));
      }
    });
  }
}

TopicRecorder::~TopicRecorder() { stop(); }

void TopicRecorder::stop() { readers_.clear(); }

std::uint64_t TopicRecorder::standard_messages() const { return standard_ ? standard_->messages() : 0; }

void TopicRecorder::write_diagnostics() {
  if (!standard_) return;
  try {
    standard_->write_diagnostics(dds::steady_now_s(), unix_now_ns());
  } catch (const std::exception& e) {
    if (failures_++ == 0) spdlog::error("record: diagnostics not written: {}", e.what());
  }
}

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
  throw std::invalid_argument("unknown command '" + name +
                              "' (valid: reset, set-k VALUE, freeze, unfreeze, release-k)");
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
  if (!writer.wait_for_matched(
          1, std::chrono::duration_cast<std::chrono::milliseconds>(deadline - std::chrono::steady_clock::now()))) {
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
