#include "summary.hpp"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <iterator>
#include <ostream>
#include <sstream>

#include "odonav/frames.hpp"
#include "odonav/geodesy.hpp"

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
  if (sim.contains("ins_heading_bias_deg") && !sim["ins_heading_bias_deg"].is_number())
    bad("ins_heading_bias_deg", "a number (deg)");
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

// A track's ENU position at t_s, interpolated between the rows bracketing it (at most 1 s apart).
template <class Row>
std::optional<Eigen::Vector3d> track_at(const std::vector<Row>& rows, const LocalEnuFrame& frame, double t_s) {
  const auto it = std::lower_bound(rows.begin(), rows.end(), t_s, [](const Row& r, double t) { return r.t_s < t; });
  if (it == rows.end()) return std::nullopt;
  const Eigen::Vector3d b = frame.to_enu(Geodetic{it->lat_rad, it->lon_rad, it->height_m});
  if (it->t_s == t_s) return b;
  if (it == rows.begin() || it->t_s - std::prev(it)->t_s > 1.0) return std::nullopt;
  const auto& p = *std::prev(it);
  const Eigen::Vector3d a = frame.to_enu(Geodetic{p.lat_rad, p.lon_rad, p.height_m});
  return Eigen::Vector3d(a + (t_s - p.t_s) / (it->t_s - p.t_s) * (b - a));
}

// The truth (INS reference point) at t_s in ENU, and the attitude of the nearer sample.
std::optional<std::pair<Eigen::Vector3d, Attitude>> truth_at(const Dataset& d, const LocalEnuFrame& frame, double t_s) {
  const auto& tr = d.truth;
  const auto it = std::lower_bound(tr.begin(), tr.end(), t_s, [](const TruthSample& r, double t) { return r.t_s < t; });
  if (it == tr.end() || (it == tr.begin() && it->t_s != t_s)) return std::nullopt;
  const Eigen::Vector3d b = frame.to_enu(it->position);
  if (it->t_s == t_s) return std::make_pair(b, it->attitude);
  const TruthSample& p = *std::prev(it);
  const double f = (t_s - p.t_s) / (it->t_s - p.t_s);
  const Eigen::Vector3d a = frame.to_enu(p.position);
  return std::make_pair(Eigen::Vector3d(a + f * (b - a)), f < 0.5 ? p.attitude : it->attitude);
}

// The INS attitude nearest to t_s (for the lever arm of a GNSS fix), if within 0.1 s.
std::optional<Attitude> ins_attitude_at(const Dataset& d, double t_s) {
  const auto& ins = d.ins;
  auto it = std::lower_bound(ins.begin(), ins.end(), t_s, [](const InsSample& r, double t) { return r.t_s < t; });
  if (it != ins.begin() && (it == ins.end() || t_s - std::prev(it)->t_s < it->t_s - t_s)) --it;
  if (it == ins.end() || std::abs(it->t_s - t_s) > 0.1) return std::nullopt;
  return it->attitude;
}

double rms_of(double sum_sq, std::size_t n) { return n > 0 ? std::sqrt(sum_sq / static_cast<double>(n)) : std::nan(""); }

// The anchored navigation position against GNSS while it is valid (the reference point from each
// valid fix: antenna minus the lever arm turned by the INS attitude), beside the pure DR; and against
// truth when there is one: while GNSS is valid (with the fixes' own error) and across each outage.
json navigation_json(const Dataset& d, const results::OutputRows& rows, const std::vector<Outage>& outages) {
  const auto& nav = rows.navigation_position;
  if (nav.empty()) return nullptr;
  const LocalEnuFrame frame(Geodetic{nav.front().lat_rad, nav.front().lon_rad, nav.front().height_m});
  const std::optional<Eigen::Vector3d> lever = d.meta.gnss_lever_arm_m;
  auto anchored_at = [&](double t_s) {
    const auto it = std::upper_bound(nav.begin(), nav.end(), t_s,
                                     [](double t, const results::NavigationPositionRow& r) { return t < r.t_s; });
    return it != nav.begin() && std::prev(it)->status == "anchored";
  };
  double nav_sq = 0.0, dr_sq = 0.0;
  std::size_t n = 0, n_dr = 0;
  for (const GnssSample& g : d.gnss) {
    if (!g.valid() || !anchored_at(g.t_s)) continue;
    Eigen::Vector3d ref = frame.to_enu(g.position);
    if (lever) {
      const std::optional<Attitude> att = ins_attitude_at(d, g.t_s);
      if (!att) continue;
      ref -= body_to_enu(*att) * *lever;
    }
    const auto p = track_at(nav, frame, g.t_s);
    if (!p) continue;
    nav_sq += ((*p - ref).head<2>()).squaredNorm();
    ++n;
    if (const auto q = track_at(rows.dead_reckoning, frame, g.t_s)) {
      dr_sq += ((*q - ref).head<2>()).squaredNorm();
      ++n_dr;
    }
  }
  json j;
  j["vs_gnss"] = {{"epochs", n},
                  {"horizontal_rms_m", number_or_null(rms_of(nav_sq, n))},
                  {"pure_dr_horizontal_rms_m", number_or_null(rms_of(dr_sq, n_dr))}};
  std::size_t anchored = 0, bridging = 0;
  for (const auto& r : nav) {
    if (r.status == "anchored") ++anchored;
    if (r.status == "dead_reckoning") ++bridging;
  }
  j["rows_anchored"] = anchored;
  j["rows_dead_reckoning"] = bridging;
  if (d.has_truth() && std::isfinite(d.truth.front().position.lat_rad)) {
    double a_sq = 0.0, b_sq = 0.0, g_sq = 0.0;
    std::size_t na = 0, ng = 0;
    for (std::size_t i = 0; i < nav.size(); ++i) {
      if (nav[i].status != "anchored") continue;
      const auto tr = truth_at(d, frame, nav[i].t_s);
      const auto q = track_at(rows.dead_reckoning, frame, nav[i].t_s);
      if (!tr || !q) continue;
      a_sq += (frame.to_enu(Geodetic{nav[i].lat_rad, nav[i].lon_rad, nav[i].height_m}) - tr->first).head<2>().squaredNorm();
      b_sq += (*q - tr->first).head<2>().squaredNorm();
      ++na;
    }
    for (const GnssSample& g : d.gnss) {
      if (!g.valid() || !anchored_at(g.t_s)) continue;
      const auto tr = truth_at(d, frame, g.t_s);
      if (!tr) continue;
      Eigen::Vector3d antenna = tr->first;
      if (lever && std::isfinite(tr->second.heading_rad)) antenna += body_to_enu(tr->second) * *lever;
      g_sq += (frame.to_enu(g.position) - antenna).head<2>().squaredNorm();
      ++ng;
    }
    json o = json::array();
    for (const Outage& out : outages) {
      // The last row before the outage, and the last before GNSS returns.
      const auto before = [&](double t) {
        auto it = std::lower_bound(nav.begin(), nav.end(), t, [](const results::NavigationPositionRow& r, double x) { return r.t_s < x; });
        return it == nav.begin() ? nav.end() : std::prev(it);
      };
      const auto a = before(out.start_s), b = before(out.end_s);
      if (a == nav.end() || b == nav.end() || a == b) continue;
      const auto ta = truth_at(d, frame, a->t_s), tb = truth_at(d, frame, b->t_s);
      if (!ta || !tb) continue;
      const double ea = (frame.to_enu(Geodetic{a->lat_rad, a->lon_rad, a->height_m}) - ta->first).head<2>().norm();
      const double eb = (frame.to_enu(Geodetic{b->lat_rad, b->lon_rad, b->height_m}) - tb->first).head<2>().norm();
      o.push_back({{"start_s", out.start_s}, {"end_s", out.end_s}, {"error_at_start_m", ea}, {"error_at_end_m", eb},
                   {"distance_m", number_or_null(b->distance_since_fix_m - a->distance_since_fix_m)}});
    }
    j["vs_truth"] = {{"rows", na},
                     {"horizontal_rms_m", number_or_null(rms_of(a_sq, na))},
                     {"pure_dr_horizontal_rms_m", number_or_null(rms_of(b_sq, na))},
                     {"gnss_horizontal_rms_m", number_or_null(rms_of(g_sq, ng))},
                     {"outages", o}};
  }
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
      // A constant INS heading error cannot be told from a heading misalignment (docs/ALGORITHM.md,
      // caveat of §1): the calibration estimates their sum, which is what dead reckoning with this
      // INS needs. Against the mechanical angle alone a right estimate would look wrong by the bias.
      if (sim.contains("ins_heading_bias_deg")) {
        const double bias_deg = sim["ins_heading_bias_deg"].get<double>();
        j["ins_heading_bias_deg"] = bias_deg;
        j["dr_heading_error_deg"] = rad_to_deg(m.heading_rad) - (*d.meta.truth_misalignment_heading_deg + bias_deg);
      }
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
    sf["turn_slip_s_per_rad"] = number_or_null(last.turn_slip_s_per_rad);
    sf["turn_slip_sigma_s_per_rad"] = last.turn_slip_sigma_s_per_rad ? number_or_null(*last.turn_slip_sigma_s_per_rad) : json();
    sf["turn_slip_applies"] = last.turn_slip_applies;
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
  s["navigation_position"] = navigation_json(d, rows, outages);
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
    if (m.contains("dr_heading_error_deg"))
      out << "\n                 heading vs truth plus the INS heading bias (" << fmt(m["ins_heading_bias_deg"], 3)
          << " deg; the angle dead reckoning needs): " << fmt(m["dr_heading_error_deg"], 4) << " deg";
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
  if (sf.contains("turn_slip_s_per_rad")) {
    out << "    turn slip     " << fmt(sf["turn_slip_s_per_rad"], 4, " s/rad") << " +- "
        << fmt(sf.value("turn_slip_sigma_s_per_rad", json()), 4, " s/rad")
        << (sf.value("turn_slip_applies", false) ? "  (applied by dead reckoning" : "  (not applied");
    if (sf.contains("turn_slip_samples")) out << "; " << sf["turn_slip_samples"].get<uint64_t>() << " turn samples";
    const std::string why = sf.value("turn_slip_reason", std::string());
    if (!why.empty()) out << ": " << why;
    out << ")\n";
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
  if (s.contains("navigation_position") && !s["navigation_position"].is_null()) {
    const json& nav = s["navigation_position"];
    out << "  navigation position (anchored on GNSS)   horizontal RMS: anchored / pure DR / GNSS fixes\n";
    out << "    vs GNSS while valid   " << fmt(nav["vs_gnss"]["horizontal_rms_m"], 2, " m") << " / "
        << fmt(nav["vs_gnss"]["pure_dr_horizontal_rms_m"], 2, " m") << " / -\n";
    if (nav.contains("vs_truth")) {
      const json& t = nav["vs_truth"];
      out << "    vs truth while valid  " << fmt(t["horizontal_rms_m"], 2, " m") << " / "
          << fmt(t["pure_dr_horizontal_rms_m"], 2, " m") << " / " << fmt(t["gnss_horizontal_rms_m"], 2, " m") << "\n";
      for (const json& o : t["outages"])
        out << "    outage " << fmt(o["start_s"], 0) << "-" << fmt(o["end_s"], 0) << " s: error " << fmt(o["error_at_start_m"], 2)
            << " -> " << fmt(o["error_at_end_m"], 2, " m") << " over " << fmt(o["distance_m"], 0, " m") << "\n";
    }
  }
  if (s.contains("warnings") && s["warnings"].is_array() && !s["warnings"].empty()) {
    out << "  warnings\n";
    for (const json& w : s["warnings"])
      if (w.is_object() && w.contains("message") && w["message"].is_string())
        out << "    " << w.value("code", std::string("-")) << ": " << w["message"].get<std::string>() << "\n";
  }
}

}  // namespace odonav::offline
