#include "gateway_node.hpp"

#include <spdlog/spdlog.h>

#include <fastdds/dds/publisher/Publisher.hpp>
#include <fastdds/dds/publisher/qos/DataWriterQos.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <thread>
#include <tuple>

#include "odonav/dds/time.hpp"
#include "odonav/topics.hpp"

namespace odonav::gateway {

void add_gateway_options(Options& o) {
  o.add_string("source", "sim:terrain",
               "sim:<straight|ring|terrain> (the simulator, in-process), replay:<dataset dir>, or a live line-protocol "
               "source udp:[<bind IPv4>:]<port> (127.0.0.1 by default) or serial:<device>[:<baud>], or GNSS only from "
               "gpsd:[<host>:]<port> (README.md)");
  o.add_string("gnss-source", "",
               "with a udp: or serial: source: take the GNSS from gpsd:[<host>:]<port> instead of GNSS lines");
  o.add_double("gnss-utc-origin-s", 0.0,
               "gpsd GNSS: t = UTC seconds since 1970 minus this (0: t is UTC; the odometer and INS lines use the "
               "same time base)",
               0.0, 1e10);
  o.add_bool("allow-non-loopback", false,
             "udp source: allow binding an address outside 127.0.0.0/8; gpsd: allow a non-loopback host");
  o.add_int("seed", 1, "sim source: seed of the sensor noise (as odonav-sim --seed)", 0,
            std::numeric_limits<int64_t>::max());
  o.add_double("duration-s", 0.0, "sim source: run length, s (as odonav-sim --duration-s); 0 = the scenario's", 0.0,
               604800.0);
  o.add_choice("on-bad-row", "fail", {"fail", "skip"}, "replay source: a bad row stops the gateway, or is skipped and counted");
  o.add_string("speed", "1", "1 = real time, N = N times real time, max = as fast as the readers acknowledge");
  o.add_int("wait-for-readers", 0,
            "before publishing, wait until this many consumers read the GNSS topic (0 = do not wait)", 0, 1000);
  o.add_double("wait-for-readers-timeout-s", 60.0, "give up waiting for the readers after this long, s", 0.1, 3600.0);
  o.add_double("ack-interval-s", 0.5,
               "speed max: wait for the readers' acknowledgments every this much data, s (at most 1 s: the "
               "writers keep the last 200 samples, 2 s at 100 Hz)",
               0.01, 1.0);
  o.add_double("ack-timeout-s", 30.0, "longest wait for the readers' acknowledgments, s", 0.1, 3600.0);
}

GatewaySettings gateway_settings_from(const Options& o) {
  GatewaySettings s;
  s.source = parse_source(o.get_string("source"));
  s.simulator.seed = static_cast<std::uint64_t>(o.get_int("seed"));
  s.simulator.duration_s = o.get_double("duration-s");
  s.on_bad_row = parse_bad_row_policy(o.get_string("on-bad-row"));
  s.speed = parse_speed(o.get_string("speed"));
  s.wait_for_readers = static_cast<int>(o.get_int("wait-for-readers"));
  s.wait_for_readers_timeout_s = o.get_double("wait-for-readers-timeout-s");
  s.ack_timeout_s = o.get_double("ack-timeout-s");
  s.ack_interval_s = o.get_double("ack-interval-s");
  return s;
}

odonav::msg::Odometer odometer_message(const OdometerSample& s, const std::string& vehicle_id) {
  odonav::msg::Odometer m;
  m.header(dds::make_header(s.t_s, "odometer"));
  m.vehicle_id(vehicle_id);
  m.pulses(s.pulses);
  m.direction(static_cast<int8_t>(s.direction));
  return m;
}

odonav::msg::InsAttitude ins_message(const InsSample& s, const std::string& vehicle_id) {
  odonav::msg::InsAttitude m;
  m.header(dds::make_header(s.t_s, "body"));
  m.vehicle_id(vehicle_id);
  m.heading_rad(s.attitude.heading_rad);
  m.pitch_rad(s.attitude.pitch_rad);
  m.roll_rad(s.attitude.roll_rad);
  m.velocity_valid(s.vel_enu_mps.has_value());
  if (s.vel_enu_mps) {
    m.velocity_east_mps(s.vel_enu_mps->x());
    m.velocity_north_mps(s.vel_enu_mps->y());
    m.velocity_up_mps(s.vel_enu_mps->z());
  }
  m.valid(true);
  return m;
}

odonav::msg::GnssFix gnss_message(const GnssSample& s, const std::string& vehicle_id) {
  odonav::msg::GnssFix m;
  m.header(dds::make_header(s.t_s, "wgs84"));
  m.vehicle_id(vehicle_id);
  m.latitude_deg(recorded_degrees(s.position.lat_rad));
  m.longitude_deg(recorded_degrees(s.position.lon_rad));
  m.height_m(s.position.height_m);
  m.velocity_east_mps(s.vel_enu_mps.x());
  m.velocity_north_mps(s.vel_enu_mps.y());
  m.velocity_up_mps(s.vel_enu_mps.z());
  m.fix_quality(static_cast<uint8_t>(std::clamp(s.fix, 0, 255)));
  m.position_std_m(s.pos_std_m.value_or(-1.0));
  m.velocity_std_mps(s.vel_std_mps.value_or(-1.0));
  const bool finite = std::isfinite(s.position.lat_rad) && std::isfinite(s.position.lon_rad) &&
                      std::isfinite(s.position.height_m) && s.vel_enu_mps.allFinite();
  m.valid(s.valid() && finite);
  return m;
}

namespace {
/// The sensor writers' profile: odonav_sensor_writer, or in "max" mode its fast-acknowledgment
/// variant (qos.xml, topics::kGatewayFastAckSensorWriterProfile: a 5 ms heartbeat, so each
/// acknowledgment wait of the flow control takes milliseconds, not up to the default 3 s). A
/// qos.xml without it (an older installation) only makes the flow control slow: warn, go on.
std::string sensor_writer_profile(const dds::Participant& participant, const GatewaySettings& settings) {
  if (!settings.speed.as_fast_as_possible) return topics::kSensorWriterProfile;
  eprosima::fastdds::dds::DataWriterQos qos;
  if (participant.core()->publisher().get_datawriter_qos_from_profile(topics::kGatewayFastAckSensorWriterProfile,
                                                                      qos) != eprosima::fastrtps::types::ReturnCode_t::RETCODE_OK) {
    spdlog::warn("{} has no data_writer profile '{}': flow control will be slow", participant.qos_file(),
                 topics::kGatewayFastAckSensorWriterProfile);
    return topics::kSensorWriterProfile;
  }
  return topics::kGatewayFastAckSensorWriterProfile;
}
}  // namespace

GatewayNode::GatewayNode(dds::ComponentRuntime& runtime, const GatewaySettings& settings, Dataset dataset)
    : runtime_(runtime),
      settings_(settings),
      dataset_(std::move(dataset)),
      odometer_(runtime.participant(), topics::kOdometer.name, sensor_writer_profile(runtime.participant(), settings)),
      ins_(runtime.participant(), topics::kInsAttitude.name, sensor_writer_profile(runtime.participant(), settings)),
      gnss_(runtime.participant(), topics::kGnssFix.name, sensor_writer_profile(runtime.participant(), settings)) {}

void GatewayNode::health(odonav::msg::HealthState state, const std::string& reason, bool force) {
  dds::HealthCounters c;
  c.emplace_back("odometer_published", static_cast<double>(published_[0]));
  c.emplace_back("ins_published", static_cast<double>(published_[1]));
  c.emplace_back("gnss_published", static_cast<double>(published_[2]));
  c.emplace_back("gnss_invalid_published", static_cast<double>(gnss_invalid_));
  c.emplace_back("event_time_s", last_t_s_);
  c.emplace_back("odometer_readers", static_cast<double>(odometer_.matched_readers()));
  c.emplace_back("ins_readers", static_cast<double>(ins_.matched_readers()));
  c.emplace_back("gnss_readers", static_cast<double>(gnss_.matched_readers()));
  c.emplace_back("write_failures", static_cast<double>(write_failures_));
  c.emplace_back("ack_timeouts", static_cast<double>(ack_timeouts_));
  const auto level = write_failures_ + ack_timeouts_ > 0 ? odonav::msg::HEALTH_LEVEL_WARN : odonav::msg::HEALTH_LEVEL_OK;
  runtime_.publish_health(state, level, reason, c, force);
}

bool GatewayNode::wait_for_readers() {
  if (settings_.wait_for_readers <= 0) return true;
  const auto n = static_cast<std::size_t>(settings_.wait_for_readers);
  spdlog::info("waiting for {} consumers on {}", n, gnss_.topic_name());
  const double deadline = dds::steady_now_s() + settings_.wait_for_readers_timeout_s;
  while (gnss_.matched_readers() < n) {
    if (runtime_.stop_signals().stop_requested()) return false;
    if (dds::steady_now_s() > deadline) {
      spdlog::error("only {} of {} consumers matched on {} after {} s (odometer readers {}, INS readers {})",
                    gnss_.matched_readers(), n, gnss_.topic_name(), settings_.wait_for_readers_timeout_s,
                    odometer_.matched_readers(), ins_.matched_readers());
      return false;
    }
    health(odonav::msg::HEALTH_STATE_STARTING, "waiting for readers", false);
    gnss_.wait_for_matched(n, std::chrono::milliseconds(100));
  }
  // A participant's readers are announced together, so once its GNSS reader matched the others
  // follow within milliseconds: wait until the counts of all three writers stay put for 0.5 s.
  auto counts = [this] {
    return std::make_tuple(odometer_.matched_readers(), ins_.matched_readers(), gnss_.matched_readers());
  };
  auto last = counts();
  double stable_since = dds::steady_now_s();
  while (dds::steady_now_s() - stable_since < 0.5 && dds::steady_now_s() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    if (counts() != last) {
      last = counts();
      stable_since = dds::steady_now_s();
    }
  }
  spdlog::info("readers matched: odometer {}, INS {}, GNSS {}", odometer_.matched_readers(), ins_.matched_readers(),
               gnss_.matched_readers());
  return true;
}

void GatewayNode::publish(const SensorEvent& e) {
  const std::string& vehicle = runtime_.settings().vehicle_id;
  bool ok = true;
  switch (e.stream) {
    case SensorEvent::Stream::kOdometer:
      ok = odometer_.write(odometer_message(dataset_.odometer[e.index], vehicle));
      break;
    case SensorEvent::Stream::kIns:
      ok = ins_.write(ins_message(dataset_.ins[e.index], vehicle));
      break;
    case SensorEvent::Stream::kGnss: {
      const odonav::msg::GnssFix m = gnss_message(dataset_.gnss[e.index], vehicle);
      if (!m.valid()) ++gnss_invalid_;
      ok = gnss_.write(m);
      break;
    }
  }
  if (!ok && ++write_failures_ <= 10) spdlog::warn("write refused by the middleware at t={} s", e.t_s);
  ++published_[static_cast<int>(e.stream)];
  last_t_s_ = e.t_s;
}

bool GatewayNode::wait_for_acknowledgments(std::chrono::milliseconds timeout) {
  bool all = true;
  for (dds::detail::WriterBase* w : {static_cast<dds::detail::WriterBase*>(&odometer_),
                                     static_cast<dds::detail::WriterBase*>(&ins_),
                                     static_cast<dds::detail::WriterBase*>(&gnss_)}) {
    if (!dds::wait_for_acknowledgments_logged(*w, timeout)) {
      ++ack_timeouts_;
      all = false;
    }
  }
  return all;
}

int GatewayNode::run() {
  using namespace odonav::msg;
  const std::vector<SensorEvent> events = interleave(dataset_);
  health(HEALTH_STATE_STARTING, "waiting for readers", true);
  if (!wait_for_readers()) {
    if (runtime_.stop_signals().stop_requested()) {
      health(HEALTH_STATE_STOPPING, "interrupted before the first sample", true);
      return 0;
    }
    health(HEALTH_STATE_ERROR, "expected readers not matched", true);
    return 1;
  }
  if (events.empty()) spdlog::warn("the source holds no sensor samples");
  else
    spdlog::info("publishing {} odometer, {} INS, {} GNSS samples, t={}..{} s, speed {}", dataset_.odometer.size(),
                 dataset_.ins.size(), dataset_.gnss.size(), events.front().t_s, events.back().t_s,
                 to_string(settings_.speed));

  const auto ack_timeout = std::chrono::milliseconds(static_cast<long long>(settings_.ack_timeout_s * 1000.0));
  const double wall_start = dds::steady_now_s();
  const PacingClock clock(settings_.speed, events.empty() ? 0.0 : events.front().t_s, wall_start);
  AckSchedule acks(settings_.ack_interval_s);
  bool interrupted = false;
  std::size_t since_health_check = 0;
  for (const SensorEvent& e : events) {
    if (runtime_.stop_signals().stop_requested()) {
      interrupted = true;
      break;
    }
    if (const auto due = clock.due_wall_s(e.t_s)) {
      // Paced: sleep until due, in short steps so SIGINT and Health stay responsive.
      for (double now = dds::steady_now_s(); now < *due; now = dds::steady_now_s()) {
        if (runtime_.stop_signals().stop_requested()) break;
        std::this_thread::sleep_for(std::chrono::duration<double>(std::min(*due - now, 0.05)));
        health(HEALTH_STATE_RUNNING, "", false);
      }
      if (runtime_.stop_signals().stop_requested()) {
        interrupted = true;
        break;
      }
    } else if (acks.wait_before(e.t_s)) {
      // As fast as possible: every ack_interval_s of data (at most 1 s: 100 samples at 100 Hz),
      // let every reader acknowledge what it got, so no writer history (KEEP_LAST 200) ever
      // overwrites a sample a reader has not received.
      wait_for_acknowledgments(ack_timeout);
    }
    try {
      publish(e);
    } catch (const std::invalid_argument& ex) {  // a stamp the message cannot carry
      spdlog::error("sample at t={} s cannot be published: {}", e.t_s, ex.what());
      health(HEALTH_STATE_ERROR, ex.what(), true);
      return 1;
    }
    if (++since_health_check >= 200) {
      since_health_check = 0;
      runtime_.run_pending();  // commands (none supported: acknowledged as rejected)
      health(HEALTH_STATE_RUNNING, "", false);
    }
  }
  const bool acknowledged = wait_for_acknowledgments(ack_timeout);
  std::ostringstream reason;
  reason.precision(10);
  reason << (interrupted ? "interrupted at t=" : "end of data at t=") << last_t_s_ << " s";
  spdlog::info("{}: published {} odometer, {} INS, {} GNSS ({} invalid fixes) in {:.1f} s{}", reason.str(),
               published_[0], published_[1], published_[2], gnss_invalid_, dds::steady_now_s() - wall_start,
               acknowledged ? "" : "; not every sample was acknowledged");
  health(HEALTH_STATE_STOPPING, reason.str(), true);
  dds::wait_for_acknowledgments_logged(runtime_.health().writer(), std::chrono::seconds(1));
  return 0;
}

}  // namespace odonav::gateway
