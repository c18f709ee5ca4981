#pragma once
// The health a component's core decides (calibration_health, identification_health,
// dead_reckoning_health: pure functions over the facts their nodes supply); the DDS layer maps it
// onto the Health topic (EventTimeNode::status_of) past its own checks on the required inputs.
#include <string>

namespace odonav {

struct ComponentHealth {
  enum class State { kStarting, kRunning, kDegraded };
  enum class Level { kOk, kWarn };
  State state = State::kRunning;
  Level level = Level::kOk;
  std::string reason;  ///< "" when all is well; parts joined by "; ".
};

}  // namespace odonav
