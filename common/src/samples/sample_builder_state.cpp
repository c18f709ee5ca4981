// SampleBuilder::save_state() / restore_state(): the builder's complete state for a component
// checkpoint (the identification's), every double exact (checkpoint_value_list).
#include <cmath>
#include <string>
#include <vector>

#include "odonav/checkpoint_file.hpp"
#include "odonav/sample_builder.hpp"
#include "odonav/stream_state_text.hpp"

namespace odonav {

namespace {
constexpr const char* kStateMagic = "odonav-sample-builder-state";
// 2: the latency sums per block (a K per candidate); 3: the sigma of the latency in force.
constexpr int kStateVersion = 3;
constexpr std::size_t kMany = 10000000;
using Values = std::vector<double>;

void append(Values& out, std::initializer_list<double> v) { out.insert(out.end(), v.begin(), v.end()); }

std::vector<uint64_t*> counter_fields(SampleBuilderCounters& c) {
  return {&c.epochs,
          &c.accepted,
          &c.chain_starts,
          &c.invalid_fix,
          &c.low_fix_quality,
          &c.no_odometer,
          &c.no_attitude,
          &c.negative_speed,
          &c.speed_jump,
          &c.gap,
          &c.min_speed,
          &c.reversing,
          &c.yaw_rate,
          &c.no_pulses,
          &c.innovation,
          &c.cross_track,
          &c.innovation_suspended,
          &c.reversing_accepted,
          &c.odometer_jumps_rejected,
          &c.odometer_rebases};
}

// A text on one line (the latency's reason): line breaks cannot occur in it, but a state file must
// stay parseable whatever a future reason says.
std::string one_line(std::string s) {
  for (char& c : s)
    if (c == '\n' || c == '\r') c = ' ';
  return s;
}
}  // namespace

std::string SampleBuilder::save_state() const {
  std::string s = std::string(kStateMagic) + " " + std::to_string(kStateVersion) + "\n";
  auto line = [&](const char* key, const Values& v) { s += checkpoint_value_list(key, v); };
  Values v;

  s += odometer_buffer_state_lines(odometer_.state());
  s += attitude_buffer_state_lines(attitude_.state());
  s += gnss_samples_state_line("pending_gnss", pending_gnss_);
  line("last_gnss_t_s", optional_state_values(last_gnss_t_s_));
  s += misalignment_history_state_lines("misalignment_history", misalignment_.state());
  const auto k = k_estimates_.state();
  for (const auto& [t, e] : k.entries) append(v, {t, e.k_m_per_pulse, e.sigma_m_per_pulse});
  line("k_estimates", v);
  line("k_estimates_last_t_s", optional_state_values(k.last_t_s));
  line("watermark_s", {watermark_s_});
  v.clear();
  if (chain_start_)
    append(v, {chain_start_->t_s, chain_start_->vel_enu_mps.x(), chain_start_->vel_enu_mps.y(),
               chain_start_->vel_enu_mps.z(), chain_start_->attitude.heading_rad, chain_start_->attitude.pitch_rad,
               chain_start_->attitude.roll_rad, chain_start_->count_pulses});
  line("chain_start", v);
  v.clear();
  if (last_good_speed_) append(v, {last_good_speed_->first, last_good_speed_->second});
  line("last_good_speed", v);
  line("consecutive_innovation_rejections", {static_cast<double>(consecutive_innovation_rejections_)});
  v.clear();
  if (frame_) append(v, {frame_->origin().lat_rad, frame_->origin().lon_rad, frame_->origin().height_m});
  line("frame_origin", v);
  SampleBuilderCounters c = counters_;
  s += "counters";
  for (const uint64_t* x : counter_fields(c)) s += " " + std::to_string(*x);
  s += "\n";
  line("gnss_intervals_s", Values(gnss_intervals_s_.begin(), gnss_intervals_s_.end()));
  line("last_period_row_t_s", optional_state_values(last_period_row_t_s_));
  line("gnss_period_s", {gnss_period_s_});

  line("latency",
       {latency_.applied_s, latency_.estimate_s, latency_.sigma_s, static_cast<double>(latency_.samples),
        latency_.fixed ? 1.0 : 0.0, static_cast<double>(latency_.blocks_left_out), latency_.applied_sigma_s});
  s += "latency_reason " + one_line(latency_.reason) + "\n";
  line("latency_closed_chi2", latency_closed_chi2_);
  line("latency_closed", {static_cast<double>(latency_closed_blocks_), static_cast<double>(latency_closed_samples_)});
  line("latency_closed_fit_s", optional_state_values(latency_closed_fit_));
  line("latency_block", {latency_block_start_s_, static_cast<double>(latency_block_samples_), latency_block_yy_m2_});
  line("latency_block_yphi", latency_block_yphi_);
  line("latency_block_phiphi", latency_block_phiphi_);
  line("latency_sums",
       {static_cast<double>(latency_samples_), latency_sums_applied_s_, static_cast<double>(latency_restarts_)});
  v.clear();
  for (const PendingLatencySample& p : latency_pending_)
    append(v, {p.t0_s, p.t1_s, p.y_m, p.applied_s, p.needs_until_s});
  line("latency_pending", v);
  return s;
}

void SampleBuilder::restore_state(const std::string& text) {
  CheckpointReader r(text);
  check_checkpoint_version(r, kStateMagic, kStateVersion);
  SampleBuilder b(params_);  // parsed into a copy: this one changes only when everything was read
  auto exactly = [&](const char* key, std::size_t n) { return r.exact_values(key, n); };
  auto count_of = [](double x, const char* key) {
    if (!(x >= 0.0) || x != std::floor(x) || x > 1e18)
      throw CheckpointError(std::string("field '") + key + "' holds a count that is not a whole number >= 0");
    return static_cast<uint64_t>(x);
  };

  b.odometer_.restore_state(read_odometer_buffer_state(r));
  b.attitude_.restore_state(read_attitude_buffer_state(r));
  b.pending_gnss_ = read_gnss_samples_state(r, "pending_gnss");
  b.last_gnss_t_s_ = read_optional_state_value(r, "last_gnss_t_s");
  b.misalignment_.restore_state(read_misalignment_history_state(r, "misalignment_history"));
  decltype(k_estimates_)::State k;
  Values v = r.value_list("k_estimates", 3, 3 * kMany);
  for (std::size_t i = 0; i < v.size(); i += 3) k.entries.emplace_back(v[i], KEstimate{v[i + 1], v[i + 2]});
  k.last_t_s = read_optional_state_value(r, "k_estimates_last_t_s");
  b.k_estimates_.restore_state(std::move(k));
  v = exactly("watermark_s", 1);
  if (std::isnan(v[0])) throw CheckpointError("field 'watermark_s' is not a number");
  b.watermark_s_ = v[0];
  v = r.value_list("chain_start", 8, 8);
  if (!v.empty()) b.chain_start_ = GoodEpoch{v[0], Eigen::Vector3d(v[1], v[2], v[3]), Attitude{v[4], v[5], v[6]}, v[7]};
  v = r.value_list("last_good_speed", 2, 2);
  if (!v.empty()) b.last_good_speed_ = std::make_pair(v[0], v[1]);
  v = exactly("consecutive_innovation_rejections", 1);
  b.consecutive_innovation_rejections_ = static_cast<int>(count_of(v[0], "consecutive_innovation_rejections"));
  v = r.value_list("frame_origin", 3, 3);
  if (!v.empty()) b.frame_.emplace(Geodetic{v[0], v[1], v[2]});
  const std::vector<uint64_t*> fields = counter_fields(b.counters_);
  const std::vector<uint64_t> c = r.unsigned_list("counters", fields.size());
  for (std::size_t i = 0; i < fields.size(); ++i) *fields[i] = c[i];
  v = r.value_list("gnss_intervals_s");
  if (v.size() > static_cast<std::size_t>(params_.gnss_period_window))
    throw CheckpointError("field 'gnss_intervals_s' is longer than the GNSS period window");
  b.gnss_intervals_s_.assign(v.begin(), v.end());
  b.last_period_row_t_s_ = read_optional_state_value(r, "last_period_row_t_s");
  b.gnss_period_s_ = exactly("gnss_period_s", 1)[0];

  v = exactly("latency", 7);
  b.latency_.applied_s = v[0];
  b.latency_.estimate_s = v[1];
  b.latency_.sigma_s = v[2];
  b.latency_.samples = count_of(v[3], "latency");
  b.latency_.fixed = v[4] != 0.0;
  b.latency_.blocks_left_out = count_of(v[5], "latency");
  b.latency_.applied_sigma_s = v[6];
  if (!std::isfinite(v[0])) throw CheckpointError("field 'latency' has an applied latency that is not finite");
  if (!std::isfinite(v[6]))
    throw CheckpointError("field 'latency' has a sigma of the applied latency that is not finite");
  b.latency_.reason = r.field("latency_reason");
  auto per_candidate = [&](const char* key) {
    Values x = r.value_list(key);
    if (x.size() != latency_candidates_s_.size())
      throw CheckpointError(std::string("field '") + key + "' does not hold one value per latency candidate (" +
                            std::to_string(latency_candidates_s_.size()) + ")");
    return x;
  };
  b.latency_closed_chi2_ = per_candidate("latency_closed_chi2");
  v = exactly("latency_closed", 2);
  b.latency_closed_blocks_ = count_of(v[0], "latency_closed");
  b.latency_closed_samples_ = count_of(v[1], "latency_closed");
  b.latency_closed_fit_ = read_optional_state_value(r, "latency_closed_fit_s");
  v = exactly("latency_block", 3);
  b.latency_block_start_s_ = v[0];
  b.latency_block_samples_ = count_of(v[1], "latency_block");
  b.latency_block_yy_m2_ = v[2];
  b.latency_block_yphi_ = per_candidate("latency_block_yphi");
  b.latency_block_phiphi_ = per_candidate("latency_block_phiphi");
  v = exactly("latency_sums", 3);
  b.latency_samples_ = count_of(v[0], "latency_sums");
  b.latency_sums_applied_s_ = v[1];
  b.latency_restarts_ = count_of(v[2], "latency_sums");
  v = r.value_list("latency_pending", 5, 5 * kMany);
  for (std::size_t i = 0; i < v.size(); i += 5)
    b.latency_pending_.push_back(PendingLatencySample{v[i], v[i + 1], v[i + 2], v[i + 3], v[i + 4]});
  if (!r.at_end()) throw CheckpointError("unexpected text after the sample builder state");
  *this = std::move(b);
}

}  // namespace odonav
