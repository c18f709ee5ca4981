#pragma once
// Dead reckoning checking its own results against independent evidence, so that an input with the
// wrong sign or unit (an INS heading of another convention, in radians instead of degrees, a pulse
// count of another unit) is named instead of giving a confident wrong track. While GNSS is valid:
//
//   heading rate    the change of the INS heading used by dead reckoning against the change of the
//                   GNSS course over the same intervals (1 s, both ends above min_speed_mps, the
//                   course turning by min_interval_turn_rad at least), as the median of the ratios
//                   dpsi / dchi over the last window_s, decided once min_intervals of them have turned
//                   min_turn_rad together. A GNSS velocity outlier turns the course by tens of
//                   degrees for one epoch and back: two adjacent intervals turning by at least
//                   spike_turn_rad each, opposite ways, back to within half of it, are left out; the
//                   median takes care of the rest. About 1 on a good drive (slip in turns
//                   moves the course, not its rate over a second); -1: another sign convention;
//                   1/57.3: radians read as degrees.
//   drift growth    how fast the DR-versus-GNSS error vector grows per distance driven, over the
//                   last growth_window_m, against what the K and misalignment sigmas allow (3 sigma
//                   each, plus the GNSS position noise over the window) and never below
//                   growth_floor_percent. Decided only while K and the misalignment say converged.
//   odometer speed  the odometer distance (with the K in force) against the GNSS distance (speed
//                   integrated between epochs) over the same window; 1 +- speed_ratio_tolerance.
//
// GNSS position jumps are counted too: a valid fix farther from the last accepted one than
// jump_speed_mps times their interval plus jump_margin_m (a fix of the track it left; after
// jump_max_consecutive such fixes in a row the receiver really is elsewhere, and the newest one is
// taken). They are outliers of the input, counted and reported; the anchored position's gate and the
// estimators (which use the GNSS velocity) keep them out of the results.
//
// A finding needs persist_s of consistent evidence before it is raised or cleared, so that one bad
// fix cannot raise it. Its text names the likely cause with the observed numbers. The monitor only
// reads: it changes no output; the node turns its findings into Health WARN and odonav-offline into
// summary.json warnings, and withdraws "converged" while one is raised.
//
// Frames and units: ENU metres of the DR origin, radians, seconds of event time.
#include <cstdint>
#include <deque>
#include <optional>
#include <string>
#include <vector>

#include "odonav/dead_reckoning/dead_reckoner.hpp"
#include "odonav/sensor_samples.hpp"

namespace odonav::dead_reckoning {

struct ConsistencyParams {
  double min_speed_mps = 3.0;           ///< course and heading compared above this GNSS speed (m/s)
  double rate_interval_s = 1.0;         ///< heading and course changes taken over this interval (s)
  double max_rate_radps = 1.0;          ///< a course change faster than this is a jump, not a turn (rad/s)
  double window_s = 120.0;              ///< evidence of the heading-rate check kept this long (s)
  double min_interval_turn_rad = 0.05;  ///< an interval counts when the course turns this much (rad)
  double spike_turn_rad = 0.15;         ///< a turn and back this large in two intervals is an outlier (rad)
  double min_turn_rad = 1.0;            ///< course turned within the window before the check decides (rad)
  double min_intervals = 10;            ///< turning intervals within the window before the check decides
  double rate_ratio_tolerance = 0.3;    ///< |ratio - 1| beyond this is a violation (-)
  double growth_window_m = 300.0;       ///< drift growth and odometer speed measured over this distance (m)
  double growth_floor_percent = 10.0;   ///< drift growth below this (%D) is never a violation
  double sigma_factor = 3.0;            ///< sigmas allowed for the growth (-)
  double gnss_position_sigma_m = 3.0;   ///< GNSS position one-sigma when a fix has none (m)
  double speed_ratio_tolerance = 0.2;   ///< |odometer / GNSS distance - 1| beyond this is a violation (-)
  double persist_s = 5.0;               ///< evidence needed this long to raise or clear a finding (s)
  double jump_speed_mps = 100.0;        ///< a fix farther than this speed allows from the last one is a jump (m/s)
  double jump_margin_m = 100.0;         ///< plus this (m): GNSS noise and a receiver's reacquisition
  double jump_max_consecutive = 10;     ///< this many jumps in a row: the receiver is elsewhere, take it
};

/// GNSS position jumps (see the file comment).
struct GnssJumpCounters {
  uint64_t jumps = 0;
  double first_t_s = 0.0;    ///< event time of the first (s)
  double largest_m = 0.0;    ///< the largest distance from the track (m)
  uint64_t relocations = 0;  ///< jump_max_consecutive jumps in a row, taken as the new track
};

/// The checks, in the order of the file comment.
enum class ConsistencyCheck { kHeadingRate, kDriftGrowth, kOdometerSpeed };
constexpr int kConsistencyChecks = 3;
/// "heading_rate", "drift_growth", "odometer_speed".
const char* to_string(ConsistencyCheck check);

/// The words for a heading-rate ratio (INS heading change / GNSS course change) over turned_rad of
/// turns; nullopt while |ratio - 1| <= tolerance. Pure.
std::optional<std::string> heading_rate_finding(double ratio, double turned_rad, double tolerance);
/// The words for a drift growth (%D) against the growth the sigmas allow (%D); nullopt while it is
/// not above max(allowed, floor). Pure.
std::optional<std::string> drift_growth_finding(double growth_percent, double allowed_percent, double floor_percent);
/// The words for an odometer / GNSS distance ratio; nullopt while |ratio - 1| <= tolerance. Pure.
std::optional<std::string> odometer_speed_finding(double ratio, double tolerance);

/// The state of one check: raised (with the text of the evidence that raised it) or not, and how
/// often it was raised.
struct ConsistencyState {
  bool raised = false;
  std::string text;          ///< the finding in force, or the last one (raised == false)
  double raised_at_s = 0.0;  ///< event time it was last raised (s)
  uint64_t times_raised = 0;
  /// The latest evidence: the ratio or growth measured (NaN before any).
  double last_value = 0.0;
};

class ConsistencyMonitor {
 public:
  /// Throws std::invalid_argument naming a parameter that is not finite and positive.
  explicit ConsistencyMonitor(const ConsistencyParams& params = {});

  /// Each GNSS sample, in time order (the dead reckoner's GNSS input).
  void add_gnss(const GnssSample& sample);
  /// The estimates in force: K (m/pulse) and its one-sigma (<= 0 or not finite: unknown), the
  /// misalignment heading one-sigma (rad; unknown likewise), and whether each says converged.
  void set_scale_factor(double k_m_per_pulse, double sigma_m_per_pulse, bool converged);
  void set_misalignment(double heading_std_rad, bool converged);
  /// Each dead-reckoning output, in time order.
  void on_output(const DeadReckoningOutput& output);

  /// True while no check is raised.
  bool consistent() const { return raised_count_ == 0; }
  /// The findings in force, "; "-separated ("" when consistent).
  std::string reason() const;
  const ConsistencyState& state(ConsistencyCheck check) const { return states_[static_cast<int>(check)]; }
  const GnssJumpCounters& gnss_jumps() const { return jumps_; }

 private:
  struct Epoch {  // a valid GNSS epoch waiting for the output that reaches it
    double t_s;
    double course_rad;       // NaN below min_speed_mps
    double gnss_distance_m;  // GNSS distance integrated up to this epoch
    uint64_t segment;        // run of valid epochs without a gap it belongs to
  };
  struct Pair {  // an epoch with the output at or just after it
    double t_s, course_rad, heading_rad, gnss_distance_m, odometer_distance_m;
    uint64_t segment;
  };
  struct Change {  // a turning interval: its heading / course change ratio
    double t_s, ratio, dchi_rad;
  };
  struct Fix {  // DR-minus-GNSS error at an anchor fix
    double t_s, distance_m, east_m, north_m, sigma_m;
  };
  void add_pair(const Pair& p);
  void add_fix(const AnchorFix& f);
  /// Evidence at t_s: a finding (or nullopt for a pass) for check c; raises or clears after persist_s.
  void evidence(ConsistencyCheck c, double t_s, const std::optional<std::string>& finding, double value);

  ConsistencyParams params_;
  void count_jump(const GnssSample& g);
  std::optional<GnssSample> last_gnss_;
  std::optional<GnssSample> last_accepted_fix_;
  int consecutive_jumps_ = 0;
  GnssJumpCounters jumps_;
  double gnss_distance_m_ = 0.0;
  uint64_t gnss_segment_ = 0;
  std::deque<Epoch> epochs_;
  std::optional<Pair> anchor_;
  std::deque<Change> changes_;
  std::deque<Pair> speed_pairs_;
  std::deque<Fix> fixes_;
  double k_m_per_pulse_ = 0.0, k_sigma_rel_ = -1.0, heading_std_rad_ = -1.0;
  bool k_converged_ = false, misalignment_converged_ = false;
  ConsistencyState states_[kConsistencyChecks];
  // Per check: since when the evidence has disagreed with the state in force (NaN: it agrees).
  double disagree_since_s_[kConsistencyChecks];
  std::string pending_text_[kConsistencyChecks];
  int raised_count_ = 0;
};

}  // namespace odonav::dead_reckoning
