#include "node/sensor_publisher.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>

#include "odonav/gateway/sensor_source.hpp"
#include "odonav/dds/time.hpp"
#include "odonav/peer_tracker.hpp"
#include "odonav/topics.hpp"

namespace odonav::gateway {

odonav::msg::Odometer odometer_message(const OdometerSample& s, const std::string& vehicle_id,
                                       double gnss_complete_through_s, std::optional<double> gnss_last_stamp_s) {
  odonav::msg::Odometer m;
  m.header(dds::make_header(s.t_s, "odometer"));
  m.vehicle_id(vehicle_id);
  m.pulses(s.pulses);
  m.direction(static_cast<int8_t>(s.direction));
  m.gnss_complete_known(true);
  m.gnss_complete_through_s(gnss_complete_through_s);
  m.gnss_last_stamp_s(gnss_last_stamp_s.value_or(-1.0));
  return m;
}

odonav::msg::InsAttitude ins_message(const InsSample& s, const std::string& vehicle_id, double gnss_complete_through_s,
                                     std::optional<double> gnss_last_stamp_s) {
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
  m.gnss_complete_known(true);
  m.gnss_complete_through_s(gnss_complete_through_s);
  m.gnss_last_stamp_s(gnss_last_stamp_s.value_or(-1.0));
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

SensorPublisher::SensorPublisher(dds::ComponentRuntime& runtime, const std::string& writer_profile)
    : runtime_(runtime),
      odometer_(runtime.participant(), topics::kOdometer.name, writer_profile),
      ins_(runtime.participant(), topics::kInsAttitude.name, writer_profile),
      gnss_(runtime.participant(), topics::kGnssFix.name, writer_profile) {}

void SensorPublisher::odometer(const OdometerSample& s) {
  const std::lock_guard<std::mutex> lock(mutex_);
  // -1 before any GNSS: consumers take it as "nothing declared yet" (nothing below their data).
  const double through = last_gnss_t_s_.value_or(-1.0);
  count(odometer_.write(odometer_message(s, vehicle(), through, last_gnss_t_s_)), 0, s.t_s);
}

void SensorPublisher::odometer(const OdometerSample& s, double gnss_complete_through_s) {
  const std::lock_guard<std::mutex> lock(mutex_);
  count(odometer_.write(odometer_message(s, vehicle(), gnss_complete_through_s, last_gnss_t_s_)), 0, s.t_s);
}

void SensorPublisher::ins(const InsSample& s) {
  const std::lock_guard<std::mutex> lock(mutex_);
  count(ins_.write(ins_message(s, vehicle(), last_gnss_t_s_.value_or(-1.0), last_gnss_t_s_)), 1, s.t_s);
}

void SensorPublisher::ins(const InsSample& s, double gnss_complete_through_s) {
  const std::lock_guard<std::mutex> lock(mutex_);
  count(ins_.write(ins_message(s, vehicle(), gnss_complete_through_s, last_gnss_t_s_)), 1, s.t_s);
}

void SensorPublisher::gnss(const GnssSample& s) {
  const std::lock_guard<std::mutex> lock(mutex_);
  const odonav::msg::GnssFix m = gnss_message(s, vehicle());
  if (!m.valid()) ++counts_.gnss_invalid;
  count(gnss_.write(m), 2, s.t_s);
  last_gnss_t_s_ = dds::to_seconds(m.header().stamp());  // as the consumers receive it
}

void SensorPublisher::count(bool written, std::size_t stream, double t_s) {
  if (!written && ++counts_.write_failures <= 10) spdlog::warn("write refused by the middleware at t={} s", t_s);
  ++counts_.published[stream];
  counts_.last_t_s = t_s;
}

bool SensorPublisher::wait_for_acknowledgments(std::chrono::milliseconds timeout) {
  bool all = true;
  for (dds::detail::WriterBase* w :
       {static_cast<dds::detail::WriterBase*>(&odometer_), static_cast<dds::detail::WriterBase*>(&ins_),
        static_cast<dds::detail::WriterBase*>(&gnss_)}) {
    if (!dds::wait_for_acknowledgments_logged(*w, timeout)) {
      const std::lock_guard<std::mutex> lock(mutex_);
      ++ack_timeouts_;
      all = false;
    }
  }
  return all;
}

PublishedCounts SensorPublisher::counts() const {
  const std::lock_guard<std::mutex> lock(mutex_);
  return counts_;
}

std::uint64_t SensorPublisher::ack_timeouts() const {
  const std::lock_guard<std::mutex> lock(mutex_);
  return ack_timeouts_;
}

std::vector<std::string> SensorPublisher::readers_lost_since(double since_s) const {
  std::vector<std::pair<std::string, std::string>> lost;  // participant, streams
  for (const dds::detail::WriterBase* w :
       {static_cast<const dds::detail::WriterBase*>(&odometer_), static_cast<const dds::detail::WriterBase*>(&ins_),
        static_cast<const dds::detail::WriterBase*>(&gnss_)}) {
    for (const auto& r : w->lost_readers()) {
      if (r.at_s < since_s) continue;
      const std::string stream = stream_name_of_topic(w->topic_name());
      auto it = std::find_if(lost.begin(), lost.end(), [&](const auto& l) { return l.first == r.reader; });
      if (it == lost.end())
        lost.emplace_back(r.reader, stream);
      else if (it->second.find(stream) == std::string::npos)
        it->second += ", " + stream;
    }
  }
  std::vector<std::string> out;
  for (const auto& [who, streams] : lost) out.push_back(who + " on " + streams);
  return out;
}

std::array<std::size_t, 3> SensorPublisher::matched_readers() const {
  return {odometer_.matched_readers(), ins_.matched_readers(), gnss_.matched_readers()};
}

void SensorPublisher::publish_health(odonav::msg::HealthState state, const std::string& reason,
                                     const SourceHealth& source, bool force) {
  const std::lock_guard<std::mutex> lock(mutex_);
  const GatewayHealth h = gateway_health(counts_, source, reason);
  runtime_.publish_health(state, h.warn ? odonav::msg::HEALTH_LEVEL_WARN : odonav::msg::HEALTH_LEVEL_OK, h.reason,
                          h.counters, force);
}

}  // namespace odonav::gateway
