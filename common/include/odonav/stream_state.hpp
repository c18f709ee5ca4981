#pragma once
// The checkpoint fields (checkpoint_state.hpp) of the common value types and of the buffered sensor
// streams (odometer and attitude buffers, step histories, GNSS samples), shared by every core whose
// state holds inputs taken in but not processed yet (DeadReckoner, SampleBuilder). Each type's
// fields are listed once, for saving and restoring. Middleware-free.
#include <type_traits>

#include "odonav/checkpoint_state.hpp"
#include "odonav/frames.hpp"
#include "odonav/geodesy.hpp"
#include "odonav/sensor_samples.hpp"
#include "odonav/stream_buffers.hpp"

namespace odonav {

ODONAV_STATE_FIELDS(Geodetic) { a("lat_rad", s.lat_rad)("lon_rad", s.lon_rad)("height_m", s.height_m); }

ODONAV_STATE_FIELDS(Attitude) { a("heading_rad", s.heading_rad)("pitch_rad", s.pitch_rad)("roll_rad", s.roll_rad); }

ODONAV_STATE_FIELDS(Misalignment) { a("heading_rad", s.heading_rad)("pitch_rad", s.pitch_rad); }

ODONAV_STATE_FIELDS(GnssSample) {
  a("t_s", s.t_s)("position", s.position)("vel_enu_mps", s.vel_enu_mps)("pos_std_m", s.pos_std_m)(
      "vel_std_mps", s.vel_std_mps)("fix", s.fix);
}

ODONAV_STATE_FIELDS(OdometerBuffer::Entry) {
  a("t_s", s.t_s)("count", s.count)("raw_pulses", s.raw_pulses)("direction", s.direction);
  a.check("direction", s.direction >= -1 && s.direction <= 1, "is not -1, 0 or 1");
}

ODONAV_STATE_FIELDS(OdometerBuffer::State) {
  a("entries", s.entries)("last_accepted", s.last_accepted)("rejected", s.rejected)(
      "last_rate_pulses_per_s", s.last_rate_pulses_per_s)("jumps_rejected", s.jumps_rejected)("rebases", s.rebases)(
      "last_t_s", s.last_t_s);
}

ODONAV_STATE_FIELDS(AttitudeBuffer::Entry) { a("t_s", s.t_s)("attitude", s.attitude); }

ODONAV_STATE_FIELDS(AttitudeBuffer::State) { a("entries", s.entries)("last_t_s", s.last_t_s); }

namespace state_detail {
/// StepHistory<Value>::State, for any Value (a nested type of a template: not deducible).
template <class T, class = void>
struct is_step_history_state : std::false_type {};
template <class T>
struct is_step_history_state<T, std::void_t<typename decltype(T::entries)::value_type::second_type>>
    : std::is_same<T, typename StepHistory<typename decltype(T::entries)::value_type::second_type>::State> {};
}  // namespace state_detail

/// StepHistory<Value>::State: entries as [t_s, value] pairs, and the last stamp.
template <class Archive, class Self,
          std::enable_if_t<state_detail::is_step_history_state<std::remove_const_t<Self>>::value, int> = 0>
void state_fields(Archive& a, Self& s) {
  a("entries", s.entries)("last_t_s", s.last_t_s);
}

}  // namespace odonav
