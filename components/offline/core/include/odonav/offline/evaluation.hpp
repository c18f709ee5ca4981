#pragma once
// Evaluation of odonav's outputs against a reference: scale-factor error against the true K, and dead
// reckoning error against a reference track (truth, or GNSS when there is no truth). Middleware-free,
// used by odonav-offline and by the pipeline's summary alike, so both report the same figures.
#include <cstddef>
#include <deque>
#include <functional>
#include <memory>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "odonav/geodesy.hpp"
#include "odonav/sensor_samples.hpp"

namespace odonav::offline {

/// A pull source: each call returns the next item in time order, nullopt at the end (and after).
/// The evaluations read truth, GNSS and INS through these, so that no file is held in memory.
template <class T>
using Source = std::function<std::optional<T>()>;
/// Opens a fresh source over the same items, from the first (each evaluated stream keeps its own
/// cursor; a cursor asked for a time before its position opens a fresh one).
template <class T>
using SourceFactory = std::function<Source<T>()>;

/// A factory over items held in memory. The vector must outlive every source made.
template <class T>
SourceFactory<T> vector_source(const std::vector<T>& items) {
  return [&items]() -> Source<T> {
    return [&items, i = std::size_t{0}]() mutable -> std::optional<T> {
      if (i >= items.size()) return std::nullopt;
      return items[i++];
    };
  };
}

/// A factory whose sources share one reader of `open`'s items while they move together: the last
/// `window_items` items read are held, and a source serves its next item from there. A source that
/// falls further behind (or starts after the first item has left the window) moves to a later
/// generation: another shared reader of a fresh source of `open`, which the sources that fall behind
/// after it share in turn. So several cursors over one file that advance side by side (the
/// evaluations of one pass over the outputs) parse it once, those of a later pass once more, and
/// memory is bounded by a window per generation whatever their lag.
template <class T>
SourceFactory<T> shared_source(SourceFactory<T> open, std::size_t window_items = 65536) {
  struct Shared {
    SourceFactory<T> open;
    std::size_t max_items = 0;
    Source<T> reader;      // this generation's reader, opened at its first read
    std::deque<T> window;  // items [base, base + window.size())
    std::size_t base = 0;
    bool ended = false;
    std::shared_ptr<Shared> later;  // the next generation, made when a source falls behind
  };
  struct Cursor {
    std::shared_ptr<Shared> s;
    std::size_t pos = 0;  // the next item to give
    std::optional<T> next() {
      while (pos < s->base) {  // fell behind this generation's window
        if (!s->later) {
          s->later = std::make_shared<Shared>();
          s->later->open = s->open;
          s->later->max_items = s->max_items;
        }
        s = s->later;
      }
      Shared& g = *s;
      while (pos - g.base >= g.window.size() && !g.ended) {  // read up to this source's place
        if (!g.reader) g.reader = g.open();
        if (std::optional<T> item = g.reader()) {
          g.window.push_back(std::move(*item));
          if (g.window.size() > g.max_items) {
            g.window.pop_front();
            ++g.base;
          }
        } else {
          g.ended = true;
        }
      }
      if (pos - g.base >= g.window.size()) return std::nullopt;
      return g.window[pos++ - g.base];
    }
  };
  auto shared = std::make_shared<Shared>();
  shared->open = std::move(open);
  shared->max_items = window_items > 0 ? window_items : 1;
  return [shared]() -> Source<T> {
    auto cursor = std::make_shared<Cursor>();
    cursor->s = shared;
    return [cursor]() { return cursor->next(); };
  };
}

/// A value at a time (t_s on the dataset's time base).
struct TimedValue {
  double t_s = 0.0;
  double value = 0.0;
};

/// A step of the true K at t_s (from the simulator's meta.json).
struct KStep {
  double t_s = 0.0;
  double k_before_m_per_pulse = 0.0;
  double k_after_m_per_pulse = 0.0;
};

/// Scale-factor accuracy figures. Times in seconds, errors relative (0.001 = 0.1 %).
struct KEvaluation {
  std::size_t epochs = 0;  ///< estimates compared (after convergence, outside settle windows).
  double rms_rel_error = std::numeric_limits<double>::quiet_NaN();
  double max_rel_error = std::numeric_limits<double>::quiet_NaN();
  double final_rel_error = std::numeric_limits<double>::quiet_NaN();
  /// Time from the first valid motion until K stays within the tolerance (until the first K step or
  /// the end); NaN when it never does.
  double time_to_converge_s = std::numeric_limits<double>::quiet_NaN();
  /// Per K step: time from the step until K stays within the tolerance of the new K (until the next
  /// step or the end); NaN when it never does.
  std::vector<double> settle_times_s;
};

struct KEvaluationParams {
  double tolerance_rel = 0.005;   ///< "within 0.5 %".
  double settle_window_s = 10.0;  ///< excluded from the RMS after each step (the allowed settle time).
};

/// evaluate_scale_factor one estimate at a time, in constant memory: estimates in time order, each
/// with the reference K in force at its time.
class ScaleFactorEvaluator {
 public:
  /// steps: the true K's steps (time order; their times in s bound the settle windows).
  explicit ScaleFactorEvaluator(std::vector<KStep> steps, const KEvaluationParams& params = {});
  /// The time (s) of the first accepted regression sample; convergence is timed from it. Estimates
  /// added before this call only count as the final estimate (they precede the first motion).
  void set_first_motion(double t_s);
  /// One estimate K (m/pulse) at t_s (s, not before the previous estimate's) against the reference K
  /// in force at t_s (m/pulse).
  void add(double t_s, double estimate_m_per_pulse, double reference_m_per_pulse);
  /// Forgets the steps from index n on (a drive cut short never reaches them); only while no
  /// estimate at or after step n's time has been added.
  void drop_steps_from(std::size_t n);
  /// The figures of the estimates added so far.
  KEvaluation result() const;

 private:
  struct Sums {  // squared and largest relative error, and their count, of an RMS span
    double sum_sq = 0.0, max_abs = 0.0;
    std::size_t n = 0;
    void add(double rel);
  };
  std::vector<KStep> steps_;
  KEvaluationParams params_;
  double first_motion_s_ = std::numeric_limits<double>::quiet_NaN();
  std::size_t segment_ = 0;  ///< 0: before the first step; s + 1: from step s to the next.
  double converge_candidate_s_ = std::numeric_limits<double>::quiet_NaN();
  std::vector<double> settle_candidate_s_;  ///< per step
  Sums since_candidate_;                    ///< estimates from the convergence candidate on
  Sums after_window_;                       ///< estimates from first motion + settle window on (never converged)
  double last_rel_ = std::numeric_limits<double>::quiet_NaN();
  bool any_ = false;
};

/// Compares an estimate series with the reference K (a step function: the latest reference value at
/// or before each estimate's time). first_motion_t_s: time of the first accepted regression sample.
/// The RMS covers estimates after convergence (time_to_converge), outside [step, step + settle_window).
/// ScaleFactorEvaluator over whole vectors.
KEvaluation evaluate_scale_factor(const std::vector<TimedValue>& estimate_m_per_pulse,
                                  const std::vector<TimedValue>& reference_m_per_pulse, const std::vector<KStep>& steps,
                                  double first_motion_t_s, const KEvaluationParams& params = {});

/// A position at a time.
struct TimedPosition {
  double t_s = 0.0;
  Geodetic position;
};

/// A span of time without GNSS.
struct Outage {
  double start_s = 0.0;
  double end_s = 0.0;
};

/// Dead-reckoning accuracy figures: horizontal error in metres and in % of distance travelled (%D).
struct DrEvaluation {
  std::size_t epochs = 0;
  double distance_m = 0.0;  ///< distance travelled at the last compared epoch.
  double final_error_m = std::numeric_limits<double>::quiet_NaN();
  double final_error_percent = std::numeric_limits<double>::quiet_NaN();
  double max_error_m = std::numeric_limits<double>::quiet_NaN();
  double max_error_percent = std::numeric_limits<double>::quiet_NaN();  ///< over distance >= min_distance_m.
  /// Per outage: the error DR accumulates across the outage alone (as if re-initialised on the
  /// reference at the last reference epoch before it): |(DR_end - DR_start) - (ref_end - ref_start)|
  /// horizontally, in metres and in % of the distance travelled over the outage.
  std::vector<double> outage_error_m;
  std::vector<double> outage_error_percent;
};

/// The GNSS outages of a drive, found as a stream is read: a fixed list (the simulator's meta.json),
/// or the spans of >= 5 s without a valid fix, found by reading a GNSS source ahead of the caller.
class OutageList {
 public:
  /// Outages known beforehand (s, in the order given).
  explicit OutageList(std::vector<Outage> outages);
  /// Outages between consecutive valid fixes of `gnss` at least min_gap_s apart (s).
  explicit OutageList(Source<GnssSample> gnss, double min_gap_s = 5.0);
  /// Reads the GNSS ahead until every outage that starts at or before t_s (s) is known.
  void discover_through(double t_s);
  /// Reads the GNSS to its end.
  void discover_all();
  /// The outages found so far, in time order of discovery.
  const std::vector<Outage>& outages() const { return outages_; }

 private:
  std::vector<Outage> outages_;
  Source<GnssSample> gnss_;
  double min_gap_s_ = 5.0;
  std::optional<double> last_valid_s_;
};

/// evaluate_dead_reckoning one DR epoch at a time, in constant memory: the reference is read
/// through two cursors of its own (one for the errors, one for the outages' end points).
class DeadReckoningEvaluator {
 public:
  /// reference: the reference track (time order); outages: as evaluate_dead_reckoning's;
  /// min_distance_m: %D maxima ignore the first metres (m).
  DeadReckoningEvaluator(const SourceFactory<TimedPosition>& reference, OutageList outages,
                         double min_distance_m = 100.0);
  /// One DR epoch: time (s, not before the previous epoch's), WGS-84 position, distance travelled (m).
  void add(double t_s, const Geodetic& position, double distance_m);
  /// The figures; reads the rest of the reference and of the outage source. Call once.
  DrEvaluation finish();
  /// The outages (complete after finish()).
  const std::vector<Outage>& outages() const { return outages_.outages(); }

 private:
  struct Epoch {  // one DR epoch as the outage computation needs it
    double t_s = 0.0;
    Geodetic position;
    double distance_m = 0.0;
  };
  struct Probe {  // a reference epoch with the DR track at its time
    TimedPosition reference;
    std::optional<Geodetic> dr;
    double dr_distance_m = 0.0;
  };
  struct OutageState {
    bool start_decided = false;
    std::optional<Probe> start;
    bool done = false;
    double error_m = std::numeric_limits<double>::quiet_NaN();
    double error_percent = std::numeric_limits<double>::quiet_NaN();
  };
  void resolve(const TimedPosition& q, const Epoch* next);
  void close_outages(const Probe& p);

  Source<TimedPosition> error_ref_, probe_ref_;
  std::optional<TimedPosition> ref_prev_, ref_next_;
  bool ref_started_ = false;
  std::optional<TimedPosition> probe_next_;
  bool probe_started_ = false;
  OutageList outages_;
  std::vector<OutageState> outage_states_;
  double min_distance_m_;
  std::optional<Epoch> first_, last_;
  Geodetic group_first_position_;  ///< position of the first epoch at last_'s time
  std::optional<Probe> last_probe_;
  DrEvaluation out_;
  double max_err_ = 0.0, max_pct_ = 0.0;
  bool any_pct_ = false;
};

/// Compares a DR track with a reference track (interpolated linearly in time; epochs outside the
/// reference's span are skipped). distance_m: distance travelled at each DR epoch (same length as dr).
/// min_distance_m: %D maxima ignore the first metres, where %D is meaningless.
/// DeadReckoningEvaluator over whole vectors.
DrEvaluation evaluate_dead_reckoning(const std::vector<TimedPosition>& dr, const std::vector<double>& distance_m,
                                     const std::vector<TimedPosition>& reference, const std::vector<Outage>& outages,
                                     double min_distance_m = 100.0);

/// Whether a truth file describes the drive of the GNSS fixes: the horizontal distance between each
/// of the first `fixes` valid moving fixes (GNSS speed >= min_speed_mps; the first valid fixes when
/// the drive has fewer) that lie within the truth's time span and the truth interpolated at its
/// stamp, their median against max_median_m. A truth of another place, or shifted in time by more
/// than max_median_m / speed, is refused. Returns why (naming the times and distances), or nullopt
/// when it matches or there is nothing to compare (no valid fix, no truth position). Reads gnss until
/// the fixes are found (and further while the truth starts later) and truth as far as they reach.
std::optional<std::string> truth_mismatch(Source<GnssSample>&& gnss, Source<TruthSample>&& truth,
                                          std::size_t fixes = 20, double min_speed_mps = 2.0,
                                          double max_median_m = 100.0);

}  // namespace odonav::offline
