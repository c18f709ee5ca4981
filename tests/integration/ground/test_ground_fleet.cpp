// odonav-ground against REAL vehicle pipelines (gateway with a simulated drive, calibration,
// identification, dead reckoning as processes on loopback DDS, domains 150-152):
//   1. the monitor lists two vehicles with every component's health, K +- sigma, misalignment and
//      DR error; a SIGKILLed identification of one vehicle is STALE within 2 deadline periods while
//      the other vehicle's identification is not;
//   2. recordings at --speed max (odonav-recorder's CSV files and odonav-ground record's MCAP) hold
//      every ScaleFactor and Misalignment the pipeline published, counted against odonav-offline;
//   3. freeze, set-k, unfreeze on a running identification: acknowledged, the published K is the
//      commanded one while frozen, and goes back toward the identified K after unfreeze.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <mutex>
#include <nlohmann/json.hpp>
#include <set>

#include "shm_clean_test.hpp"
#include "ground_test_support.hpp"
#include "odonav/dds/endpoints.hpp"
#include "odonav/dds/time.hpp"
#include "odonav/msg/ScaleFactor.h"
#include "odonav/results/output_files.hpp"

using namespace odonav::test;

namespace {

class GroundFleet : public odonav::test::ShmCleanTest {};

}  // namespace

// ---- 1. the monitor against two real vehicles ----

TEST_F(GroundFleet, MonitorShowsTwoRealVehiclesAndMarksAKilledComponentStale) {
  constexpr int kDomain = 150;
  constexpr double kHealthDeadlineS = 3.0;    // odonav_health_reader
  constexpr double kEstimateDeadlineS = 1.0;  // odonav_estimate_reader (the monitor's K reader)
  const fs::path dir = scratch_dir("fleet_monitor");
  const std::vector<std::string> vehicles{"fleet-alpha", "fleet-bravo"};
  const ScenarioTruth truth = scenario_truth("terrain", 1, dir / "truth");

  // Two vehicles, moderate pace (2x real time: the whole fleet fits the 2 shared cores).
  std::vector<std::unique_ptr<VehiclePipeline>> fleet;
  for (std::size_t i = 0; i < vehicles.size(); ++i) {
    PipelineOptions o;
    o.speed = "2";
    o.seed = 1;  // the same drive for both: one truth to compare with
    fleet.push_back(std::make_unique<VehiclePipeline>(kDomain, vehicles[i], dir, o));
  }
  for (auto& v : fleet) v->start_consumers();
  for (auto& v : fleet) v->start_gateway();
  ChildProcess monitor(binary("odonav-ground"), ground_args("monitor", kDomain, {"--json", "--refresh-s", "0.1"}),
                       dir / "monitor.out", dir / "monitor.err");
  ASSERT_TRUE(monitor.started());

  // Live monitor: wait (bounded) until both vehicles are complete and K has converged.
  const auto t0 = std::chrono::steady_clock::now();
  bool ready = false;
  while (!ready && seconds_since(t0) < 90.0) {
    std::this_thread::sleep_for(250ms);
    const auto snap = last_json_line(dir / "monitor.out");
    ready = snap && vehicle_ready(*snap, vehicles[0]) && vehicle_ready(*snap, vehicles[1]);
  }
  ASSERT_TRUE(ready) << "the fleet never showed complete; last snapshot: "
                     << last_json_line(dir / "monitor.out").value_or(json()).dump(1) << "\n"
                     << fleet[0]->logs_tail() << fleet[1]->logs_tail() << monitor.err();
  std::cerr << "both vehicles complete and K converged after " << seconds_since(t0) << " s\n";

  // `monitor --once --json`: one document listing both vehicles with everything. A new participant
  // discovers the two vehicles' ten participants and hears each component's 1 Hz health within the
  // settle time: 2 s once left one component out while the whole test suite loaded both cores.
  const RunResult once = run(binary("odonav-ground"),
                             ground_args("monitor", kDomain, {"--once", "--json", "--settle-s", "4"}), dir, "once");
  ASSERT_EQ(once.exit_code, 0) << once.err;
  const json snap = json::parse(once.out);
  ASSERT_EQ(snap.at("vehicles").size(), vehicles.size()) << once.out;
  for (const auto& id : vehicles) {
    SCOPED_TRACE(id);
    const json* v = find_by(snap.at("vehicles"), "vehicle_id", id);
    ASSERT_NE(v, nullptr);
    ASSERT_EQ(v->at("components").size(), kVehicleComponents.size()) << v->dump(1);
    for (const auto& c : kVehicleComponents) {
      const json* jc = find_by(v->at("components"), "component", c);
      ASSERT_NE(jc, nullptr) << c;
      EXPECT_EQ(jc->at("state"), "RUNNING") << c;
      EXPECT_TRUE(jc->at("level") == "OK" || jc->at("level") == "WARN") << c << " " << jc->dump();
      EXPECT_TRUE(jc->at("reason").is_string()) << c;
      EXPECT_FALSE(jc->at("stale").get<bool>()) << c;
      EXPECT_LT(jc->at("age_s").get<double>(), kHealthDeadlineS) << c;
    }
    // K +- sigma: converged on the simulated truth (the drive's first K step is at 250 s).
    const json& k = v->at("scale_factor");
    EXPECT_NEAR(k.at("k_m_per_pulse").get<double>() / truth.k_m_per_pulse, 1.0, 0.01) << k.dump();
    EXPECT_GT(k.at("sigma_m_per_pulse").get<double>(), 0.0);
    EXPECT_LT(k.at("sigma_m_per_pulse").get<double>(), 0.01 * truth.k_m_per_pulse);
    EXPECT_EQ(k.at("estimator"), "vff_lm_rls");
    EXPECT_GT(k.at("samples_accepted").get<double>(), 10);
    EXPECT_EQ(k.at("source"), "identification");  // the instance K comes from (ScaleFactor.source)
    // Misalignment +- sigma, in degrees, near the installation truth.
    const json& m = v->at("misalignment");
    EXPECT_NEAR(m.at("heading_deg").get<double>(), truth.heading_deg, 0.5) << m.dump();
    EXPECT_NEAR(m.at("pitch_deg").get<double>(), truth.pitch_deg, 0.5) << m.dump();
    EXPECT_GT(m.at("heading_std_deg").get<double>(), 0.0);
    EXPECT_LT(m.at("heading_std_deg").get<double>(), 1.0);
    EXPECT_GT(m.at("samples_used").get<double>(), 0);
    // DR error against GNSS, metres and % of distance.
    const json& d = v->at("dead_reckoning");
    EXPECT_GT(d.at("distance_m").get<double>(), 20.0) << d.dump();
    EXPECT_GE(d.at("horizontal_error_m").get<double>(), 0.0);
    EXPECT_LT(d.at("horizontal_error_m").get<double>(), 0.05 * d.at("distance_m").get<double>() + 5.0);
    EXPECT_LT(d.at("error_percent").get<double>(), 5.0);
    EXPECT_TRUE(v->at("gnss").at("valid").get<bool>());
    // Rates: odometer at 100 Hz and GNSS at 10 Hz of simulated time, at 2x real time.
    EXPECT_GT(v->at("rates_hz").at("odometer").get<double>(), 100.0);
    EXPECT_GT(v->at("rates_hz").at("gnss").get<double>(), 10.0);
    EXPECT_FALSE(v->at("stale").get<bool>());
  }

  // SIGKILL one vehicle's identification; the live monitor must mark it (Health: deadline 3 s) and
  // its K (deadline 1 s) STALE within 2 deadline periods, and nothing of the other vehicle.
  fleet[1]->process("odonav-identification").signal(SIGKILL);
  const auto killed_at = std::chrono::steady_clock::now();
  std::optional<double> health_stale_s, k_stale_s;
  while ((!health_stale_s || !k_stale_s) && seconds_since(killed_at) < 15.0) {
    std::this_thread::sleep_for(50ms);
    const auto s = last_json_line(dir / "monitor.out");
    if (!s) continue;
    const json* killed = snapshot_component(*s, vehicles[1], "odonav-identification");
    const json* killed_vehicle = find_by(s->at("vehicles"), "vehicle_id", vehicles[1]);
    const json* other_vehicle = find_by(s->at("vehicles"), "vehicle_id", vehicles[0]);
    ASSERT_TRUE(killed && killed_vehicle && other_vehicle);
    const bool k_stale = killed_vehicle->at("scale_factor").at("stale").get<bool>();
    if (k_stale && !k_stale_s) k_stale_s = seconds_since(killed_at);
    if (killed->at("stale").get<bool>() && !health_stale_s) {
      health_stale_s = seconds_since(killed_at);
      EXPECT_TRUE(killed_vehicle->at("stale").get<bool>());
    }
    // The other vehicle's same component and K, and the killed vehicle's other components, stay live.
    const json* same = snapshot_component(*s, vehicles[0], "odonav-identification");
    EXPECT_FALSE(same->at("stale").get<bool>()) << "after " << seconds_since(killed_at) << " s";
    EXPECT_FALSE(other_vehicle->at("scale_factor").at("stale").get<bool>()) << seconds_since(killed_at) << " s";
    for (const auto& c : {"odonav-gateway", "odonav-calibration"})
      EXPECT_FALSE(snapshot_component(*s, vehicles[1], c)->at("stale").get<bool>()) << c;
    if (HasFailure()) break;
  }
  ASSERT_TRUE(health_stale_s.has_value()) << "the killed identification never turned STALE";
  ASSERT_TRUE(k_stale_s.has_value()) << "the killed identification's K never turned STALE";
  std::cerr << "SIGKILLed identification: Health STALE after " << *health_stale_s << " s (deadline " << kHealthDeadlineS
            << " s), K STALE after " << *k_stale_s << " s (deadline " << kEstimateDeadlineS << " s)\n";
  // 2 deadline periods, plus one refresh of the display (0.1 s) and the polling step (0.05 s).
  EXPECT_LE(*health_stale_s, 2 * kHealthDeadlineS + 0.15);
  EXPECT_LE(*k_stale_s, 2 * kEstimateDeadlineS + 0.15);

  monitor.signal(SIGINT);
  ASSERT_TRUE(monitor.wait_exit(10s));
  EXPECT_EQ(monitor.exit_code(), 0) << monitor.err();
}

// ---- 2. recordings at maximum replay speed hold every estimate ----

namespace {

/// Stamps (s) of the decoded messages of one MCAP channel, heartbeats (a repeat of the previous
/// stamp) dropped, in recording order.
std::vector<double> mcap_stamps(const json& doc, const std::string& topic, const std::string& vehicle) {
  std::vector<double> stamps;
  for (const auto& m : doc.at("messages")) {
    if (m.at("topic") != topic || m.at("data").at("vehicle_id") != vehicle) continue;
    const auto& st = m.at("data").at("header").at("stamp");
    const double t = static_cast<double>(st.at("sec").get<std::int64_t>()) + 1e-9 * st.at("nanosec").get<double>();
    if (stamps.empty() || stamps.back() != t) stamps.push_back(t);
  }
  return stamps;
}

template <class Row>
void expect_same_stamps(const std::vector<double>& got, const std::vector<Row>& ref, const std::string& what) {
  ASSERT_EQ(got.size(), ref.size()) << what << ": recorded " << got.size() << " of " << ref.size();
  for (std::size_t i = 0; i < ref.size(); ++i)
    ASSERT_NEAR(got[i], ref[i].t_s, 1e-6) << what << " sample " << i;  // ns on the wire, us in the CSV
}

}  // namespace

TEST_F(GroundFleet, RecordingsAtMaximumSpeedHoldEveryPublishedEstimate) {
  constexpr int kDomain = 151;
  const fs::path dir = scratch_dir("record_max_speed");
  const std::string vehicle = "rec-vehicle";
  ASSERT_TRUE(npm_reader_modules().has_value());  // before the run: the install may take a while

  const fs::path mcap = dir / "estimates.mcap";
  ChildProcess recorder(
      binary("odonav-ground"),
      ground_args("record", kDomain, {"--out", mcap.string(), "--topics", "misalignment,scale_factor"}),
      dir / "record.out", dir / "record.err");
  ASSERT_TRUE(recorder.started());
  std::this_thread::sleep_for(1s);  // its readers exist before any estimate: deploy/launch simulates first

  // The whole pipeline with odonav-recorder, replayed as fast as the readers acknowledge; the
  // launcher also runs odonav-offline on the same dataset (out/offline): the reference of what the
  // identification and calibration publish (equal row by row: test_pipeline.cpp).
  const fs::path out = dir / "run";
  const RunResult launch = run("/bin/bash",
                               {std::string(ODONAV_SOURCE_DIR) + "/deploy/launch", "--build-dir", ODONAV_BINARY_DIR,
                                "--source", "sim:terrain", "--duration-s", "90", "--seed", "4", "--speed", "max",
                                "--domain", std::to_string(kDomain), "--vehicle-id", vehicle, "--out", out.string()},
                               dir, "launch", 300s);
  ASSERT_EQ(launch.exit_code, 0) << launch.out << launch.err;
  recorder.signal(SIGINT);
  ASSERT_TRUE(recorder.wait_exit(20s));
  ASSERT_EQ(recorder.exit_code(), 0) << recorder.err();

  const odonav::results::OutputRows ref = odonav::results::read_output_rows((out / "offline").string());
  ASSERT_GT(ref.scale_factor.size(), 800u);  // 90 s at 10 Hz, minus the standstill
  ASSERT_GT(ref.misalignment.size(), 800u);

  // odonav-recorder (CSV files).
  const odonav::results::OutputRows csv = odonav::results::read_output_rows(out.string());
  std::vector<double> t;
  for (const auto& r : csv.scale_factor) t.push_back(r.t_s);
  expect_same_stamps(t, ref.scale_factor, "odonav-recorder scale_factor.csv");
  t.clear();
  for (const auto& r : csv.misalignment) t.push_back(r.t_s);
  expect_same_stamps(t, ref.misalignment, "odonav-recorder misalignment.csv");
  // The last K recorded is the last the identification computed.
  ASSERT_TRUE(csv.scale_factor.back().k_m_per_pulse && ref.scale_factor.back().k_m_per_pulse);
  EXPECT_NEAR(*csv.scale_factor.back().k_m_per_pulse / *ref.scale_factor.back().k_m_per_pulse, 1.0, 1e-9);
  EXPECT_EQ(csv.scale_factor.back().samples_accepted, ref.scale_factor.back().samples_accepted);

  // odonav-ground record (MCAP, read back by @mcap/core and the ROS 2 CDR decoder).
  const McapRead read = read_mcap(mcap, "indexed");
  ASSERT_EQ(read.exit_code, 0) << read.err;
  const std::vector<double> k_stamps = mcap_stamps(read.doc, "/odonav/scale_factor", vehicle);
  const std::vector<double> m_stamps = mcap_stamps(read.doc, "/odonav/misalignment", vehicle);
  expect_same_stamps(k_stamps, ref.scale_factor, "odonav-ground record /odonav/scale_factor");
  expect_same_stamps(m_stamps, ref.misalignment, "odonav-ground record /odonav/misalignment");
  std::cerr << "at --speed max: " << ref.scale_factor.size() << " ScaleFactor and " << ref.misalignment.size()
            << " Misalignment published; odonav-recorder holds " << csv.scale_factor.size() << " / "
            << csv.misalignment.size() << ", odonav-ground record " << k_stamps.size() << " / " << m_stamps.size()
            << "\n";
}

// ---- 3. set K on a running identification ----

namespace {

/// Every ScaleFactor of one vehicle with its arrival time, read with the vehicle consumers' profile
/// (what dead reckoning sees).
class ScaleFactorLog {
 public:
  ScaleFactorLog(const odonav::dds::Participant& p, std::string vehicle)
      : vehicle_(std::move(vehicle)),
        reader_(p, topics::kScaleFactor.name, topics::kScaleFactor.reader_profile, [this](const msg::ScaleFactor& s) {
          if (s.vehicle_id() != vehicle_) return;
          std::lock_guard<std::mutex> lock(mutex_);
          samples_.push_back({std::chrono::steady_clock::now(), s});
        }) {}
  struct Entry {
    std::chrono::steady_clock::time_point arrival;
    msg::ScaleFactor sample;
  };
  std::vector<Entry> since(std::chrono::steady_clock::time_point t) const {
    std::lock_guard<std::mutex> lock(mutex_);
    std::vector<Entry> out;
    for (const auto& e : samples_)
      if (e.arrival >= t) out.push_back(e);
    return out;
  }
  std::optional<msg::ScaleFactor> last() const {
    std::lock_guard<std::mutex> lock(mutex_);
    if (samples_.empty()) return std::nullopt;
    return samples_.back().sample;
  }

 private:
  std::string vehicle_;
  mutable std::mutex mutex_;
  std::vector<Entry> samples_;
  odonav::dds::Reader<msg::ScaleFactor> reader_;
};

/// Waits (bounded) until pred(last sample) holds.
bool wait_for(const ScaleFactorLog& log, const std::function<bool(const msg::ScaleFactor&)>& pred,
              std::chrono::seconds timeout) {
  const auto end = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < end) {
    const auto s = log.last();
    if (s && pred(*s)) return true;
    std::this_thread::sleep_for(50ms);
  }
  return false;
}

}  // namespace

TEST_F(GroundFleet, SetKOnARunningIdentificationIsAcknowledgedAndPublished) {
  constexpr int kDomain = 152;
  const fs::path dir = scratch_dir("set_k");
  const std::string vehicle = "cmd-vehicle";
  odonav::dds::Participant participant(participant_options(kDomain, "set-k-test"));
  ScaleFactorLog k_log(participant, vehicle);

  PipelineOptions o;
  o.speed = "3";  // 240 s of drive in 80 s; terrain's first K step (250 s) is never reached
  o.seed = 2;
  o.with_dead_reckoning = false;
  VehiclePipeline pipeline(kDomain, vehicle, dir, o);
  pipeline.start_consumers();
  pipeline.start_gateway();
  ASSERT_TRUE(wait_for(
      k_log, [](const msg::ScaleFactor& s) { return s.converged() && s.samples_accepted() > 100; }, 60s))
      << "K never converged\n"
      << pipeline.logs_tail();
  const double k_identified = k_log.last()->k_m_per_pulse();

  auto command = [&](std::vector<std::string> what, const std::string& tag) {
    std::vector<std::string> args{"--vehicle", vehicle, "--component", "odonav-identification", "--timeout-s", "15"};
    args.insert(args.end(), what.begin(), what.end());
    return run(binary("odonav-ground"), ground_args("command", kDomain, args), dir, tag);
  };

  // freeze: acknowledged, K held.
  const RunResult freeze = command({"freeze"}, "freeze");
  ASSERT_EQ(freeze.exit_code, 0) << freeze.out << freeze.err;
  EXPECT_NE(freeze.out.find("ACCEPTED"), std::string::npos) << freeze.out;
  EXPECT_TRUE(wait_for(
      k_log, [](const msg::ScaleFactor& s) { return s.frozen(); }, 5s));

  // set-k: 1.5 % above the identified K, written with every digit so the command carries it exactly.
  const double commanded = k_identified * 1.015;
  char text[40];
  std::snprintf(text, sizeof text, "%.17g", commanded);
  const RunResult set_k = command({"set-k", text}, "set_k");
  ASSERT_EQ(set_k.exit_code, 0) << set_k.out << set_k.err;
  EXPECT_NE(set_k.out.find("set-k " + std::string(text)), std::string::npos) << set_k.out;
  EXPECT_NE(set_k.out.find("ACCEPTED: K set to"), std::string::npos) << set_k.out;
  // From the acknowledgement on (the K was published before the Health carrying it), for the next
  // 3 s (about 9 s of drive, 90 GNSS epochs at 3x): every K is the commanded one, frozen.
  const auto acked = std::chrono::steady_clock::now();
  std::this_thread::sleep_for(3s);
  const auto held = k_log.since(acked);
  ASSERT_GE(held.size(), 10u) << "ScaleFactor not published while frozen";
  for (const auto& e : held) {
    EXPECT_NEAR(e.sample.k_m_per_pulse() / commanded, 1.0, 1e-12) << "K " << e.sample.k_m_per_pulse();
    EXPECT_TRUE(e.sample.frozen());
  }
  std::cerr << "set-k " << text << " (identified " << k_identified << "): " << held.size()
            << " ScaleFactor in 3 s, all at the commanded K\n";

  // unfreeze: the identification continues from the commanded K and goes back to the data's K.
  const RunResult unfreeze = command({"unfreeze"}, "unfreeze");
  ASSERT_EQ(unfreeze.exit_code, 0) << unfreeze.out << unfreeze.err;
  EXPECT_NE(unfreeze.out.find("ACCEPTED"), std::string::npos) << unfreeze.out;
  const double offset = commanded - k_identified;
  const bool back = wait_for(
      k_log,
      [&](const msg::ScaleFactor& s) {
        return !s.frozen() && std::abs(s.k_m_per_pulse() - k_identified) < 0.25 * std::abs(offset);
      },
      40s);
  EXPECT_TRUE(back) << "K after unfreeze: " << k_log.last()->k_m_per_pulse() << ", identified " << k_identified
                    << ", commanded " << commanded;
  std::cerr << "after unfreeze K = " << k_log.last()->k_m_per_pulse() << " (identified " << k_identified << ")\n";
  EXPECT_TRUE(pipeline.process("odonav-identification").running());
}
