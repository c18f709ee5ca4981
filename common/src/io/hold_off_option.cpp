#include "odonav/hold_off_option.hpp"

#include "odonav/consumer_rules.hpp"

namespace odonav {

void add_estimate_hold_off_option(Options& o) {
  if (o.declared("estimate-hold-off-s")) return;  // identification and dead reckoning options in one tool
  o.add_double("estimate-hold-off-s", kDefaultEstimateHoldOff_s,
               "an estimate (misalignment, K) or GNSS reference of epoch g applies to odometer samples stamped "
               ">= g + this (s): covers the GNSS receiver latency plus one hop, so no output waits for a later "
               "epoch; 0 = apply from the epoch itself (outputs then wait for it)",
               0.0, 10.0);
}

double estimate_hold_off_from(const Options& o) { return o.get_double("estimate-hold-off-s"); }

}  // namespace odonav
