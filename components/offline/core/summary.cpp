#include "summary.hpp"

#include <cmath>
#include <iomanip>
#include <ostream>
#include <sstream>

#include "odonav/frames.hpp"

namespace odonav::offline {
namespace {

using nlohmann::json;

json number_or_null(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }

// meta.json's "simulation" object, with the keys the evaluation reads checked: a malformed one is a
// DatasetError naming meta.json and the key, not a JSON library message.
nlohmann::json simulation_meta(const Dataset& d) {
  if (d.meta.raw_json.empty()) return json::object();
  const json meta = json::parse(d.meta.raw_json, nullptr, /*allow_exceptions=*/false);
  if (meta.is_discarded() || !meta.is_object() || !meta.contains("simulation")) return json::object();
  const json& sim = meta["simulation"];
  const auto bad = [](const std::string& key, const std::string& expected) {
    throw DatasetError("meta.json: key 'simulation." + key + "' must be " + expected);
  };
  if (!sim.is_object()) bad("", "an object");
  if (sim.contains("k_true_initial_m_per_pulse") && !sim["k_true_initial_m_per_pulse"].is_number())
    bad("k_true_initial_m_per_pulse", "a number (m/pulse)");
  if (sim.contains("k_steps")) {
    if (!sim["k_steps"].is_array()) bad("k_steps", "a list of {t_s, k_before, k_after}");
    for (const json& step : sim["k_steps"])
      if (!step.is_object() || !step.contains("t_s") || !step["t_s"].is_number() || !step.contains("k_before") ||
          !step["k_before"].is_number() || !step.contains("k_after") || !step["k_after"].is_number())
        bad("k_steps", "a list of {t_s, k_before, k_after} with numbers");
  }
  if (sim.contains("gnss_outages")) {
    if (!sim["gnss_outages"].is_array()) bad("gnss_outages", "a list of [start_s, end_s]");
    for (const json& o : sim["gnss_outages"])
      if (!o.is_array() || o.size() != 2 || !o[0].is_number() || !o[1].is_number())
        bad("gnss_outages", "a list of [start_s, end_s] with numbers");
  }
  return sim;
}

// The true K timeline: the simulator's base K with its steps (slip in turns excluded: the gates keep
// turns out of the regression, so no estimator is meant to follow it), else truth.csv's k_true.
std::vector<TimedValue> reference_k(const Dataset& d, const json& sim, std::vector<KStep>* steps) {
  std::vector<TimedValue> ref;
  if (sim.contains("k_true_initial_m_per_pulse") && sim.contains("k_steps")) {
    const double t0 = d.odometer.empty() ? 0.0 : d.odometer.front().t_s;
    const double t_end = d.odometer.empty() ? 0.0 : d.odometer.back().t_s;
    ref.push_back({t0, sim["k_true_initial_m_per_pulse"].get<double>()});
    for (const json& s : sim["k_steps"]) {
      KStep step{s["t_s"].get<double>(), s["k_before"].get<double>(), s["k_after"].get<double>()};
      if (step.t_s > t_end) break;  // a drive cut short (--duration-s) never reaches this step
      steps->push_back(step);
      ref.push_back({step.t_s, step.k_after_m_per_pulse});
    }
    return ref;
  }
  for (const TruthSample& t : d.truth)
    if (std::isfinite(t.k_true_m_per_pulse)) ref.push_back({t.t_s, t.k_true_m_per_pulse});
  return ref;
}

std::vector<Outage> outages_of(const Dataset& d, const json& sim) {
  std::vector<Outage> out;
  if (sim.contains("gnss_outages")) {
    for (const json& o : sim["gnss_outages"]) out.push_back({o[0].get<double>(), o[1].get<double>()});
    return out;
  }
  // Without meta: spans of >= 5 s with no valid fix.
  std::optional<double> last_valid;
  for (const GnssSample& g : d.gnss) {
    if (!g.valid()) continue;
    if (last_valid && g.t_s - *last_valid >= 5.0) out.push_back({*last_valid, g.t_s});
    last_valid = g.t_s;
  }
  return out;
}

json dr_json(const std::vector<results::DeadReckoningRow>& rows, const std::vector<TimedPosition>& reference,
             const std::vector<Outage>& outages, double min_distance_m) {
  if (rows.empty()) return nullptr;
  std::vector<TimedPosition> track;
  std::vector<double> distance;
  track.reserve(rows.size());
  distance.reserve(rows.size());
  for (const results::DeadReckoningRow& r : rows) {
    track.push_back({r.t_s, Geodetic{r.lat_rad, r.lon_rad, r.height_m}});
    distance.push_back(r.distance_m);
  }
  const DrEvaluation e = evaluate_dead_reckoning(track, distance, reference, outages, min_distance_m);
  json j;
  j["epochs_compared"] = e.epochs;
  j["distance_m"] = e.distance_m;
  j["final_error_m"] = number_or_null(e.final_error_m);
  j["final_error_percent"] = number_or_null(e.final_error_percent);
  j["max_error_m"] = number_or_null(e.max_error_m);
  j["max_error_percent"] = number_or_null(e.max_error_percent);
  j["final_k_m_per_pulse"] = rows.back().k_m_per_pulse;
  j["final_k_source"] = rows.back().k_source;
  json o = json::array();
  for (std::size_t i = 0; i < outages.size(); ++i)
    o.push_back({{"start_s", outages[i].start_s},
                 {"end_s", outages[i].end_s},
                 {"error_m", number_or_null(e.outage_error_m[i])},
                 {"error_percent_of_outage_distance", number_or_null(e.outage_error_percent[i])}});
  j["outages"] = o;
  return j;
}

}  // namespace

json make_summary(const Dataset& d, const results::OutputRows& rows, const SummaryOptions& options) {
  json s;
  const json sim = simulation_meta(d);
  s["dataset"] = {{"name", options.dataset_name},
                  {"vehicle_id", d.meta.vehicle_id},
                  {"duration_s", d.odometer.empty() ? 0.0 : d.odometer.back().t_s - d.odometer.front().t_s},
                  {"has_ins", d.has_ins()},
                  {"has_truth", d.has_truth()}};
  if (options.elapsed_s) {
    s["processing"] = {{"elapsed_s", *options.elapsed_s},
                       {"odometer_epochs_per_s", d.odometer.size() / std::max(*options.elapsed_s, 1e-9)}};
  }

  // Misalignment: the final estimate, and its error when the truth is known.
  if (!rows.misalignment.empty()) {
    const results::MisalignmentRow& m = rows.misalignment.back();
    json j = {{"heading_deg", rad_to_deg(m.heading_rad)},
              {"pitch_deg", rad_to_deg(m.pitch_rad)},
              {"heading_std_deg", number_or_null(rad_to_deg(m.heading_std_rad))},
              {"pitch_std_deg", number_or_null(rad_to_deg(m.pitch_std_rad))},
              {"converged", m.converged},
              {"state", m.state},
              {"samples_used", m.samples_used}};
    for (const results::MisalignmentRow& r : rows.misalignment)
      if (r.converged) {
        j["converged_at_s"] = r.t_s;
        break;
      }
    if (d.meta.truth_misalignment_heading_deg && d.meta.truth_misalignment_pitch_deg) {
      j["truth_heading_deg"] = *d.meta.truth_misalignment_heading_deg;
      j["truth_pitch_deg"] = *d.meta.truth_misalignment_pitch_deg;
      j["heading_error_deg"] = rad_to_deg(m.heading_rad) - *d.meta.truth_misalignment_heading_deg;
      j["pitch_error_deg"] = rad_to_deg(m.pitch_rad) - *d.meta.truth_misalignment_pitch_deg;
    }
    s["misalignment"] = j;
  }

  // Scale factor: every estimator that has a column, evaluated against the true K when known.
  std::vector<KStep> steps;
  const std::vector<TimedValue> k_ref = reference_k(d, sim, &steps);
  double first_motion = std::numeric_limits<double>::quiet_NaN();
  for (const results::ScaleFactorRow& r : rows.scale_factor)
    if (r.samples_accepted > 0) {
      first_motion = r.t_s;
      break;
    }
  json estimators = json::object();
  std::vector<std::string> names;
  if (!rows.scale_factor.empty())
    for (const auto& [name, value] : rows.scale_factor.front().k_by_estimator) names.push_back(name);
  for (const std::string& name : names) {
    std::vector<TimedValue> series;
    for (const results::ScaleFactorRow& r : rows.scale_factor)
      for (const auto& [n, v] : r.k_by_estimator)
        if (n == name && v) series.push_back({r.t_s, *v});
    if (series.empty()) continue;
    json j = {{"final_k_m_per_pulse", series.back().value}};
    if (!k_ref.empty() && std::isfinite(first_motion)) {
      const KEvaluation e = evaluate_scale_factor(series, k_ref, steps, first_motion, options.k_evaluation);
      j["rms_rel_error_percent"] = number_or_null(100.0 * e.rms_rel_error);
      j["max_rel_error_percent"] = number_or_null(100.0 * e.max_rel_error);
      j["final_rel_error_percent"] = number_or_null(100.0 * e.final_rel_error);
      j["time_to_converge_s"] = number_or_null(e.time_to_converge_s);
      json settle = json::array();
      for (double t : e.settle_times_s) settle.push_back(number_or_null(t));
      j["settle_times_s"] = settle;
    }
    estimators[name] = j;
  }
  json sf = {{"estimators", estimators}};
  if (!rows.scale_factor.empty()) {
    const results::ScaleFactorRow& last = rows.scale_factor.back();
    sf["main_estimator"] = last.estimator;
    sf["samples_accepted"] = last.samples_accepted;
    sf["samples_rejected"] = last.samples_rejected;
    sf["first_motion_t_s"] = number_or_null(first_motion);
    sf["gnss_latency_s"] = number_or_null(last.gnss_latency_s);
    sf["gnss_latency_sigma_s"] = last.gnss_latency_sigma_s ? number_or_null(*last.gnss_latency_sigma_s) : json();
    if (sim.is_object() && sim.contains("gnss_latency_s") && sim["gnss_latency_s"].is_number())
      sf["gnss_latency_error_s"] = number_or_null(last.gnss_latency_s - sim["gnss_latency_s"].get<double>());
  }
  if (!k_ref.empty()) {
    sf["true_k_final_m_per_pulse"] = k_ref.back().value;
    json st = json::array();
    for (const KStep& k : steps) st.push_back({{"t_s", k.t_s}, {"k_before", k.k_before_m_per_pulse}, {"k_after", k.k_after_m_per_pulse}});
    sf["k_steps"] = st;
  }
  s["scale_factor"] = sf;

  // Dead reckoning against truth positions, or valid GNSS fixes without truth.
  std::vector<TimedPosition> reference;
  std::string reference_name;
  if (d.has_truth() && std::isfinite(d.truth.front().position.lat_rad)) {
    for (const TruthSample& t : d.truth) reference.push_back({t.t_s, t.position});
    reference_name = "truth";
  } else {
    for (const GnssSample& g : d.gnss)
      if (g.valid()) reference.push_back({g.t_s, g.position});
    reference_name = "gnss";
  }
  const std::vector<Outage> outages = outages_of(d, sim);
  s["dead_reckoning"] = {{"reference", reference_name},
                         {"online_k", dr_json(rows.dead_reckoning, reference, outages, options.dr_min_distance_m)},
                         {"coarse_k", dr_json(rows.dead_reckoning_coarse, reference, outages, options.dr_min_distance_m)},
                         {"coarse_k_origin", options.coarse_k_origin}};
  return s;
}

namespace {
std::string fmt(const json& v, int precision, const char* unit = "") {
  if (v.is_null() || !v.is_number()) return "-";
  std::ostringstream o;
  o << std::fixed << std::setprecision(precision) << v.get<double>() << unit;
  return o.str();
}
}  // namespace

void print_summary(const json& s, std::ostream& out) {
  out << "odonav summary: " << s["dataset"]["name"].get<std::string>() << " (" << fmt(s["dataset"]["duration_s"], 1)
      << " s";
  if (s.contains("processing")) out << ", processed in " << fmt(s["processing"]["elapsed_s"], 3) << " s";
  out << ")\n";
  if (s.contains("misalignment")) {
    const json& m = s["misalignment"];
    out << "  misalignment   heading " << fmt(m["heading_deg"], 3) << " deg +- " << fmt(m["heading_std_deg"], 3)
        << ", pitch " << fmt(m["pitch_deg"], 3) << " deg +- " << fmt(m["pitch_std_deg"], 3) << "  ("
        << m["state"].get<std::string>() << ")";
    if (m.contains("heading_error_deg"))
      out << "\n                 error vs truth: heading " << fmt(m["heading_error_deg"], 4) << " deg, pitch "
          << fmt(m["pitch_error_deg"], 4) << " deg";
    out << "\n";
  }
  const json& sf = s["scale_factor"];
  out << "  scale factor   (main: " << sf.value("main_estimator", std::string("-")) << ", accepted "
      << sf.value("samples_accepted", 0) << ", rejected " << sf.value("samples_rejected", 0) << ")\n";
  out << "    estimator     final K [m/pulse]   RMS err %   converge s   settle s after each step\n";
  for (const auto& [name, e] : sf["estimators"].items()) {
    out << "    " << std::left << std::setw(12) << name << std::right << std::setw(14) << fmt(e["final_k_m_per_pulse"], 7);
    out << std::setw(14) << fmt(e.value("rms_rel_error_percent", json()), 3) << std::setw(13)
        << fmt(e.value("time_to_converge_s", json()), 1) << "   ";
    if (e.contains("settle_times_s"))
      for (const json& t : e["settle_times_s"]) out << fmt(t, 1) << " ";
    out << "\n";
  }
  if (sf.contains("true_k_final_m_per_pulse")) out << "    true K (final) " << fmt(sf["true_k_final_m_per_pulse"], 7) << "\n";
  if (sf.contains("gnss_latency_s")) {
    out << "    GNSS latency  " << fmt(sf["gnss_latency_s"], 4, " s") << " +- " << fmt(sf.value("gnss_latency_sigma_s", json()), 4, " s");
    if (sf.contains("gnss_latency_error_s")) out << "  (error vs simulation " << fmt(sf["gnss_latency_error_s"], 4, " s") << ")";
    out << "\n";
  }
  const json& dr = s["dead_reckoning"];
  out << "  dead reckoning (vs " << dr["reference"].get<std::string>() << ")\n";
  out << "    K             final err m   final %D   max %D   outage err m (% of outage distance)\n";
  for (const char* which : {"online_k", "coarse_k"}) {
    const json& j = dr[which];
    if (j.is_null()) continue;
    out << "    " << std::left << std::setw(12) << which << std::right << std::setw(12) << fmt(j["final_error_m"], 2)
        << std::setw(11) << fmt(j["final_error_percent"], 3) << std::setw(9) << fmt(j["max_error_percent"], 3) << "   ";
    for (const json& o : j["outages"])
      out << fmt(o["error_m"], 2) << " (" << fmt(o["error_percent_of_outage_distance"], 3) << " %) ";
    out << "\n";
  }
  if (!dr["coarse_k"].is_null()) out << "    coarse K from: " << dr["coarse_k_origin"].get<std::string>() << "\n";
  if (s.contains("warnings") && s["warnings"].is_array() && !s["warnings"].empty()) {
    out << "  warnings\n";
    for (const json& w : s["warnings"])
      if (w.is_object() && w.contains("message") && w["message"].is_string())
        out << "    " << w.value("code", std::string("-")) << ": " << w["message"].get<std::string>() << "\n";
  }
}

}  // namespace odonav::offline
