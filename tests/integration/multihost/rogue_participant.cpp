// odonav-multihost-rogue: a participant the multi-host test places on a host of the vehicle network
// to play an intruder (or, in the plain run, a passive listener that proves the network path).
//
// It joins the domain with the given profile and, optionally, DDS Security material (which may be
// from another CA, or absent), listens to the scale factor, dead reckoning and odometer topics of
// every vehicle, and unless --listen-only publishes a fake ScaleFactor (--fake-k, converged, the
// vehicle's key, ownership strength 1000 so it would win over identification's) at 10 Hz with event-time stamps that follow the wall clock from --stamp-start-s,
// i.e. stamps a dead-reckoning node would apply if the sample reached it.
// At the end (--duration-s or SIGINT/SIGTERM) it prints ONE JSON document on stdout:
//   {"written": n, "fake_matched_readers_max": n,
//    "received": {"scale_factor": n, "scale_factor_not_fake": n, "dead_reckoning": n, "odometer": n}}
// (null for a reader its own permissions refuse).
// Exit: 0 done; 2 bad flags; 3 the participant or an endpoint was refused (the reason on stderr and
// as {"error": "..."} on stdout: e.g. the permissions do not allow the fake writer).
#include <signal.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <iostream>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <thread>
#include <tuple>

#include <nlohmann/json.hpp>

#include "odonav/config.hpp"
#include "odonav/dds/endpoints.hpp"
#include "odonav/dds/participant.hpp"
#include "odonav/dds/security.hpp"
#include "odonav/dds/time.hpp"
#include "odonav/msg/DeadReckoning.h"
#include "odonav/msg/Odometer.h"
#include "odonav/msg/ScaleFactor.h"
#include "odonav/topics.hpp"
#include "stop_signals.hpp"

namespace {

using odonav::test::g_stop;

namespace topics = odonav::topics;
namespace msg = odonav::msg;

struct Counts {
  std::atomic<std::uint64_t> scale_factor{0};
  std::atomic<std::uint64_t> scale_factor_not_fake{0};
  std::atomic<std::uint64_t> dead_reckoning{0};
  std::atomic<std::uint64_t> odometer{0};
};

int run(const odonav::Options& o) {
  odonav::dds::ParticipantOptions p;
  p.profiles_file = o.get_string("profile");
  if (p.profiles_file.empty()) throw odonav::ConfigError("--profile: required (the participant profile file)");
  p.participant_profile = o.get_string("profile-name");
  p.domain_id = static_cast<int>(o.get_int("domain"));
  p.participant_name = o.get_string("name");
  std::tie(p.security_dir, p.security_identity) = odonav::dds::security_options_from(o);
  const double fake_k = o.get_double("fake-k");
  const bool listen_only = o.get_bool("listen-only");
  const std::string vehicle = o.get_string("vehicle-id");

  odonav::dds::Participant participant(p);
  Counts counts;
  // Best-effort readers, as a ground station on a weak link would use: they match any writer.
  // The writer first: a refused writer is the point of the permissions check.
  std::unique_ptr<odonav::dds::Writer<msg::ScaleFactor>> fake;
  if (!listen_only) {
    // A higher priority than identification's (10), as source_priority and as ownership strength:
    // without security, every consumer's arbiter would follow this writer instead, so "never
    // reaches DR" is what security achieves.
    odonav::dds::WriterSettings w;
    w.ownership_strength = static_cast<uint32_t>(o.get_int("ownership-strength"));
    fake = std::make_unique<odonav::dds::Writer<msg::ScaleFactor>>(participant, topics::kScaleFactor.name,
                                                                   topics::kScaleFactor.writer_profile, w);
  }

  // The readers its own permissions allow (a foreign identity may lack some): a refused reader is
  // reported as null, not an error.
  std::vector<std::string> refused;
  const auto optional_reader = [&](auto make, const char* topic) {
    try {
      return make();
    } catch (const std::runtime_error&) {
      refused.push_back(topic);
      return decltype(make())();
    }
  };
  auto k_reader = optional_reader(
      [&] {
        return std::make_unique<odonav::dds::Reader<msg::ScaleFactor>>(participant, topics::kScaleFactor.name,
                                                                       topics::kGroundBestEffortReaderProfile,
                                                                       [&](const msg::ScaleFactor& m) {
                                                                         ++counts.scale_factor;
                                                                         if (m.k_m_per_pulse() != fake_k)
                                                                           ++counts.scale_factor_not_fake;
                                                                       });
      },
      "scale_factor");
  auto dr_reader = optional_reader(
      [&] {
        return std::make_unique<odonav::dds::Reader<msg::DeadReckoning>>(
            participant, topics::kDeadReckoning.name, topics::kGroundBestEffortReaderProfile,
            [&](const msg::DeadReckoning&) { ++counts.dead_reckoning; });
      },
      "dead_reckoning");
  auto odo_reader = optional_reader(
      [&] {
        return std::make_unique<odonav::dds::Reader<msg::Odometer>>(participant, topics::kOdometer.name,
                                                                    topics::kGroundBestEffortReaderProfile,
                                                                    [&](const msg::Odometer&) { ++counts.odometer; });
      },
      "odometer");

  const auto t0 = std::chrono::steady_clock::now();
  const auto end = t0 + std::chrono::microseconds(static_cast<std::int64_t>(o.get_double("duration-s") * 1e6));
  std::uint64_t written = 0;
  std::size_t matched_max = 0;
  while (!g_stop.load() && std::chrono::steady_clock::now() < end) {
    if (fake) {
      const double elapsed_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      msg::ScaleFactor m;
      m.header(odonav::dds::make_header(o.get_double("stamp-start-s") + elapsed_s, "odometer"));
      m.vehicle_id(vehicle);
      m.k_m_per_pulse(fake_k);
      m.sigma_m_per_pulse(1e-6);
      m.estimator("vff-lm-rls");
      m.converged(true);
      m.source("identification");
      m.source_priority(static_cast<std::uint32_t>(o.get_int("ownership-strength")));
      if (fake->write(m)) ++written;
      matched_max = std::max(matched_max, fake->matched_readers());
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  const auto count = [&](const char* topic, std::uint64_t n) {
    return std::find(refused.begin(), refused.end(), topic) != refused.end() ? nlohmann::json(nullptr)
                                                                             : nlohmann::json(n);
  };
  nlohmann::json j{{"written", written},
                   {"fake_matched_readers_max", matched_max},
                   {"received",
                    {{"scale_factor", count("scale_factor", counts.scale_factor.load())},
                     {"scale_factor_not_fake", count("scale_factor", counts.scale_factor_not_fake.load())},
                     {"dead_reckoning", count("dead_reckoning", counts.dead_reckoning.load())},
                     {"odometer", count("odometer", counts.odometer.load())}}}};
  std::cout << j.dump() << std::endl;
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  odonav::Options o("odonav-multihost-rogue",
                    "An intruder (or passive listener) participant for the multi-host test: listens to the "
                    "estimates and outputs and publishes a fake scale factor.");
  o.add_int("domain", 0, "DDS domain id", 0, 232);
  o.add_string("profile", "", "Fast DDS XML file with the participant profile (qos.xml beside it)");
  o.add_string("profile-name", "vehicle", "participant profile name in --profile");
  o.add_string("name", "odonav-rogue", "participant name (and default security identity)");
  o.add_string("vehicle-id", "vehicle-01", "vehicle key of the fake scale factor");
  o.add_double("fake-k", 9.99, "K of the fake scale factor (m/pulse)", 1e-6, 100.0);
  o.add_double("stamp-start-s", 0.0, "event time (s) of the first fake sample; then + wall time", 0.0, 1e9);
  o.add_double("duration-s", 10.0, "how long to run (s)", 0.1, 3600.0);
  o.add_bool("listen-only", false, "only listen, write nothing");
  o.add_int("ownership-strength", 1000,
            "priority (source_priority, ownership strength) of the fake writer (identification's: 10)", 0, 1000000);
  odonav::dds::add_security_options(o);
  odonav::test::stop_on_signals();
  try {
    if (o.parse(argc, argv) == odonav::ParseResult::kHelp) return 0;
  } catch (const odonav::ConfigError& e) {
    std::cerr << "odonav-multihost-rogue: bad configuration: " << e.what() << "\n";
    return 2;
  }
  try {
    return run(o);
  } catch (const odonav::ConfigError& e) {
    std::cerr << "odonav-multihost-rogue: bad configuration: " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "odonav-multihost-rogue: refused: " << e.what() << "\n";
    std::cout << nlohmann::json{{"error", e.what()}}.dump() << std::endl;
    return 3;
  }
}
