// odonav-bench-fleet-publisher: a synthetic fleet in one process, for the ground station's
// fleet-scale benchmark (BENCHMARKS.md, "Ground station at fleet scale"; bench/fleet_bench.sh).
//
// N vehicles ("fleet-000" ...), each: DeadReckoning at 10 Hz (a circle of 100 m radius at 5 m/s),
// ScaleFactor and Misalignment at 1 Hz, Health of four components at 1 Hz, with the contract's
// writer profiles. Every stamp is the UNIX time of publication, so a client on the same host
// measures the delay from the DDS sample to its WebSocket frame (frame timestamp = sample stamp).
// --silence-after-s T: at T s, fleet-000's odonav-identification stops (Health and ScaleFactor);
// the UNIX time of that moment is printed ("silenced at <s>") so the client times the STALE.
// Loopback profile only; stops on SIGINT/SIGTERM or after --duration-s.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "odonav/config.hpp"
#include "odonav/dds/component.hpp"
#include "odonav/dds/endpoints.hpp"
#include "odonav/dds/participant.hpp"
#include "odonav/dds/time.hpp"
#include "odonav/logging.hpp"
#include "odonav/msg/DeadReckoning.h"
#include "odonav/msg/Health.h"
#include "odonav/msg/Misalignment.h"
#include "odonav/msg/ScaleFactor.h"
#include "odonav/topics.hpp"

namespace odds = odonav::dds;
namespace omsg = odonav::msg;
namespace topics = odonav::topics;

int main(int argc, char** argv) {
  odds::StopSignals stop;
  odonav::Options o("odonav-bench-fleet-publisher",
                    "A synthetic fleet's estimates, dead reckoning and health (benchmark).");
  o.add_int("vehicles", 10, "number of vehicles", 1, 10000);
  o.add_int("domain", 189, "DDS domain", 0, 232);
  o.add_string("profile", "", "Fast DDS profile file (deploy/profiles/loopback.xml)");
  o.add_double("duration-s", 60.0, "stop after this long (s)", 1.0, 1e6);
  o.add_double("silence-after-s", 0.0, "fleet-000's identification falls silent after this long (0: never)", 0.0, 1e6);
  o.add_string("log-level", "warn", "log level");
  try {
    if (o.parse(argc, argv) == odonav::ParseResult::kHelp) return 0;
  } catch (const odonav::ConfigError& e) {
    std::cerr << e.what() << "\n";
    return 2;
  }
  odonav::setup_logging("odonav-bench-fleet-publisher", o.get_string("log-level"));
  odds::ParticipantOptions p;
  p.profiles_file = o.get_string("profile");
  p.participant_profile = topics::kLoopbackParticipantProfile;
  p.domain_id = static_cast<int>(o.get_int("domain"));
  p.participant_name = "odonav-bench-fleet-publisher";
  odds::Participant participant(p);
  const int n = static_cast<int>(o.get_int("vehicles"));
  // A writer keeps at most 10 instances (keys: vehicles) with the profiles' default resource limits,
  // as each vehicle's own writers need one: one set of writers per group of 10 vehicles.
  struct Group {
    odds::Writer<omsg::DeadReckoning> dr;
    odds::Writer<omsg::ScaleFactor> sf;
    odds::Writer<omsg::Misalignment> mis;
    odds::Writer<omsg::Health> health;
  };
  std::vector<std::unique_ptr<Group>> groups;
  for (int g = 0; g < (n + 9) / 10; ++g) {
    groups.push_back(std::unique_ptr<Group>(
        new Group{{participant, topics::kDeadReckoning.name, topics::kDeadReckoning.writer_profile},
                  {participant, topics::kScaleFactor.name, topics::kScaleFactor.writer_profile},
                  {participant, topics::kMisalignment.name, topics::kMisalignment.writer_profile},
                  {participant, topics::kHealth.name, topics::kHealth.writer_profile}}));
  }
  std::vector<std::string> ids;
  for (int i = 0; i < n; ++i) {
    char b[32];
    std::snprintf(b, sizeof b, "fleet-%03d", i);
    ids.emplace_back(b);
  }
  const char* components[] = {"odonav-gateway", "odonav-calibration", "odonav-identification", "odonav-dead-reckoning"};
  const double silence_after_s = o.get_double("silence-after-s");
  const auto t0 = std::chrono::steady_clock::now();
  bool silenced = false;
  long tick = 0;
  while (!stop.stop_requested()) {
    const double run_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (run_s >= o.get_double("duration-s")) break;
    if (silence_after_s > 0.0 && run_s >= silence_after_s && !silenced) {
      silenced = true;
      std::printf("silenced at %.6f\n", odds::unix_now_s());
      std::fflush(stdout);
    }
    for (int i = 0; i < n; ++i) {
      Group& w = *groups[i / 10];
      const double now = odds::unix_now_s();
      const double a = 0.05 * run_s + i;  // 5 m/s on a 100 m circle
      omsg::DeadReckoning d;
      d.header(odds::make_header(now, "wgs84"));
      d.vehicle_id(ids[i]);
      d.enu_east_m(100.0 * std::cos(a));
      d.enu_north_m(100.0 * std::sin(a));
      d.origin_latitude_deg(52.5 + 0.01 * i);
      d.origin_longitude_deg(13.4);
      d.latitude_deg(52.5 + 0.01 * i + d.enu_north_m() / 111250.0);
      d.longitude_deg(13.4 + d.enu_east_m() / 67800.0);
      d.distance_m(5.0 * run_s);
      d.k_m_per_pulse(0.0125);
      d.k_source(omsg::K_SOURCE_IDENTIFIED);
      d.gnss_valid(true);
      d.horizontal_error_m(0.5);
      d.error_percent_distance(0.2);
      w.dr.write(d);
      if (tick % 10 != i % 10) continue;  // the 1 Hz topics, spread over the ticks
      const bool silent = silenced && i == 0;
      if (!silent) {
        omsg::ScaleFactor k;
        k.header(odds::make_header(now, "odometer"));
        k.vehicle_id(ids[i]);
        k.k_m_per_pulse(0.0125 * (1.0 + 0.001 * std::sin(run_s)));
        k.sigma_m_per_pulse(1e-5);
        k.forgetting_factor(0.999);
        k.window_fill(1.0);
        k.estimator("vff_lm_rls");
        k.converged(true);
        k.source("identification");
        w.sf.write(k);
      }
      omsg::Misalignment m;
      m.header(odds::make_header(now, "odometer"));
      m.vehicle_id(ids[i]);
      m.heading_rad(0.01);
      m.pitch_rad(0.005);
      m.heading_std_rad(0.001);
      m.pitch_std_rad(0.001);
      m.converged(true);
      w.mis.write(m);
      for (const char* c : components) {
        if (silent && std::string(c) == "odonav-identification") continue;
        omsg::Health h;
        h.header(odds::make_header(now, ""));
        h.vehicle_id(ids[i]);
        h.component(c);
        h.state(omsg::HEALTH_STATE_RUNNING);
        h.level(omsg::HEALTH_LEVEL_OK);
        h.reason("synthetic");
        w.health.write(h);
      }
    }
    ++tick;
    // 10 Hz: the next tick at its time (no drift), whatever this one took.
    std::this_thread::sleep_until(t0 + std::chrono::milliseconds(100 * tick));
  }
  return 0;
}
