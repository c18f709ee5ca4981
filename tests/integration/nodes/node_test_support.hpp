#pragma once
// Helpers of the node tests: a short simulated dataset reduced to what survives the wire (stamps
// in ns, angles in degrees), sample -> message builders, and a collecting reader; child processes
// come from tests/support/child_process.hpp.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <functional>
#include <limits>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "child_process.hpp"
#include "locked_vector.hpp"
#include "odonav/simulator/simulator.hpp"
#include "odonav/dataset.hpp"
#include "odonav/dds/endpoints.hpp"
#include "odonav/dds/participant.hpp"
#include "odonav/dds/time.hpp"
#include "odonav/msg/GnssFix.h"
#include "odonav/msg/Health.h"
#include "odonav/msg/InsAttitude.h"
#include "odonav/msg/Odometer.h"
#include "odonav/topics.hpp"

namespace odonav::test {

inline constexpr const char* kVehicle = "test-vehicle";

/// The common flags of a node under test: its domain, the loopback profile, the test vehicle.
inline std::vector<std::string> node_args(int domain, double max_wait_s, std::vector<std::string> extra = {}) {
  std::vector<std::string> a{"--domain",     std::to_string(domain),
                             "--profile",    std::string(ODONAV_SOURCE_DIR) + "/deploy/profiles/loopback.xml",
                             "--vehicle-id", kVehicle,
                             "--max-wait-s", std::to_string(max_wait_s),
                             "--log-level",  "warn"};
  a.insert(a.end(), extra.begin(), extra.end());
  return a;
}

inline dds::ParticipantOptions test_participant(int domain) {
  dds::ParticipantOptions p;
  p.profiles_file = std::string(ODONAV_SOURCE_DIR) + "/deploy/profiles/loopback.xml";
  p.domain_id = domain;
  p.participant_name = "odonav-node-test";
  return p;
}

/// t as it arrives through builtin_interfaces/Time (ns), and lat/lon through degrees: the dataset
/// the node really sees, so the reference core can be fed exactly the same numbers.
inline double wire_time(double t_s) { return dds::to_seconds(dds::to_time_msg(t_s)); }
/// An angle (rad) that comes back unchanged through degrees: rad -> deg -> rad is not always the
/// identity, but its fixed point (reached in a step or two) is what the node computes too.
inline double wire_angle(double rad) {
  for (int i = 0; i < 8; ++i) {
    const double back = deg_to_rad(rad_to_deg(rad));
    if (back == rad) break;
    rad = back;
  }
  return rad;
}

/// A short straight run of the simulator (start standing, then 10 m/s), reduced to the wire.
inline Dataset short_dataset(double duration_s) {
  simulator::SimulationConfig cfg = simulator::scenario_config("straight");
  cfg.duration_s = duration_s;
  Dataset d = simulator::simulate(cfg);
  for (auto& o : d.odometer) o.t_s = wire_time(o.t_s);
  for (auto& i : d.ins) i.t_s = wire_time(i.t_s);
  for (auto& g : d.gnss) {
    g.t_s = wire_time(g.t_s);
    g.position.lat_rad = wire_angle(g.position.lat_rad);
    g.position.lon_rad = wire_angle(g.position.lon_rad);
  }
  return d;
}

inline msg::Odometer odometer_message(const OdometerSample& s) {
  msg::Odometer m;
  m.header(dds::make_header(s.t_s, "odometer"));
  m.vehicle_id(kVehicle);
  m.pulses(s.pulses);
  m.direction(static_cast<int8_t>(s.direction));
  return m;
}

inline msg::GnssFix gnss_message(const GnssSample& s) {
  msg::GnssFix m;
  m.header(dds::make_header(s.t_s, "wgs84"));
  m.vehicle_id(kVehicle);
  m.latitude_deg(rad_to_deg(s.position.lat_rad));
  m.longitude_deg(rad_to_deg(s.position.lon_rad));
  m.height_m(s.position.height_m);
  m.velocity_east_mps(s.vel_enu_mps.x());
  m.velocity_north_mps(s.vel_enu_mps.y());
  m.velocity_up_mps(s.vel_enu_mps.z());
  m.fix_quality(static_cast<uint8_t>(s.fix));
  m.position_std_m(s.pos_std_m.value_or(-1.0));
  m.velocity_std_mps(s.vel_std_mps.value_or(-1.0));
  m.valid(s.valid());
  return m;
}

inline msg::InsAttitude ins_message(const InsSample& s) {
  msg::InsAttitude m;
  m.header(dds::make_header(s.t_s, "body"));
  m.vehicle_id(kVehicle);
  m.heading_rad(s.attitude.heading_rad);
  m.pitch_rad(s.attitude.pitch_rad);
  m.roll_rad(s.attitude.roll_rad);
  if (s.vel_enu_mps) {
    m.velocity_east_mps(s.vel_enu_mps->x());
    m.velocity_north_mps(s.vel_enu_mps->y());
    m.velocity_up_mps(s.vel_enu_mps->z());
  }
  m.velocity_valid(s.vel_enu_mps.has_value());
  m.valid(true);
  return m;
}

/// Collects every sample of a topic (callback mode: nothing is lost to a shallow history).
template <class T>
class Collector {
 public:
  Collector(const dds::Participant& p, const topics::TopicSpec& topic)
      : reader_(p, topic.name, topic.reader_profile, [this](const T& s) { samples_.push_back(s); }) {}
  std::vector<T> samples() const { return samples_.copy(); }
  std::size_t size() const { return samples_.size(); }
  /// The sample time (s) of the latest sample received, -infinity before the first.
  double latest_t_s() const {
    const std::optional<T> last = samples_.last();
    return last ? dds::to_seconds(last->header().stamp()) : -std::numeric_limits<double>::infinity();
  }
  dds::Reader<T>& reader() { return reader_; }
  /// Waits until pred(samples) holds or timeout; returns whether it held.
  bool wait_until(const std::function<bool(const std::vector<T>&)>& pred, std::chrono::milliseconds timeout) {
    const auto end = std::chrono::steady_clock::now() + timeout;
    while (std::chrono::steady_clock::now() < end) {
      if (pred(samples())) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return pred(samples());
  }

 private:
  LockedVector<T> samples_;
  dds::Reader<T> reader_;
};

/// The value of a named counter of a Health message (NaN if absent).
inline double counter(const msg::Health& h, const std::string& name) {
  for (const auto& c : h.counters())
    if (c.name() == name) return c.value();
  return std::nan("");
}

/// One timed message of the replay: publishes itself when called.
struct TimedWrite {
  double t_s;
  int order;  // ties: lower first (sensors before the estimates derived from them)
  std::function<void()> write;
};

/// The sample time (s) of the node's latest output, -infinity before its first: how far the node
/// under test has got.
using ConsumerProgress = std::function<double()>;

/// Replays writes in event-time order, pausing briefly every 50 writes. The KEEP_LAST histories of
/// the sensor and estimate topics (3000 and 300 samples: 30 s) drop what a node has not taken when
/// the replay runs that far ahead of it, which a loaded machine makes happen at full replay speed
/// (a node then missed 250-480 odometer samples and dozens of misalignments). So the replay never
/// writes more than 5 s of sample time beyond the node's `progress`, unless the node makes no
/// progress for 5 s of wall time (it may be waiting, by design, for an input to fall silent).
/// (Waiting for acknowledgments instead is not enough: an acknowledged sample can still be dropped
/// from a full reader history.) The end waits for every writer in `flush` to be acknowledged.
inline void replay(std::vector<TimedWrite> writes, const std::vector<dds::detail::WriterBase*>& flush,
                   const ConsumerProgress& progress) {
  constexpr std::size_t kChunk = 50;
  constexpr double kMaxLeadS = 5.0;
  constexpr auto kMaxStall = std::chrono::seconds(5);
  std::stable_sort(writes.begin(), writes.end(), [](const TimedWrite& a, const TimedWrite& b) {
    return a.t_s < b.t_s || (a.t_s == b.t_s && a.order < b.order);
  });
  // Before the node's first output, the lead counts from the first write.
  const double start_s = writes.empty() ? 0.0 : writes.front().t_s;
  std::size_t n = 0;
  for (auto& w : writes) {
    if (n % kChunk == 0) {
      double reached_s = std::max(start_s, progress());
      auto progressed_at = std::chrono::steady_clock::now();
      while (w.t_s - reached_s > kMaxLeadS && std::chrono::steady_clock::now() - progressed_at < kMaxStall) {
        std::this_thread::sleep_for(std::chrono::milliseconds(2));
        const double now_s = std::max(start_s, progress());
        if (now_s > reached_s) {
          reached_s = now_s;
          progressed_at = std::chrono::steady_clock::now();
        }
      }
    }
    w.write();
    if (++n % kChunk == 0) std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  for (auto* f : flush) f->wait_for_acknowledgments(std::chrono::milliseconds(5000));
}

/// Drops heartbeats: an estimate republished with the stamp of the previous one.
template <class T>
std::vector<T> without_repeats(const std::vector<T>& in) {
  std::vector<T> out;
  for (const T& m : in)
    if (out.empty() || !(out.back().header().stamp() == m.header().stamp())) out.push_back(m);
  return out;
}

}  // namespace odonav::test
