// The checkpoint state of the dead reckoning's cores (DeadReckoner, AnchoredPositionFilter):
// save_state() / restore_state(), every double exact (checkpoint_value_list).
#include <cmath>
#include <string>
#include <vector>

#include "odonav/checkpoint_file.hpp"
#include "odonav/dead_reckoning/anchored_position.hpp"
#include "odonav/dead_reckoning/dead_reckoner.hpp"
#include "odonav/stream_state_text.hpp"

namespace odonav {

namespace {
constexpr const char* kStateMagic = "odonav-dead-reckoner-state";
constexpr int kStateVersion = 2;

using Values = std::vector<double>;

Values optional_values(const std::optional<double>& v) { return optional_state_values(v); }
std::optional<double> optional_of(const Values& v) { return v.empty() ? std::nullopt : std::optional<double>(v[0]); }
constexpr std::size_t kGnssValues = kGnssStateValues;
void append(Values& out, std::initializer_list<double> v) { out.insert(out.end(), v.begin(), v.end()); }

// Anchor fix: t, fix ENU (3), DR ENU (3), distance, sigma.
constexpr std::size_t kFixValues = 9;
void append_fix(Values& out, const AnchorFix& f) {
  append(out, {f.t_s, f.fix_enu_m.x(), f.fix_enu_m.y(), f.fix_enu_m.z(), f.dr_enu_m.x(), f.dr_enu_m.y(), f.dr_enu_m.z(),
               f.dr_distance_m, f.sigma_m});
}
AnchorFix fix_of(const double* v) {
  return AnchorFix{v[0], Eigen::Vector3d(v[1], v[2], v[3]), Eigen::Vector3d(v[4], v[5], v[6]), v[7], v[8]};
}
ScaleFactorSource source_of(double v) {
  if (v == 0.0) return ScaleFactorSource::kNominal;
  if (v == 1.0) return ScaleFactorSource::kIdentified;
  if (v == 2.0) return ScaleFactorSource::kCommanded;
  throw CheckpointError("a K source is not 0, 1 or 2");
}
double finite_or_throw(double v, const char* what) {
  if (!std::isfinite(v)) throw CheckpointError(std::string("field '") + what + "' is not finite");
  return v;
}
}  // namespace

std::string DeadReckoner::save_state() const {
  std::string s = std::string(kStateMagic) + " " + std::to_string(kStateVersion) + "\n";
  auto line = [&](const char* key, const Values& v) { s += checkpoint_value_list(key, v); };

  s += odometer_buffer_state_lines(odometer_.state());
  line("odometer_pending_t_s", Values(pending_odometer_t_s_.begin(), pending_odometer_t_s_.end()));
  s += attitude_buffer_state_lines(attitude_.state());
  s += gnss_samples_state_line("gnss", gnss_);
  Values v;
  line("gnss_gap_s", Values(gnss_gap_s_.begin(), gnss_gap_s_.end()));
  line("gnss_intervals_s", Values(gnss_intervals_s_.begin(), gnss_intervals_s_.end()));
  line("gnss_last_gap_s", {last_gnss_gap_s_});
  line("gnss_last_t_s", optional_values(last_gnss_t_s_));
  v.clear();
  for (const auto& [g, gap] : error_epochs_) {
    append_gnss_state_values(v, g);
    v.push_back(gap);
  }
  line("error_epochs", v);
  v.clear();
  for (const Past& p : past_)
    append(v, {p.t_s, p.enu_m.x(), p.enu_m.y(), p.enu_m.z(), p.distance_m, p.lever_arm_enu_m ? 1.0 : 0.0,
               p.lever_arm_enu_m ? p.lever_arm_enu_m->x() : 0.0, p.lever_arm_enu_m ? p.lever_arm_enu_m->y() : 0.0,
               p.lever_arm_enu_m ? p.lever_arm_enu_m->z() : 0.0});
  line("past_outputs", v);
  v.clear();
  if (last_error_)
    append(v, {last_error_->epoch_s, last_error_->applies_s, last_error_->horizontal_error_m,
               last_error_->error_percent_distance, last_error_->carry_s});
  line("last_error", v);
  line("start_t_s", optional_values(start_t_s_));

  const auto k = k_history_.state();
  v.clear();
  for (const auto& [t, e] : k.entries) append(v, {t, e.k_m_per_pulse, static_cast<double>(static_cast<int>(e.source))});
  line("k_history", v);
  line("k_history_last_t_s", optional_values(k.last_t_s));
  s += misalignment_history_state_lines("misalignment_history", misalignment_.state());
  const auto l = gnss_latency_.state();
  v.clear();
  for (const auto& [t, e] : l.entries) append(v, {t, e});
  line("gnss_latency_history", v);
  line("gnss_latency_history_last_t_s", optional_values(l.last_t_s));
  v.clear();
  if (last_gnss_latency_) append(v, {last_gnss_latency_->first, last_gnss_latency_->second});
  line("gnss_latency_last", v);
  const auto ts = turn_slip_.state();
  v.clear();
  for (const auto& [t, e] : ts.entries) append(v, {t, e.g_s_per_rad, e.threshold_radps});
  line("turn_slip_history", v);
  line("turn_slip_history_last_t_s", optional_values(ts.last_t_s));
  v.clear();
  if (last_turn_slip_)
    append(v, {last_turn_slip_->first, last_turn_slip_->second.g_s_per_rad, last_turn_slip_->second.threshold_radps});
  line("turn_slip_last", v);
  line("watermark_s", {watermark_s_});

  v.clear();
  if (frame_) append(v, {frame_->origin().lat_rad, frame_->origin().lon_rad, frame_->origin().height_m});
  line("origin", v);
  line("position", {position_.lat_rad, position_.lon_rad, position_.height_m});
  line("integration", {last_t_s_, last_count_, distance_m_, static_cast<double>(held_direction_)});
  line("held_heading_rad", optional_values(held_heading_rad_));
  v.clear();
  if (last_attitude_) append(v, {last_attitude_->heading_rad, last_attitude_->pitch_rad, last_attitude_->roll_rad});
  line("last_attitude", v);
  v.clear();
  if (start_fix_) append_fix(v, *start_fix_);
  line("start_fix", v);
  const DeadReckonerCounters& c = counters_;
  s += "counters";
  for (uint64_t x :
       {c.odometer_samples, c.outputs, c.before_start, c.unknown_direction, c.reversing, c.heading_held,
        c.distance_lost, c.pulse_jumps_rejected, c.pulse_rebases, c.anchor_fixes, c.anchor_fixes_no_attitude,
        c.gnss_latency_stale, c.outputs_on_held_k, c.outputs_on_held_misalignment, c.turn_slip_stale})
    s += " " + std::to_string(x);
  s += "\n";
  line("epochs_to_apply_s", Values(epochs_to_apply_s_.begin(), epochs_to_apply_s_.end()));
  line("latest_applicable_epoch_s", optional_values(latest_applicable_epoch_s_));
  for (int i = 0; i < 2; ++i) {
    const HeldTracker& h = held_[i];
    const std::string name = i == 0 ? "held_k" : "held_misalignment";
    line((name + "_received_s").c_str(), Values(h.received_s.begin(), h.received_s.end()));
    line((name + "_last_applicable_s").c_str(), optional_values(h.last_applicable_s));
    v.clear();
    if (h.span)
      append(v, {h.span->first_t_s, h.span->last_t_s, static_cast<double>(h.span->outputs), h.span->estimate_epoch_s,
                 h.span->open ? 1.0 : 0.0});
    line((name + "_span").c_str(), v);
  }
  v.clear();
  if (heading_position_offset_enu_m_)
    append(v, {heading_position_offset_enu_m_->x(), heading_position_offset_enu_m_->y(),
               heading_position_offset_enu_m_->z()});
  line("heading_position_offset_enu_m", v);
  return s;
}

void DeadReckoner::restore_state(const std::string& text) {
  CheckpointReader r(text);
  check_checkpoint_version(r, kStateMagic, kStateVersion);
  DeadReckoner d(params_);  // parsed into a copy: this one changes only when everything was read
  auto opt = [&](const char* key) {
    const Values v = r.value_list(key);
    if (v.size() > 1) throw CheckpointError(std::string("field '") + key + "' holds more than one value");
    return optional_of(v);
  };
  auto records = [&](const char* key, std::size_t stride, std::size_t max_records) {
    const Values v = r.value_list(key, stride, stride * max_records);
    return v;
  };
  constexpr std::size_t kMany = 10000000;

  d.odometer_.restore_state(read_odometer_buffer_state(r));
  Values v = r.value_list("odometer_pending_t_s");
  d.pending_odometer_t_s_.assign(v.begin(), v.end());
  d.attitude_.restore_state(read_attitude_buffer_state(r));
  d.gnss_ = read_gnss_samples_state(r, "gnss");
  v = r.value_list("gnss_gap_s");
  d.gnss_gap_s_.assign(v.begin(), v.end());
  if (d.gnss_gap_s_.size() != d.gnss_.size()) throw CheckpointError("field 'gnss_gap_s' does not match 'gnss'");
  v = r.value_list("gnss_intervals_s");
  if (v.size() > static_cast<std::size_t>(params_.gnss_period_window))
    throw CheckpointError("field 'gnss_intervals_s' is longer than the GNSS period window");
  d.gnss_intervals_s_.assign(v.begin(), v.end());
  v = r.value_list("gnss_last_gap_s", 1, 1);
  if (v.size() != 1) throw CheckpointError("field 'gnss_last_gap_s' does not hold 1 value");
  d.last_gnss_gap_s_ = finite_or_throw(v[0], "gnss_last_gap_s");
  d.last_gnss_t_s_ = opt("gnss_last_t_s");
  v = records("error_epochs", kGnssValues + 1, kMany);
  for (std::size_t i = 0; i < v.size(); i += kGnssValues + 1)
    d.error_epochs_.emplace_back(gnss_from_state_values(&v[i]), v[i + kGnssValues]);
  v = records("past_outputs", 9, kMany);
  for (std::size_t i = 0; i < v.size(); i += 9)
    d.past_.push_back(Past{v[i], Eigen::Vector3d(v[i + 1], v[i + 2], v[i + 3]), v[i + 4],
                           v[i + 5] != 0.0
                               ? std::optional<Eigen::Vector3d>(Eigen::Vector3d(v[i + 6], v[i + 7], v[i + 8]))
                               : std::nullopt});
  v = records("last_error", 5, 1);
  if (!v.empty()) d.last_error_ = EpochError{v[0], v[1], v[2], v[3], v[4]};
  d.start_t_s_ = opt("start_t_s");

  decltype(k_history_)::State k;
  v = records("k_history", 3, kMany);
  for (std::size_t i = 0; i < v.size(); i += 3)
    k.entries.emplace_back(v[i], KInForce{finite_or_throw(v[i + 1], "k_history"), source_of(v[i + 2])});
  k.last_t_s = opt("k_history_last_t_s");
  d.k_history_.restore_state(std::move(k));
  d.misalignment_.restore_state(read_misalignment_history_state(r, "misalignment_history"));
  decltype(gnss_latency_)::State l;
  v = records("gnss_latency_history", 2, kMany);
  for (std::size_t i = 0; i < v.size(); i += 2) l.entries.emplace_back(v[i], v[i + 1]);
  l.last_t_s = opt("gnss_latency_history_last_t_s");
  d.gnss_latency_.restore_state(std::move(l));
  v = records("gnss_latency_last", 2, 1);
  if (!v.empty()) d.last_gnss_latency_ = std::make_pair(v[0], v[1]);
  decltype(turn_slip_)::State ts;
  v = records("turn_slip_history", 3, kMany);
  for (std::size_t i = 0; i < v.size(); i += 3)
    ts.entries.emplace_back(v[i], TurnSlipInForce{finite_or_throw(v[i + 1], "turn_slip_history"),
                                                  finite_or_throw(v[i + 2], "turn_slip_history")});
  ts.last_t_s = opt("turn_slip_history_last_t_s");
  d.turn_slip_.restore_state(std::move(ts));
  v = records("turn_slip_last", 3, 1);
  if (!v.empty()) d.last_turn_slip_ = std::make_pair(v[0], TurnSlipInForce{v[1], v[2]});
  v = r.value_list("watermark_s", 1, 1);
  if (v.size() != 1 || std::isnan(v[0])) throw CheckpointError("field 'watermark_s' does not hold 1 number");
  d.watermark_s_ = v[0];

  v = records("origin", 3, 1);
  if (!v.empty()) d.frame_.emplace(Geodetic{v[0], v[1], v[2]});
  v = r.value_list("position", 3, 3);
  if (v.size() != 3) throw CheckpointError("field 'position' does not hold 3 values");
  d.position_ = Geodetic{v[0], v[1], v[2]};
  v = r.value_list("integration", 4, 4);
  if (v.size() != 4) throw CheckpointError("field 'integration' does not hold 4 values");
  d.last_t_s_ = v[0];
  d.last_count_ = v[1];
  d.distance_m_ = v[2];
  d.held_direction_ = static_cast<int>(v[3]);
  if (d.held_direction_ < -1 || d.held_direction_ > 1) throw CheckpointError("field 'integration' has a bad direction");
  d.held_heading_rad_ = opt("held_heading_rad");
  v = records("last_attitude", 3, 1);
  if (!v.empty()) d.last_attitude_ = Attitude{v[0], v[1], v[2]};
  v = records("start_fix", kFixValues, 1);
  if (!v.empty()) d.start_fix_ = fix_of(v.data());
  const std::vector<uint64_t> c = r.unsigned_list("counters", 15);
  d.counters_ = DeadReckonerCounters{c[0], c[1], c[2],  c[3],  c[4],  c[5],  c[6], c[7],
                                     c[8], c[9], c[10], c[11], c[12], c[13], c[14]};
  v = r.value_list("epochs_to_apply_s");
  d.epochs_to_apply_s_.assign(v.begin(), v.end());
  d.latest_applicable_epoch_s_ = opt("latest_applicable_epoch_s");
  for (int i = 0; i < 2; ++i) {
    HeldTracker& h = d.held_[i];
    const std::string name = i == 0 ? "held_k" : "held_misalignment";
    v = r.value_list(name + "_received_s");
    h.received_s.assign(v.begin(), v.end());
    h.last_applicable_s = opt((name + "_last_applicable_s").c_str());
    v = records((name + "_span").c_str(), 5, 1);
    if (!v.empty()) h.span = HeldSpan{v[0], v[1], static_cast<uint64_t>(v[2]), v[3], v[4] != 0.0};
  }
  // Absent from checkpoints written before it existed (it only matters in the polar cap).
  if (!r.at_end()) {
    v = records("heading_position_offset_enu_m", 3, 1);
    if (!v.empty()) d.heading_position_offset_enu_m_ = Eigen::Vector3d(v[0], v[1], v[2]);
  }
  if (!r.at_end()) throw CheckpointError("unexpected text after the dead reckoner state");
  if (d.frame_.has_value() != d.start_t_s_.has_value())
    throw CheckpointError("fields 'origin' and 'start_t_s' disagree on whether the dead reckoning started");
  *this = std::move(d);
}

namespace {
constexpr const char* kAnchorMagic = "odonav-anchored-position-state";
constexpr int kAnchorStateVersion = 1;
}  // namespace

std::string AnchoredPositionFilter::save_state() const {
  std::string s = std::string(kAnchorMagic) + " " + std::to_string(kAnchorStateVersion) + "\n";
  Values v;
  for (const AnchorFix& f : queued_) append_fix(v, f);
  s += checkpoint_value_list("queued_fixes", v);
  s += checkpoint_value_list("last_added_t_s", optional_values(last_added_t_s_));
  s += checkpoint_value_list("last_step_t_s", optional_values(last_step_t_s_));
  s += checkpoint_value_list("last_enu_m", {last_enu_m_.x(), last_enu_m_.y(), last_enu_m_.z()});
  s += checkpoint_value_list("x", Values(x_.data(), x_.data() + kN));
  s += checkpoint_value_list("p", Values(p_.data(), p_.data() + kN * kN));
  s += checkpoint_value_list("scalars", {initialised_ ? 1.0 : 0.0, correlated_sigma_h_m_, last_distance_m_,
                                         last_fix_t_s_, last_fix_distance_m_, static_cast<double>(consecutive_gated_),
                                         counters_.last_rejected_innovation_m, counters_.last_rejected_gate_m});
  s += "counters " + std::to_string(counters_.steps) + " " + std::to_string(counters_.fixes_added) + " " +
       std::to_string(counters_.fixes_applied) + " " + std::to_string(counters_.fixes_rejected_gate) + " " +
       std::to_string(counters_.gate_restarts) + "\n";
  return s;
}

void AnchoredPositionFilter::restore_state(const std::string& text) {
  CheckpointReader r(text);
  check_checkpoint_version(r, kAnchorMagic, kAnchorStateVersion);
  AnchoredPositionFilter a(params_);  // parsed into a copy: this one changes only when everything was read
  auto exactly = [&](const char* key, std::size_t n) { return r.exact_values(key, n); };
  auto opt = [&](const char* key) {
    const Values v = r.value_list(key, 1, 1);
    return optional_of(v);
  };
  Values v = r.value_list("queued_fixes", kFixValues);
  for (std::size_t i = 0; i < v.size(); i += kFixValues) a.queued_.push_back(fix_of(&v[i]));
  a.last_added_t_s_ = opt("last_added_t_s");
  a.last_step_t_s_ = opt("last_step_t_s");
  v = exactly("last_enu_m", 3);
  a.last_enu_m_ = Eigen::Vector3d(v[0], v[1], v[2]);
  v = exactly("x", kN);
  a.x_ = Eigen::Map<const Vector>(v.data());
  v = exactly("p", kN * kN);
  a.p_ = Eigen::Map<const Matrix>(v.data());
  v = exactly("scalars", 8);
  if (v[0] != 0.0 && v[0] != 1.0) throw CheckpointError("field 'scalars' has a bad initialised flag");
  a.initialised_ = v[0] == 1.0;
  a.correlated_sigma_h_m_ = v[1];
  a.last_distance_m_ = v[2];
  a.last_fix_t_s_ = v[3];
  a.last_fix_distance_m_ = v[4];
  a.consecutive_gated_ = static_cast<int>(v[5]);
  a.counters_.last_rejected_innovation_m = v[6];
  a.counters_.last_rejected_gate_m = v[7];
  const std::vector<uint64_t> c = r.unsigned_list("counters", 5);
  a.counters_.steps = c[0];
  a.counters_.fixes_added = c[1];
  a.counters_.fixes_applied = c[2];
  a.counters_.fixes_rejected_gate = c[3];
  a.counters_.gate_restarts = c[4];
  if (!r.at_end()) throw CheckpointError("unexpected text after the anchored position state");
  *this = std::move(a);
}

}  // namespace odonav
