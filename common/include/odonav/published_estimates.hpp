#pragma once
// What the estimate topics carry to their consumers, in the cores' units and without middleware:
// the fields of idl/Misalignment.idl and idl/ScaleFactor.idl that identification and dead reckoning
// use. A DDS node converts a received message into one of these; odonav-offline converts a
// producer's output into one with the same function the producer's node publishes from. Either way
// the consumer's component class applies it by the rules of consumer_rules.hpp, so both transports
// decide alike.
#include <cstdint>
#include <string>

namespace odonav {

/// One Misalignment sample (odometer-to-body installation angles, rad; heading about the body z
/// axis, pitch about the body y axis).
struct PublishedMisalignment {
  double t_s = 0.0;  ///< GNSS epoch of the estimate (event time, s)
  double heading_rad = 0.0;
  double pitch_rad = 0.0;
  double heading_std_rad = -1.0;  ///< one-sigma (rad); -1 (or not finite) = unknown
  double pitch_std_rad = -1.0;
  bool converged = false;
  uint64_t samples_used = 0;  ///< GNSS epochs the calibration has used so far
};

/// One ScaleFactor sample of an identification instance.
struct PublishedScaleFactor {
  double t_s = 0.0;                 ///< GNSS epoch of the estimate (event time, s)
  double k_m_per_pulse = 0.0;       ///< odometer scale factor (m/pulse); 0 = no value yet
  double sigma_m_per_pulse = -1.0;  ///< one-sigma of K (m/pulse); -1 = unknown
  bool converged = false;
  uint64_t samples_accepted = 0;  ///< regression samples the identification accepted so far
  std::string source;             ///< publishing identification instance (e.g. "identification")
  double gnss_latency_s = 0.0;  ///< GNSS receiver latency in force (s): a fix stamped g is the position at g - latency
  /// Track slip in turns (turn_slip.hpp): whether the gain applies, the gain (s/rad, >= 0) and the
  /// yaw rate (rad/s, >= 0) beyond which it applies.
  bool turn_slip_applies = false;
  double turn_slip_s_per_rad = 0.0;
  double turn_slip_threshold_radps = 0.0;
};

}  // namespace odonav
