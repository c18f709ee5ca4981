#pragma once
// Holes in a periodic output stream, from the sample stamps alone: "missed 522 dead-reckoning
// outputs t=40.010-45.220 s". The period is declared, or learned as the smallest interval seen (a
// stream at the odometer's 100 Hz: 0.01 s). An interval longer than 1.5 periods is a gap of
// round(interval / period) - 1 outputs. Stamps must come in order; repeats and backward stamps
// are ignored (counted by the caller). Event time only: the same at any replay speed. No DDS here.
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace odonav {

struct OutputGap {
  double first_missing_t_s;  ///< the stamp the first missing output would have had
  double last_missing_t_s;   ///< and the last
  std::uint64_t missed;      ///< outputs missing between the two samples around the gap
};

class GapDetector {
 public:
  /// declared_period_s: the stream's period, s (> 0), or 0 to learn it from the stamps. Throws
  /// std::invalid_argument for a negative or non-finite value.
  explicit GapDetector(double declared_period_s = 0.0);

  /// The next stamp (s). Returns the gap it closes, if any.
  std::optional<OutputGap> offer(double t_s);

  std::uint64_t missed() const { return missed_; }  ///< outputs missing in all gaps
  std::uint64_t gaps() const { return gaps_; }      ///< number of gaps
  const std::optional<OutputGap>& last_gap() const { return last_gap_; }
  /// The period in use (declared or learned so far); nothing before two stamps when learning.
  std::optional<double> period_s() const;

 private:
  double declared_period_s_;
  std::optional<double> learned_period_s_;
  std::optional<double> last_t_s_;
  std::uint64_t missed_ = 0;
  std::uint64_t gaps_ = 0;
  std::optional<OutputGap> last_gap_;
};

/// "missed 522 dead-reckoning outputs t=40.010-45.220 s" (what: "dead-reckoning").
std::string describe_gap(const OutputGap& gap, const std::string& what);

/// The epochs (s) of a reference stream without a row of a stream that has one row per reference
/// epoch (the estimators publish one Misalignment and one ScaleFactor per GNSS epoch), as runs of
/// consecutive reference epochs: first and last epoch missing, and how many. A row matches an
/// epoch within 1 us (a stamp that crossed DDS is integer nanoseconds). Both in any order; repeats
/// count once; rows at no epoch are ignored. Runs in time order.
std::vector<OutputGap> missing_epochs(std::vector<double> epochs_s, std::vector<double> rows_s);

}  // namespace odonav
