#pragma once
// Dead reckoning from its first metre against a truth track (the simulator's): the %D figures of
// docs/ALGORITHM.md §4 over the whole drive, with the part the DR start fix is responsible for
// taken apart. The DR starts at its first GNSS fix, so its error is that fix's error (the start
// offset) plus what dead reckoning adds (the drift). What other origins, built from the same GNSS
// fixes, would have given is computed alongside (the DR outputs carry the fixes they are compared
// with: AnchorFix), to show how much of the start offset any origin from these fixes can remove.
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "odonav/dataset.hpp"
#include "odonav/dead_reckoning/dead_reckoner.hpp"

namespace odonav::offline {

struct FirstMetres {
  static constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  double final_percent = kNaN;            ///< |DR - truth| horizontal / odometer distance, at the end (%D)
  double max_after_500m_percent = kNaN;   ///< max over the drive once past 500 m (%D)
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

/// The figures of `dr` (DeadReckoner outputs of one drive, time order) against d.truth (matched by
/// stamp to the millisecond; outputs without a truth sample are skipped). %D below 1 m of distance is
/// not counted.
FirstMetres evaluate_first_metres(const Dataset& d, const std::vector<DeadReckoningOutput>& dr);

/// One line of text with every figure, for test traces and logs.
std::string describe(const FirstMetres& f);

}  // namespace odonav::offline
