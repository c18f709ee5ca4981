// The calibration, identification and dead-reckoning nodes as real processes on loopback DDS: each
// test starts the node executable, publishes a short simulated drive from this process, collects
// what the node publishes, stops it with SIGINT and compares with the core run directly on the
// same inputs (bit-identical: the inputs are reduced to what survives the wire first).
// Domains 40-45, one per test.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "shm_clean_test.hpp"
#include "node/calibration_node.hpp"
#include "node/dead_reckoning_node.hpp"
#include "node/identification_node.hpp"
#include "node_test_support.hpp"
#include "odonav/consumer_rules.hpp"
#include "odonav/dead_reckoning/scale_factor_selection.hpp"
#include "odonav/msg/Command.h"
#include "odonav/msg/DeadReckoning.h"
#include "odonav/msg/Misalignment.h"
#include "odonav/msg/ScaleFactor.h"

using namespace odonav;
using namespace odonav::test;
using namespace std::chrono_literals;

namespace {

constexpr double kDriveS = 50.0;  // long enough for the misalignment and K to converge

class NodeProcess : public odonav::test::ShmCleanTest {};

/// Waits until a collector holds at least `at_least` samples (heartbeats aside), then until it has
/// received nothing new for `quiet`; at most `limit` in all. The count comes first because a node
/// starved of processor time by other work on the machine can pause for longer than `quiet`.
template <class T>
void wait_quiet(Collector<T>& c, std::size_t at_least = 0, std::chrono::milliseconds quiet = 1500ms,
                std::chrono::milliseconds limit = 60s) {
  const auto end = std::chrono::steady_clock::now() + limit;
  while (std::chrono::steady_clock::now() < end && without_repeats(c.samples()).size() < at_least)
    std::this_thread::sleep_for(100ms);
  std::size_t n = without_repeats(c.samples()).size();
  auto since = std::chrono::steady_clock::now();
  while (std::chrono::steady_clock::now() < end) {
    std::this_thread::sleep_for(100ms);
    const std::size_t m = without_repeats(c.samples()).size();
    if (m != n) {
      n = m;
      since = std::chrono::steady_clock::now();
    } else if (std::chrono::steady_clock::now() - since >= quiet) {
      return;
    }
  }
}

/// Matching is seen by each side on its own: our writer may see the node's reader before that
/// reader sees our writer (and the node's writer may not see our reader yet), and VOLATILE samples
/// written in between are lost. Give both sides' discovery time to complete.
void settle_discovery() { std::this_thread::sleep_for(1s); }

/// Every writer has matched the node's reader and `reader` the node's writer (20 s each), then
/// discovery settles.
template <class Reader>
void wait_matched(const std::vector<odonav::dds::detail::WriterBase*>& writers, Reader& reader) {
  for (odonav::dds::detail::WriterBase* w : writers) ASSERT_TRUE(w->wait_for_matched(1, 20s)) << w->topic_name();
  ASSERT_TRUE(reader.wait_for_matched(1, 20s));
  settle_discovery();
}

/// SIGINT: the node drains and exits 0 within 30 s.
void stop_node(ChildProcess& node) {
  node.signal(SIGINT);
  ASSERT_TRUE(node.wait_exit(30s));
  EXPECT_EQ(node.exit_code(), 0);
}

/// The last Health of `component` received, if any.
std::optional<msg::Health> last_health(const Collector<msg::Health>& h, const std::string& component) {
  std::optional<msg::Health> found;
  for (const auto& m : h.samples())
    if (m.component() == component) found = m;
  return found;
}

std::vector<TimedWrite> sensor_writes(const Dataset& d, odonav::dds::Writer<msg::Odometer>* odo,
                                      odonav::dds::Writer<msg::GnssFix>* gnss,
                                      odonav::dds::Writer<msg::InsAttitude>* ins) {
  std::vector<TimedWrite> w;
  if (odo)
    for (const auto& s : d.odometer) w.push_back({s.t_s, 0, [odo, m = odometer_message(s)] { odo->write(m); }});
  if (gnss)
    for (const auto& s : d.gnss) w.push_back({s.t_s, 0, [gnss, m = gnss_message(s)] { gnss->write(m); }});
  if (ins)
    for (const auto& s : d.ins) w.push_back({s.t_s, 0, [ins, m = ins_message(s)] { ins->write(m); }});
  return w;
}

/// The writers of the sensor topics and of the misalignment, as the gateway and the calibration
/// node have them.
struct InputWriters {
  explicit InputWriters(odonav::dds::Participant& p)
      : odo(p, topics::kOdometer.name, topics::kOdometer.writer_profile),
        gnss(p, topics::kGnssFix.name, topics::kGnssFix.writer_profile),
        ins(p, topics::kInsAttitude.name, topics::kInsAttitude.writer_profile),
        misalignment(p, topics::kMisalignment.name, topics::kMisalignment.writer_profile) {}
  odonav::dds::Writer<msg::Odometer> odo;
  odonav::dds::Writer<msg::GnssFix> gnss;
  odonav::dds::Writer<msg::InsAttitude> ins;
  odonav::dds::Writer<msg::Misalignment> misalignment;
};

/// The misalignments as the calibration node publishes them: after the GNSS epoch of their stamp.
void add_misalignment_writes(std::vector<TimedWrite>& writes, const std::vector<calibration::MisalignmentOutput>& mis,
                             odonav::dds::Writer<msg::Misalignment>& writer) {
  for (const auto& m : mis)
    writes.push_back(
        {m.t_s, 1, [&writer, msg = calibration::misalignment_message(m, kVehicle)] { writer.write(msg); }});
}

std::vector<calibration::MisalignmentOutput> reference_calibration(const Dataset& d) {
  calibration::MisalignmentCalibrator c{calibration::MisalignmentCalibratorParams{}};
  for (const auto& g : d.gnss) c.add_gnss(g);
  for (const auto& i : d.ins) c.add_ins(i);
  return c.finish();
}

std::vector<identification::IdentificationOutput> reference_identification(
    const Dataset& d, const std::vector<calibration::MisalignmentOutput>& mis) {
  identification::IdentificationCore core{identification::IdentificationParams{}};
  for (const auto& o : d.odometer) core.add_odometer(o);
  for (const auto& g : d.gnss) core.add_gnss(g);
  for (const auto& i : d.ins) core.add_ins(i);
  for (const auto& m : mis)
    if (misalignment_applicable(m.converged, m.samples_used, m.misalignment.heading_rad, m.misalignment.pitch_rad,
                                m.sigma_heading_rad, m.sigma_pitch_rad))
      core.add_misalignment(estimate_applies_from_s(m.t_s, kDefaultEstimateHoldOff_s), m.misalignment);
  return core.finish();
}

std::vector<dead_reckoning::DeadReckoningOutput> reference_dead_reckoning(
    const Dataset& d, const std::vector<calibration::MisalignmentOutput>& mis, const std::vector<msg::ScaleFactor>* k) {
  dead_reckoning::DeadReckoner dr{dead_reckoning::DeadReckonerParams{}};
  for (const auto& o : d.odometer) dr.add_odometer(o);
  for (const auto& i : d.ins) dr.add_ins(i);
  for (const auto& g : d.gnss) dr.add_gnss(g);
  for (const auto& m : mis)
    if (misalignment_applicable(m.converged, m.samples_used, m.misalignment.heading_rad, m.misalignment.pitch_rad,
                                m.sigma_heading_rad, m.sigma_pitch_rad))
      dr.add_misalignment(estimate_applies_from_s(m.t_s, kDefaultEstimateHoldOff_s), m.misalignment);
  if (k)
    for (const auto& s : *k)
      dr.add_gnss_latency(
          estimate_applies_from_s(odonav::dds::to_seconds(s.header().stamp()), kDefaultEstimateHoldOff_s),
          s.gnss_latency_s());
  dead_reckoning::ScaleFactorSelection selection(dead_reckoning::DeadReckonerParams{}.nominal_k_m_per_pulse);
  if (k)
    for (const auto& s : *k) {
      const dead_reckoning::IdentifiedScaleFactor in{
          estimate_applies_from_s(odonav::dds::to_seconds(s.header().stamp()), kDefaultEstimateHoldOff_s),
          s.k_m_per_pulse(),
          s.converged(),
          s.source(),
          s.sigma_m_per_pulse(),
          s.samples_accepted()};
      if (const auto update = selection.on_identified(in, 0.0))
        dr.add_scale_factor(update->t_s, update->k_m_per_pulse, update->source);
    }
  return dr.finish();
}

void expect_same_dead_reckoning(const std::vector<msg::DeadReckoning>& got,
                                const std::vector<dead_reckoning::DeadReckoningOutput>& want) {
  ASSERT_EQ(got.size(), want.size());
  for (std::size_t i = 0; i < got.size(); ++i) {
    const auto& g = got[i];
    const auto& w = want[i];
    ASSERT_EQ(odonav::dds::to_seconds(g.header().stamp()), w.t_s) << i;
    EXPECT_EQ(g.latitude_deg(), rad_to_deg(w.position.lat_rad)) << i;
    EXPECT_EQ(g.longitude_deg(), rad_to_deg(w.position.lon_rad)) << i;
    EXPECT_EQ(g.height_m(), w.position.height_m) << i;
    EXPECT_EQ(g.enu_east_m(), w.enu_m.x()) << i;
    EXPECT_EQ(g.enu_north_m(), w.enu_m.y()) << i;
    EXPECT_EQ(g.distance_m(), w.distance_m) << i;
    EXPECT_EQ(g.heading_rad(), w.heading_rad) << i;
    EXPECT_EQ(g.k_m_per_pulse(), w.k_m_per_pulse) << i;
    EXPECT_EQ(static_cast<int>(g.k_source()), static_cast<int>(w.k_source)) << i;
    EXPECT_EQ(g.gnss_valid(), w.gnss_reference) << i;
    if (std::isfinite(w.horizontal_error_m)) {
      EXPECT_EQ(g.horizontal_error_m(), w.horizontal_error_m) << i;
      EXPECT_EQ(g.error_t_s(), w.error_t_s) << i;
    }
    if (::testing::Test::HasFailure()) return;  // one mismatch is enough to read
  }
}

}  // namespace

TEST_F(NodeProcess, CalibrationNodePublishesWhatTheCalibratorComputesAndDrainsOnSigint) {
  const int domain = 40;
  const Dataset d = short_dataset(kDriveS);
  const auto expected = reference_calibration(d);
  ASSERT_EQ(expected.size(), d.gnss.size());

  odonav::dds::Participant p(test_participant(domain));
  odonav::dds::Writer<msg::GnssFix> gnss(p, topics::kGnssFix.name, topics::kGnssFix.writer_profile);
  odonav::dds::Writer<msg::InsAttitude> ins(p, topics::kInsAttitude.name, topics::kInsAttitude.writer_profile);
  Collector<msg::Misalignment> out(p, topics::kMisalignment);
  Collector<msg::Health> health(p, topics::kHealth);

  ChildProcess node(binary("odonav-calibration"), node_args(domain, 10.0));
  ASSERT_TRUE(node.started());
  ASSERT_NO_FATAL_FAILURE(wait_matched({&gnss, &ins}, out.reader()));
  replay(sensor_writes(d, nullptr, &gnss, &ins), {&gnss, &ins}, [&out] { return out.latest_t_s(); });
  wait_quiet(out, expected.size());
  const std::size_t before_stop = without_repeats(out.samples()).size();

  ASSERT_NO_FATAL_FAILURE(stop_node(node));
  const auto got = without_repeats(out.samples());
  // The yaw-rate window looks backwards: no epoch waits for INS after it, so every one was
  // published before the stop (the drain has nothing left).
  EXPECT_EQ(before_stop, expected.size());
  ASSERT_EQ(got.size(), expected.size());
  std::size_t converged = 0;
  for (std::size_t i = 0; i < got.size(); ++i) {
    const auto want = calibration::misalignment_message(expected[i], kVehicle);
    ASSERT_EQ(got[i].header().stamp(), want.header().stamp()) << i;
    EXPECT_EQ(got[i].heading_rad(), want.heading_rad()) << i;
    EXPECT_EQ(got[i].pitch_rad(), want.pitch_rad()) << i;
    EXPECT_EQ(got[i].heading_std_rad(), want.heading_std_rad()) << i;
    EXPECT_EQ(got[i].samples_used(), want.samples_used()) << i;
    EXPECT_EQ(got[i].converged(), want.converged()) << i;
    EXPECT_EQ(got[i].state(), want.state()) << i;
    converged += got[i].converged();
  }
  EXPECT_GT(converged, 0u);  // the run reaches the converged state the consumers wait for
  // Close to the simulated installation (0.8 deg, -0.5 deg): the node computes the real thing.
  EXPECT_NEAR(rad_to_deg(got.back().heading_rad()), 0.8, 0.1);
  EXPECT_NEAR(rad_to_deg(got.back().pitch_rad()), -0.5, 0.1);

  ASSERT_TRUE(
      health.wait_until([](const auto& v) { return !v.empty() && v.back().reason() == "stopped: drained"; }, 10s));
  const auto h = last_health(health, "odonav-calibration");
  ASSERT_TRUE(h.has_value());
  EXPECT_EQ(counter(*h, "gnss_in"), static_cast<double>(d.gnss.size()));
  std::string all;
  for (const auto& c : h->counters()) all += c.name() + "=" + std::to_string(c.value()) + " ";
  EXPECT_EQ(counter(*h, "ins_in"), static_cast<double>(d.ins.size())) << all;
  EXPECT_EQ(counter(*h, "outputs"), static_cast<double>(expected.size()));
  EXPECT_EQ(counter(*h, "gnss_rejected"), 0.0);
}

TEST_F(NodeProcess, IdentificationNodeEqualsTheCoreFedTheSameMisalignments) {
  const int domain = 41;
  const Dataset d = short_dataset(kDriveS);
  const auto mis = reference_calibration(d);
  const auto expected = reference_identification(d, mis);
  ASSERT_EQ(expected.size(), d.gnss.size());

  odonav::dds::Participant p(test_participant(domain));
  InputWriters writers(p);
  auto& [odo, gnss, ins, mis_writer] = writers;
  odonav::dds::Writer<msg::Command> command(p, topics::kCommand.name, topics::kCommand.writer_profile);
  Collector<msg::ScaleFactor> out(p, topics::kScaleFactor);
  Collector<msg::Health> health(p, topics::kHealth);

  ChildProcess node(binary("odonav-identification"), node_args(domain, 10.0));
  ASSERT_TRUE(node.started());
  ASSERT_NO_FATAL_FAILURE(wait_matched({&odo, &gnss, &ins, &mis_writer, &command}, out.reader()));

  auto writes = sensor_writes(d, &odo, &gnss, &ins);
  add_misalignment_writes(writes, mis, mis_writer);
  replay(writes, {&odo, &gnss, &ins, &mis_writer}, [&out] { return out.latest_t_s(); });
  wait_quiet(out);

  // A set_k far outside [0.1, 10] x the nominal K (a metre per pulse: a typo, not a K): acknowledged
  // as rejected, and nothing changes. (An accepted set_k: tests/integration/ground, ground_fleet.)
  msg::Command c;
  c.vehicle_id(kVehicle);
  c.target_component("odonav-identification");
  c.command(msg::COMMAND_SET_K);
  c.value(1.0);
  c.command_id(77);
  command.write(c);
  EXPECT_TRUE(health.wait_until(
      [](const auto& v) {
        return !v.empty() && v.back().last_command_id() == 77u &&
               v.back().last_command_result() == msg::COMMAND_RESULT_REJECTED;
      },
      5s));

  ASSERT_NO_FATAL_FAILURE(stop_node(node));
  const auto got = without_repeats(out.samples());
  ASSERT_EQ(got.size(), expected.size());
  std::size_t converged = 0;
  for (std::size_t i = 0; i < got.size(); ++i) {
    const auto want = identification::scale_factor_message(expected[i], "vff_lm_rls", kVehicle);
    ASSERT_EQ(got[i].header().stamp(), want.header().stamp()) << i;
    EXPECT_EQ(got[i].k_m_per_pulse(), want.k_m_per_pulse()) << i;
    EXPECT_EQ(got[i].sigma_m_per_pulse(), want.sigma_m_per_pulse()) << i;
    EXPECT_EQ(got[i].forgetting_factor(), want.forgetting_factor()) << i;
    EXPECT_EQ(got[i].converged(), want.converged()) << i;
    EXPECT_EQ(got[i].samples_accepted(), want.samples_accepted()) << i;
    EXPECT_EQ(got[i].samples_rejected(), want.samples_rejected()) << i;
    EXPECT_EQ(got[i].estimator(), "vff_lm_rls") << i;
    if (HasFailure()) break;
    converged += got[i].converged();
  }
  EXPECT_GT(converged, 0u);
  // The simulated K is 0.0125 * 1.015: the node identifies the real thing.
  EXPECT_NEAR(got.back().k_m_per_pulse(), 0.0125 * 1.015, 0.0125 * 0.003);
  const auto h = last_health(health, "odonav-identification");
  ASSERT_TRUE(h.has_value());
  EXPECT_EQ(counter(*h, "odometer_in"), static_cast<double>(d.odometer.size()));
  EXPECT_EQ(counter(*h, "misalignment_in"), static_cast<double>(mis.size()));
  EXPECT_GT(counter(*h, "misalignments_applied"), 0.0);
}

TEST_F(NodeProcess, DeadReckoningNodeEqualsTheDeadReckonerFedTheSameEstimates) {
  const int domain = 42;
  const Dataset d = short_dataset(kDriveS);
  const auto mis = reference_calibration(d);
  const auto ident = reference_identification(d, mis);
  std::vector<msg::ScaleFactor> k_messages;
  for (const auto& o : ident) k_messages.push_back(identification::scale_factor_message(o, "vff_lm_rls", kVehicle));
  const auto expected = reference_dead_reckoning(d, mis, &k_messages);

  odonav::dds::Participant p(test_participant(domain));
  InputWriters writers(p);
  auto& [odo, gnss, ins, mis_writer] = writers;
  odonav::dds::Writer<msg::ScaleFactor> k_writer(p, topics::kScaleFactor.name, topics::kScaleFactor.writer_profile);
  Collector<msg::DeadReckoning> out(p, topics::kDeadReckoning);
  Collector<msg::Health> health(p, topics::kHealth);

  ChildProcess node(binary("odonav-dead-reckoning"), node_args(domain, 10.0));
  ASSERT_TRUE(node.started());
  ASSERT_NO_FATAL_FAILURE(wait_matched({&odo, &gnss, &ins, &mis_writer, &k_writer}, out.reader()));

  auto writes = sensor_writes(d, &odo, &gnss, &ins);
  add_misalignment_writes(writes, mis, mis_writer);
  for (const auto& k : k_messages)
    writes.push_back({odonav::dds::to_seconds(k.header().stamp()), 2, [&k_writer, k] { k_writer.write(k); }});
  replay(writes, {&odo, &gnss, &ins, &mis_writer, &k_writer}, [&out] { return out.latest_t_s(); });
  wait_quiet(out, expected.size());

  ASSERT_NO_FATAL_FAILURE(stop_node(node));
  // Every input reached the node (a sample dropped on the way would show as a missing or different row).
  ASSERT_TRUE(
      health.wait_until([](const auto& v) { return !v.empty() && v.back().reason() == "stopped: drained"; }, 10s));
  const auto h = last_health(health, "odonav-dead-reckoning");
  ASSERT_TRUE(h.has_value());
  EXPECT_EQ(counter(*h, "odometer_in"), static_cast<double>(d.odometer.size()));
  EXPECT_EQ(counter(*h, "ins_in"), static_cast<double>(d.ins.size()));
  EXPECT_EQ(counter(*h, "misalignment_in"), static_cast<double>(mis.size()));
  const auto got = out.samples();
  expect_same_dead_reckoning(got, expected);
  std::size_t identified = 0;
  for (const auto& g : got) identified += g.k_source() == msg::K_SOURCE_IDENTIFIED;
  EXPECT_GT(identified, 0u);  // the run switches from the nominal to the identified K
}

TEST_F(NodeProcess, DeadReckoningWithoutIdentificationUsesTheNominalKAndSaysSo) {
  const int domain = 43;
  const Dataset d = short_dataset(20.0);
  const auto mis = reference_calibration(d);
  const auto expected = reference_dead_reckoning(d, mis, nullptr);

  odonav::dds::Participant p(test_participant(domain));
  InputWriters writers(p);
  auto& [odo, gnss, ins, mis_writer] = writers;
  Collector<msg::DeadReckoning> out(p, topics::kDeadReckoning);
  Collector<msg::Health> health(p, topics::kHealth);

  ChildProcess node(binary("odonav-dead-reckoning"), node_args(domain, 0.5));
  ASSERT_TRUE(node.started());
  ASSERT_NO_FATAL_FAILURE(wait_matched({&odo, &gnss, &ins, &mis_writer}, out.reader()));
  auto writes = sensor_writes(d, &odo, &gnss, &ins);
  add_misalignment_writes(writes, mis, mis_writer);
  replay(writes, {&odo, &gnss, &ins, &mis_writer}, [&out] { return out.latest_t_s(); });

  // No identification: after the maximum wait the scale-factor input is absent, counted and told.
  EXPECT_TRUE(health.wait_until(
      [](const auto& v) {
        return !v.empty() && v.back().reason().find("using nominal K: no identification") != std::string::npos &&
               v.back().level() == msg::HEALTH_LEVEL_WARN && counter(v.back(), "scale_factor_absent_events") >= 1.0;
      },
      10s));
  wait_quiet(out, expected.size());
  ASSERT_NO_FATAL_FAILURE(stop_node(node));
  const auto got = out.samples();
  expect_same_dead_reckoning(got, expected);
  ASSERT_FALSE(got.empty());
  for (const auto& g : got) {
    ASSERT_EQ(g.k_source(), msg::K_SOURCE_NOMINAL);
    ASSERT_EQ(g.k_m_per_pulse(), 0.0125);
  }
}

TEST_F(NodeProcess, LateJoiningDeadReckoningGetsTheLastPublishedK) {
  const int domain = 44;
  const Dataset d = short_dataset(15.0);
  ASSERT_GE(d.gnss.size(), 3u);
  const double g0 = d.gnss[0].t_s, g1 = d.gnss[1].t_s;
  auto k_message = [](double t_s, double k) {
    msg::ScaleFactor m;
    m.header(odonav::dds::make_header(t_s, "odometer"));
    m.vehicle_id(kVehicle);
    m.k_m_per_pulse(k);
    m.sigma_m_per_pulse(1e-6);
    m.forgetting_factor(1.0);
    m.window_fill(1.0);
    m.estimator("vff_lm_rls");
    m.converged(true);
    return m;
  };

  odonav::dds::Participant p(test_participant(domain));
  odonav::dds::Writer<msg::Odometer> odo(p, topics::kOdometer.name, topics::kOdometer.writer_profile);
  odonav::dds::Writer<msg::GnssFix> gnss(p, topics::kGnssFix.name, topics::kGnssFix.writer_profile);
  odonav::dds::Writer<msg::InsAttitude> ins(p, topics::kInsAttitude.name, topics::kInsAttitude.writer_profile);
  odonav::dds::Writer<msg::ScaleFactor> k_writer(p, topics::kScaleFactor.name, topics::kScaleFactor.writer_profile);
  Collector<msg::DeadReckoning> out(p, topics::kDeadReckoning);
  Collector<msg::Health> health(p, topics::kHealth);
  // "Identification" published K for the first epoch before dead reckoning existed.
  ASSERT_TRUE(k_writer.write(k_message(g0, 0.0131)));

  // --max-wait-s 10: the sensor streams start only after discovery has settled (a few seconds after
  // the node), and with a short wait the node would declare them absent behind the K published at
  // g0 and drop their first samples as late (seen once in CI with 1 s). The late-joiner delivery is
  // still what is tested: without it the K stream's first sample would be g1's, and the interval
  // g0..g1 would be dead-reckoned with the nominal K (k_source NOMINAL), which the checks below refuse.
  ChildProcess node(binary("odonav-dead-reckoning"), node_args(domain, 10.0));
  ASSERT_TRUE(node.started());
  ASSERT_NO_FATAL_FAILURE(wait_matched({&odo, &gnss, &ins, &k_writer}, out.reader()));
  // The node tells in its Health (1 Hz) that it received the K published before it existed.
  ASSERT_TRUE(
      health.wait_until([](const auto& v) { return !v.empty() && counter(v.back(), "scale_factor_in") >= 1.0; }, 5s));
  auto writes = sensor_writes(d, &odo, &gnss, &ins);
  for (std::size_t i = 1; i < d.gnss.size(); ++i)  // later epochs: a different K
    writes.push_back({d.gnss[i].t_s, 2, [&k_writer, m = k_message(d.gnss[i].t_s, 0.0132)] { k_writer.write(m); }});
  replay(writes, {&odo, &gnss, &ins, &k_writer}, [&out] { return out.latest_t_s(); });
  wait_quiet(out, d.odometer.size() - 1);
  ASSERT_NO_FATAL_FAILURE(stop_node(node));

  const auto got = out.samples();
  std::size_t first_interval = 0;
  // The hold-off rule (consumer_rules.hpp): the K of epoch g applies from g + 0.2 s.
  const double from0 = estimate_applies_from_s(g0, kDefaultEstimateHoldOff_s);
  const double from1 = estimate_applies_from_s(g1, kDefaultEstimateHoldOff_s);
  for (const auto& g : got) {
    const double t = odonav::dds::to_seconds(g.header().stamp());
    ASSERT_GT(t, g0);
    if (t < from0) {
      ASSERT_EQ(g.k_source(), msg::K_SOURCE_NOMINAL) << t;
      continue;
    }
    ASSERT_EQ(g.k_source(), msg::K_SOURCE_IDENTIFIED) << t;
    if (t < from1) {
      ++first_interval;
      EXPECT_EQ(g.k_m_per_pulse(), 0.0131) << t;  // only the late-joiner delivery carries it
    } else {
      EXPECT_EQ(g.k_m_per_pulse(), 0.0132) << t;
    }
  }
  EXPECT_GT(first_interval, 0u);
  EXPECT_EQ(got.size() + 1, d.odometer.size());  // every odometer sample after the start fix at g0
}

// The dead-reckoning node's commands as an operator sends them: set-k latches K (range from
// consumer_rules.hpp, the DR's nominal K 0.0125 m/pulse), reset is refused naming release-k (wire value
// 0 used to mean "release" here), release-k releases. Each is acknowledged in Health at once.
TEST_F(NodeProcess, DeadReckoningCommandsSetKReleaseKAndRefuseReset) {
  const int domain = 45;
  odonav::dds::Participant p(test_participant(domain));
  odonav::dds::Writer<msg::Command> command(p, topics::kCommand.name, topics::kCommand.writer_profile);
  Collector<msg::Health> health(p, topics::kHealth);

  ChildProcess node(binary("odonav-dead-reckoning"), node_args(domain, 10.0));
  ASSERT_TRUE(node.started());
  ASSERT_NO_FATAL_FAILURE(wait_matched({&command}, health.reader()));
  ASSERT_TRUE(health.wait_until([](const auto& v) { return !v.empty(); }, 10s));

  // Sends one command and returns the Health that acknowledges it.
  auto send = [&](msg::CommandKind kind, double value, uint32_t id) -> std::optional<msg::Health> {
    msg::Command c;
    c.vehicle_id(kVehicle);
    c.target_component("odonav-dead-reckoning");
    c.command(kind);
    c.value(value);
    c.command_id(id);
    EXPECT_TRUE(command.write(c));
    if (!health.wait_until([id](const auto& v) { return !v.empty() && v.back().last_command_id() == id; }, 10s))
      return std::nullopt;
    return health.samples().back();
  };

  auto set = send(msg::COMMAND_SET_K, 0.0127, 101);
  ASSERT_TRUE(set);
  EXPECT_EQ(set->last_command_result(), msg::COMMAND_RESULT_ACCEPTED);
  EXPECT_EQ(set->last_command_detail(), "K = 0.0127 m/pulse commanded (identified K ignored until release_k)");

  // 1 m/pulse was inside dead reckoning's former (0, 10]: a unit slip, now refused as identification does.
  auto too_big = send(msg::COMMAND_SET_K, 1.0, 102);
  ASSERT_TRUE(too_big);
  EXPECT_EQ(too_big->last_command_result(), msg::COMMAND_RESULT_REJECTED);
  EXPECT_EQ(too_big->last_command_detail(), "set_k: K = 1 m/pulse is outside [0.1, 10] x nominal K (0.0125 m/pulse)");

  auto reset = send(msg::COMMAND_RESET_ESTIMATION, 0.0, 103);
  ASSERT_TRUE(reset);
  EXPECT_EQ(reset->last_command_result(), msg::COMMAND_RESULT_REJECTED);
  EXPECT_NE(reset->last_command_detail().find("release-k (COMMAND_RELEASE_K)"), std::string::npos)
      << reset->last_command_detail();

  auto release = send(msg::COMMAND_RELEASE_K, 0.0, 104);
  ASSERT_TRUE(release);
  EXPECT_EQ(release->last_command_result(), msg::COMMAND_RESULT_ACCEPTED);
  EXPECT_EQ(release->last_command_detail(), "following the identified K again (from its next estimate)");

  ASSERT_NO_FATAL_FAILURE(stop_node(node));
}
