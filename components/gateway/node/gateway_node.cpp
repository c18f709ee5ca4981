#include "gateway_node.hpp"

#include <spdlog/spdlog.h>

#include <fastdds/dds/publisher/Publisher.hpp>
#include <fastdds/dds/publisher/qos/DataWriterQos.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <thread>

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
  o.add_int("seed", 1, "sim source: seed of the sensor noise (as odonav-simulator --seed)", 0,
            std::numeric_limits<int64_t>::max());
  o.add_double("duration-s", 0.0, "sim source: run length, s (as odonav-simulator --duration-s); 0 = the scenario's",
               0.0, 604800.0);
  o.add_choice("on-bad-row", "fail", {"fail", "skip"},
               "replay source: a bad row stops the gateway, or is skipped and counted");
  o.add_string("speed", "1", "1 = real time, N = N times real time, max = as fast as the readers acknowledge");
  o.add_int("wait-for-readers", 0,
            "before publishing, wait until this many consumers read the GNSS topic (0 = do not wait)", 0, 1000);
  o.add_double("wait-for-readers-timeout-s", 60.0, "give up waiting for the readers after this long, s", 0.1, 3600.0);
  o.add_double("ack-interval-s", 0.5,
               "speed max: wait for the readers' acknowledgments every this much data, s (at most 1 s: the "
               "writers keep the last 200 samples, 2 s at 100 Hz)",
               0.01, 1.0);
  o.add_double("ack-timeout-s", 30.0, "longest wait for the readers' acknowledgments, s", 0.1, 3600.0);
  o.add_string("can-odometer", "ccvs1",
               "candump source: the odometer channels, ';'-separated: ccvs1[:sa=N] (J1939 wheel-based speed), "
               "etc1[:sa=N] (J1939 output shaft speed), signal:id=<3|8 hex digits>,start=<bit>,length=<1..64>,"
               "as=counter|speed[,order=intel|motorola][,signed=0|1][,scale=X][,offset=X][,wrap=<bits>] (a speed "
               "signal in m/s after scale and offset); several are averaged (README.md, CAN input)");
  o.add_double("can-pulses-per-m", 100.0,
               "candump source: pulses per metre a speed channel is integrated into (ccvs1, etc1 without "
               "--can-etc1-pulses-per-rev, signal as=speed), pulses/m",
               1e-6, 1e6);
  o.add_double("can-gear-ratio", 1.0,
               "candump etc1: transmission output shaft revolutions per sprocket (wheel) revolution", 1e-6, 1000.0);
  o.add_double("can-sprocket-radius-m", 0.3, "candump etc1: effective sprocket (wheel) radius, m", 1e-3, 5.0);
  o.add_double("can-etc1-pulses-per-rev", 0.0,
               "candump etc1: > 0: pulses per output shaft revolution (the speed, gear ratio and radius unused)", 0.0,
               1e6);
  o.add_string("candump-dataset", "",
               "candump:<file> source: replay the INS and GNSS of this dataset directory with the CAN odometer "
               "(its odometer.csv is read but replaced); empty: the odometer only");
  o.add_string("ins-source", "",
               "candump:- source: INS (and GNSS lines unless --gnss-source) from a line-protocol source "
               "udp:[<bind IPv4>:]<port> or serial:<device>[:<baud>]; its ODO lines are ignored and counted");
  o.add_bool("tolerate-lost-readers", false,
             "exit 0 even when a reliable reader went away (left, killed, cut off) before the data was complete "
             "(default: exit 4 naming it)");
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
  s.tolerate_lost_readers = o.get_bool("tolerate-lost-readers");
  s.can.channels = parse_can_channels(o.get_string("can-odometer"));
  s.can.pulses_per_m = o.get_double("can-pulses-per-m");
  s.can.gear_ratio = o.get_double("can-gear-ratio");
  s.can.sprocket_radius_m = o.get_double("can-sprocket-radius-m");
  s.can.etc1_pulses_per_rev = o.get_double("can-etc1-pulses-per-rev");
  validate(s.can);
  s.candump_dataset = o.get_string("candump-dataset");
  if (!s.candump_dataset.empty() && s.source.kind != SourceSpec::Kind::kCandump)
    throw ConfigError("--candump-dataset goes with --source candump:<file>");
  if (!o.get_string("ins-source").empty())
    throw ConfigError("--ins-source goes with --source candump:- (a live CAN input)");
  return s;
}

namespace {
/// The sensor writers' profile: odonav_sensor_writer, or in "max" mode its fast-acknowledgment
/// variant (qos.xml, topics::kGatewayFastAckSensorWriterProfile: a 5 ms heartbeat, so each
/// acknowledgment wait of the flow control takes milliseconds, not up to the default 3 s). A
/// qos.xml without it (an older installation) only makes the flow control slow: warn, go on.
std::string sensor_writer_profile(const dds::Participant& participant, const GatewaySettings& settings) {
  if (!settings.speed.as_fast_as_possible) return topics::kSensorWriterProfile;
  eprosima::fastdds::dds::DataWriterQos qos;
  if (participant.core()->publisher().get_datawriter_qos_from_profile(
          topics::kGatewayFastAckSensorWriterProfile, qos) != eprosima::fastrtps::types::ReturnCode_t::RETCODE_OK) {
    spdlog::warn("{} has no data_writer profile '{}': flow control will be slow", participant.qos_file(),
                 topics::kGatewayFastAckSensorWriterProfile);
    return topics::kSensorWriterProfile;
  }
  return topics::kGatewayFastAckSensorWriterProfile;
}
}  // namespace

GatewayNode::GatewayNode(dds::ComponentRuntime& runtime, const GatewaySettings& settings, Dataset dataset,
                         SourceHealth source_health)
    : runtime_(runtime),
      settings_(settings),
      dataset_(std::move(dataset)),
      source_health_(std::move(source_health)),
      publisher_(runtime, sensor_writer_profile(runtime.participant(), settings)) {}

void GatewayNode::health(odonav::msg::HealthState state, const std::string& reason, bool force) {
  const double now = dds::steady_now_s();
  if (!force && now - last_health_s_ < dds::kHealthEvaluationPeriod_s) return;
  last_health_s_ = now;
  publisher_.publish_health(
      state, reason,
      combine(replay_source_health(publisher_.matched_readers(), publisher_.ack_timeouts()), source_health_), force);
}

bool GatewayNode::wait_for_readers() {
  if (settings_.wait_for_readers <= 0) return true;
  const auto n = static_cast<std::size_t>(settings_.wait_for_readers);
  const auto& gnss = publisher_.gnss_writer();
  spdlog::info("waiting for {} consumers on {}", n, gnss.topic_name());
  const double deadline = dds::steady_now_s() + settings_.wait_for_readers_timeout_s;
  while (gnss.matched_readers() < n) {
    if (runtime_.stop_signals().stop_requested()) return false;
    if (dds::steady_now_s() > deadline) {
      const auto readers = publisher_.matched_readers();
      spdlog::error("only {} of {} consumers matched on {} after {} s (odometer readers {}, INS readers {})",
                    gnss.matched_readers(), n, gnss.topic_name(), settings_.wait_for_readers_timeout_s, readers[0],
                    readers[1]);
      return false;
    }
    health(odonav::msg::HEALTH_STATE_STARTING, "waiting for readers", false);
    gnss.wait_for_matched(n, std::chrono::milliseconds(100));
  }
  // A participant's readers are announced together, so once its GNSS reader matched the others
  // follow within milliseconds: wait until the counts of all three writers stay put for 0.5 s.
  auto last = publisher_.matched_readers();
  double stable_since = dds::steady_now_s();
  while (dds::steady_now_s() - stable_since < 0.5 && dds::steady_now_s() < deadline) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    if (publisher_.matched_readers() != last) {
      last = publisher_.matched_readers();
      stable_since = dds::steady_now_s();
    }
  }
  const auto readers = publisher_.matched_readers();
  spdlog::info("readers matched: odometer {}, INS {}, GNSS {}", readers[0], readers[1], readers[2]);
  return true;
}

void GatewayNode::publish(const SensorEvent& e) {
  switch (e.stream) {
    case SensorEvent::Stream::kOdometer:
      publisher_.odometer(dataset_.odometer[e.index], gnss_declared_through_s(dataset_.odometer[e.index].t_s));
      break;
    case SensorEvent::Stream::kIns:
      publisher_.ins(dataset_.ins[e.index], gnss_declared_through_s(dataset_.ins[e.index].t_s));
      break;
    case SensorEvent::Stream::kGnss:
      publisher_.gnss(dataset_.gnss[e.index]);
      gnss_published_ = e.index + 1;
      break;
  }
}

double GatewayNode::gnss_declared_through_s(double sample_t_s) const {
  // The file order is known: every GNSS before the next one to publish is out. Declared up to the
  // sample's own time at most (all a consumer of this sample needs). Both as the stamps reach the
  // consumers (whole nanoseconds): a GNSS stamp a few ulps after the sample's may arrive equal to
  // it, and must not be declared published before it is.
  const auto wire = [](double s) { return dds::to_seconds(dds::make_header(s, "").stamp()); };
  const double t = wire(sample_t_s);
  return gnss_published_ < dataset_.gnss.size()
             ? std::min(t, std::nextafter(wire(dataset_.gnss[gnss_published_].t_s), -INFINITY))
             : t;
}

bool GatewayNode::sleep_until(double due_wall_s) {
  for (double now = dds::steady_now_s(); now < due_wall_s; now = dds::steady_now_s()) {
    if (runtime_.stop_signals().stop_requested()) break;
    std::this_thread::sleep_for(std::chrono::duration<double>(std::min(due_wall_s - now, 0.05)));
    health(odonav::msg::HEALTH_STATE_RUNNING, "", false);
  }
  return !runtime_.stop_signals().stop_requested();
}

GatewayNode::Outcome GatewayNode::publish_all(const std::vector<SensorEvent>& events, double wall_start_s,
                                              std::chrono::milliseconds ack_timeout) {
  const PacingClock clock(settings_.speed, events.empty() ? 0.0 : events.front().t_s, wall_start_s);
  AckSchedule acks(settings_.ack_interval_s);
  std::size_t since_health_check = 0;
  for (const SensorEvent& e : events) {
    if (runtime_.stop_signals().stop_requested()) return Outcome::kInterrupted;
    if (const auto due = clock.due_wall_s(e.t_s)) {
      if (!sleep_until(*due)) return Outcome::kInterrupted;
    } else if (acks.wait_before(e.t_s)) {
      // As fast as possible: every ack_interval_s of data (at most 1 s: 100 samples at 100 Hz),
      // let every reader acknowledge what it got, so no writer history (KEEP_LAST 3000) ever
      // overwrites a sample a reader has not received.
      publisher_.wait_for_acknowledgments(ack_timeout);
    }
    try {
      publish(e);
    } catch (const std::invalid_argument& ex) {  // a stamp the message cannot carry
      spdlog::error("sample at t={} s cannot be published: {}", e.t_s, ex.what());
      health(odonav::msg::HEALTH_STATE_ERROR, ex.what(), true);
      return Outcome::kFailed;
    }
    if (++since_health_check >= 200) {
      since_health_check = 0;
      runtime_.run_pending();  // commands (none supported: acknowledged as rejected)
      health(odonav::msg::HEALTH_STATE_RUNNING, "", false);
    }
  }
  return Outcome::kEndOfData;
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
  if (events.empty())
    spdlog::warn("the source holds no sensor samples");
  else
    spdlog::info("publishing {} odometer, {} INS, {} GNSS samples, t={}..{} s, speed {}", dataset_.odometer.size(),
                 dataset_.ins.size(), dataset_.gnss.size(), events.front().t_s, events.back().t_s,
                 to_string(settings_.speed));

  const auto ack_timeout = std::chrono::milliseconds(static_cast<long long>(settings_.ack_timeout_s * 1000.0));
  const double wall_start = dds::steady_now_s();
  const Outcome outcome = publish_all(events, wall_start, ack_timeout);
  if (outcome == Outcome::kFailed) return 1;
  const bool acknowledged = publisher_.wait_for_acknowledgments(ack_timeout);
  const PublishedCounts counts = publisher_.counts();
  std::ostringstream reason;
  reason.precision(10);
  reason << (outcome == Outcome::kInterrupted ? "interrupted at t=" : "end of data at t=") << counts.last_t_s << " s";
  spdlog::info("{}: published {} odometer, {} INS, {} GNSS ({} invalid fixes) in {:.1f} s{}", reason.str(),
               counts.published[0], counts.published[1], counts.published[2], counts.gnss_invalid,
               dds::steady_now_s() - wall_start, acknowledged ? "" : "; not every sample was acknowledged");
  // A reader that went away while samples were owed to it never got them: say who, and fail.
  const std::vector<std::string> lost = publisher_.readers_lost_since(wall_start);
  int rc = 0;
  if (!lost.empty()) {
    std::string who;
    for (const auto& l : lost) who += (who.empty() ? "" : "; ") + l;
    spdlog::error("lost {} reliable reader(s) before the data was complete: {}{}", lost.size(), who,
                  settings_.tolerate_lost_readers ? " (tolerated: --tolerate-lost-readers)" : "");
    reason << "; lost " << lost.size() << " reader(s) before the data was complete: " << who;
    if (!settings_.tolerate_lost_readers) rc = kExitLostReaders;
  }
  health(HEALTH_STATE_STOPPING, reason.str(), true);
  dds::wait_for_acknowledgments_logged(runtime_.health().writer(), std::chrono::seconds(1));
  return rc;
}

}  // namespace odonav::gateway
