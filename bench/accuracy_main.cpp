// odonav-bench-accuracy: every estimator compared side by side against the simulator's truth, so the
// choice of the main estimator and its defaults rests on measured figures (BENCHMARKS.md §3).
//
// For every scenario (straight, ring, terrain, slow_robot, and variants such as terrain+1hz or
// terrain+lat100) and every seed, simulates the drive in memory, runs the
// whole offline chain (run_offline: calibration, every estimator side by side on the same samples, DR
// with the online K and with the coarse K of the straight run of the SAME seed) and evaluates it with
// make_summary, exactly as odonav-offline does. Prints, per scenario and estimator, the median and the
// range [min, max] over the seeds of: RMS relative K error in steady state, time to converge within
// 0.5 %, settle time after each K step; and per DR run: final and maximum %D, and the error across
// the GNSS outage. Then the sensitivity of VFF-LM-RLS to L, C (vff-kappa) and lambda_min on terrain.
//
// It is a benchmark, not a test: it prints figures (Markdown tables) and gates nothing. One process,
// one thread; about 3 s per seed on a 2-core EPYC VM. Options: --seeds N, --first-seed S,
// --sensitivity-seeds M (0: skip the table), and every estimator / gate / DR option of odonav-offline
// (--window, --vff-kappa, --lambda-min, ...) to evaluate other settings.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <iomanip>
#include <iostream>
#include <limits>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "bench_scenarios.hpp"
#include "odonav/simulator/simulator.hpp"
#include "odonav/calibration/calibration_options.hpp"
#include "odonav/config.hpp"
#include "odonav/consumer_rules.hpp"
#include "odonav/dead_reckoning/dead_reckoning_options.hpp"
#include "odonav/identification/identification_options.hpp"
#include "odonav/logging.hpp"
#include "odonav/offline/first_metres.hpp"
#include "odonav/offline/offline_runner.hpp"
#include "odonav/offline/summary.hpp"

namespace {

using nlohmann::json;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// ---- statistics over seeds -----------------------------------------------------------------------

// A figure collected over seeds; NaN means "never" (did not converge / settle) or "not defined".
struct Figure {
  std::vector<double> values;
  void add(double v) { values.push_back(v); }
  void add(const json& v) { values.push_back(v.is_number() ? v.get<double>() : kNaN); }
};

double quantile(std::vector<double> sorted_values, double q) {
  std::sort(sorted_values.begin(), sorted_values.end());
  const double pos = q * static_cast<double>(sorted_values.size() - 1);
  const std::size_t lo = static_cast<std::size_t>(std::floor(pos));
  const std::size_t hi = std::min(lo + 1, sorted_values.size() - 1);
  return sorted_values[lo] + (pos - static_cast<double>(lo)) * (sorted_values[hi] - sorted_values[lo]);
}

// "median [min, max]" over the finite values, with "(k/n never)" when some were NaN.
std::string describe(const Figure& f, int precision) {
  std::vector<double> finite;
  for (double v : f.values)
    if (std::isfinite(v)) finite.push_back(v);
  std::ostringstream o;
  o << std::fixed << std::setprecision(precision);
  if (finite.empty()) {
    o << "never";
  } else {
    o << quantile(finite, 0.5) << " [" << *std::min_element(finite.begin(), finite.end()) << ", "
      << *std::max_element(finite.begin(), finite.end()) << "]";
  }
  const std::size_t missing = f.values.size() - finite.size();
  if (missing > 0 && !finite.empty()) o << " (" << missing << "/" << f.values.size() << " never)";
  return o.str();
}

double median_of_finite(const Figure& f) {
  std::vector<double> finite;
  for (double v : f.values)
    if (std::isfinite(v)) finite.push_back(v);
  return finite.empty() ? kNaN : quantile(finite, 0.5);
}

std::size_t count_never(const Figure& f) {
  return static_cast<std::size_t>(
      std::count_if(f.values.begin(), f.values.end(), [](double v) { return !std::isfinite(v); }));
}

// ---- one run ---------------------------------------------------------------------------------------

using odonav::bench::params_for;
using odonav::bench::simulate;

json summary_of(const odonav::Dataset& d, const odonav::results::OutputRows& rows, const std::string& name) {
  odonav::offline::SummaryOptions options;
  options.dataset_name = name;
  return odonav::offline::make_summary(d, rows, options);
}

// ---- the comparison --------------------------------------------------------------------------------

struct EstimatorFigures {
  Figure rms_percent, converge_s;
  std::vector<Figure> settle_s;  // per K step
};
struct DrFigures {
  Figure final_percent, max_percent, outage_m, outage_percent;
};
struct ScenarioFigures {
  std::map<std::string, EstimatorFigures> estimators;
  DrFigures online, coarse;
  Figure latency_error_ms, latency_sigma_ms;  ///< final GNSS latency estimate minus the simulated one
  std::vector<double> rms_by_seed;            ///< vff_lm_rls RMS K error per seed (%), for the worst seed
  std::size_t steps = 0;
  bool has_outage = false;
  /// The online DR from its first metre (first_metres.hpp): start offset and max %D after 500 m,
  /// as it is, without the start offset, and with an origin from the standstill fixes or from every
  /// fix of the first 500 m.
  Figure start_offset_m, max_after_500m, drift_max_after_500m, standstill_offset_m, standstill_max_after_500m,
      first_500m_offset_m, first_500m_max_after_500m, drift_final;
};

void collect(const odonav::offline::FirstMetres& m, ScenarioFigures& f) {
  f.start_offset_m.add(m.start_offset_m);
  f.max_after_500m.add(m.max_after_500m_percent);
  f.drift_max_after_500m.add(m.drift_max_after_500m_percent);
  f.drift_final.add(m.drift_final_percent);
  f.standstill_offset_m.add(m.standstill_origin_offset_m);
  f.standstill_max_after_500m.add(m.standstill_origin_max_after_500m_percent);
  f.first_500m_offset_m.add(m.first_500m_origin_offset_m);
  f.first_500m_max_after_500m.add(m.first_500m_origin_max_after_500m_percent);
}

void collect(const json& s, ScenarioFigures& f) {
  const json& sf = s["scale_factor"];
  f.steps = sf.contains("k_steps") ? sf["k_steps"].size() : 0;
  for (const auto& [name, e] : sf["estimators"].items()) {
    EstimatorFigures& ef = f.estimators[name];
    ef.rms_percent.add(e.value("rms_rel_error_percent", json()));
    ef.converge_s.add(e.value("time_to_converge_s", json()));
    ef.settle_s.resize(f.steps);
    const json settle = e.value("settle_times_s", json::array());
    for (std::size_t i = 0; i < f.steps; ++i) ef.settle_s[i].add(i < settle.size() ? settle[i] : json());
  }
  if (sf.contains("gnss_latency_error_s") && sf["gnss_latency_error_s"].is_number())
    f.latency_error_ms.add(1000.0 * sf["gnss_latency_error_s"].get<double>());
  if (sf.contains("gnss_latency_sigma_s"))
    f.latency_sigma_ms.add(sf["gnss_latency_sigma_s"].is_number() ? 1000.0 * sf["gnss_latency_sigma_s"].get<double>()
                                                                  : kNaN);
  if (sf["estimators"].contains("vff_lm_rls"))
    f.rms_by_seed.push_back(sf["estimators"]["vff_lm_rls"].value("rms_rel_error_percent", kNaN));
  for (const char* which : {"online_k", "coarse_k"}) {
    const json& j = s["dead_reckoning"][which];
    DrFigures& d = std::string(which) == "online_k" ? f.online : f.coarse;
    if (j.is_null()) continue;
    d.final_percent.add(j["final_error_percent"]);
    d.max_percent.add(j["max_error_percent"]);
    for (const json& o : j["outages"]) {
      f.has_outage = true;
      d.outage_m.add(o["error_m"]);
      d.outage_percent.add(o["error_percent_of_outage_distance"]);
    }
  }
}

void print_scenario(const std::string& scenario, const ScenarioFigures& f, std::size_t seeds, std::ostream& out) {
  out << "\n### " << scenario << " (" << seeds << " seeds; median [min, max])\n\n";
  out << "| estimator | RMS K error, steady state (%) | converge within 0.5 % (s) |";
  for (std::size_t i = 0; i < f.steps; ++i) out << " settle after step " << i + 1 << " (s) |";
  out << "\n|---|---|---|";
  for (std::size_t i = 0; i < f.steps; ++i) out << "---|";
  out << "\n";
  for (const auto& [name, e] : f.estimators) {
    out << "| " << name << " | " << describe(e.rms_percent, 3) << " | " << describe(e.converge_s, 1) << " |";
    for (std::size_t i = 0; i < f.steps; ++i) out << " " << describe(e.settle_s[i], 1) << " |";
    out << "\n";
  }
  if (!f.latency_error_ms.values.empty()) {
    out << "\nGNSS latency: final estimate minus simulated (ms) " << describe(f.latency_error_ms, 1) << ", sigma (ms) "
        << describe(f.latency_sigma_ms, 1) << "\n";
    out << "GNSS latency error per seed (ms):";
    for (double v : f.latency_error_ms.values) out << " " << std::fixed << std::setprecision(1) << v;
    out << "\n";
  }
  out << "\nDR final %D per seed (online K):";
  for (double v : f.online.final_percent.values) out << " " << std::fixed << std::setprecision(3) << v;
  out << "\n";
  out << "\nvff_lm_rls RMS K error per seed (%):";
  for (double v : f.rms_by_seed) out << " " << std::fixed << std::setprecision(3) << v;
  out << "\n";
  out << "\n| DR with | final %D | max %D (after 100 m) |"
      << (f.has_outage ? " outage error (m) | outage error (% of outage distance) |" : "") << "\n|---|---|---|"
      << (f.has_outage ? "---|---|" : "") << "\n";
  for (const auto& [label, d] : {std::pair<const char*, const DrFigures*>{"online K (vff_lm_rls)", &f.online},
                                 {"coarse K (S/N of the straight run, same seed)", &f.coarse}}) {
    out << "| " << label << " | " << describe(d->final_percent, 3) << " | " << describe(d->max_percent, 3) << " |";
    if (f.has_outage) out << " " << describe(d->outage_m, 2) << " | " << describe(d->outage_percent, 3) << " |";
    out << "\n";
  }
  out << "\nOnline DR, its origin against the truth (m) and its max %D after 500 m:\n\n"
      << "| DR origin | origin error (m) | max %D after 500 m |\n|---|---|---|\n"
      << "| first fix (the DR's) | " << describe(f.start_offset_m, 2) << " | " << describe(f.max_after_500m, 3)
      << " |\n"
      << "| the truth (start offset removed) | 0 | " << describe(f.drift_max_after_500m, 3) << " |\n"
      << "| mean of the standstill fixes | " << describe(f.standstill_offset_m, 2) << " | "
      << describe(f.standstill_max_after_500m, 3) << " |\n"
      << "| mean of the fixes of the first 500 m | " << describe(f.first_500m_offset_m, 2) << " | "
      << describe(f.first_500m_max_after_500m, 3) << " |\n";
  out << "\nOnline DR final %D with the start offset removed (its own drift): " << describe(f.drift_final, 3) << "\n";
}

// ---- sensitivity of VFF-LM-RLS (identification only: the DR does not depend on these settings
// except through K, which the K figures already measure) -----------------------------------------

struct Setting {
  std::string label;
  std::size_t window = 0;
  double kappa = 0.0;
  double lambda_min = 0.0;
};

json identification_summary(const odonav::Dataset& d, const odonav::offline::OfflineParams& params,
                            const std::vector<odonav::calibration::MisalignmentOutput>& misalignment) {
  odonav::identification::IdentificationParams ip = params.identification;
  ip.run_all_estimators = false;
  ip.estimator_name = "vff_lm_rls";
  ip.builder.use_ins = d.has_ins();
  odonav::identification::IdentificationCore core(ip);
  for (const auto& o : d.odometer) core.add_odometer(o);
  for (const auto& g : d.gnss) core.add_gnss(g);
  for (const auto& i : d.ins) core.add_ins(i);
  // Applied by the identification's own rule, as the pipeline applies them.
  for (const auto& m : misalignment) core.apply_misalignment(odonav::calibration::published_misalignment(m));
  odonav::results::OutputRows rows;
  for (const auto& k : core.finish())
    rows.scale_factor.push_back(odonav::identification::output_row(k, "vff_lm_rls", {}));
  return summary_of(d, rows, "terrain");
}

void run_sensitivity(const odonav::offline::OfflineParams& base, const odonav::Options& opts, std::size_t seeds,
                     uint64_t first_seed, std::ostream& out) {
  const odonav::ScaleFactorEstimatorParams& e = base.identification.estimator;
  std::vector<Setting> settings;
  const auto add = [&](const std::string& label, std::size_t window, double kappa, double lambda_min) {
    settings.push_back({label, window, kappa, lambda_min});
  };
  add("defaults", e.window_length, e.vff_kappa, e.lambda_min);
  for (std::size_t l : {25, 50, 200, 400})
    if (l != e.window_length) add("L = " + std::to_string(l), l, e.vff_kappa, e.lambda_min);
  for (double k : {0.5, 1.0, 2.0, 10.0, 30.0})
    if (k != e.vff_kappa) {
      std::ostringstream label;
      label << "kappa = " << k;
      add(label.str(), e.window_length, k, e.lambda_min);
    }
  for (double lm : {0.8, 0.9, 0.98, 1.0})
    if (lm != e.lambda_min) {
      std::ostringstream label;
      label << "lambda_min = " << lm;
      add(label.str(), e.window_length, e.vff_kappa, lm);
    }

  std::vector<EstimatorFigures> figures(settings.size());
  for (uint64_t seed = first_seed; seed < first_seed + seeds; ++seed) {
    const odonav::Dataset d = simulate("terrain", seed);
    odonav::offline::OfflineParams p = params_for(d, base, opts);
    p.identification.estimator = base.identification.estimator;
    odonav::calibration::MisalignmentCalibrator calibrator(p.calibration);
    for (const auto& g : d.gnss) calibrator.add_gnss(g);
    for (const auto& i : d.ins) calibrator.add_ins(i);
    const std::vector<odonav::calibration::MisalignmentOutput> misalignment = calibrator.finish();
    for (std::size_t i = 0; i < settings.size(); ++i) {
      odonav::offline::OfflineParams q = p;
      q.identification.estimator.window_length = settings[i].window;
      q.identification.estimator.vff_kappa = settings[i].kappa;
      q.identification.estimator.lambda_min = settings[i].lambda_min;
      const json s = identification_summary(d, q, misalignment);
      const json& est = s["scale_factor"]["estimators"]["vff_lm_rls"];
      figures[i].rms_percent.add(est.value("rms_rel_error_percent", json()));
      figures[i].converge_s.add(est.value("time_to_converge_s", json()));
      figures[i].settle_s.resize(1);
      for (const json& t : est.value("settle_times_s", json::array())) figures[i].settle_s[0].add(t);
    }
  }
  out << "\n### Sensitivity of VFF-LM-RLS on terrain (" << seeds << " seeds, one setting changed at a time; "
      << "settle: both K steps pooled; median [min, max])\n\n";
  out << "| setting | L | kappa (C = kappa sigma_y^2) | lambda_min | RMS K error (%) | converge (s) | settle after a step (s) |\n";
  out << "|---|---|---|---|---|---|---|\n";
  for (std::size_t i = 0; i < settings.size(); ++i) {
    out << "| " << settings[i].label << " | " << settings[i].window << " | " << settings[i].kappa << " | "
        << settings[i].lambda_min << " | " << describe(figures[i].rms_percent, 3) << " | "
        << describe(figures[i].converge_s, 1) << " | " << describe(figures[i].settle_s[0], 1) << " |\n";
  }
  // A one-line ranking to help read the table: steady-state noise against tracking speed.
  out << "\nmedian RMS x median settle (lower is a better trade-off):";
  for (std::size_t i = 0; i < settings.size(); ++i) {
    const double score = median_of_finite(figures[i].rms_percent) * median_of_finite(figures[i].settle_s[0]);
    out << (i ? "," : "") << " " << settings[i].label << " " << std::setprecision(3) << score
        << (count_never(figures[i].settle_s[0]) ? "*" : "");
  }
  out << "   (* some step never settled)\n";
}

}  // namespace

int main(int argc, char** argv) {
  odonav::Options opts("odonav-bench-accuracy",
                       "Accuracy benchmark: every estimator on every simulated scenario over several "
                       "seeds (median and range), DR %D with the online and the coarse K, and the sensitivity of "
                       "VFF-LM-RLS to L, C and lambda_min. Prints Markdown tables. Not a test.");
  odonav::bench::add_scenario_bench_options(
      opts, "straight,ring,terrain",
      "comma-separated scenarios to compare; variants: +<N>hz (GNSS rate), +lat<ms> (GNSS latency), e.g. "
      "terrain+1hz,terrain+lat100,slow_robot");
  opts.add_int("sensitivity-seeds", 3, "seeds of the sensitivity table on terrain (0: skip it)", 0, 1000);
  odonav::offline::OfflineParams base;
  if (const auto status = odonav::bench::parse_scenario_bench(opts, argc, argv, "bench-accuracy", base)) return *status;
  const odonav::bench::ScenarioRuns runs = odonav::bench::scenario_runs(opts);

  try {
    const auto t0 = std::chrono::steady_clock::now();
    std::map<std::string, ScenarioFigures> figures;
    for (uint64_t seed = runs.first_seed; seed < runs.first_seed + runs.seeds; ++seed) {
      // The coarse K of the DR comparison: S/N of the straight calibration run of the same seed, as a
      // crew would calibrate before the drive.
      const odonav::Dataset straight = simulate("straight", seed);
      const std::optional<double> coarse_k = odonav::offline::coarse_k_of(straight, params_for(straight, base, opts));
      for (const std::string& scenario : runs.scenarios) {
        const odonav::Dataset d = scenario == "straight" ? straight : simulate(scenario, seed);
        odonav::offline::OfflineParams p = params_for(d, base, opts);
        if (coarse_k) {
          p.coarse_k_m_per_pulse = *coarse_k;
          p.coarse_k_origin = "coarse S/N of straight";
        }
        const odonav::offline::OfflineResult r = odonav::offline::run_offline(d, p);
        const json s = summary_of(d, odonav::offline::to_output_rows(r, p.identification.estimator_name), scenario);
        collect(s, figures[scenario]);
        collect(odonav::offline::evaluate_first_metres(d, r.dr_online), figures[scenario]);
      }
      std::cerr << "seed " << seed << " done ("
                << std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() << " s)\n";
    }
    std::cout << "## Accuracy: estimators side by side (simulator truth; seeds " << runs.first_seed << ".."
              << runs.first_seed + runs.seeds - 1 << ")\n";
    std::cout << "\nK error figures as odonav-offline's summary defines them (steady state: after converging, "
                 "outside 10 s after each K step); settle = time after a K step until K stays within 0.5 % of "
                 "the new K; %D against the truth track.\n";
    for (const std::string& scenario : runs.scenarios)
      print_scenario(scenario, figures[scenario], runs.seeds, std::cout);
    const auto sensitivity_seeds = static_cast<std::size_t>(opts.get_int("sensitivity-seeds"));
    if (sensitivity_seeds > 0) run_sensitivity(base, opts, sensitivity_seeds, runs.first_seed, std::cout);
    std::cout << "\n(run time " << std::fixed << std::setprecision(1)
              << std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() << " s)\n";
  } catch (const std::exception& e) {
    std::cerr << "odonav-bench-accuracy: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
