#include "odonav/offline/coverage.hpp"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <utility>

#include <nlohmann/json.hpp>

#include "odonav/frames.hpp"
#include "odonav/geodesy.hpp"

namespace odonav::offline {

void Coverage::add(double error, double sigma) {
  if (!std::isfinite(error) || !std::isfinite(sigma) || sigma < 0.0) return;
  const double z = sigma > 0.0 ? std::abs(error) / sigma : (error == 0.0 ? 0.0 : HUGE_VAL);
  ++n;
  if (z <= 1.0) ++within_1_sigma;
  if (z <= 2.0) ++within_2_sigma;
  if (z <= 3.0) ++within_3_sigma;
  sum_nees += z * z;
  max_abs_z = std::max(max_abs_z, z);
}

void Coverage::merge(const Coverage& other) {
  n += other.n;
  within_1_sigma += other.within_1_sigma;
  within_2_sigma += other.within_2_sigma;
  within_3_sigma += other.within_3_sigma;
  sum_nees += other.sum_nees;
  max_abs_z = std::max(max_abs_z, other.max_abs_z);
}

double Coverage::fraction_within(int k_sigma) const {
  if (n == 0) return std::numeric_limits<double>::quiet_NaN();
  const std::size_t within = k_sigma <= 1 ? within_1_sigma : k_sigma == 2 ? within_2_sigma : within_3_sigma;
  return static_cast<double>(within) / static_cast<double>(n);
}

double Coverage::mean_nees() const {
  return n == 0 ? std::numeric_limits<double>::quiet_NaN() : sum_nees / static_cast<double>(n);
}

namespace {

using nlohmann::json;

// A number of meta.json's "simulation" object; nullopt when absent. A present key that is not a
// number is a DatasetError naming it.
std::optional<double> simulation_number(const json& sim, const char* key) {
  if (!sim.is_object() || !sim.contains(key)) return std::nullopt;
  if (!sim[key].is_number())
    throw DatasetError(std::string("meta.json: key 'simulation.") + key + "' must be a number");
  return sim[key].get<double>();
}

json simulation_of(const DatasetMeta& meta) {
  if (meta.raw_json.empty()) return json();
  const json m = json::parse(meta.raw_json, nullptr, /*allow_exceptions=*/false);
  if (m.is_discarded() || !m.is_object() || !m.contains("simulation")) return json();
  return m["simulation"];
}

// The true K in force at t_s, queried in time order: the simulation's K timeline
// (k_true_initial_m_per_pulse and k_steps), else the last finite k_true of truth.csv at or before
// t_s. The timeline comes first because truth.csv's k_true is the instantaneous metres per pulse,
// which a simulated turn slip lowers in every turn; the published K is the straight-line K (the
// turn slip is a separate estimate), as odonav-offline's summary evaluates it.
class KTruth {
 public:
  KTruth(const json& sim, const std::vector<TruthSample>& truth) : truth_(truth) {
    if (const std::optional<double> k0 = simulation_number(sim, "k_true_initial_m_per_pulse");
        k0 && sim.contains("k_steps") && sim["k_steps"].is_array()) {
      k_ = *k0;
      for (const json& step : sim["k_steps"]) {
        if (!step.is_object() || !step.contains("t_s") || !step["t_s"].is_number() || !step.contains("k_after") ||
            !step["k_after"].is_number())
          throw DatasetError(
              "meta.json: key 'simulation.k_steps' must be a list of {t_s, k_before, k_after} with numbers");
        steps_.push_back({step["t_s"].get<double>(), step["k_after"].get<double>()});
      }
      timeline_ = true;
    }
  }
  bool known() const {
    return timeline_ || std::any_of(truth_.begin(), truth_.end(),
                                    [](const TruthSample& t) { return std::isfinite(t.k_true_m_per_pulse); });
  }
  std::optional<double> at(double t_s) {
    if (timeline_) {
      while (i_ < steps_.size() && steps_[i_].first <= t_s) k_ = steps_[i_++].second;
      return k_;
    }
    while (i_ < truth_.size() && truth_[i_].t_s <= t_s) {
      if (std::isfinite(truth_[i_].k_true_m_per_pulse)) k_ = truth_[i_].k_true_m_per_pulse;
      ++i_;
    }
    return k_;
  }

 private:
  const std::vector<TruthSample>& truth_;
  bool timeline_ = false;
  std::vector<std::pair<double, double>> steps_;  // (t_s, K after the step)
  std::size_t i_ = 0;
  std::optional<double> k_;
};

bool has_truth_positions(const std::vector<TruthSample>& truth) {
  return !truth.empty() && std::isfinite(truth.front().position.lat_rad);
}

// A navigation row's variance per ENU axis.
Eigen::Vector3d variances_of(const results::NavigationPositionRow& r) {
  return {r.var_east_m2, r.var_north_m2, r.var_up_m2};
}

bool has_variances(const results::NavigationPositionRow& r) {
  return r.status != "not_started" && std::isfinite(r.var_east_m2) && std::isfinite(r.var_north_m2) &&
         std::isfinite(r.var_up_m2);
}

void add_axes(QuantityCoverage* axes, const Eigen::Vector3d& error_m, const Eigen::Vector3d& variance_m2,
              bool anchored) {
  for (int a = 0; a < 3; ++a) {
    const double sigma_m = variance_m2[a] >= 0.0 ? std::sqrt(variance_m2[a]) : std::nan("");
    axes[a].all.add(error_m[a], sigma_m);
    if (anchored) axes[a].converged.add(error_m[a], sigma_m);
  }
}

// Each navigation row against the truth interpolated at its time (truth rows in time order).
void position_against_truth(const Dataset& d, const std::vector<results::NavigationPositionRow>& nav,
                            QuantityCoverage* axes) {
  const LocalEnuFrame frame(d.truth.front().position);
  std::size_t j = 0;  // first truth row at or after the navigation row's time
  for (const results::NavigationPositionRow& r : nav) {
    if (!has_variances(r)) continue;
    while (j < d.truth.size() && d.truth[j].t_s < r.t_s) ++j;
    if (j >= d.truth.size()) break;
    Eigen::Vector3d truth_m = frame.to_enu(d.truth[j].position);
    if (d.truth[j].t_s != r.t_s) {
      if (j == 0) continue;
      const TruthSample& p = d.truth[j - 1];
      const double f = (r.t_s - p.t_s) / (d.truth[j].t_s - p.t_s);
      const Eigen::Vector3d a = frame.to_enu(p.position);
      truth_m = a + f * (truth_m - a);
    }
    const Eigen::Vector3d nav_m = frame.to_enu(Geodetic{r.lat_rad, r.lon_rad, r.height_m});
    add_axes(axes, nav_m - truth_m, variances_of(r), r.status == "anchored");
  }
}

// Each valid fix of epoch g against the navigation position interpolated at g from rows stamped
// before g + hold_off_s (the fix does not act on them), the fix's own variance added. The fix also
// pulls the earlier rows a little through its correlated error, which this ignores: with a precise
// reference that is small.
void position_against_fixes(const Dataset& d, const std::vector<results::NavigationPositionRow>& nav,
                            const CoverageOptions& options, QuantityCoverage* axes) {
  std::optional<LocalEnuFrame> frame;
  std::size_t j = 0;  // first navigation row at or after the fix's epoch
  for (const GnssSample& g : d.gnss) {
    if (!g.valid() || !g.pos_std_m) continue;
    if (!frame) frame.emplace(g.position);
    while (j < nav.size() && nav[j].t_s < g.t_s) ++j;
    if (j >= nav.size()) break;
    const results::NavigationPositionRow& b = nav[j];
    if (!has_variances(b) || !(b.t_s < g.t_s + options.hold_off_s || b.t_s == g.t_s)) continue;
    Eigen::Vector3d nav_m = frame->to_enu(Geodetic{b.lat_rad, b.lon_rad, b.height_m});
    Eigen::Vector3d variance_m2 = variances_of(b);
    bool anchored = b.status == "anchored";
    if (b.t_s != g.t_s) {
      if (j == 0 || !has_variances(nav[j - 1])) continue;
      const results::NavigationPositionRow& a = nav[j - 1];
      const double f = (g.t_s - a.t_s) / (b.t_s - a.t_s);
      const Eigen::Vector3d a_m = frame->to_enu(Geodetic{a.lat_rad, a.lon_rad, a.height_m});
      nav_m = a_m + f * (nav_m - a_m);
      variance_m2 = variances_of(a) + f * (variance_m2 - variances_of(a));
      anchored = a.status == "anchored";
    }
    const double sigma_h_m = *g.pos_std_m;
    const double sigma_v_m = options.fix_vertical_sigma_factor * sigma_h_m;
    variance_m2 += Eigen::Vector3d(sigma_h_m * sigma_h_m, sigma_h_m * sigma_h_m, sigma_v_m * sigma_v_m);
    add_axes(axes, nav_m - frame->to_enu(g.position), variance_m2, anchored);
  }
}

}  // namespace

std::vector<QuantityCoverage> evaluate_coverage(const Dataset& d, const results::OutputRows& rows,
                                                const CoverageOptions& options) {
  std::vector<QuantityCoverage> out;
  const json sim = simulation_of(d.meta);

  // K: the main estimator's published K and sigma.
  KTruth truth(sim, d.truth);
  if (truth.known() || options.k_reference_m_per_pulse) {
    QuantityCoverage q{"K", {}, {}};
    for (const results::ScaleFactorRow& r : rows.scale_factor) {
      if (!r.k_m_per_pulse || !r.sigma_m_per_pulse) continue;
      const std::optional<double> k_true = truth.known() ? truth.at(r.t_s) : options.k_reference_m_per_pulse;
      if (!k_true) continue;
      const double error = *r.k_m_per_pulse - *k_true;
      q.all.add(error, *r.sigma_m_per_pulse);
      if (r.converged) q.converged.add(error, *r.sigma_m_per_pulse);
    }
    out.push_back(q);
  }

  // Misalignment: heading against the mechanical angle plus the INS heading bias, pitch.
  if (d.meta.truth_misalignment_heading_deg && d.meta.truth_misalignment_pitch_deg) {
    const double heading_true_rad = deg_to_rad(*d.meta.truth_misalignment_heading_deg +
                                               simulation_number(sim, "ins_heading_bias_deg").value_or(0.0));
    const double pitch_true_rad = deg_to_rad(*d.meta.truth_misalignment_pitch_deg);
    QuantityCoverage heading{"misalignment heading", {}, {}}, pitch{"misalignment pitch", {}, {}};
    for (const results::MisalignmentRow& r : rows.misalignment) {
      const double e_heading = wrap_pi(r.heading_rad - heading_true_rad);
      const double e_pitch = wrap_pi(r.pitch_rad - pitch_true_rad);
      heading.all.add(e_heading, r.heading_std_rad);
      pitch.all.add(e_pitch, r.pitch_std_rad);
      if (r.converged) {
        heading.converged.add(e_heading, r.heading_std_rad);
        pitch.converged.add(e_pitch, r.pitch_std_rad);
      }
    }
    out.push_back(heading);
    out.push_back(pitch);
  }

  // GNSS latency: the latency in force against the simulated one.
  if (sim.is_object()) {
    const double latency_true_s = simulation_number(sim, "gnss_latency_s").value_or(0.0);
    QuantityCoverage q{"GNSS latency", {}, {}};
    for (const results::ScaleFactorRow& r : rows.scale_factor) {
      if (!r.gnss_latency_sigma_s) continue;
      const double error = r.gnss_latency_s - latency_true_s;
      q.all.add(error, *r.gnss_latency_sigma_s);
      if (r.converged) q.converged.add(error, *r.gnss_latency_sigma_s);
    }
    out.push_back(q);
  }

  // The anchored navigation position per axis.
  QuantityCoverage axes[3] = {{"position east", {}, {}}, {"position north", {}, {}}, {"position up", {}, {}}};
  if (has_truth_positions(d.truth)) {
    position_against_truth(d, rows.navigation_position, axes);
  } else if (!d.meta.gnss_lever_arm_m) {
    position_against_fixes(d, rows.navigation_position, options, axes);
  } else {
    return out;  // a fix is the antenna, not the navigation point: no reference without the attitude
  }
  out.insert(out.end(), std::begin(axes), std::end(axes));
  return out;
}

}  // namespace odonav::offline
