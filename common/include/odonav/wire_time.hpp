#pragma once
// The time a stamp has on the wire. A DDS sample carries its stamp as builtin_interfaces/Time:
// whole seconds (int32) and nanoseconds, rounded to the nearest nanosecond. Every consumer in the
// pipeline sees that rounded time, not the producer's double; odonav-offline delivers the same
// (wire_time_s) so its components see the times the pipeline's nodes see. A dataset time such as
// 16.150000000000002 (323 x 0.05 s) reads 16.15 on the wire, equal to the odometer's 16.15: which
// samples share a stamp decides what goes into an epoch, so both must see the same.
#include <cstdint>

namespace odonav {

/// A time split as on the wire: sec = floor(t_s), nanosec the fraction rounded to the nearest
/// nanosecond, in [0, 1e9) (a fraction that rounds up to 1 s carries into sec). -0.25 s is
/// {-1, 750000000}.
struct WireTime {
  std::int32_t sec = 0;
  std::uint32_t nanosec = 0;
};

/// Valid range: finite t_s whose floor fits int32 ([-2147483648, 2147483647.9999999995] s).
/// Throws std::invalid_argument naming the value outside it (NaN, infinity, beyond 2038).
/// Exactness: a double holds a nanosecond exactly only while its ulp is below 1 ns, i.e. for
/// |t_s| < 2^22 s (48 days); there to_wire_time(from_wire_time(w)) == w for every w.
WireTime to_wire_time(double t_s);

/// True when to_wire_time(t_s) succeeds: t_s finite and its floor within int32 once rounded to
/// the nanosecond. A dataset reader refuses a row whose time fails this, so nothing accepted from a
/// file is refused later by the pipeline.
bool fits_wire_time(double t_s);

/// sec + nanosec * 1e-9 in seconds, rounded once to the nearest double. Throws
/// std::invalid_argument if nanosec >= 1e9 (not a normalized time, e.g. from a bad peer).
double from_wire_time(std::int32_t sec, std::uint32_t nanosec);

/// from_wire_time(to_wire_time(t_s)): the time a consumer reads for a sample stamped t_s.
/// Idempotent. Same range and errors as to_wire_time.
double wire_time_s(double t_s);

}  // namespace odonav
