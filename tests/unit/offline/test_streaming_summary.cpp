// The summary and evaluations computed one row at a time: the accumulators fed in a streaming run's
// order give make_summary's figures; each evaluation finds a known error placed on a track against
// its reference; and their buffers do not grow with the drive.
#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <tuple>

#include "odonav/simulator/simulator.hpp"
#include "odonav/offline/evaluation.hpp"
#include "odonav/offline/first_metres.hpp"
#include "odonav/offline/offline_runner.hpp"
#include "offline_test_params.hpp"
#include "odonav/offline/run_diagnosis.hpp"
#include "odonav/offline/summary.hpp"

using namespace odonav;
using namespace odonav::offline;
using namespace odonav::offline::test;
using nlohmann::json;

namespace {

// Feeds an accumulator a run's inputs and rows in the order a streaming run produces them: by time,
// the odometer times lagging the outputs by odometer_lag_s (so that scale-factor rows past a K step
// wait for it), the navigation rows 30 ms behind the DR rows, the coarse DR rows in a second pass.
// Returns the largest footprint seen.
SummaryAccumulator::Footprint feed_streaming(SummaryAccumulator& acc, const Dataset& d, const results::OutputRows& rows,
                                             double odometer_lag_s) {
  enum Kind { kOdometer, kMisalignment, kScaleFactor, kDeadReckoning, kNavigation };
  std::vector<std::tuple<double, int, std::size_t>> events;  // (time fed, kind, index)
  for (std::size_t i = 0; i < d.odometer.size(); ++i)
    events.emplace_back(d.odometer[i].t_s + odometer_lag_s, kOdometer, i);
  for (std::size_t i = 0; i < rows.misalignment.size(); ++i)
    events.emplace_back(rows.misalignment[i].t_s, kMisalignment, i);
  for (std::size_t i = 0; i < rows.scale_factor.size(); ++i)
    events.emplace_back(rows.scale_factor[i].t_s, kScaleFactor, i);
  for (std::size_t i = 0; i < rows.dead_reckoning.size(); ++i)
    events.emplace_back(rows.dead_reckoning[i].t_s, kDeadReckoning, i);
  for (std::size_t i = 0; i < rows.navigation_position.size(); ++i)
    events.emplace_back(rows.navigation_position[i].t_s + 0.03, kNavigation, i);
  std::stable_sort(events.begin(), events.end(),
                   [](const auto& a, const auto& b) { return std::get<0>(a) < std::get<0>(b); });
  SummaryAccumulator::Footprint most;
  for (const auto& [t, kind, i] : events) {
    switch (kind) {
      case kOdometer: acc.add_odometer(d.odometer[i].t_s); break;
      case kMisalignment: acc.add(rows.misalignment[i]); break;
      case kScaleFactor: acc.add(rows.scale_factor[i]); break;
      case kDeadReckoning: acc.add_dead_reckoning(rows.dead_reckoning[i]); break;
      default: acc.add(rows.navigation_position[i]); break;
    }
    const SummaryAccumulator::Footprint f = acc.footprint();
    most.scale_factor_rows_waiting = std::max(most.scale_factor_rows_waiting, f.scale_factor_rows_waiting);
    most.navigation_rows_buffered = std::max(most.navigation_rows_buffered, f.navigation_rows_buffered);
    most.dead_reckoning_rows_buffered = std::max(most.dead_reckoning_rows_buffered, f.dead_reckoning_rows_buffered);
  }
  for (const results::DeadReckoningRow& r : rows.dead_reckoning_coarse) acc.add_dead_reckoning_coarse(r);
  return most;
}

// A point of a straight northbound track, east_m / north_m from the origin (m).
Geodetic enu_point(const LocalEnuFrame& frame, double east_m, double north_m) {
  return frame.to_geodetic(Eigen::Vector3d(east_m, north_m, 0.0));
}

const Geodetic kOrigin{52.5 * kDegToRad, 13.4 * kDegToRad, 40.0};

/// Reads `file` one row at a time: every row is checked by expect_same(row, whole[n], n) against
/// `whole` (the file read at once), and the file holds `written` rows.
template <class Row, class ExpectSame>
void expect_read_row_by_row(const std::filesystem::path& file, const std::vector<Row>& whole, std::size_t written,
                            ExpectSame expect_same) {
  results::OutputFileReader reader(file.string());
  std::size_t n = 0;
  for (Row r; reader.next(r); ++n) {
    ASSERT_LT(n, whole.size());
    expect_same(r, whole[n], n);
  }
  EXPECT_EQ(n, written);
}

}  // namespace

TEST(StreamingSummary, FedInStreamingOrderItGivesMakeSummarysFigures) {
  simulator::SimulationConfig cfg = simulator::scenario_config("terrain");  // K steps, an outage, truth
  cfg.seed = 3;
  cfg.gnss_rate_hz = 1.0;
  Dataset d = simulator::simulate(cfg);
  const OfflineParams p = user_params(d);
  const OfflineResult r = run_offline(d, p);
  const results::OutputRows rows = to_output_rows(r, p.identification.estimator_name);
  SummaryOptions o;
  o.dataset_name = "terrain";
  o.coarse_k_origin = r.coarse_k_origin;
  {
    const json expected = make_summary(d, rows, o);
    SummaryAccumulator acc(summary_inputs(d, o));
    const SummaryAccumulator::Footprint most = feed_streaming(acc, d, rows, 5.0);
    EXPECT_GT(most.scale_factor_rows_waiting, 0u);  // rows past the 250 s step waited for the odometer
    EXPECT_EQ(acc.finish().dump(2), expected.dump(2));
    ASSERT_EQ(expected["dead_reckoning"]["online_k"]["outages"].size(), 1u);
  }
  // Without meta.json's simulation object: the outage from the GNSS fixes, the true K from truth.csv.
  d.meta.raw_json.clear();
  const json expected = make_summary(d, rows, o);
  SummaryAccumulator acc(summary_inputs(d, o));
  feed_streaming(acc, d, rows, 0.0);
  EXPECT_EQ(acc.finish().dump(2), expected.dump(2));
  ASSERT_EQ(expected["dead_reckoning"]["online_k"]["outages"].size(), 1u);
  EXPECT_EQ(expected["navigation_position"]["vs_truth"]["outages"].size(), 1u);
}

TEST(StreamingSummary, ADeadReckoningTrackOffsetFromTheReferenceHasThatError) {
  // Reference northbound at 10 m/s, 10 Hz, 200 s; the DR 3 m east of it, plus 4 m more east built
  // up linearly across the outage 100-150 s (and kept after it).
  const LocalEnuFrame frame(kOrigin);
  std::vector<TimedPosition> reference;
  for (int i = 0; i <= 2000; ++i) reference.push_back({0.1 * i, enu_point(frame, 0.0, i * 1.0)});
  DeadReckoningEvaluator e(vector_source(reference), OutageList({{100.0, 150.0}}), 100.0);
  for (int i = 0; i <= 2000; ++i) {
    const double t = 0.1 * i;
    const double extra_east_m = 4.0 * std::clamp((t - 100.0) / 50.0, 0.0, 1.0);
    e.add(t, enu_point(frame, 3.0 + extra_east_m, i * 1.0), i * 1.0);
  }
  const DrEvaluation r = e.finish();
  EXPECT_EQ(r.epochs, 2001u);
  EXPECT_NEAR(r.final_error_m, 7.0, 1e-4);
  EXPECT_NEAR(r.final_error_percent, 100.0 * 7.0 / 2000.0, 1e-4);
  EXPECT_NEAR(r.max_error_m, 7.0, 1e-4);
  EXPECT_NEAR(r.max_error_percent, 3.0, 1e-4);  // 3 m at 100 m
  ASSERT_EQ(r.outage_error_m.size(), 1u);
  EXPECT_NEAR(r.outage_error_m[0], 4.0, 1e-3);                        // what the outage added
  EXPECT_NEAR(r.outage_error_percent[0], 100.0 * 4.0 / 500.0, 1e-3);  // over its 500 m
}

TEST(StreamingSummary, ScaleFactorFiguresOfAKnownEstimate) {
  // True K 0.0125 stepping to 0.0130 at 300 s; the estimate 0.2 % high throughout, except that it
  // keeps the old K for 20 s after the step. First motion at 10 s.
  const double k0 = 0.0125, k1 = 0.0130;
  ScaleFactorEvaluator e({{300.0, k0, k1}}, KEvaluationParams{});
  e.set_first_motion(10.0);
  for (int i = 0; i <= 600; ++i) {
    const double t = i * 1.0;
    const double truth = t < 300.0 ? k0 : k1;
    const double estimate = t < 10.0 ? 0.0 : (t >= 300.0 && t < 320.0 ? k0 : truth * 1.002);
    e.add(t, estimate, truth);
  }
  const KEvaluation r = e.result();
  EXPECT_NEAR(r.time_to_converge_s, 0.0, 1e-12);  // within 0.5 % from the first motion on
  ASSERT_EQ(r.settle_times_s.size(), 1u);
  EXPECT_NEAR(r.settle_times_s[0], 20.0, 1e-12);
  // The RMS from convergence (10 s) on leaves out the settle window 300-310 s, not 310-320 s
  // (3.8 % off).
  const double rms = std::sqrt((290 * 0.002 * 0.002 + 10 * std::pow((k0 - k1) / k1, 2) + 281 * 0.002 * 0.002) / 581.0);
  EXPECT_EQ(r.epochs, 581u);
  EXPECT_NEAR(r.rms_rel_error, rms, 1e-12);
  EXPECT_NEAR(r.max_rel_error, (k1 - k0) / k1, 1e-12);
  EXPECT_NEAR(r.final_rel_error, 0.002, 1e-12);
}

TEST(StreamingSummary, NavigationAndDeadReckoningOffsetsFromTheTruthAreFound) {
  // Truth and 1 Hz GNSS on the northbound track (5 m/s, 10 Hz truth, 100 s); the navigation
  // position 2 m north of the truth, the DR 3 m east. Fed row by row.
  const LocalEnuFrame frame(kOrigin);
  Dataset d;
  for (int i = 0; i <= 1000; ++i) {
    TruthSample t;
    t.t_s = 0.1 * i;
    t.position = enu_point(frame, 0.0, 0.5 * i);
    t.attitude = Attitude{0.0, 0.0, 0.0};
    d.truth.push_back(t);
    OdometerSample o;
    o.t_s = t.t_s;
    d.odometer.push_back(o);
    if (i % 10 == 0) {
      GnssSample g;
      g.t_s = t.t_s;
      g.position = t.position;
      d.gnss.push_back(g);
    }
  }
  SummaryOptions o;
  SummaryAccumulator acc(summary_inputs(d, o));
  for (int i = 0; i <= 1000; ++i) {
    acc.add_odometer(0.1 * i);
    results::DeadReckoningRow dr;
    dr.t_s = 0.1 * i;
    const Geodetic p = enu_point(frame, 3.0, 0.5 * i);
    dr.lat_rad = p.lat_rad, dr.lon_rad = p.lon_rad, dr.height_m = p.height_m;
    dr.distance_m = 0.5 * i;
    acc.add_dead_reckoning(dr);
    results::NavigationPositionRow nav;
    nav.t_s = 0.1 * i;
    const Geodetic q = enu_point(frame, 0.0, 0.5 * i + 2.0);
    nav.lat_rad = q.lat_rad, nav.lon_rad = q.lon_rad, nav.height_m = q.height_m;
    nav.status = "anchored";
    acc.add(nav);
  }
  const json s = acc.finish();
  const json& nav = s["navigation_position"];
  EXPECT_EQ(nav["rows_anchored"].get<int>(), 1001);
  EXPECT_EQ(nav["vs_gnss"]["epochs"].get<int>(), 101);
  EXPECT_NEAR(nav["vs_gnss"]["horizontal_rms_m"].get<double>(), 2.0, 1e-3);
  EXPECT_NEAR(nav["vs_gnss"]["pure_dr_horizontal_rms_m"].get<double>(), 3.0, 1e-3);
  EXPECT_NEAR(nav["vs_truth"]["horizontal_rms_m"].get<double>(), 2.0, 1e-3);
  EXPECT_NEAR(nav["vs_truth"]["pure_dr_horizontal_rms_m"].get<double>(), 3.0, 1e-3);
  EXPECT_NEAR(nav["vs_truth"]["gnss_horizontal_rms_m"].get<double>(), 0.0, 1e-6);
  EXPECT_NEAR(s["dead_reckoning"]["online_k"]["final_error_m"].get<double>(), 3.0, 1e-3);
  EXPECT_EQ(s["dead_reckoning"]["reference"].get<std::string>(), "truth");
}

TEST(StreamingSummary, FirstMetresOfATrackOneMetreEastOfTheTruth) {
  const LocalEnuFrame frame(kOrigin);
  std::vector<TruthSample> truth;
  for (int i = 0; i <= 1000; ++i) {
    TruthSample t;
    t.t_s = 0.1 * i;
    t.position = enu_point(frame, 0.0, 1.0 * i);
    truth.push_back(t);
  }
  FirstMetresAccumulator acc(vector_source(truth));
  for (int i = 0; i <= 1000; ++i) {
    dead_reckoning::DeadReckoningOutput o;
    o.t_s = 0.1 * i;
    o.position = enu_point(frame, 1.0, 1.0 * i);
    o.distance_m = 1.0 * i;
    o.k_source = i >= 50 ? dead_reckoning::ScaleFactorSource::kIdentified : dead_reckoning::ScaleFactorSource::kNominal;
    // A fix every second, 0.5 m west of the truth: the origin from the fixes would be 1.5 m off.
    if (i % 10 == 0) {
      dead_reckoning::AnchorFix f;
      f.t_s = o.t_s;
      f.fix_enu_m = Eigen::Vector3d(-0.5, 1.0 * i, 0.0);
      f.dr_enu_m = Eigen::Vector3d(1.0, 1.0 * i, 0.0);
      f.dr_distance_m = o.distance_m;
      o.gnss_fixes.push_back(f);
    }
    acc.add(o);
  }
  const FirstMetres f = acc.finish();
  EXPECT_NEAR(f.start_offset_m, 1.0, 1e-6);
  EXPECT_NEAR(f.final_percent, 100.0 * 1.0 / 1000.0, 1e-6);
  EXPECT_NEAR(f.max_after_500m_percent, 100.0 * 1.0 / 501.0, 1e-6);
  EXPECT_NEAR(f.drift_final_percent, 0.0, 1e-6);
  EXPECT_NEAR(f.distance_on_nominal_k_m, 50.0, 1e-12);
  EXPECT_NEAR(f.standstill_origin_offset_m, 0.5, 1e-6);  // the fix at 0 m: 0.5 m west of the truth
  EXPECT_NEAR(f.first_500m_origin_offset_m, 0.5, 1e-6);
  EXPECT_NEAR(f.first_500m_origin_max_after_500m_percent, 100.0 * 0.5 / 501.0, 1e-6);
}

// A source computing a long drive's samples as they are pulled (no vector behind it): northbound at
// 10 m/s from kOrigin, n samples at period_s.
template <class T, class Make>
SourceFactory<T> generated(std::size_t n, double period_s, Make make) {
  return [=]() -> Source<T> {
    return [=, i = std::size_t{0}]() mutable -> std::optional<T> {
      if (i >= n) return std::nullopt;
      const double t = period_s * static_cast<double>(i++);
      return make(t);
    };
  };
}

Geodetic north_at(double t_s) {
  return Geodetic{kOrigin.lat_rad + 10.0 * t_s / 6378137.0, kOrigin.lon_rad, kOrigin.height_m};
}

TEST(StreamingSummary, BuffersDoNotGrowWithTheDrive) {
  // 5000 s at 100 Hz: 500k DR rows and 500k navigation rows, 50k scale-factor rows at 10 Hz, truth
  // at 100 Hz and GNSS at 10 Hz computed as they are read.
  constexpr std::size_t kRows = 500000;
  SummaryInputs in;
  in.truth = generated<TruthSample>(kRows, 0.01, [](double t) {
    TruthSample s;
    s.t_s = t;
    s.position = north_at(t);
    s.attitude = Attitude{0.0, 0.0, 0.0};
    s.k_true_m_per_pulse = 0.0125;
    return s;
  });
  in.gnss = generated<GnssSample>(kRows / 10, 0.1, [](double t) {
    GnssSample g;
    g.t_s = t;
    g.position = north_at(t);
    return g;
  });
  SummaryAccumulator acc(std::move(in));
  FirstMetresAccumulator first(generated<TruthSample>(kRows, 0.01, [](double t) {
    TruthSample s;
    s.t_s = t;
    s.position = north_at(t);
    return s;
  }));
  MedianPeriod period;
  SummaryAccumulator::Footprint most;
  std::size_t first_waiting = 0;
  for (std::size_t i = 0; i < kRows; ++i) {
    const double t = 0.01 * static_cast<double>(i);
    acc.add_odometer(t);
    if (i % 10 == 0) {
      results::ScaleFactorRow k;
      k.t_s = t;
      k.k_by_estimator = {{"rls", 0.0125}};
      k.samples_accepted = i / 10;
      acc.add(k);
      period.add(t);
    }
    const Geodetic p = north_at(t);
    results::DeadReckoningRow dr;
    dr.t_s = t;
    dr.lat_rad = p.lat_rad, dr.lon_rad = p.lon_rad + 1e-7, dr.height_m = p.height_m;
    dr.distance_m = 10.0 * t;
    acc.add_dead_reckoning(dr);
    acc.add_dead_reckoning_coarse(dr);
    results::NavigationPositionRow nav;
    nav.t_s = t;
    nav.lat_rad = p.lat_rad, nav.lon_rad = p.lon_rad, nav.height_m = p.height_m;
    nav.status = "anchored";
    acc.add(nav);
    dead_reckoning::DeadReckoningOutput o;
    o.t_s = t;
    o.position = Geodetic{dr.lat_rad, dr.lon_rad, dr.height_m};
    o.distance_m = dr.distance_m;
    if (i % 10 == 0) {
      dead_reckoning::AnchorFix f;
      f.dr_distance_m = o.distance_m;
      o.gnss_fixes.push_back(f);
    }
    first.add(o);
    const SummaryAccumulator::Footprint f = acc.footprint();
    most.scale_factor_rows_waiting = std::max(most.scale_factor_rows_waiting, f.scale_factor_rows_waiting);
    most.navigation_rows_buffered = std::max(most.navigation_rows_buffered, f.navigation_rows_buffered);
    most.dead_reckoning_rows_buffered = std::max(most.dead_reckoning_rows_buffered, f.dead_reckoning_rows_buffered);
    most.outages = std::max(most.outages, f.outages);
    first_waiting = std::max(first_waiting, first.waiting());
  }
  EXPECT_EQ(most.scale_factor_rows_waiting, 0u);
  EXPECT_LE(most.navigation_rows_buffered, 3u);
  EXPECT_LE(most.dead_reckoning_rows_buffered, 3u);
  EXPECT_EQ(most.outages, 0u);
  EXPECT_LE(first_waiting, 10u);  // the outputs between 500 m and the next fix
  EXPECT_LE(period.distinct(), 1000u) << "distinct GNSS intervals of a 10 Hz clock over 5000 s";
  const json s = acc.finish();
  // The figures are still those of the drive: the DR 1e-7 rad of longitude (0.39 m) east.
  EXPECT_EQ(s["dead_reckoning"]["online_k"]["epochs_compared"].get<std::size_t>(), kRows);
  EXPECT_NEAR(s["dead_reckoning"]["online_k"]["final_error_m"].get<double>(),
              1e-7 * 6378137.0 * std::cos(kOrigin.lat_rad), 0.05);
  EXPECT_EQ(s["navigation_position"]["vs_truth"]["rows"].get<std::size_t>(), kRows);
  EXPECT_NEAR(period.median_s(), 0.1, 1e-9);
}

TEST(StreamingSummary, OutputFilesReadRowByRowAreTheRowsWritten) {
  namespace fs = std::filesystem;
  simulator::SimulationConfig cfg = simulator::scenario_config("straight");
  cfg.seed = 2;
  cfg.duration_s = 60.0;
  const Dataset d = simulator::simulate(cfg);
  const OfflineParams p = user_params(d);
  const results::OutputRows rows = to_output_rows(run_offline(d, p), p.identification.estimator_name);
  const fs::path dir = fs::temp_directory_path() / ("odonav-streaming-summary-" + std::to_string(::getpid()));
  fs::create_directories(dir);
  results::write_output_rows(dir.string(), rows);
  const results::OutputRows whole = results::read_output_rows(dir.string());
  ASSERT_FALSE(whole.dead_reckoning.empty());
  ASSERT_FALSE(whole.navigation_position.empty());
  expect_read_row_by_row<results::DeadReckoningRow>(
      dir / "dead_reckoning.csv", whole.dead_reckoning, rows.dead_reckoning.size(),
      [&](const results::DeadReckoningRow& r, const results::DeadReckoningRow& w, std::size_t n) {
        EXPECT_EQ(r.t_s, w.t_s);
        EXPECT_EQ(r.lat_rad, w.lat_rad);
        EXPECT_EQ(r.distance_m, w.distance_m);
        EXPECT_EQ(r.k_source, w.k_source);
        EXPECT_EQ(r.t_s, rows.dead_reckoning[n].t_s);  // and the rows written
      });
  expect_read_row_by_row<results::ScaleFactorRow>(
      dir / "scale_factor.csv", whole.scale_factor, rows.scale_factor.size(),
      [&](const results::ScaleFactorRow& r, const results::ScaleFactorRow& w, std::size_t) {
        EXPECT_EQ(r.k_by_estimator, w.k_by_estimator);
        EXPECT_EQ(r.samples_accepted, w.samples_accepted);
      });
  // A malformed value is named with its file, line and column.
  {
    std::ofstream bad(dir / "navigation_position.csv", std::ios::app);
    bad << "1.0,x";
    for (std::size_t i = 2; i < results::navigation_position_columns().size(); ++i) bad << ",";
    bad << "\n";
  }
  results::OutputFileReader reader((dir / "navigation_position.csv").string());
  results::NavigationPositionRow r;
  std::string error;
  try {
    while (reader.next(r)) {
    }
  } catch (const std::runtime_error& e) {
    error = e.what();
  }
  EXPECT_NE(error.find("navigation_position.csv:" + std::to_string(rows.navigation_position.size() + 2) +
                       ": column 'lat_deg': not a number: 'x'"),
            std::string::npos)
      << error;
  fs::remove_all(dir);
}

// Cursors over one file that advance side by side read it once; one that falls behind the window, or
// starts after it moved, reads on its own and still gives every item in order.
TEST(SharedSource, CursorsMovingTogetherReadTheFileOnceAndALateOneReadsOnItsOwn) {
  struct Counts {
    int opens = 0;
    int reads = 0;
  };
  auto counts = std::make_shared<Counts>();
  constexpr int kItems = 100000;
  const SourceFactory<int> file = [counts]() -> Source<int> {
    ++counts->opens;
    return [counts, i = 0]() mutable -> std::optional<int> {
      if (i == kItems) return std::nullopt;
      ++counts->reads;
      return i++;
    };
  };
  const SourceFactory<int> shared = shared_source(file, 1000);
  Source<int> a = shared(), b = shared(), c = shared();
  { Source<int> probe = shared(); }  // opened, never read: costs nothing
  for (int i = 0; i < kItems; ++i) {
    ASSERT_EQ(a(), i);
    if (i >= 3) {
      ASSERT_EQ(b(), i - 3);  // 3 items behind
    }
    if (i >= 900) {
      ASSERT_EQ(c(), i - 900);  // 900 behind: still inside the window
    }
  }
  EXPECT_EQ(counts->opens, 1);
  EXPECT_EQ(counts->reads, kItems);
  // Two sources starting after the window moved (a second pass): a later generation, read once
  // for both, from the start.
  Source<int> late = shared(), later = shared();
  for (int i = 0; i < kItems; ++i) {
    ASSERT_EQ(late(), i);
    ASSERT_EQ(later(), i);
  }
  EXPECT_EQ(counts->opens, 2);
  EXPECT_EQ(counts->reads, 2 * kItems);
  // Half the pace of a fresh shared reader: falls out of the window and goes on in a later
  // generation, every item in order.
  const SourceFactory<int> again = shared_source(file, 1000);
  Source<int> fast = again(), slow = again();
  for (int i = 0; i < kItems; ++i) {
    ASSERT_EQ(fast(), i);
    if (i % 2 == 0) {
      ASSERT_EQ(slow(), i / 2);
    }
  }
  EXPECT_FALSE(fast().has_value());
  EXPECT_EQ(counts->opens, 4);
}
