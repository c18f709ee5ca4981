#pragma once
// Evaluation of dead reckoning as error in percent of distance travelled (%D), against GNSS (the
// horizontal_error_m of DeadReckoningOutput) or against a truth track (TruthTrack below).
#include <cstdint>
#include <limits>
#include <optional>
#include <vector>

#include "odonav/dataset.hpp"
#include "odonav/geodesy.hpp"

namespace odonav::dead_reckoning {

struct DriftSummary {
  uint64_t points = 0;  ///< points with distance >= min_distance_m.
  double final_distance_m = std::numeric_limits<double>::quiet_NaN();
  double final_error_m = std::numeric_limits<double>::quiet_NaN();
  double final_percent = std::numeric_limits<double>::quiet_NaN();           ///< 100 final error / final distance.
  double max_percent = std::numeric_limits<double>::quiet_NaN();             ///< max of 100 error / distance.
  double max_percent_distance_m = std::numeric_limits<double>::quiet_NaN();  ///< where the max was.
};

/// Accumulates (distance travelled, horizontal error) pairs in time order. Points below
/// min_distance_m are ignored, because %D of a short distance is dominated by the initial error.
class DriftEvaluator {
 public:
  /// min_distance_m >= 0 (m). Default 100.
  explicit DriftEvaluator(double min_distance_m = 100.0);
  /// distance_m >= 0 (m), horizontal_error_m >= 0 (m); NaN errors (no reference) are skipped.
  void add(double distance_m, double horizontal_error_m);
  DriftSummary summary() const { return summary_; }

 private:
  double min_distance_m_;
  DriftSummary summary_;
};

/// A truth track (truth.csv rows with a position), position at a time by linear interpolation of
/// latitude, longitude and height between the bracketing rows (the truth is dense: 10 Hz or more).
class TruthTrack {
 public:
  /// Rows without a finite position are skipped. max_gap_s: longest gap interpolated (s).
  explicit TruthTrack(const std::vector<TruthSample>& truth, double max_gap_s = 1.0);
  /// Position at t_s, or nullopt outside the track or across a gap.
  std::optional<Geodetic> position_at(double t_s) const;

 private:
  std::vector<TruthSample> rows_;
  double max_gap_s_;
};

}  // namespace odonav::dead_reckoning
