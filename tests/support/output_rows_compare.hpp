#pragma once
// The distributed pipeline's output files against odonav-offline's on the same dataset, row by row
// (tests/integration/pipeline and live): every column the pipeline publishes, as the file holds it
// (row_json: file column names, angles in degrees, an empty field null). Numbers within an absolute
// tolerance (K and its sigma: a relative one), empty only where the other is empty, text and counts
// equal. The first differing row of a file fails the test and names the file, the row and the column.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "odonav/results/output_files.hpp"

namespace odonav::test {

/// Whether `column` of a row of the pipeline (`pipe_row`, as row_json) is published: not the other
/// estimators' k_<name> and not the epoch status (neither is on the wire), and lambda_vff_lm_rls only
/// when VFF-LM-RLS is the main estimator.
inline bool published_column(const std::string& column, const nlohmann::json& pipe_row) {
  if (column == "epoch_status") return false;
  if (column == "lambda_vff_lm_rls") return pipe_row.value("estimator", "") == "vff_lm_rls";
  return column.rfind("k_", 0) != 0 || column == "k_m_per_pulse" || column == "k_source";
}

/// One column of one row: numbers close (relative for K and its sigma), null only with null,
/// anything else equal.
inline void expect_same_field(const nlohmann::json& a, const nlohmann::json& b, double tol, const std::string& column,
                              std::size_t row) {
  if (a.is_number_float() || b.is_number_float()) {
    ASSERT_TRUE(a.is_number() && b.is_number()) << column << " row " << row << ": " << a << " vs " << b;
    const double x = a.get<double>(), y = b.get<double>();
    const bool relative = column == "k_m_per_pulse" || column == "sigma_m_per_pulse";
    EXPECT_NEAR(x, y, relative ? tol * std::max(std::abs(x), std::abs(y)) : tol) << column << " row " << row;
  } else {
    EXPECT_EQ(a, b) << column << " row " << row;
  }
}

/// pipe against ref, row by row (`file` names them in a failure).
template <class Row>
void expect_rows_equal(const std::vector<Row>& pipe, const std::vector<Row>& ref, double tol, const char* file) {
  ASSERT_EQ(pipe.size(), ref.size()) << file << " rows";
  for (std::size_t i = 0; i < ref.size(); ++i) {
    ASSERT_NEAR(pipe[i].t_s, ref[i].t_s, tol) << file << " row " << i;
    const nlohmann::json a = results::row_json(pipe[i]);
    const nlohmann::json b = results::row_json(ref[i]);
    for (auto column = b.begin(); column != b.end(); ++column)
      if (published_column(column.key(), a))
        expect_same_field(a.at(column.key()), column.value(), tol, column.key(), i);
    if (::testing::Test::HasFailure()) FAIL() << "first difference at " << file << " row " << i;
  }
}

/// The estimates and the dead reckoning: misalignment, scale factor and dead-reckoning files.
inline void expect_estimate_rows_equal(const results::OutputRows& pipe, const results::OutputRows& ref, double tol) {
  // The misalignment first: identification and DR apply it, so a calibration row missing or
  // differing shows up downstream only as a tiny difference in K.
  ASSERT_NO_FATAL_FAILURE(expect_rows_equal(pipe.misalignment, ref.misalignment, tol, "misalignment"));
  ASSERT_GT(ref.scale_factor.size(), 100u);
  ASSERT_NO_FATAL_FAILURE(expect_rows_equal(pipe.scale_factor, ref.scale_factor, tol, "scale-factor"));
  ASSERT_GT(ref.dead_reckoning.size(), 100u);
  expect_rows_equal(pipe.dead_reckoning, ref.dead_reckoning, tol, "dead-reckoning");
}

/// navigation_position.csv: the GNSS-anchored position, one row per DR output (the DR node's filter
/// against odonav-offline's). mostly_anchored: GNSS valid through most of the drive, and a DR that
/// can use it.
inline void expect_navigation_rows_equal(const results::OutputRows& pipe, const results::OutputRows& ref, double tol,
                                         bool mostly_anchored = false) {
  ASSERT_EQ(ref.navigation_position.size(), ref.dead_reckoning.size());  // one per DR output
  ASSERT_NO_FATAL_FAILURE(
      expect_rows_equal(pipe.navigation_position, ref.navigation_position, tol, "navigation-position"));
  if (mostly_anchored) {
    const auto anchored = std::count_if(ref.navigation_position.begin(), ref.navigation_position.end(),
                                        [](const results::NavigationPositionRow& r) { return r.status == "anchored"; });
    EXPECT_GT(static_cast<std::size_t>(anchored), ref.navigation_position.size() / 2);
  }
}

}  // namespace odonav::test
