// Cost of one update() of each scale-factor estimator, and of the naive alternative the O(1)
// window recursion replaces: re-solving the weighted window from scratch on every sample (O(L)).
// Run: build/bin/odonav-bench-estimators ; the reported time is per update.
#include <benchmark/benchmark.h>

#include <cmath>
#include <deque>
#include <random>
#include <string>
#include <vector>

#include "odonav/estimators.hpp"

namespace {

// A fixed cycle of realistic samples: ~80 pulses per 0.1 s, y noise 5 mm, positions along a line with
// a turn every 500 samples (so the coarse method opens and closes runs).
const std::vector<odonav::ScaleFactorSample>& sample_cycle() {
  static const std::vector<odonav::ScaleFactorSample> cycle = [] {
    std::mt19937_64 rng(1);
    std::uniform_real_distribution<double> phi(70.0, 90.0);
    std::normal_distribution<double> noise(0.0, 0.005);
    std::vector<odonav::ScaleFactorSample> out(4096);
    double x = 0.0;
    for (std::size_t i = 0; i < out.size(); ++i) {
      out[i].phi_pulses = std::round(phi(rng));
      out[i].y_m = 0.01 * out[i].phi_pulses + noise(rng);
      out[i].dt_s = 0.1;
      x += 0.01 * out[i].phi_pulses;
      out[i].gnss_position_enu_m = Eigen::Vector3d(x, 0.0, 0.0);
      out[i].straight = (i % 500) >= 5;
    }
    return out;
  }();
  return cycle;
}

void BM_EstimatorUpdate(benchmark::State& state, const std::string& name) {
  odonav::ScaleFactorEstimatorParams params;
  params.window_length = static_cast<std::size_t>(state.range(0));
  auto estimator = odonav::make_scale_factor_estimator(name, params);
  const auto& cycle = sample_cycle();
  std::size_t i = 0;
  double t = 0.0;
  for (auto _ : state) {
    odonav::ScaleFactorSample s = cycle[i];
    t += 0.1;
    s.t_s = t;
    estimator->update(s);
    benchmark::DoNotOptimize(estimator->estimate());
    i = (i + 1) % cycle.size();
  }
  state.SetItemsProcessed(state.iterations());
}

// The naive weighted window: keep the last L (phi, y, lambda) and re-solve K from scratch each
// update, weights as products of the lambdas (same VFF law, C fixed here to keep it simple).
void BM_NaiveWeightedWindowResolve(benchmark::State& state) {
  const std::size_t window = static_cast<std::size_t>(state.range(0));
  struct Held {
    double phi, y, lambda;
  };
  std::deque<Held> held;
  const auto& cycle = sample_cycle();
  std::size_t i = 0;
  double k = 0.0;
  double s_pp_prev = 0.0;
  const double c_m2 = 4.0 * (0.5 * std::pow(0.005, 2) + 0.01 * 0.01 / 6.0);
  for (auto _ : state) {
    const double phi = cycle[i].phi_pulses, y = cycle[i].y_m;
    double lambda = 1.0;
    if (held.size() == window && s_pp_prev > 0.0) {
      const double eps = y - k * phi;
      const double s = 1.0 + phi * phi / s_pp_prev;
      lambda = std::max(0.95, std::min(1.0, 1.0 - eps * eps / (s * static_cast<double>(window) * c_m2)));
    }
    if (held.size() == window) held.pop_front();
    held.push_back({phi, y, lambda});
    double weight = 1.0, s_pp = 0.0, s_py = 0.0;
    for (std::size_t j = held.size(); j-- > 0;) {  // newest first: weight = product of later lambdas
      s_pp += weight * held[j].phi * held[j].phi;
      s_py += weight * held[j].phi * held[j].y;
      weight *= held[j].lambda;
    }
    k = s_py / s_pp;
    s_pp_prev = s_pp;
    benchmark::DoNotOptimize(k);
    i = (i + 1) % cycle.size();
  }
  state.SetItemsProcessed(state.iterations());
}

}  // namespace

BENCHMARK_CAPTURE(BM_EstimatorUpdate, rls, std::string("rls"))->Arg(100);
BENCHMARK_CAPTURE(BM_EstimatorUpdate, ff_rls, std::string("ff_rls"))->Arg(100);
BENCHMARK_CAPTURE(BM_EstimatorUpdate, lm_rls, std::string("lm_rls"))->Arg(100)->Arg(1000);
BENCHMARK_CAPTURE(BM_EstimatorUpdate, vff_lm_rls, std::string("vff_lm_rls"))->Arg(100)->Arg(1000);
BENCHMARK_CAPTURE(BM_EstimatorUpdate, coarse, std::string("coarse"))->Arg(100);
BENCHMARK_CAPTURE(BM_EstimatorUpdate, kf_rw, std::string("kf_rw"))->Arg(100);
BENCHMARK(BM_NaiveWeightedWindowResolve)->Arg(100)->Arg(1000);
