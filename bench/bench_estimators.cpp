// Cost of one update() of each scale-factor estimator, and of the naive alternative the O(1)
// window recursion replaces: re-solving the weighted window from scratch on every sample (O(L));
// and the per-epoch cost of the other event-time cores: the sample builder per GNSS epoch, one dead
// reckoning step per odometer sample, the misalignment calibrator per GNSS epoch (each including
// the buffering of that epoch's inputs, as the DDS components and odonav-offline pay it).
// Run: build/bin/odonav-bench-estimators ; the reported time is per update / epoch / step.
#include <benchmark/benchmark.h>

#include <cmath>
#include <deque>
#include <random>
#include <string>
#include <vector>

#include "odonav/calibration/misalignment_calibrator.hpp"
#include "odonav/dead_reckoning/dead_reckoner.hpp"
#include "odonav/estimators.hpp"
#include "odonav/geodesy.hpp"
#include "odonav/sample_builder.hpp"

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

// ---- the event-time cores, fed a synthetic drive -------------------------------------------------
// A vehicle driving at 10 m/s on a gentle curve (0.5 deg/s, inside the straight-segment gates of the
// sample builder and the calibrator), odometer and INS at 100 Hz, GNSS at 10 Hz, K = 0.0125 m/pulse.
// Everything is generated on the fly from the time, so the benchmarks never run out of data.
struct SyntheticDrive {
  static constexpr double kSpeedMps = 10.0;
  static constexpr double kK = 0.0125;
  static constexpr double kYawRateRadS = 0.5 * odonav::kDegToRad;
  odonav::Geodetic position{52.5 * odonav::kDegToRad, 13.4 * odonav::kDegToRad, 80.0};
  double heading_rad = 0.5;
  double pulses = 1000.0;
  double t_s = 0.0;

  // Advances by dt and returns the odometer and INS samples at the new time.
  void step(double dt_s, odonav::OdometerSample& odo, odonav::InsSample& ins) {
    t_s += dt_s;
    heading_rad += kYawRateRadS * dt_s;
    const double d = kSpeedMps * dt_s;
    position =
        odonav::move_geodetic(position, Eigen::Vector3d(d * std::sin(heading_rad), d * std::cos(heading_rad), 0.0));
    pulses += d / kK;
    odo.t_s = t_s;
    odo.pulses = static_cast<uint32_t>(static_cast<uint64_t>(pulses) & 0xffffffffu);
    odo.direction = 1;
    ins.t_s = t_s;
    ins.attitude = odonav::Attitude{heading_rad, 0.0, 0.0};
  }
  // Advances by one GNSS period (10 steps of 10 ms), handing each step's odometer and INS samples
  // to on_step(odo, ins).
  template <class OnStep>
  void gnss_period(OnStep on_step) {
    odonav::OdometerSample odo;
    odonav::InsSample ins;
    for (int i = 0; i < 10; ++i) {
      step(0.01, odo, ins);
      on_step(odo, ins);
    }
  }
  odonav::GnssSample gnss() const {
    odonav::GnssSample g;
    g.t_s = t_s;
    g.position = position;
    g.vel_enu_mps = Eigen::Vector3d(kSpeedMps * std::sin(heading_rad), kSpeedMps * std::cos(heading_rad), 0.0);
    g.fix = 1;
    return g;
  }
};

// One GNSS epoch of the sample builder: buffering 10 odometer + 10 INS samples and the fix, then
// process_until (interpolation, projection, gates, the regression sample). Arg: 1 = lever arm on;
// 2 = lever arm on and a precise K estimate fed back every epoch, so that every accepted sample also
// enters the GNSS-latency sums (71 candidates: pulse rates, per-candidate K, the parabola fit).
void BM_SampleBuilderEpoch(benchmark::State& state) {
  odonav::SampleBuilderParams params;
  if (state.range(0) >= 1) params.lever_arm_body_m = Eigen::Vector3d(-0.5, 0.3, 2.2);
  const bool feed_k = state.range(0) >= 2;
  odonav::SampleBuilder builder(params);
  SyntheticDrive drive;
  std::size_t samples = 0;
  for (auto _ : state) {
    drive.gnss_period([&](const odonav::OdometerSample& odo, const odonav::InsSample& ins) {
      builder.add_odometer(odo);
      builder.add_ins(ins);
    });
    builder.add_gnss(drive.gnss());
    // The watermark lags one INS half-window behind, as it does in the components.
    for (const auto& epoch : builder.process_until(drive.t_s - 0.06)) {
      samples += epoch.sample.has_value();
      if (feed_k) builder.add_scale_factor_estimate(epoch.t_s, SyntheticDrive::kK, 1e-6);
    }
  }
  state.SetItemsProcessed(state.iterations());
  state.counters["accepted_fraction"] = static_cast<double>(samples) / static_cast<double>(state.iterations());
}

// One dead-reckoning step: one odometer + one INS sample (a GNSS fix every 10th), process_until:
// attitude interpolation, the rotation, the WGS-84 position update, ENU of the new position and
// the error against the GNSS reference interpolated between two fixes.
void BM_DeadReckonerStep(benchmark::State& state) {
  odonav::dead_reckoning::DeadReckonerParams params;
  params.lever_arm_body_m = Eigen::Vector3d(-0.5, 0.3, 2.2);
  odonav::dead_reckoning::DeadReckoner dr(params);
  SyntheticDrive drive;
  odonav::OdometerSample odo;
  odonav::InsSample ins;
  std::size_t outputs = 0, n = 0;
  for (auto _ : state) {
    drive.step(0.01, odo, ins);
    dr.add_odometer(odo);
    dr.add_ins(ins);
    if (++n % 10 == 0) dr.add_gnss(drive.gnss());
    outputs += dr.process_until(drive.t_s - 0.1).size();
  }
  state.SetItemsProcessed(state.iterations());
  state.counters["outputs_per_step"] = static_cast<double>(outputs) / static_cast<double>(state.iterations());
}

// One GNSS epoch of the misalignment calibrator: 10 INS samples and the fix buffered, one RLS update.
void BM_MisalignmentUpdate(benchmark::State& state) {
  odonav::calibration::MisalignmentCalibrator calibrator;
  SyntheticDrive drive;
  std::size_t outputs = 0;
  for (auto _ : state) {
    drive.gnss_period([&](const odonav::OdometerSample&, const odonav::InsSample& ins) { calibrator.add_ins(ins); });
    calibrator.add_gnss(drive.gnss());
    outputs += calibrator.process_until(drive.t_s - 0.3).size();
  }
  state.SetItemsProcessed(state.iterations());
  state.counters["outputs_per_epoch"] = static_cast<double>(outputs) / static_cast<double>(state.iterations());
}

}  // namespace

BENCHMARK_CAPTURE(BM_EstimatorUpdate, rls, std::string("rls"))->Arg(100);
BENCHMARK_CAPTURE(BM_EstimatorUpdate, ff_rls, std::string("ff_rls"))->Arg(100);
BENCHMARK_CAPTURE(BM_EstimatorUpdate, lm_rls, std::string("lm_rls"))->Arg(100)->Arg(1000);
BENCHMARK_CAPTURE(BM_EstimatorUpdate, vff_lm_rls, std::string("vff_lm_rls"))->Arg(100)->Arg(1000);
BENCHMARK_CAPTURE(BM_EstimatorUpdate, coarse, std::string("coarse"))->Arg(100);
BENCHMARK_CAPTURE(BM_EstimatorUpdate, kf_rw, std::string("kf_rw"))->Arg(100);
BENCHMARK(BM_NaiveWeightedWindowResolve)->Arg(100)->Arg(1000);
BENCHMARK(BM_SampleBuilderEpoch)->Arg(0)->Arg(1)->Arg(2);
BENCHMARK(BM_DeadReckonerStep);
BENCHMARK(BM_MisalignmentUpdate);
