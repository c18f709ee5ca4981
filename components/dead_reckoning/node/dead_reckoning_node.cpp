#include "dead_reckoning_node.hpp"

#include <cmath>
#include <limits>
#include <sstream>
#include <thread>
#include <stdexcept>

#include "odonav/lever_arm_option.hpp"
#include "odonav/consumer_rules.hpp"
#include "odonav/dds/time.hpp"
#include "odonav/dead_reckoning/dead_reckoning_options.hpp"
#include "odonav/topics.hpp"

namespace odonav::nodes {

namespace {
DeadReckoner make_core(const DeadReckonerParams& p) {
  try {
    return DeadReckoner(p);
  } catch (const std::invalid_argument& e) {
    throw ConfigError(std::string("dead-reckoning parameters: ") + e.what());
  }
}

odonav::msg::KSource to_message_source(ScaleFactorSource s) {
  switch (s) {
    case ScaleFactorSource::kNominal: return odonav::msg::K_SOURCE_NOMINAL;
    case ScaleFactorSource::kIdentified: return odonav::msg::K_SOURCE_IDENTIFIED;
    case ScaleFactorSource::kCommanded: return odonav::msg::K_SOURCE_COMMANDED;
  }
  return odonav::msg::K_SOURCE_NOMINAL;
}

double or_minus_one(double v) { return std::isfinite(v) ? v : -1.0; }

// The scale-factor topic read with the fast-failover profile (kScaleFactorReaderProfile).
topics::TopicSpec scale_factor_topic() {
  topics::TopicSpec spec = topics::kScaleFactor;
  spec.reader_profile = kScaleFactorReaderProfile;
  return spec;
}

// How long (wall time) health tells about an event (K source change, pulse jump): long enough for a monitor.
constexpr double kSourceNoteDuration_s = 30.0;
}  // namespace

void add_dead_reckoning_node_options(Options& o) {
  add_dead_reckoning_options(o);
  add_lever_arm_option(o);
  o.add_bool("use-ins", true,
             "the vehicle has an INS; false = degraded mode (GNSS course, horizontal only), as odonav-offline "
             "does for a dataset without ins.csv");
}

DeadReckonerParams dead_reckoning_node_params_from(const Options& o) {
  DeadReckonerParams p = dead_reckoning_params_from(o);
  if (p.nominal_k_m_per_pulse == 0.0) p.nominal_k_m_per_pulse = DeadReckonerParams{}.nominal_k_m_per_pulse;
  p.lever_arm_body_m = lever_arm_from(o);
  p.use_ins = o.get_bool("use-ins");
  return p;
}

odonav::msg::DeadReckoning dead_reckoning_message(const DeadReckoningOutput& o, const Geodetic& origin,
                                                  const Misalignment& mis, const std::string& vehicle_id) {
  odonav::msg::DeadReckoning m;
  m.header(dds::make_header(o.t_s, "wgs84"));
  m.vehicle_id(vehicle_id);
  m.latitude_deg(rad_to_deg(o.position.lat_rad));
  m.longitude_deg(rad_to_deg(o.position.lon_rad));
  m.height_m(o.position.height_m);
  m.enu_east_m(o.enu_m.x());
  m.enu_north_m(o.enu_m.y());
  m.enu_up_m(o.enu_m.z());
  m.origin_latitude_deg(rad_to_deg(origin.lat_rad));
  m.origin_longitude_deg(rad_to_deg(origin.lon_rad));
  m.origin_height_m(origin.height_m);
  m.heading_rad(o.heading_rad);
  m.distance_m(o.distance_m);
  m.k_m_per_pulse(o.k_m_per_pulse);
  m.k_source(to_message_source(o.k_source));
  m.misalignment_heading_rad(mis.heading_rad);
  m.misalignment_pitch_rad(mis.pitch_rad);
  m.gnss_valid(o.gnss_reference);
  m.horizontal_error_m(or_minus_one(o.horizontal_error_m));
  m.error_percent_distance(or_minus_one(o.error_percent_distance));
  return m;
}

DeadReckoningNode::DeadReckoningNode(dds::ComponentRuntime& runtime, const DeadReckonerParams& params)
    : EventTimeNode(runtime),
      params_(params),
      core_(make_core(params)),
      odometer_(add_input("odometer", true)),
      gnss_(add_input("gnss", true)),
      misalignment_(add_input("misalignment", false, &gnss_)),
      scale_factor_(add_input("scale_factor", false, &gnss_)),
      writer_(runtime.participant(), topics::kDeadReckoning.name, topics::kDeadReckoning.writer_profile) {
  if (params_.use_ins) ins_ = &add_input("ins", true);
  runtime.set_command_handler([this](const odonav::msg::Command& c) { return on_command(c); });

  odometer_reader_ = subscribe<odonav::msg::Odometer>(topics::kOdometer, odometer_, [this](const auto& m, double) {
    core_.add_odometer(dds::odometer_sample_from(m));
  });
  gnss_reader_ = subscribe<odonav::msg::GnssFix>(topics::kGnssFix, gnss_, [this](const auto& m, double) {
    core_.add_gnss(dds::gnss_sample_from(m));
  });
  if (ins_) {
    ins_reader_ = subscribe<odonav::msg::InsAttitude>(topics::kInsAttitude, *ins_, [this](const auto& m, double) {
      if (!m.valid()) {
        ++ins_->dropped_invalid;
        return;
      }
      core_.add_ins(dds::ins_sample_from(m));
    });
  }
  misalignment_reader_ = subscribe<odonav::msg::Misalignment>(
      topics::kMisalignment, misalignment_, [this](const auto& m, double t_s) { on_misalignment(m, t_s); });
  scale_factor_reader_ = subscribe<odonav::msg::ScaleFactor>(
      scale_factor_topic(), scale_factor_, [this](const auto& m, double t_s) { on_scale_factor(m, t_s); });
}

DeadReckoningNode::~DeadReckoningNode() { close_inputs(); }

void DeadReckoningNode::close_inputs() {
  odometer_reader_.reset();
  gnss_reader_.reset();
  ins_reader_.reset();
  misalignment_reader_.reset();
  scale_factor_reader_.reset();
}

void DeadReckoningNode::on_misalignment(const odonav::msg::Misalignment& m, double t_s) {
  if (!misalignment_applicable(m.converged(), m.samples_used())) return;  // consumer_rules.hpp, as odonav-offline
  const Misalignment mis{m.heading_rad(), m.pitch_rad()};
  core_.add_misalignment(t_s, mis);  // throws StreamInputError on non-finite angles: counted
  applied_misalignment_.add(t_s, mis);
  ++misalignments_applied_;
}

void DeadReckoningNode::on_scale_factor(const odonav::msg::ScaleFactor& m, double t_s) {
  // Which identification instance is followed (the DDS owner): logged, and told in health for a
  // while after a change (hot standby taking over, the primary coming back).
  if (m.source() != k_source_) {
    std::ostringstream note;
    note.precision(10);
    if (k_source_.empty()) {
      spdlog::info("following K from '{}' (t={} s)", m.source(), t_s);
    } else {
      ++k_source_changes_;
      note << "K source changed from '" << k_source_ << "' to '" << m.source() << "' at t=" << t_s << " s";
      spdlog::warn("{}", note.str());
      k_source_note_ = note.str();
      k_source_note_until_s_ = dds::steady_now_s() + kSourceNoteDuration_s;
    }
    k_source_ = m.source();
  }
  // The message has no "valid" flag: K = 0 (or not finite) means "no value yet".
  const bool valid = std::isfinite(m.k_m_per_pulse()) && m.k_m_per_pulse() > 0.0;
  if (!scale_factor_applicable(valid, m.converged())) return;  // consumer_rules.hpp, as odonav-offline
  if (commanded_k_ || (last_k_stamp_s_ && t_s <= *last_k_stamp_s_)) {
    ++k_ignored_commanded_;
    return;
  }
  core_.add_scale_factor(t_s, m.k_m_per_pulse(), ScaleFactorSource::kIdentified);
  last_k_stamp_s_ = t_s;
  ++k_applied_;
}

void DeadReckoningNode::publish(const std::vector<DeadReckoningOutput>& outputs) {
  if (outputs.empty()) return;
  const Geodetic origin = core_.origin().value_or(Geodetic{});
  for (const DeadReckoningOutput& o : outputs) {
    const Misalignment mis = applied_misalignment_.at_or_before(o.t_s).value_or(Misalignment{});
    if (!writer_.write(dead_reckoning_message(o, origin, mis, runtime_.settings().vehicle_id)))
      spdlog::warn("{}: write refused by the middleware", writer_.topic_name());
    // A burst (catching up after a wait, the drain) larger than the KEEP_LAST history would
    // overwrite samples not yet delivered: let the transport drain every 100 samples.
    if (++burst_writes_ % 100 == 0) std::this_thread::sleep_for(std::chrono::milliseconds(2));
    applied_misalignment_.drop_before(o.t_s);
  }
  last_output_ = outputs.back();
  count_outputs(outputs.size());
}

void DeadReckoningNode::process_until(double watermark_s) { publish(core_.process_until(watermark_s)); }

void DeadReckoningNode::finish() { publish(core_.finish()); }

std::vector<dds::detail::WriterBase*> DeadReckoningNode::output_writers() { return {&writer_}; }

dds::CommandAck DeadReckoningNode::on_command(const odonav::msg::Command& c) {
  using namespace odonav::msg;
  switch (c.command()) {
    case COMMAND_SET_K: {
      const double k = c.value();
      if (!std::isfinite(k) || !(k > 0.0) || k > 10.0) {
        std::ostringstream m;
        m << "set_k: K = " << k << " m/pulse is not in (0, 10]";
        return {c.command_id(), COMMAND_RESULT_REJECTED, m.str()};
      }
      // In force after everything already processed and after the last K given to the core.
      double base = std::max(aligner_.processed_s(), last_k_stamp_s_.value_or(-std::numeric_limits<double>::infinity()));
      if (!std::isfinite(base)) base = -std::numeric_limits<double>::max();
      const double t = std::nextafter(base, std::numeric_limits<double>::infinity());
      core_.add_scale_factor(t, k, ScaleFactorSource::kCommanded);
      last_k_stamp_s_ = t;
      commanded_k_ = true;
      std::ostringstream m;
      m.precision(10);
      m << "K = " << k << " m/pulse commanded (identified K ignored until reset_calibration)";
      return {c.command_id(), COMMAND_RESULT_ACCEPTED, m.str()};
    }
    case COMMAND_RESET_CALIBRATION:
      commanded_k_ = false;
      return {c.command_id(), COMMAND_RESULT_ACCEPTED, "following the identified K again (from its next estimate)"};
    case COMMAND_FREEZE_IDENTIFICATION:
    case COMMAND_UNFREEZE_IDENTIFICATION:
      return {c.command_id(), COMMAND_RESULT_REJECTED, "freeze/unfreeze is for odonav-identification"};
  }
  return {c.command_id(), COMMAND_RESULT_REJECTED, "unknown command kind"};
}

dds::EventTimeNode::Status DeadReckoningNode::node_status(double now_s) {
  using namespace odonav::msg;
  Status s{HEALTH_STATE_RUNNING, HEALTH_LEVEL_OK, ""};
  auto add = [&s](const std::string& r) { s.reason = s.reason.empty() ? r : s.reason + "; " + r; };
  if (!core_.started()) {
    s.state = HEALTH_STATE_STARTING;
    add("waiting for a valid GNSS fix to start from");
  }
  // K: the reason DR navigates with what it uses.
  if (commanded_k_) {
    add("using commanded K");
  } else if (input_absent(scale_factor_, now_s)) {
    s.state = s.state == HEALTH_STATE_STARTING ? s.state : HEALTH_STATE_DEGRADED;
    s.level = HEALTH_LEVEL_WARN;
    // Absent after being heard: the core keeps the last identified K (it is not reset).
    add(k_applied_ > 0 ? "no identification: keeping the last identified K" : "using nominal K: no identification");
  } else if (!input_heard(scale_factor_, now_s)) {
    add("waiting for identification");
  } else if (k_applied_ == 0) {
    add("K not converged yet: using nominal K");
  }
  if (!k_source_note_.empty() && now_s < k_source_note_until_s_) add(k_source_note_);
  // Odometer pulse jumps (a counter glitch): WARN for a while after the last one, with the total.
  const uint64_t jumps = core_.counters().pulse_jumps_rejected;
  if (jumps != jumps_seen_) {
    jumps_seen_ = jumps;
    jumps_note_until_s_ = now_s + kSourceNoteDuration_s;
  }
  if (jumps > 0 && now_s < jumps_note_until_s_) {
    s.level = HEALTH_LEVEL_WARN;
    add("rejected " + std::to_string(jumps) + " odometer samples: pulse jump (counter glitch)");
  }
  if (input_absent(misalignment_, now_s))
    add("using zero misalignment: no calibration");
  else if (input_heard(misalignment_, now_s) && misalignments_applied_ == 0)
    add("misalignment not converged yet: using zero");
  return s;
}

void DeadReckoningNode::append_counters(dds::HealthCounters& c) {
  const DeadReckonerCounters& k = core_.counters();
  c.emplace_back("odometer_processed", static_cast<double>(k.odometer_samples));
  c.emplace_back("before_start", static_cast<double>(k.before_start));
  c.emplace_back("heading_held", static_cast<double>(k.heading_held));
  c.emplace_back("reversing", static_cast<double>(k.reversing));
  c.emplace_back("pulse_jumps_rejected", static_cast<double>(k.pulse_jumps_rejected));
  c.emplace_back("pulse_rebases", static_cast<double>(k.pulse_rebases));
  c.emplace_back("k_applied", static_cast<double>(k_applied_));
  c.emplace_back("k_ignored", static_cast<double>(k_ignored_commanded_));
  c.emplace_back("k_source_changes", static_cast<double>(k_source_changes_));
  c.emplace_back("misalignments_applied", static_cast<double>(misalignments_applied_));
  if (last_output_) {
    c.emplace_back("distance_m", last_output_->distance_m);
    c.emplace_back("k_m_per_pulse", last_output_->k_m_per_pulse);
    if (std::isfinite(last_output_->horizontal_error_m))
      c.emplace_back("horizontal_error_m", last_output_->horizontal_error_m);
  }
}

}  // namespace odonav::nodes
