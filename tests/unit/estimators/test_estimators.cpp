// Scale-factor estimators: each recursive estimator against a brute-force weighted batch least-squares
// solution after every update, the O(1) window sums against an exact re-summation after 10^7
// samples, tracking of a 3 % step of K (windows and the Kalman filter recover, growing-memory RLS
// does not), the VFF law recomputed independently, the coarse S/N method on exact geometry, sigma
// calibration, the factory and parameter errors, and save/restore.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <cmath>
#include <cstdio>
#include <functional>
#include <memory>
#include <optional>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "odonav/checkpoint_state.hpp"
#include "odonav/estimators.hpp"

using namespace odonav;

namespace {

ScaleFactorSample make_sample(double t_s, double phi, double y, double dt_s = 0.1) {
  ScaleFactorSample s;
  s.t_s = t_s;
  s.phi_pulses = phi;
  s.y_m = y;
  s.dt_s = dt_s;
  return s;
}

// A drive at 10 Hz with real pulse quantisation: the pulse counter accumulates distance / K(t) and
// phi is the increment of its integer part; y is the true distance plus Gaussian noise (the GNSS
// velocity error). Speed ~8 m/s with K = 0.01 m/pulse gives phi ~ 80 pulses.
struct Drive {
  std::vector<ScaleFactorSample> samples;
  std::vector<double> k_true;
};

Drive simulate_drive(std::size_t n, double k0, std::size_t step_at, double step_rel, double sigma_y_m, unsigned seed,
                     bool quantise = true) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, sigma_y_m);
  std::uniform_real_distribution<double> speed_jitter(-0.5, 0.5);
  Drive d;
  double counter = 0.0;
  double previous_count = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double k = i >= step_at ? k0 * (1.0 + step_rel) : k0;
    const double distance_m = (8.0 + speed_jitter(rng)) * 0.1;
    counter += distance_m / k;
    const double count = quantise ? std::floor(counter) : counter;
    d.samples.push_back(make_sample(0.1 * static_cast<double>(i + 1), count - previous_count, distance_m + noise(rng)));
    d.k_true.push_back(k);
    previous_count = count;
  }
  return d;
}

double relative_error(double value, double reference) { return std::abs(value - reference) / std::abs(reference); }

// Brute-force weighted batch least squares: K = (w0 K0 + sum w phi y) / (w0 + sum w phi^2).
struct BatchSums {
  double s_pp = 0.0;
  double s_py = 0.0;
};
BatchSums batch_sums(const std::vector<ScaleFactorSample>& samples, const std::vector<double>& weights) {
  BatchSums b;
  for (std::size_t i = 0; i < samples.size(); ++i) {
    b.s_pp += weights[i] * samples[i].phi_pulses * samples[i].phi_pulses;
    b.s_py += weights[i] * samples[i].phi_pulses * samples[i].y_m;
  }
  return b;
}

// Random regression data with jumps of K (so the VFF really varies lambda) and occasional outliers.
std::vector<ScaleFactorSample> random_regression_data(std::size_t n, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> phi(30.0, 130.0);
  std::normal_distribution<double> noise(0.0, 0.004);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<ScaleFactorSample> out;
  for (std::size_t i = 0; i < n; ++i) {
    const double k = i < n / 3 ? 0.0100 : i < 2 * n / 3 ? 0.0105 : 0.0102;
    const double p = phi(rng);
    double y = k * p + noise(rng);
    if (unit(rng) < 0.02) y += 0.05;  // GNSS velocity outlier
    out.push_back(make_sample(0.1 * static_cast<double>(i + 1), p, y));
  }
  return out;
}

// Weights of each estimator over samples 0..k (inclusive), product-wise from the applied lambdas.
std::vector<double> brute_force_weights(const std::string& name, std::size_t k, std::size_t window, double ff_lambda,
                                        const std::vector<double>& applied_lambda) {
  std::vector<double> w(k + 1, 0.0);
  for (std::size_t i = 0; i <= k; ++i) {
    if (name == "rls") {
      w[i] = 1.0;
    } else if (name == "ff_rls") {
      double product = 1.0;
      for (std::size_t j = i + 1; j <= k; ++j) product *= ff_lambda;
      w[i] = product;
    } else if (name == "lm_rls") {
      w[i] = (k - i < window) ? 1.0 : 0.0;
    } else {  // vff_lm_rls: in the window, the product of the lambdas applied after it entered
      if (k - i >= window) continue;
      double product = 1.0;
      for (std::size_t j = i + 1; j <= k; ++j) product *= applied_lambda[j];
      w[i] = product;
    }
  }
  return w;
}

}  // namespace

// ---------------------------------------------------------------------------------------------------
// Exactness against brute-force weighted batch LS after every update.

class BatchEquivalence : public ::testing::TestWithParam<std::tuple<std::string, bool>> {};

TEST_P(BatchEquivalence, EqualsWeightedBatchLeastSquaresAfterEveryUpdate) {
  const auto& [name, with_prior] = GetParam();
  ScaleFactorEstimatorParams params;
  params.window_length = 50;
  params.forgetting_factor = 0.97;
  params.resum_interval = 37;  // not a divisor of anything here: re-summation at odd moments
  if (with_prior) {
    params.k_prior_m_per_pulse = 0.011;
    params.prior_weight_pulses2 = 500.0;
  }
  const double w0 = params.prior_weight_pulses2;
  const double k0 = params.k_prior_m_per_pulse;
  auto estimator = make_scale_factor_estimator(name, params);
  const std::vector<ScaleFactorSample> data = random_regression_data(600, 11);
  std::vector<double> applied_lambda;
  for (std::size_t k = 0; k < data.size(); ++k) {
    estimator->update(data[k]);
    const ScaleFactorEstimate e = estimator->estimate();
    applied_lambda.push_back(e.forgetting_factor);
    const std::vector<ScaleFactorSample> seen(data.begin(), data.begin() + static_cast<long>(k) + 1);
    const BatchSums b =
        batch_sums(seen, brute_force_weights(name, k, params.window_length, params.forgetting_factor, applied_lambda));
    const double k_batch = (w0 * k0 + b.s_py) / (w0 + b.s_pp);
    ASSERT_TRUE(e.valid) << name << " sample " << k;
    ASSERT_LT(relative_error(e.k_m_per_pulse, k_batch), 1e-9) << name << " sample " << k;
    EXPECT_EQ(e.samples_used, k + 1);
    if (auto* window = dynamic_cast<WindowRlsEstimator*>(estimator.get())) {
      ASSERT_LT(relative_error(window->window_sums().s_pp, b.s_pp), 1e-9) << name << " sample " << k;
      EXPECT_EQ(window->window_sums().held, std::min<std::size_t>(k + 1, params.window_length));
      EXPECT_DOUBLE_EQ(e.window_fill, static_cast<double>(std::min<std::size_t>(k + 1, 50)) / 50.0);
    }
  }
  if (name == "vff_lm_rls") {
    // The brute force above is only meaningful if lambda really varied.
    const double smallest = *std::min_element(applied_lambda.begin(), applied_lambda.end());
    const auto below_one =
        std::count_if(applied_lambda.begin(), applied_lambda.end(), [](double l) { return l < 1.0; });
    EXPECT_LE(smallest, params.lambda_min + 1e-15);
    EXPECT_GT(below_one, 100);
  }
}

INSTANTIATE_TEST_SUITE_P(AllRecursive, BatchEquivalence,
                         ::testing::Combine(::testing::Values("rls", "ff_rls", "lm_rls", "vff_lm_rls"),
                                            ::testing::Bool()),
                         [](const auto& info) {
                           return std::get<0>(info.param) + (std::get<1>(info.param) ? "_prior" : "_no_prior");
                         });

TEST(VffLmRls, ForgettingFactorFollowsTheFortescueLawComputedIndependently) {
  // lambda_k = clamp(1 - eps^2 / (s L C), lambda_min, 1) once L samples are held, with the a-priori
  // error and s from the brute-force weighted sums before sample k, and C from the documented model.
  for (double c_m2 : {0.0, 2e-4}) {
    ScaleFactorEstimatorParams params;
    params.window_length = 40;
    params.vff_c_m2 = c_m2;
    VffLmRlsEstimator estimator(params);
    const std::vector<ScaleFactorSample> data = random_regression_data(400, 5);
    std::vector<double> applied;
    for (std::size_t k = 0; k < data.size(); ++k) {
      double expected = 1.0;
      if (k >= params.window_length) {
        const std::vector<ScaleFactorSample> seen(data.begin(), data.begin() + static_cast<long>(k));
        const BatchSums b =
            batch_sums(seen, brute_force_weights("vff_lm_rls", k - 1, params.window_length, 1.0, applied));
        const double k_prev = b.s_py / b.s_pp;
        const double eps = data[k].y_m - k_prev * data[k].phi_pulses;
        const double s = 1.0 + data[k].phi_pulses * data[k].phi_pulses / b.s_pp;
        const double sigma_y2 = std::max(std::pow(0.05 * 0.1, 2) / 2.0 + k_prev * k_prev / 6.0, 1e-6);
        const double c = c_m2 > 0.0 ? c_m2 : 4.0 * sigma_y2;
        expected = std::clamp(1.0 - eps * eps / (s * 40.0 * c), 0.95, 1.0);
      }
      estimator.update(data[k]);
      applied.push_back(estimator.estimate().forgetting_factor);
      ASSERT_NEAR(applied.back(), expected, 1e-9) << "sample " << k << " C " << c_m2;
    }
  }
}

// ---------------------------------------------------------------------------------------------------
// Long-run numerical stability: 10^7 samples, O(1) sums against an exact re-summation.

namespace {
// splitmix64: a cheap, fixed-seed generator so 10^7 samples cost little beyond the estimator.
struct FastUniform {
  uint64_t state;
  double operator()() {  // uniform in [-1, 1)
    uint64_t z = (state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    z ^= z >> 31;
    return static_cast<double>(z >> 11) * 0x1.0p-52 - 1.0;
  }
};

void run_ten_million(const std::string& name) {
  ScaleFactorEstimatorParams params;  // L = 100, M = L, lambda_min = 0.95
  auto estimator = make_scale_factor_estimator(name, params);
  auto* window = dynamic_cast<WindowRlsEstimator*>(estimator.get());
  ASSERT_NE(window, nullptr);
  FastUniform unit{2024};
  double k_true = 0.01;
  double max_abs_log_weight = 0.0;
  std::size_t lambda_below_one = 0;
  // 99 samples past a multiple of M: the sums have been downdated 99 times since the last
  // re-summation, the worst point of the cycle.
  const std::size_t n = 10000000 + 99;
  for (std::size_t i = 0; i < n; ++i) {
    if (i % 100000 == 0) k_true = 0.01 * (1.0 + 0.03 * unit());  // steps keep the VFF working
    const double phi = 80.0 + 10.0 * unit();
    estimator->update(make_sample(0.1 * static_cast<double>(i + 1), phi, k_true * phi + 0.0087 * unit()));
    if ((i & 15) == 0) {
      max_abs_log_weight = std::max(max_abs_log_weight, std::abs(window->log_weight()));
      if (estimator->estimate().forgetting_factor < 1.0) ++lambda_below_one;
    }
  }
  const WindowSums fast = window->window_sums();
  const WindowSums exact = window->exact_window_sums();
  EXPECT_LT(relative_error(fast.s_pp, exact.s_pp), 1e-9) << name;
  EXPECT_LT(relative_error(fast.s_py, exact.s_py), 1e-9) << name;
  EXPECT_LT(relative_error(fast.s_py / fast.s_pp, exact.s_py / exact.s_pp), 1e-9) << name;
  EXPECT_LT(relative_error(estimator->estimate().k_m_per_pulse, k_true), 2e-3) << name;
  // Re-basing keeps Lambda within M |ln lambda_min| (M = L = 100).
  EXPECT_LE(max_abs_log_weight, 100.0 * std::abs(std::log(0.95)) + 1e-9) << name;
  if (name == "vff_lm_rls") {
    EXPECT_GT(lambda_below_one, 1000u) << "the law was active, not a bare window";
    EXPECT_GT(max_abs_log_weight, 0.0);
  }
  std::printf("[ info ] %s after %zu samples: |dS_pp|/S_pp = %.3g, |dS_py|/S_py = %.3g, max|Lambda| = %.3g\n",
              name.c_str(), n, relative_error(fast.s_pp, exact.s_pp), relative_error(fast.s_py, exact.s_py),
              max_abs_log_weight);
}
}  // namespace

TEST(WindowRls, LmRlsTenMillionSamplesStayWithin1e9OfExactResummation) { run_ten_million("lm_rls"); }
TEST(WindowRls, VffLmRlsTenMillionSamplesStayWithin1e9OfExactResummation) { run_ten_million("vff_lm_rls"); }

// ---------------------------------------------------------------------------------------------------
// Tracking a 3 % step of K.

TEST(Tracking, WindowsRecoverFromA3PercentStepWithinLSamplesGrowingRlsDoesNot) {
  const std::size_t step_at = 3000;  // 300 s of steady driving first: RLS is saturated by then
  const double k0 = 0.01;
  const Drive drive = simulate_drive(step_at + 1000, k0, step_at, 0.03, 0.005, 77);
  ScaleFactorEstimatorParams params;                                // L = 100
  const std::size_t check_at = step_at + params.window_length - 1;  // the L-th sample after the step
  std::vector<std::string> names = {"rls", "lm_rls", "vff_lm_rls", "kf_rw"};
  for (const std::string& name : names) {
    auto estimator = make_scale_factor_estimator(name, params);
    double lambda_min_seen = 1.0, lambda_min_after_step = 1.0;
    double first_lambda_below_one_at = -1.0;
    std::size_t settled_at = 0;  // first sample after the step from which |error| < 0.5 % for good
    for (std::size_t i = 0; i < drive.samples.size(); ++i) {
      estimator->update(drive.samples[i]);
      const ScaleFactorEstimate e = estimator->estimate();
      lambda_min_seen = std::min(lambda_min_seen, e.forgetting_factor);
      if (i >= step_at && i <= check_at) lambda_min_after_step = std::min(lambda_min_after_step, e.forgetting_factor);
      if (e.forgetting_factor < 1.0 && first_lambda_below_one_at < 0.0)
        first_lambda_below_one_at = static_cast<double>(i);
      if (i >= step_at && relative_error(e.k_m_per_pulse, drive.k_true[i]) >= 0.005) settled_at = i + 1;
      if (i == step_at - 1) {
        EXPECT_LT(relative_error(e.k_m_per_pulse, k0), 0.004) << name << " before the step";
      }
      if (i == check_at) {
        const double error = relative_error(e.k_m_per_pulse, drive.k_true[i]);
        std::printf("[ info ] %s: relative K error %zu samples after the 3 %% step: %.4f %%\n", name.c_str(),
                    params.window_length, 100.0 * error);
        if (name == "rls") {
          EXPECT_GT(error, 0.02) << "growing-memory RLS must still be far off (data saturation)";
        } else {
          EXPECT_LT(error, 0.005) << name;
        }
      }
    }
    std::printf("[ info ] %s: within 0.5 %% for good from %zu samples after the step\n", name.c_str(),
                settled_at - step_at);
    if (name != "rls") {
      EXPECT_LE(settled_at - step_at, params.window_length) << name;
    }
    if (name == "vff_lm_rls") {
      EXPECT_GE(first_lambda_below_one_at, static_cast<double>(params.window_length))
          << "lambda must be 1 while the window fills";
      EXPECT_LT(lambda_min_after_step, 0.99) << "the step must pull lambda down";
      EXPECT_GE(lambda_min_seen, params.lambda_min);
    }
  }
}

namespace {
// The same 8 m/s drive sampled every interval_s: phi and y are the distance over the interval, the
// noise on y is the GNSS velocity noise (0.05 m/s, the estimators' default model) times the interval.
// Returns the time (s) after a 3 % K step at 300 s until VFF-LM-RLS stays within 0.5 % of the new K.
double vff_settle_time_s(double interval_s, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, 0.05 * interval_s / std::sqrt(2.0));
  const double k0 = 0.01;
  const auto n = static_cast<std::size_t>(std::lround(600.0 / interval_s));
  const auto step_at = static_cast<std::size_t>(std::lround(300.0 / interval_s));
  ScaleFactorEstimatorParams params;  // defaults: L = 100, lambda_min 0.95, reference interval 0.1 s
  VffLmRlsEstimator estimator(params);
  double counter = 0.0, previous = 0.0, settled_at_s = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double k = i >= step_at ? k0 * 1.03 : k0;
    const double distance_m = 8.0 * interval_s;
    counter += distance_m / k;
    const double count = std::floor(counter);
    const double t_s = interval_s * static_cast<double>(i + 1);
    estimator.update(make_sample(t_s, count - previous, distance_m + noise(rng), interval_s));
    previous = count;
    if (i >= step_at && relative_error(estimator.estimate().k_m_per_pulse, k) >= 0.005) settled_at_s = t_s;
  }
  return settled_at_s - interval_s * static_cast<double>(step_at);
}
}  // namespace

TEST(Tracking, VffForgetsPerSecondSoAStepSettlesInAboutTheSameTimeAtOneAndTenHertz) {
  // The law's memory and its clamp count in reference intervals (0.1 s), not in samples: at 1 Hz a
  // per-sample clamp of 0.95 and memory of 100 samples settled a step ten times slower in time.
  for (unsigned seed : {1u, 2u, 3u}) {
    const double at_10hz = vff_settle_time_s(0.1, seed);
    const double at_1hz = vff_settle_time_s(1.0, seed);
    std::printf("[ info ] seed %u: 3 %% step settles in %.1f s at 10 Hz, %.1f s at 1 Hz\n", seed, at_10hz, at_1hz);
    EXPECT_GT(at_10hz, 0.0);
    EXPECT_LE(at_10hz, 10.0);
    EXPECT_LE(at_1hz, 2.0 * at_10hz + 2.0) << "seed " << seed;
  }
}

TEST(ChangeDetector, ASustainedBiasFiresOnceAndNamesTheSampleWhereItsRunBegan) {
  CusumChangeDetector detector(12.0, 0.5);
  // One 10-sigma outlier: 10 - 0.5 stays below 12, no change; the drift empties the sum in 19 samples.
  for (uint64_t i = 0; i < 50; ++i) EXPECT_FALSE(detector.add(i == 20 ? 10.0 : 0.0, i));
  EXPECT_EQ(detector.statistic(), 0.0);
  // From sample 50 on a bias of +2 sigma: the high side gains 1.5 per sample and passes 12 at the
  // ninth (13.5); the change began at 50 (the sample after the side was last at 0).
  std::optional<uint64_t> began;
  uint64_t fired_at = 0;
  for (uint64_t i = 50; i < 70 && !began; ++i) {
    began = detector.add(2.0, i);
    fired_at = i;
  }
  ASSERT_TRUE(began.has_value());
  EXPECT_EQ(fired_at, 58u);
  EXPECT_EQ(*began, 50u);
  EXPECT_EQ(detector.statistic(), 0.0) << "both sums restart after a change";
  EXPECT_EQ(detector.changes_detected(), 1u);
  // The low side the same way, from sample 100.
  for (uint64_t i = 70; i < 100; ++i) EXPECT_FALSE(detector.add(0.0, i));
  began.reset();
  for (uint64_t i = 100; i < 120 && !began; ++i) began = detector.add(-2.0, i);
  ASSERT_TRUE(began.has_value());
  EXPECT_EQ(*began, 100u);
  EXPECT_EQ(detector.changes_detected(), 2u);
}

namespace {
// A drive sampled every interval_s with a 3 % K step at 300 s, GNSS velocity noise 0.05 m/s (y
// carries 0.05 T / sqrt(2)) and real pulse quantisation, through VFF-LM-RLS with `params`. Like the
// simulator's terrain drive, the step comes on a slow stretch: 12 m/s until 290 s, 5 m/s after,
// so the samples from before the step weigh (12/5)^2 times more in the sums than those after it.
// Returns the relative K error after every sample; `changes` the changes its detector found, and
// `check` (if set) is called after every update with the sample (for save/restore).
using StepDriveCheck = std::function<void(std::size_t, const ScaleFactorSample&, VffLmRlsEstimator&)>;
std::vector<double> vff_step_drive(double interval_s, const ScaleFactorEstimatorParams& params, unsigned seed,
                                   uint64_t* changes = nullptr, const StepDriveCheck& check = {}) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0.0, 0.05 * interval_s / std::sqrt(2.0));
  const double k0 = 0.01;
  const auto n = static_cast<std::size_t>(std::lround(600.0 / interval_s));
  const auto step_at = static_cast<std::size_t>(std::lround(300.0 / interval_s));
  VffLmRlsEstimator estimator(params);
  std::vector<double> errors;
  double counter = 0.0, previous = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double k = i >= step_at ? k0 * 1.03 : k0;
    const double speed_mps = interval_s * static_cast<double>(i) < 290.0 ? 12.0 : 5.0;
    const double distance_m = speed_mps * interval_s;
    counter += distance_m / k;
    const double count = std::floor(counter);
    const ScaleFactorSample sample =
        make_sample(interval_s * static_cast<double>(i + 1), count - previous, distance_m + noise(rng), interval_s);
    estimator.update(sample);
    previous = count;
    if (check) check(i, sample, estimator);
    errors.push_back(estimator.estimate().k_m_per_pulse / k - 1.0);
  }
  if (changes) *changes = estimator.changes_detected();
  return errors;
}

// RMS of errors[i] for the samples i whose time (interval_s (i + 1)) lies in [from_s, to_s).
double rms_between(const std::vector<double>& errors, double interval_s, double from_s, double to_s) {
  double sum = 0.0;
  std::size_t n = 0;
  for (std::size_t i = 0; i < errors.size(); ++i) {
    const double t = interval_s * static_cast<double>(i + 1);
    if (t >= from_s && t < to_s) {
      sum += errors[i] * errors[i];
      ++n;
    }
  }
  return std::sqrt(sum / static_cast<double>(n));
}
}  // namespace

TEST(Tracking, VffChangeDetectorRemovesTheStepTailAtOneHertzAndLeavesTenHertzAlone) {
  // At 1 Hz the VFF law stops forgetting once the residuals look like noise, while its window
  // still holds the samples from before the step: K lags by tenths of a percent for tens of
  // seconds. The detector cuts the window back to the samples since the change began.
  ScaleFactorEstimatorParams with;  // defaults: threshold 12, drift 0.5
  ScaleFactorEstimatorParams without;
  without.vff_change_threshold = 0.0;
  for (unsigned seed : {1u, 2u, 3u}) {
    uint64_t changes = 0;
    const std::vector<double> cut = vff_step_drive(1.0, with, seed, &changes);
    const std::vector<double> law_only = vff_step_drive(1.0, without, seed);
    // 10-40 s after the step: the tail; 100-300 s: steady state (no false alarm may cost noise there).
    const double tail_cut = rms_between(cut, 1.0, 310.0, 340.0), tail_law = rms_between(law_only, 1.0, 310.0, 340.0);
    const double steady_cut = rms_between(cut, 1.0, 100.0, 300.0);
    const double steady_law = rms_between(law_only, 1.0, 100.0, 300.0);
    std::printf(
        "[ info ] seed %u at 1 Hz: tail RMS %.3f %% with the detector, %.3f %% without; steady %.3f / %.3f %%; "
        "%llu change(s)\n",
        seed, 100 * tail_cut, 100 * tail_law, 100 * steady_cut, 100 * steady_law,
        static_cast<unsigned long long>(changes));
    EXPECT_EQ(changes, 1u) << "seed " << seed << ": the step, and no false alarm in 600 s";
    EXPECT_LT(tail_cut, 0.5 * tail_law) << "seed " << seed;
    EXPECT_EQ(steady_cut, steady_law) << "seed " << seed << ": nothing changes before the step";
  }
  // At 10 Hz the window (L samples) is no longer than the detector's floor (L reference intervals):
  // the detector may fire, but it never cuts, and the estimates are those of the law alone.
  uint64_t changes_10hz = 0;
  EXPECT_EQ(vff_step_drive(0.1, with, 1, &changes_10hz), vff_step_drive(0.1, without, 1));
  EXPECT_GE(changes_10hz, 1u);
}

TEST(SaveRestore, VffRestoredWhileTheDetectorIsCountingContinuesBitIdentically) {
  // Saved two samples after a 1 Hz step, while the CUSUM is part-way to its threshold: the restored
  // estimator must fire at the same sample and cut the window at the same place.
  ScaleFactorEstimatorParams params;
  std::unique_ptr<VffLmRlsEstimator> restored;
  std::size_t compared = 0;
  vff_step_drive(1.0, params, 1, nullptr, [&](std::size_t i, const ScaleFactorSample& sample, VffLmRlsEstimator& e) {
    if (i == 301) {
      const StateJson saved = e.save_state();
      EXPECT_TRUE(saved.at("change_detector").contains("high_start"));
      EXPECT_GT(e.estimate().forgetting_factor, 0.0);
      restored = std::make_unique<VffLmRlsEstimator>(params);
      restored->restore_state(saved);
      EXPECT_EQ(restored->save_state(), saved);
    } else if (i > 301) {
      restored->update(sample);
      EXPECT_EQ(restored->estimate().k_m_per_pulse, e.estimate().k_m_per_pulse) << "sample " << i;
      EXPECT_EQ(restored->changes_detected(), e.changes_detected()) << "sample " << i;
      ++compared;
    }
  });
  EXPECT_EQ(compared, 298u);
  ASSERT_TRUE(restored);
  EXPECT_EQ(restored->changes_detected(), 1u);
}

TEST(Tracking, KalmanRandomWalkIsQuieterThanTheWindowInSteadyStateAndDetectsTheStepOnce) {
  const std::size_t step_at = 3000;
  const Drive drive = simulate_drive(6000, 0.01, step_at, 0.03, 0.005, 4242);
  ScaleFactorEstimatorParams params;
  LmRlsEstimator window(params);
  KfRandomWalkEstimator kalman(params);
  double window_sq = 0.0, kalman_sq = 0.0;
  std::size_t n = 0;
  uint64_t changes_before_step = 0;
  for (std::size_t i = 0; i < drive.samples.size(); ++i) {
    window.update(drive.samples[i]);
    kalman.update(drive.samples[i]);
    if (i == step_at - 1) changes_before_step = kalman.changes_detected();
    const bool steady = (i >= 1000 && i < step_at) || i >= step_at + 1000;
    if (steady) {
      window_sq += std::pow(window.estimate().k_m_per_pulse / drive.k_true[i] - 1.0, 2);
      kalman_sq += std::pow(kalman.estimate().k_m_per_pulse / drive.k_true[i] - 1.0, 2);
      ++n;
    }
  }
  const double window_rms = std::sqrt(window_sq / static_cast<double>(n));
  const double kalman_rms = std::sqrt(kalman_sq / static_cast<double>(n));
  std::printf("[ info ] steady-state relative K rms: lm_rls %.5f %%, kf_rw %.5f %%\n", 100 * window_rms,
              100 * kalman_rms);
  EXPECT_LT(kalman_rms, 0.5 * window_rms);
  EXPECT_EQ(changes_before_step, 0u) << "no false alarm in 300 s of steady driving";
  EXPECT_EQ(kalman.changes_detected(), 1u);
}

// ---------------------------------------------------------------------------------------------------
// Sigma and convergence.

TEST(Sigma, ReportedSigmaMatchesTheScatterOverIndependentRuns) {
  // Without pulse quantisation the residuals are white: sigma_y must be found online (~0.005 m) and
  // sigma_K must describe the actual scatter of K over 300 independent runs. With quantisation the
  // residuals also carry K (frac_{k-1} - frac_k): variance K^2/6 per sample, but consecutive terms
  // cancel in the sums (a cumulative counter loses no pulse), so sigma_K is then conservative.
  ScaleFactorEstimatorParams params;
  params.sigma_y_ewma_alpha = 0.01;
  for (const bool quantise : {false, true}) {
    const double expected_sigma_y = std::sqrt(0.005 * 0.005 + (quantise ? 0.01 * 0.01 / 6.0 : 0.0));
    double sum_sq_error = 0.0, sum_sigma = 0.0, sum_sigma_y = 0.0;
    const int runs = 300;
    for (int r = 0; r < runs; ++r) {
      const Drive drive = simulate_drive(150, 0.01, 1000000, 0.0, 0.005, 1000 + static_cast<unsigned>(r), quantise);
      RlsEstimator rls(params);
      for (const ScaleFactorSample& s : drive.samples) rls.update(s);
      const ScaleFactorEstimate e = rls.estimate();
      sum_sq_error += std::pow(e.k_m_per_pulse - 0.01, 2);
      sum_sigma += e.sigma_m_per_pulse;
      sum_sigma_y += e.sigma_m_per_pulse * std::sqrt(rls.data_s_pp());
    }
    const double scatter = std::sqrt(sum_sq_error / runs);
    const double mean_sigma = sum_sigma / runs;
    std::printf(
        "[ info ] RLS over 150 samples, quantised %d: K scatter %.3g, mean reported sigma %.3g m/pulse, "
        "mean sigma_y %.4g m\n",
        quantise, scatter, mean_sigma, sum_sigma_y / runs);
    EXPECT_NEAR(sum_sigma_y / runs, expected_sigma_y, 0.05 * expected_sigma_y) << quantise;
    if (quantise) {
      EXPECT_GT(mean_sigma / scatter, 1.0);
      EXPECT_LT(mean_sigma / scatter, 1.0 * expected_sigma_y / 0.005 + 0.15);
    } else {
      EXPECT_NEAR(mean_sigma / scatter, 1.0, 0.12);
    }
  }
}

TEST(Sigma, ConvergedNeedsSmallRelativeSigmaAndMinSamples) {
  // sigma_K / K ~ 0.0065 / (80 sqrt(n)) / 0.01 < 0.001 needs n > ~66 samples.
  const Drive drive = simulate_drive(300, 0.01, 1000000, 0.0, 0.005, 9);
  ScaleFactorEstimatorParams params;
  RlsEstimator rls(params);
  std::size_t converged_at = 0;
  for (std::size_t i = 0; i < drive.samples.size(); ++i) {
    rls.update(drive.samples[i]);
    const ScaleFactorEstimate e = rls.estimate();
    const bool rule = e.samples_used >= params.min_samples && e.sigma_m_per_pulse / e.k_m_per_pulse < 0.001;
    EXPECT_EQ(e.converged, rule);
    if (e.converged && converged_at == 0) converged_at = i + 1;
  }
  EXPECT_GT(converged_at, 40u);
  EXPECT_LT(converged_at, 110u);
  // A huge floor makes convergence impossible; min_samples blocks it on few clean samples.
  params.sigma_y_floor_m = 1.0;
  RlsEstimator floored(params);
  for (const ScaleFactorSample& s : drive.samples) floored.update(s);
  EXPECT_FALSE(floored.estimate().converged);
  ScaleFactorEstimatorParams few;
  few.min_samples = 50;
  RlsEstimator clean(few);
  for (int i = 0; i < 49; ++i) clean.update(make_sample(0.1 * (i + 1), 80000.0, 800.0));
  EXPECT_FALSE(clean.estimate().converged);
  clean.update(make_sample(5.0, 80000.0, 800.0));
  EXPECT_TRUE(clean.estimate().converged);
}

TEST(Estimators, InvalidUntilTheFirstSampleAndAfterReset) {
  ScaleFactorEstimatorParams params;
  params.prior_weight_pulses2 = 1.0;
  params.k_prior_m_per_pulse = 0.0125;
  for (const std::string& name : estimator_names()) {
    auto estimator = make_scale_factor_estimator(name, params);
    EXPECT_FALSE(estimator->estimate().valid) << name;
    EXPECT_EQ(estimator->name(), name);
    if (name == "coarse") continue;
    estimator->update(make_sample(0.1, 80.0, 0.8));
    EXPECT_TRUE(estimator->estimate().valid) << name;
    // One sample at 80 pulses and a weight-1 prior: K = (0.0125 + 80 * 0.8) / (1 + 6400).
    if (name != "kf_rw") {
      EXPECT_NEAR(estimator->estimate().k_m_per_pulse, (0.0125 + 64.0) / 6401.0, 1e-15) << name;
    }
    estimator->reset();
    EXPECT_FALSE(estimator->estimate().valid) << name;
    EXPECT_EQ(estimator->estimate().samples_used, 0u) << name;
  }
}

// ---------------------------------------------------------------------------------------------------
// Coarse S/N.

TEST(Coarse, StraightRunsGiveKEqualsSOverNExactly) {
  // Exact geometry: along each straight leg the GNSS position advances K * (pulses) along a fixed
  // 3-D direction, so every rightly delimited run has S / N = K. Any wrong rule (counting the first
  // sample's pulses without its start point, keeping pulses across a gap, bridging a turn) changes K.
  const double k = 0.0123;
  ScaleFactorEstimatorParams params;  // coarse_min_length_m = 100
  CoarseEstimator coarse(params);
  std::mt19937 rng(3);
  std::uniform_int_distribution<int> pulses(60, 90);
  Eigen::Vector3d position(1000.0, -200.0, 30.0);
  double t = 50.0;
  double expected_s = 0.0, expected_n = 0.0;
  auto leg = [&](const Eigen::Vector3d& direction, int count, bool straight, bool counted_run, bool skip_first) {
    for (int i = 0; i < count; ++i) {
      const double phi = pulses(rng);
      t += 0.1;
      position += direction.normalized() * (k * phi);
      ScaleFactorSample s = make_sample(t, phi, k * phi);
      s.gnss_position_enu_m = position;
      s.straight = straight;
      coarse.update(s);
      if (counted_run && !(skip_first && i == 0)) expected_n += phi;
    }
  };
  // Leg 1: 200 samples straight, the very first sample only marks the start (no earlier position).
  leg(Eigen::Vector3d(1.0, 2.0, 0.1), 1, true, true, true);
  const Eigen::Vector3d run1_start = position;
  leg(Eigen::Vector3d(1.0, 2.0, 0.1), 199, true, true, false);
  // The open run counts as soon as it is long enough (a calibration drive that ends on its straight
  // never sees a sample that closes it), and gives K = S / N exactly already.
  ASSERT_TRUE(coarse.estimate().valid) << "the open run (> 100 m) counts";
  EXPECT_NEAR(coarse.estimate().k_m_per_pulse, k, 1e-12 * k);
  EXPECT_EQ(coarse.runs_counted(), 0u) << "closed runs only";
  expected_s += (position - run1_start).norm();
  // A turn: three non-straight samples close run 1.
  leg(Eigen::Vector3d(0.0, 1.0, 0.0), 1, false, false, false);
  ASSERT_TRUE(coarse.estimate().valid);
  EXPECT_NEAR(coarse.estimate().k_m_per_pulse, k, 1e-12 * k);
  leg(Eigen::Vector3d(-1.0, 1.0, 0.0), 2, false, false, false);
  // Leg 2: starts where the turn ended (contiguous), 150 samples, counted with all its pulses.
  const Eigen::Vector3d run2_start = position;
  leg(Eigen::Vector3d(-2.0, 0.5, -0.05), 150, true, true, false);
  const Eigen::Vector3d run2_end = position;
  // Gap: 20 samples gated out (not given to the estimator) while driving straight on.
  for (int i = 0; i < 20; ++i) {
    t += 0.1;
    position += Eigen::Vector3d(-2.0, 0.5, -0.05).normalized() * (k * pulses(rng));
  }
  expected_s += (run2_end - run2_start).norm();
  // After the gap: the first sample only marks the start; 120 samples more.
  leg(Eigen::Vector3d(-2.0, 0.5, -0.05), 1, true, true, true);
  const Eigen::Vector3d run3_start = position;
  leg(Eigen::Vector3d(-2.0, 0.5, -0.05), 120, true, true, false);
  expected_s += (position - run3_start).norm();
  leg(Eigen::Vector3d(0.0, -1.0, 0.0), 1, false, false, false);
  // A short run (about 40 samples ~ 37 m < 100 m): not counted.
  leg(Eigen::Vector3d(0.0, -1.0, 0.0), 40, true, false, false);
  leg(Eigen::Vector3d(1.0, 0.0, 0.0), 1, false, false, false);

  const ScaleFactorEstimate e = coarse.estimate();
  ASSERT_TRUE(e.valid);
  EXPECT_EQ(coarse.runs_counted(), 3u);
  EXPECT_NEAR(coarse.total_length_m(), expected_s, 1e-9);
  EXPECT_DOUBLE_EQ(coarse.total_pulses(), expected_n);
  EXPECT_NEAR(e.k_m_per_pulse, k, 1e-12 * k);
  EXPECT_NEAR(e.sigma_m_per_pulse, std::sqrt(6.0) * params.coarse_position_sigma_m / expected_n, 1e-18);
}

TEST(Coarse, ATurnInsideTheGateWouldBiasK) {
  // Sanity of the test above: a run whose "straight" flag hid a 90 deg corner gives S < path, K low.
  const double k = 0.01;
  ScaleFactorEstimatorParams params;
  CoarseEstimator coarse(params);
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  double t = 0.0;
  for (int i = 0; i < 401; ++i) {
    position += (i <= 200 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY()) * (k * 80.0);
    t += 0.1;
    ScaleFactorSample s = make_sample(t, 80.0, 0.8);
    s.gnss_position_enu_m = position;
    coarse.update(s);
  }
  ScaleFactorSample end = make_sample(t + 0.1, 80.0, 0.8);
  end.straight = false;
  coarse.update(end);
  ASSERT_TRUE(coarse.estimate().valid);
  EXPECT_NEAR(coarse.estimate().k_m_per_pulse, k * std::sqrt(2.0) / 2.0, 1e-6 * k);
}

// ---------------------------------------------------------------------------------------------------
// Factory, parameters, bad input.

TEST(Factory, UnknownNameListsTheValidOnes) {
  try {
    make_scale_factor_estimator("vff", ScaleFactorEstimatorParams{});
    FAIL() << "no exception";
  } catch (const std::invalid_argument& error) {
    const std::string message = error.what();
    EXPECT_NE(message.find("'vff'"), std::string::npos) << message;
    for (const std::string& name : estimator_names()) EXPECT_NE(message.find(name), std::string::npos) << message;
  }
  const std::vector<std::string> expected = {"rls", "ff_rls", "lm_rls", "vff_lm_rls", "coarse", "kf_rw"};
  EXPECT_EQ(estimator_names(), expected);
}

TEST(Factory, InvalidParametersAreNamed) {
  struct Case {
    const char* name;
    void (*apply)(ScaleFactorEstimatorParams&);
  };
  const Case cases[] = {
      {"forgetting_factor", [](ScaleFactorEstimatorParams& p) { p.forgetting_factor = 1.5; }},
      {"forgetting_factor", [](ScaleFactorEstimatorParams& p) { p.forgetting_factor = 0.0; }},
      {"window_length", [](ScaleFactorEstimatorParams& p) { p.window_length = 0; }},
      {"lambda_min", [](ScaleFactorEstimatorParams& p) { p.lambda_min = -0.1; }},
      {"vff_c_m2", [](ScaleFactorEstimatorParams& p) { p.vff_c_m2 = -1.0; }},
      {"vff_kappa", [](ScaleFactorEstimatorParams& p) { p.vff_kappa = std::nan(""); }},
      {"sigma_y_floor_m", [](ScaleFactorEstimatorParams& p) { p.sigma_y_floor_m = 0.0; }},
      {"prior_weight_pulses2", [](ScaleFactorEstimatorParams& p) { p.prior_weight_pulses2 = -1.0; }},
      {"k_prior_m_per_pulse", [](ScaleFactorEstimatorParams& p) { p.k_prior_m_per_pulse = HUGE_VAL; }},
      {"converged_rel_sigma", [](ScaleFactorEstimatorParams& p) { p.converged_rel_sigma = 0.0; }},
      {"min_samples", [](ScaleFactorEstimatorParams& p) { p.min_samples = 0; }},
      {"sample_interval_s", [](ScaleFactorEstimatorParams& p) { p.sample_interval_s = 0.0; }},
      {"coarse_min_length_m", [](ScaleFactorEstimatorParams& p) { p.coarse_min_length_m = -5.0; }},
      {"kf_change_threshold", [](ScaleFactorEstimatorParams& p) { p.kf_change_threshold = 0.0; }},
  };
  EXPECT_NO_THROW(ScaleFactorEstimatorParams{}.validate());
  for (const Case& c : cases) {
    ScaleFactorEstimatorParams params;
    c.apply(params);
    try {
      make_scale_factor_estimator("vff_lm_rls", params);
      ADD_FAILURE() << c.name << ": no exception";
    } catch (const std::invalid_argument& error) {
      EXPECT_NE(std::string(error.what()).find(c.name), std::string::npos) << error.what();
    }
  }
}

TEST(Estimators, BadSamplesAreRejectedWithWhereAndWhatAndLeaveTheStateAlone) {
  for (const std::string& name : estimator_names()) {
    auto estimator = make_scale_factor_estimator(name, ScaleFactorEstimatorParams{});
    for (int i = 0; i < 5; ++i) {
      ScaleFactorSample s = make_sample(0.1 * (i + 1), 80.0, 0.8);
      s.gnss_position_enu_m = Eigen::Vector3d(0.8 * (i + 1), 0.0, 0.0);
      estimator->update(s);
    }
    const StateJson before = estimator->save_state();
    struct Bad {
      ScaleFactorSample sample;
      const char* field;
    };
    std::vector<Bad> bad;
    bad.push_back({make_sample(12.5, 0.0, 0.8), "phi_pulses"});
    bad.push_back({make_sample(12.5, -3.0, 0.8), "phi_pulses"});
    bad.push_back({make_sample(12.5, 80.0, std::nan("")), "y_m"});
    bad.push_back({make_sample(12.5, 80.0, 0.8, -0.1), "dt_s"});
    ScaleFactorSample bad_position = make_sample(12.5, 80.0, 0.8);
    bad_position.gnss_position_enu_m.y() = HUGE_VAL;
    bad.push_back({bad_position, "gnss_position_enu_m.north"});
    for (const Bad& b : bad) {
      try {
        estimator->update(b.sample);
        ADD_FAILURE() << name << " accepted a bad " << b.field;
      } catch (const std::invalid_argument& error) {
        const std::string message = error.what();
        EXPECT_NE(message.find(b.field), std::string::npos) << message;
        EXPECT_NE(message.find(name), std::string::npos) << message;
        EXPECT_NE(message.find("12.5"), std::string::npos) << message;
      }
    }
    EXPECT_EQ(estimator->save_state(), before) << name;
  }
}

// ---------------------------------------------------------------------------------------------------
// Save / restore.

TEST(SaveRestore, RestoredEstimatorContinuesBitIdentically) {
  const Drive drive = simulate_drive(800, 0.01, 400, 0.03, 0.005, 31);
  ScaleFactorEstimatorParams params;
  params.window_length = 60;
  params.coarse_min_length_m = 20.0;
  for (const std::string& name : estimator_names()) {
    auto original = make_scale_factor_estimator(name, params);
    Eigen::Vector3d position = Eigen::Vector3d::Zero();
    std::vector<ScaleFactorSample> samples = drive.samples;
    for (std::size_t i = 0; i < samples.size(); ++i) {
      position.x() += samples[i].y_m;
      samples[i].gnss_position_enu_m = position;
      samples[i].straight = (i / 50) % 4 != 3;  // straight runs with turns for the coarse method
    }
    for (std::size_t i = 0; i < 333; ++i) original->update(samples[i]);
    const StateJson state = original->save_state();
    auto restored = make_scale_factor_estimator(name, params);
    restored->restore_state(state);
    EXPECT_EQ(restored->save_state(), state) << name;
    EXPECT_EQ(restored->save_state().dump(), state.dump()) << name << ": saved again, the same bytes";
    // Through the file's text too (the checkpoint writes and reads it).
    auto reread = make_scale_factor_estimator(name, params);
    reread->restore_state(StateJson::parse(state.dump()));
    EXPECT_EQ(reread->save_state().dump(), state.dump()) << name;
    for (std::size_t i = 333; i < samples.size(); ++i) {
      original->update(samples[i]);
      restored->update(samples[i]);
      const ScaleFactorEstimate a = original->estimate(), b = restored->estimate();
      ASSERT_EQ(a.valid, b.valid) << name << " " << i;
      ASSERT_EQ(a.k_m_per_pulse, b.k_m_per_pulse) << name << " " << i;  // bit-identical on purpose
      ASSERT_EQ(a.sigma_m_per_pulse, b.sigma_m_per_pulse) << name << " " << i;
      ASSERT_EQ(a.forgetting_factor, b.forgetting_factor) << name << " " << i;
      ASSERT_EQ(a.samples_used, b.samples_used) << name << " " << i;
    }
    EXPECT_TRUE(original->estimate().valid) << name;
  }
}

TEST(SaveRestore, CorruptOrMismatchedStateIsRefusedWithAReason) {
  ScaleFactorEstimatorParams params;
  VffLmRlsEstimator source(params);
  const Drive drive = simulate_drive(150, 0.01, 1000, 0.0, 0.005, 8);
  for (const ScaleFactorSample& s : drive.samples) source.update(s);
  const StateJson state = source.save_state();

  VffLmRlsEstimator target(params);
  target.update(make_sample(0.1, 80.0, 0.8));
  const StateJson target_before = target.save_state();
  auto expect_refused = [&](ScaleFactorEstimator& estimator, const StateJson& bad, const std::string& reason) {
    try {
      estimator.restore_state(bad);
      ADD_FAILURE() << "accepted: " << reason;
    } catch (const std::runtime_error& error) {
      EXPECT_NE(std::string(error.what()).find(reason), std::string::npos) << error.what();
    }
  };
  // Corruption and versions are the checkpoint file's (checksum, envelope version: test_checkpoint);
  // a state itself is refused when a field is missing, of the wrong kind or out of range, and the
  // reason names the estimator and the field.
  StateJson wrong_kind = state;
  wrong_kind["s_pp"] = "1.5";
  expect_refused(target, wrong_kind, "estimator state for 'vff_lm_rls': field 's_pp' is not a number");
  StateJson missing = state;
  missing.erase("samples_used");
  expect_refused(target, missing, "field 'samples_used' is missing");
  expect_refused(target, StateJson(), "is not an object");
  StateJson negative = state;
  negative["residual_scale"][1] = -1.0;
  expect_refused(target, negative, "field 'residual_scale' has a negative variance");
  StateJson long_window = state;
  for (int i = 0; i < 200; ++i)
    long_window["window"].push_back(StateJson::array({1.0, 1.0, 0.0, 0.0}));  // (phi, y, Lambda, dv)
  expect_refused(target, long_window, "field 'window' is longer than the window length");
  EXPECT_EQ(target.save_state(), target_before) << "a refused restore leaves the state alone";

  LmRlsEstimator other_kind(params);
  expect_refused(other_kind, state, "saved by estimator 'vff_lm_rls'");
  ScaleFactorEstimatorParams other_params = params;
  other_params.window_length = 50;
  VffLmRlsEstimator other_window(other_params);
  expect_refused(other_window, state, "window_length");
  target.restore_state(state);
  EXPECT_EQ(target.estimate().k_m_per_pulse, source.estimate().k_m_per_pulse);
}

TEST(Estimators, RegressionNoiseVarianceIsVelocityNoisePlusPulseQuantisation) {
  // sigma_v 0.05 m/s over T = 0.1 s: (0.005 m)^2 / 2 = 1.25e-5 m^2; K = 0.0125 m/pulse: K^2 / 6.
  EXPECT_NEAR(regression_noise_variance_m2(0.05, 0.1, 0.0125), 1.25e-5 + 0.0125 * 0.0125 / 6.0, 1e-20);
  EXPECT_NEAR(regression_noise_variance_m2(0.05, 0.1, 0.0125), 3.854166666666668e-05, 1e-19);
  EXPECT_DOUBLE_EQ(regression_noise_variance_m2(0.0, 0.1, 0.06), 0.0006);  // quantisation only
  EXPECT_DOUBLE_EQ(regression_noise_variance_m2(0.2, 0.5, 0.0), 0.005);    // velocity only
  // The estimators' model (automatic VFF C) is this variance floored by sigma_y_floor_m^2.
  ScaleFactorEstimatorParams p;
  p.sigma_y_floor_m = 1e-3;
  EXPECT_GT(regression_noise_variance_m2(p.sigma_v_mps, p.sample_interval_s, 0.0125),
            p.sigma_y_floor_m * p.sigma_y_floor_m);
}

// A latency error d moves every sample by -d * speed_change (y = K phi - d dv): the window's K moves
// by exactly d * dk_dlatency, the sensitivity the estimate reports.
TEST(HonestSigma, LatencySensitivityIsHowTheWindowKMovesWithALatencyError) {
  for (const char* name : {"lm_rls", "vff_lm_rls"}) {
    SCOPED_TRACE(name);
    ScaleFactorEstimatorParams params;
    const double k = 0.0125, d_s = 0.1;
    auto clean = make_scale_factor_estimator(name, params);
    auto late = make_scale_factor_estimator(name, params);
    for (int i = 0; i < 60; ++i) {  // accelerating from 4 m/s at 1 m/s^2, then 2 s at a steady speed
      const double v0 = 4.0 + 0.1 * std::min(i, 40), v1 = 4.0 + 0.1 * std::min(i + 1, 40);
      ScaleFactorSample s = make_sample(0.1 * (i + 1), 0.5 * (v0 + v1) * 0.1 / k, 0.5 * (v0 + v1) * 0.1);
      s.speed_change_mps = v1 - v0;
      clean->update(s);
      s.y_m -= d_s * s.speed_change_mps;
      late->update(s);
    }
    const ScaleFactorEstimate c = clean->estimate(), l = late->estimate();
    EXPECT_NEAR(c.k_m_per_pulse, k, 1e-12);
    EXPECT_LT(c.dk_dlatency_m_per_pulse_per_s, 0.0);  // accelerating: a late GNSS reads K low
    EXPECT_NEAR(l.k_m_per_pulse, k + d_s * c.dk_dlatency_m_per_pulse_per_s, 1e-12);
    EXPECT_GT(std::abs(l.k_m_per_pulse / k - 1.0), 0.005);  // 0.9 % low: many times the scatter's sigma
    EXPECT_LT(l.sigma_m_per_pulse / k, 0.001);
  }
  // Estimators without the sums report no sensitivity.
  auto rls = make_scale_factor_estimator("rls", ScaleFactorEstimatorParams{});
  rls->update(make_sample(0.1, 80.0, 1.0));
  EXPECT_EQ(rls->estimate().dk_dlatency_m_per_pulse_per_s, 0.0);
}

// After a detected change the window's K lags; the lag sigma covers it, and is 0 once the samples
// from before the change have left the window.
TEST(HonestSigma, LagSigmaCoversTheLagAfterAStepUntilTheOldSamplesHaveLeft) {
  for (const double interval_s : {0.1, 1.0}) {
    SCOPED_TRACE(interval_s);
    ScaleFactorEstimatorParams params;
    const auto step_at = static_cast<std::size_t>(std::lround(300.0 / interval_s));
    std::size_t covered_by_lag = 0, lagging = 0;
    std::optional<std::size_t> detected_at, last_lag_sample;
    vff_step_drive(interval_s, params, 1, nullptr, [&](std::size_t i, const ScaleFactorSample&, VffLmRlsEstimator& e) {
      const ScaleFactorEstimate est = e.estimate();
      if (est.lag_sigma_m_per_pulse > 0.0) last_lag_sample = i;
      if (i < step_at) {
        EXPECT_EQ(est.lag_sigma_m_per_pulse, 0.0) << i;  // no change detected before the step
        return;
      }
      if (!detected_at && e.last_change_began() && *e.last_change_began() + 5 >= step_at) detected_at = i;
      if (!detected_at) return;  // nothing tells the step yet: the samples after it are the only witness
      const double error = std::abs(est.k_m_per_pulse - 0.0103);
      if (error <= 3.0 * est.sigma_m_per_pulse) return;
      ++lagging;  // the scatter's sigma alone does not cover it
      if (error <= 3.0 * std::max(est.sigma_m_per_pulse, est.lag_sigma_m_per_pulse)) ++covered_by_lag;
    });
    ASSERT_TRUE(detected_at);
    ASSERT_TRUE(last_lag_sample);
    EXPECT_LE(*detected_at, step_at + 10);  // the detector fires within a few samples of the step
    if (interval_s < 0.5) {
      EXPECT_GT(lagging, 3u);  // the step's lag is outside 3 of the scatter's sigmas ...
    }
    EXPECT_EQ(covered_by_lag, lagging);  // ... and inside 3 of the lag's, on every sample
    // The window holds 100 samples (10 s at 10 Hz; at 1 Hz cut back to the run, never below 10 s).
    EXPECT_LE(*last_lag_sample, step_at + static_cast<std::size_t>(std::lround(110.0 / interval_s)));
  }
}

TEST(HonestSigma, SaveRestoreKeepsTheSpeedChangesAndTheChangeStart) {
  ScaleFactorEstimatorParams params;
  std::unique_ptr<VffLmRlsEstimator> restored;
  vff_step_drive(0.1, params, 2, nullptr, [&](std::size_t i, const ScaleFactorSample& sample, VffLmRlsEstimator& e) {
    ScaleFactorSample s = sample;
    if (i == 3010) {  // just after the step, its lag still in the window
      ASSERT_TRUE(e.last_change_began());
      restored = std::make_unique<VffLmRlsEstimator>(params);
      restored->restore_state(e.save_state());
      EXPECT_EQ(restored->save_state(), e.save_state());
      EXPECT_EQ(restored->last_change_began(), e.last_change_began());
      EXPECT_EQ(restored->estimate().lag_sigma_m_per_pulse, e.estimate().lag_sigma_m_per_pulse);
      EXPECT_GT(e.estimate().lag_sigma_m_per_pulse, 0.0);
    } else if (i > 3010 && i < 3100) {
      restored->update(s);
      EXPECT_EQ(restored->estimate().lag_sigma_m_per_pulse, e.estimate().lag_sigma_m_per_pulse) << i;
    }
  });
  // A state with a speed change in its rows keeps it.
  VffLmRlsEstimator a(params), b(params);
  for (int i = 0; i < 20; ++i) {
    ScaleFactorSample s = make_sample(0.1 * (i + 1), 80.0, 1.0 + 0.01 * i);
    s.speed_change_mps = 0.1;
    a.update(s);
  }
  b.restore_state(a.save_state());
  EXPECT_EQ(b.estimate().dk_dlatency_m_per_pulse_per_s, a.estimate().dk_dlatency_m_per_pulse_per_s);
  EXPECT_LT(a.estimate().dk_dlatency_m_per_pulse_per_s, 0.0);
  EXPECT_EQ(b.window_sums().s_pdv, a.window_sums().s_pdv);
  EXPECT_NEAR(a.window_sums().s_pdv, a.exact_window_sums().s_pdv, 1e-9);
  EXPECT_NEAR(a.window_sums().s_pdv, 20 * 80.0 * 0.1, 1e-9);
}

// ---------------------------------------------------------------------------------------------------
// Serially correlated residuals.

// The mean sigma factor of a tracker fed n residuals x_t = e_t + c e_(t-1), e white (fixed seed),
// after the first 200 (its running means settled).
double mean_correlation_factor(double c, unsigned seed, int n = 20000) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> e(0.0, 1.0);
  ResidualCorrelationTracker tracker(0.02);
  double previous = e(rng), sum = 0.0;
  for (int i = 0; i < n; ++i) {
    const double now = e(rng);
    tracker.add(now + c * previous, 10.0);
    previous = now;
    if (i >= 200) sum += tracker.sigma_factor();
  }
  return sum / (n - 200);
}

TEST(ResidualCorrelation, FactorIsTheBartlettLongRunRatioAndNeverBelowOne) {
  // Lag-1 correlation c / (1 + c^2), none beyond: the 3-lag Bartlett ratio is 1 + 2 (3/4) rho.
  const double white = mean_correlation_factor(0.0, 1);
  const double shared = mean_correlation_factor(1.0, 2);     // rho 0.5: sqrt(1.75) = 1.323
  const double opposite = mean_correlation_factor(-1.0, 3);  // rho -0.5: the long-run ratio 0.25
  std::printf("[ info ] mean correlation factor: white %.3f, rho +0.5 %.3f, rho -0.5 %.3f\n", white, shared, opposite);
  EXPECT_GE(white, 1.0);
  EXPECT_LT(white, 1.12);  // the running means' own noise, cut at 1 from below
  EXPECT_NEAR(shared, std::sqrt(1.75), 0.06);
  EXPECT_LT(opposite, 1.01);

  ResidualCorrelationTracker t(0.02);
  EXPECT_EQ(t.sigma_factor(), 1.0);
  for (int i = 0; i < 3; ++i) t.add(1.0, 10.0);  // a constant: fully correlated, but too few yet
  EXPECT_EQ(t.sigma_factor(), 1.0);
  t.add(1.0, 10.0);
  EXPECT_DOUBLE_EQ(t.sigma_factor(), 2.0);  // the largest: sqrt(1 + 3)
  t.add(1e9, 3.0);                          // clipped: an outlier counts as 3
  EXPECT_LE(t.sigma_factor(), 2.0);
}

TEST(ResidualCorrelation, StateRestoresExactlyAndRefusesNonFiniteValues) {
  ResidualCorrelationTracker a(0.02), b(0.02);
  for (int i = 0; i < 40; ++i) a.add(std::sin(0.3 * i), 10.0);
  b.restore_state(a.state());
  for (int i = 40; i < 60; ++i) {
    a.add(std::sin(0.3 * i), 10.0);
    b.add(std::sin(0.3 * i), 10.0);
    EXPECT_EQ(a.sigma_factor(), b.sigma_factor()) << i;
  }
  ResidualCorrelationTracker::State bad = a.state();
  bad.gamma[2] = std::nan("");
  EXPECT_THROW(b.restore_state(bad), std::runtime_error);
  bad = a.state();
  bad.gamma[0] = -1.0;
  EXPECT_THROW(b.restore_state(bad), std::runtime_error);
  EXPECT_EQ(b.sigma_factor(), a.sigma_factor());  // unchanged by the refused states
}

TEST(ResidualCorrelation, WidenedSigmaMatchesTheScatterWhenSamplesShareAGnssSpeed) {
  // 1 Hz samples whose distances are trapezoids of GNSS speeds with white errors: neighbours share
  // one speed error (rho 0.5), so K scatters sqrt(2) times more than sigma_y / sqrt(S_pp) says.
  // Over 300 independent runs of lm_rls (window 100) the widened sigma must describe the scatter.
  ScaleFactorEstimatorParams params;
  params.window_length = 100;
  params.sample_interval_s = 1.0;
  double sum_sq_error = 0.0, sum_sigma = 0.0, sum_widened = 0.0;
  const int runs = 300;
  for (int r = 0; r < runs; ++r) {
    std::mt19937_64 rng(5000 + static_cast<unsigned>(r));
    std::normal_distribution<double> speed_error(0.0, 0.05);
    LmRlsEstimator lm(params);
    double previous_error = speed_error(rng);
    for (int i = 0; i < 300; ++i) {
      const double error = speed_error(rng);
      const double distance_m = 8.0;  // 800 pulses of 0.01 m over 1 s
      lm.update(make_sample(1.0 * (i + 1), 800.0, distance_m + 0.5 * (previous_error + error), 1.0));
      previous_error = error;
    }
    const ScaleFactorEstimate e = lm.estimate();
    sum_sq_error += std::pow(e.k_m_per_pulse - 0.01, 2);
    sum_sigma += e.sigma_m_per_pulse;
    sum_widened += e.sigma_m_per_pulse * e.correlation_factor;
  }
  const double scatter = std::sqrt(sum_sq_error / runs);
  std::printf("[ info ] 1 Hz trapezoid residuals: K scatter %.3g, mean sigma %.3g, widened %.3g m/pulse\n", scatter,
              sum_sigma / runs, sum_widened / runs);
  EXPECT_LT(sum_sigma / runs / scatter, 0.8);  // the plain sigma is optimistic
  EXPECT_NEAR(sum_widened / runs / scatter, 1.0, 0.15);
}
