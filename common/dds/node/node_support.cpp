// Message -> sample conversion, the nodes' shared options, input bookkeeping and health reasons of
// the event-time nodes (node_support.hpp).
#include "odonav/dds/node_support.hpp"

#include "odonav/lever_arm_option.hpp"
#include "odonav/restart_policy.hpp"
#include "odonav/topics.hpp"

namespace odonav::dds {

void add_sensor_node_options(Options& o, const std::string& degraded_mode, const std::string& checkpoint_file) {
  add_lever_arm_option(o);
  o.add_bool("use-ins", true,
             "the vehicle has an INS; false = degraded mode (" + degraded_mode +
                 "), as odonav-offline does for a dataset without ins.csv");
  add_checkpoint_options(o, checkpoint_file);
}

const char* sensor_reader_profile(const std::optional<double>& restored_t_s) {
  if (!restored_t_s) return topics::kSensorReaderProfile;
  spdlog::info("sensor readers: TRANSIENT_LOCAL, processing the producers' history from t={:.3f} s on", *restored_t_s);
  return topics::kSensorReplayReaderProfile;
}

OdometerSample odometer_sample_from(const odonav::msg::Odometer& m) {
  OdometerSample s;
  s.t_s = to_seconds(m.header().stamp());
  s.pulses = m.pulses();
  s.direction = m.direction();
  return s;
}

PublishedMisalignment published_misalignment_from(const odonav::msg::Misalignment& m, double t_s) {
  PublishedMisalignment p;
  p.t_s = t_s;
  p.heading_rad = m.heading_rad();
  p.pitch_rad = m.pitch_rad();
  p.heading_std_rad = m.heading_std_rad();
  p.pitch_std_rad = m.pitch_std_rad();
  p.converged = m.converged();
  p.samples_used = m.samples_used();
  return p;
}

PublishedScaleFactor published_scale_factor_from(const odonav::msg::ScaleFactor& m, double t_s) {
  PublishedScaleFactor p;
  p.t_s = t_s;
  p.k_m_per_pulse = m.k_m_per_pulse();
  p.sigma_m_per_pulse = m.sigma_m_per_pulse();
  p.converged = m.converged();
  p.samples_accepted = m.samples_accepted();
  p.source = m.source();
  p.gnss_latency_s = m.gnss_latency_s();
  p.turn_slip_applies = m.turn_slip_applies();
  p.turn_slip_s_per_rad = m.turn_slip_s_per_rad();
  p.turn_slip_threshold_radps = m.turn_slip_threshold_radps();
  return p;
}

GnssSample gnss_sample_from(const odonav::msg::GnssFix& m) {
  GnssSample s;
  s.t_s = to_seconds(m.header().stamp());
  s.position = Geodetic{deg_to_rad(m.latitude_deg()), deg_to_rad(m.longitude_deg()), m.height_m()};
  s.vel_enu_mps = Eigen::Vector3d(m.velocity_east_mps(), m.velocity_north_mps(), m.velocity_up_mps());
  if (m.position_std_m() >= 0.0) s.pos_std_m = m.position_std_m();
  if (m.velocity_std_mps() >= 0.0) s.vel_std_mps = m.velocity_std_mps();
  s.fix = m.valid() ? static_cast<int>(m.fix_quality()) : 0;
  return s;
}

InsSample ins_sample_from(const odonav::msg::InsAttitude& m) {
  InsSample s;
  s.t_s = to_seconds(m.header().stamp());
  s.attitude = Attitude{m.heading_rad(), m.pitch_rad(), m.roll_rad()};
  if (m.velocity_valid())
    s.vel_enu_mps = Eigen::Vector3d(m.velocity_east_mps(), m.velocity_north_mps(), m.velocity_up_mps());
  return s;
}

void NodeInput::note_problem(const std::string& why, double now_s) {
  ++problems;
  last_problem = why;
  last_problem_wall_s = now_s;
  if (problems <= 10 || problems % 1000 == 0) spdlog::warn("{}: sample not used ({} so far): {}", name, problems, why);
}

void append_input_counters(HealthCounters& c, const EventTimeAligner& aligner, const NodeInput& in, double now_s) {
  const EventTimeAligner::StreamStatus st = aligner.status(in.id, now_s);
  const double rejected = static_cast<double>(st.backwards - in.republished + st.invalid + in.refused +
                                              in.dropped_invalid + (in.estimate ? 0 : st.repeated));
  c.emplace_back(in.name + "_in", static_cast<double>(st.accepted));
  c.emplace_back(in.name + "_late", static_cast<double>(st.late));
  c.emplace_back(in.name + "_rejected", rejected);
  c.emplace_back(in.name + "_absent_events", static_cast<double>(st.absent_events));
  c.emplace_back(in.name + "_silent_s", std::round(st.silent_for_s * 10.0) / 10.0);
  if (in.estimate) c.emplace_back(in.name + "_skipped_epochs", static_cast<double>(st.skipped_pacing_epochs));
  if (in.estimate) c.emplace_back(in.name + "_republished", static_cast<double>(in.republished));
  if (in.estimate || st.hold_off_s > 0.0)
    c.emplace_back(in.name + "_hold_off_waits", static_cast<double>(st.hold_off_waits));
  if (aligner.in_flight_max_wait_s() > aligner.max_wait_s())
    c.emplace_back(in.name + "_in_flight_waits", static_cast<double>(st.in_flight_waits));
}

std::optional<std::string> absent_reason(const EventTimeAligner& aligner, const std::vector<const NodeInput*>& inputs,
                                         double now_s) {
  for (const NodeInput* in : inputs) {
    const EventTimeAligner::StreamStatus st = aligner.status(in->id, now_s);
    if (st.absent) {
      std::ostringstream m;
      m << "no " << in->name << " for " << static_cast<long long>(std::floor(st.silent_for_s)) << " s";
      return m.str();
    }
  }
  return std::nullopt;
}

std::optional<std::string> waiting_reason(const EventTimeAligner& aligner, const std::vector<const NodeInput*>& inputs,
                                          double now_s) {
  for (const NodeInput* in : inputs)
    if (!aligner.status(in->id, now_s).last_t_s) return "waiting for " + in->name;
  return std::nullopt;
}

std::optional<std::string> rejection_reason(const std::vector<const NodeInput*>& inputs, double now_s,
                                            double recent_s) {
  for (const NodeInput* in : inputs) {
    if (in->last_problem_wall_s && now_s - *in->last_problem_wall_s <= recent_s) {
      std::ostringstream m;
      m << "rejected " << in->problems << " " << in->name << " samples: " << in->last_problem;
      return m.str();
    }
  }
  return std::nullopt;
}

}  // namespace odonav::dds
