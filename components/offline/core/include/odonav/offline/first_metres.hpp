#pragma once
// Dead reckoning from its first metre against a truth track (the simulator's): the %D figures of
// docs/ALGORITHM.md §4 over the whole drive, with the part the DR start fix is responsible for
// taken apart. The DR starts at its first GNSS fix, so its error is that fix's error (the start
// offset) plus what dead reckoning adds (the drift). What other origins, built from the same GNSS
// fixes, would have given is computed alongside (the DR outputs carry the fixes they are compared
// with: AnchorFix), to show how much of the start offset any origin from these fixes can remove.
#include <cmath>
#include <cstddef>
#include <deque>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "odonav/offline/evaluation.hpp"
#include "odonav/dataset.hpp"
#include "odonav/dead_reckoning/dead_reckoner.hpp"

namespace odonav::offline {

struct FirstMetres {
  static constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  double final_percent = kNaN;           ///< |DR - truth| horizontal / odometer distance, at the end (%D)
  double max_after_500m_percent = kNaN;  ///< max over the drive once past 500 m (%D)
  /// The same two with the start offset taken out.
  double drift_final_percent = kNaN;
  double drift_max_after_500m_percent = kNaN;
  double distance_on_nominal_k_m = kNaN;  ///< odometer distance before the first identified K (m)
  double start_offset_m = kNaN;           ///< |DR - truth| horizontal at the first output (m)
  /// Other origins from the same fixes: the DR shifted by the mean of (fix - DR) over the fixes
  /// taken standing still before the first metre (distance 0), or over every fix up to 500 m.
  /// Horizontal error of that origin (m) and the max %D after 500 m the DR would then have had.
  double standstill_origin_offset_m = kNaN;
  double standstill_origin_max_after_500m_percent = kNaN;
  double first_500m_origin_offset_m = kNaN;
  double first_500m_origin_max_after_500m_percent = kNaN;
};

/// evaluate_first_metres one DR output at a time. The other origins are the means of fixes that
/// come with the outputs; the outputs past 500 m wait (their errors, a few numbers each) until the
/// last fix of the first 500 m has come, which the DR distance (a sum of |dS|, never decreasing)
/// tells: memory does not grow with the drive.
class FirstMetresAccumulator {
 public:
  /// truth: the truth track (time order), matched to the outputs by stamp to the millisecond.
  explicit FirstMetresAccumulator(SourceFactory<TruthSample> truth);
  /// The next DeadReckoner output of the drive (time order).
  void add(const dead_reckoning::DeadReckoningOutput& o);
  /// The figures. Call once.
  FirstMetres finish();
  /// Outputs past 500 m waiting for the origin of the first 500 m (to check the memory bound).
  std::size_t waiting() const { return waiting_.size(); }

 private:
  struct Origin {  // an origin's offset: the mean of (fix - DR) over fixes within max_distance_m
    double max_distance_m;
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    std::size_t n = 0;
    bool complete = false;  ///< a fix beyond max_distance_m has come: no more fixes count
    std::optional<Eigen::Vector3d> mean() const;
  };
  struct Past500m {  // an output past 500 m: its horizontal error (ENU, m) and distance (m)
    Eigen::Vector3d error_m;
    double distance_m;
  };
  std::optional<TruthSample> truth_at_ms(long long t_ms);
  void count_past_500m(const Past500m& p);

  SourceFactory<TruthSample> factory_;
  Source<TruthSample> truth_;
  std::optional<TruthSample> truth_next_;
  bool truth_started_ = false;
  long long matched_ms_ = 0;
  bool matched_valid_ = false;
  std::optional<TruthSample> matched_;
  Origin standstill_{0.0}, first_500m_{500.0};
  std::optional<LocalEnuFrame> frame_;
  std::optional<Eigen::Vector3d> start_offset_;
  std::deque<Past500m> waiting_;
  FirstMetres f_;
};

/// The figures of `dr` (DeadReckoner outputs of one drive, time order) against d.truth (matched by
/// stamp to the millisecond; outputs without a truth sample are skipped). %D below 1 m of distance is
/// not counted. A FirstMetresAccumulator fed the outputs.
FirstMetres evaluate_first_metres(const Dataset& d, const std::vector<dead_reckoning::DeadReckoningOutput>& dr);

/// One line of text with every figure, for test traces and logs.
std::string describe(const FirstMetres& f);

}  // namespace odonav::offline
