#pragma once
// Sigma coverage: whether the one-sigmas odonav publishes beside its estimates are the size of the
// actual error. For each published estimate with a sigma, z = (estimate - reference) / sigma; an
// honest Gaussian sigma has 68.3 % of |z| within 1, 95.4 % within 2, 99.7 % within 3, and a mean
// normalised error squared (NEES, z^2 per axis) of 1. A mean NEES far above 1 is a sigma too small
// (overconfident), far below 1 a sigma too large.
//
// Quantities and their references (what a dataset has):
//   K                     scale_factor.csv k_m_per_pulse, sigma_m_per_pulse against the true K in force
//                         at the row's time: the simulation's K timeline (k_true_initial_m_per_pulse,
//                         k_steps; truth.csv's k_true also holds the turn slip, which is not K), else
//                         truth.csv's k_true, else CoverageOptions::k_reference_m_per_pulse
//   misalignment heading, misalignment.csv against meta.json's truth; the heading against the
//   misalignment pitch    mechanical angle plus simulation.ins_heading_bias_deg (a constant INS
//                         heading error cannot be told from a misalignment: the calibration estimates
//                         their sum, docs/ALGORITHM.md §1)
//   GNSS latency          scale_factor.csv gnss_latency_s (the latency in force), gnss_latency_sigma_s,
//                         against simulation.gnss_latency_s (0 when the simulation has no latency)
//   position east / north / up   navigation_position.csv against truth.csv's positions at the row's
//                         time; without truth positions, against each valid GNSS fix (no lever arm)
//                         with the rows from before the fix applied (a one-step prediction), the
//                         fix's variance added to the row's
// Each quantity is counted from its first estimate with a sigma, every later row with one; the
// "converged" subset holds the rows flagged converged (GNSS latency: rows whose K is flagged
// converged; position: rows with status anchored).
#include <cstddef>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "odonav/dataset.hpp"
#include "odonav/defaults.hpp"
#include "odonav/results/output_files.hpp"

namespace odonav::offline {

/// Counts of normalised errors z = error / sigma.
struct Coverage {
  std::size_t n = 0;
  std::size_t within_1_sigma = 0, within_2_sigma = 0, within_3_sigma = 0;
  double sum_nees = 0.0;   ///< sum of z^2
  double max_abs_z = 0.0;  ///< the largest |z|

  /// One estimate: error and its published one-sigma (same unit). A sigma of 0 claims an exact
  /// value: any error is then outside every bound (z infinite). Ignored when the error is not
  /// finite or the sigma is negative or not finite (no claim to test).
  void add(double error, double sigma);
  void merge(const Coverage& other);
  /// Fraction of |z| <= k for k = 1, 2, 3; NaN without estimates.
  double fraction_within(int k_sigma) const;
  /// Mean z^2; NaN without estimates.
  double mean_nees() const;
};

struct QuantityCoverage {
  std::string quantity;  ///< "K", "misalignment heading", ..., "position up"
  Coverage all;          ///< every estimate with a sigma from the first one
  Coverage converged;    ///< those flagged converged (latency: K converged; position: anchored)
};

struct CoverageOptions {
  /// K reference for a dataset whose truth.csv has no k_true (m/pulse), e.g. a recording's ratio of
  /// reference distance to pulses; unset: K is not evaluated there.
  std::optional<double> k_reference_m_per_pulse;
  /// Without truth positions, a fix of epoch g is compared with the navigation rows before
  /// g + hold_off_s (the DR's --estimate-hold-off-s: the fix applies from there on).
  double hold_off_s = kDefaultEstimateHoldOff_s;
  /// Vertical sigma of a GNSS fix = this x its pos_std_m (the anchored filter's vertical_sigma_factor).
  double fix_vertical_sigma_factor = 1.5;
};

/// The coverage of every quantity `dataset` has a reference for, in the order of the list above
/// (quantities without a reference are left out). Rows in time order, as the output files hold them.
/// Throws DatasetError on a malformed meta.json "simulation" object.
std::vector<QuantityCoverage> evaluate_coverage(const Dataset& dataset, const results::OutputRows& rows,
                                                const CoverageOptions& options = {});

}  // namespace odonav::offline
