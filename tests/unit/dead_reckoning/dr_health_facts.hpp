#pragma once
// The health facts of a dead reckoning that runs with both estimates: the start of the tests of its
// health decision (tests/unit/dead_reckoning), which then add what they check.
#include <cstdint>

#include "odonav/dead_reckoning/dead_reckoning_health.hpp"

namespace odonav::test {

/// Started (a start fix found), a K and a misalignment heard, k_applied K values and
/// misalignments_applied misalignments given to the DR: OK as it is.
inline dead_reckoning::DeadReckoningHealthFacts running_dr_facts(uint64_t k_applied, uint64_t misalignments_applied) {
  dead_reckoning::DeadReckoningHealthFacts f;
  f.started = true;
  f.scale_factor_heard = true;
  f.k_applied = k_applied;
  f.misalignment_heard = true;
  f.misalignments_applied = misalignments_applied;
  return f;
}

}  // namespace odonav::test
