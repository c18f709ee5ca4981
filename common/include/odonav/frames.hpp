#pragma once
// Frames and rotations used everywhere in odonav.
//
// Navigation frame n: local East-North-Up (ENU).
// Body frame b: the INS body, forward-left-up (FLU, REP-103).
// Odometer frame m: forward axis of the odometer, turned from the INS body by the installation
//   misalignment (see docs/DATASET.md "Frames and sign conventions").
//
// Attitude conventions (as in docs/DATASET.md):
//   heading_rad: true azimuth of the body forward axis, clockwise from north, any value (wrapped);
//   pitch_rad:   positive nose up, valid range [-pi/2, pi/2];
//   roll_rad:    positive right side down, any value.
// Misalignment conventions:
//   heading misalignment a_h: odometer forward axis turned LEFT (counter-clockwise seen from above)
//     of the INS forward axis;  pitch misalignment a_p: odometer forward axis points UP.
//   A motion along the odometer axis at speed v shows in the body frame (FLU):
//     v * (cos a_h cos a_p, sin a_h cos a_p, sin a_p).
#include <Eigen/Dense>
#include <cmath>
#include <limits>

namespace odonav {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDegToRad = kPi / 180.0;
constexpr double kRadToDeg = 180.0 / kPi;

inline double deg_to_rad(double deg) { return deg * kDegToRad; }
inline double rad_to_deg(double rad) { return rad * kRadToDeg; }

namespace detail {
/// The x with forward(x) == target exactly, walked from `guess` (forward(guess) ~ target) at most
/// 16 ulps of x towards the side that closes the gap; when no such x is met, the x with the
/// smallest |forward(x) - target| seen. forward must be monotonic increasing (a multiplication by a
/// positive constant is). The one walk behind exact_degrees_of and exact_radians_of.
template <class Forward>
inline double exact_preimage(double target, double guess, Forward forward) {
  double best = guess;
  double best_error = std::abs(forward(best) - target);
  double candidate = best;
  for (int step = 0; step < 16 && best_error != 0.0; ++step) {
    const double back = forward(candidate);
    if (back == target) return candidate;
    candidate = std::nextafter(
        candidate, back < target ? std::numeric_limits<double>::infinity() : -std::numeric_limits<double>::infinity());
    const double error = std::abs(forward(candidate) - target);
    if (error < best_error) {
      best = candidate;
      best_error = error;
    }
  }
  return best;
}
}  // namespace detail

/// The degree value d for which deg_to_rad(d) == angle_rad exactly, when such a double exists; else
/// the nearest one (within 1 ulp of the radians). This is what the dataset writer writes, so an angle
/// read back from a file equals the one written. rad_to_deg then deg_to_rad may be off by an ulp either
/// way: walk a few ulps of the degree value towards the side that closes the gap (d -> d * kDegToRad
/// is monotonic). Non-finite values are returned unchanged.
inline double exact_degrees_of(double angle_rad) {
  if (!std::isfinite(angle_rad)) return angle_rad;
  return detail::exact_preimage(angle_rad, rad_to_deg(angle_rad), [](double deg) { return deg_to_rad(deg); });
}

/// The mirror of exact_degrees_of: the radian value r for which rad_to_deg(r) == angle_deg exactly,
/// when one exists within 16 ulps of deg_to_rad(angle_deg); else the closest found. Why: a message
/// carries degrees its producer computed as rad_to_deg of its radians; a writer that holds radians
/// and converts with rad_to_deg (the results files) then writes the producer's degrees unchanged.
/// Non-finite values are returned unchanged.
inline double exact_radians_of(double angle_deg) {
  if (!std::isfinite(angle_deg)) return angle_deg;
  return detail::exact_preimage(angle_deg, deg_to_rad(angle_deg), [](double rad) { return rad_to_deg(rad); });
}

/// Wraps an angle in radians to [-pi, pi).
inline double wrap_pi(double angle_rad) {
  double a = std::fmod(angle_rad + kPi, 2.0 * kPi);
  if (a < 0) a += 2.0 * kPi;
  return a - kPi;
}

/// Wraps an angle in radians to [0, 2*pi).
inline double wrap_two_pi(double angle_rad) {
  double a = std::fmod(angle_rad, 2.0 * kPi);
  if (a < 0) a += 2.0 * kPi;
  return a;
}

/// INS attitude of the body, radians (conventions above).
struct Attitude {
  double heading_rad = 0.0;
  double pitch_rad = 0.0;
  double roll_rad = 0.0;
};

/// Odometer-to-INS installation misalignment, radians (conventions above). Roll is unobservable.
struct Misalignment {
  double heading_rad = 0.0;
  double pitch_rad = 0.0;
};

/// Direction cosine matrix C_b^n: body (FLU) to navigation (ENU). x_n = C_b^n * x_b.
/// C_b^n = Rz(pi/2 - heading) * Ry(-pitch) * Rx(roll)  (REP-103 yaw/pitch/roll with our signs).
inline Eigen::Matrix3d body_to_enu(const Attitude& att) {
  const Eigen::AngleAxisd yaw(kPi / 2.0 - att.heading_rad, Eigen::Vector3d::UnitZ());
  const Eigen::AngleAxisd pitch(-att.pitch_rad, Eigen::Vector3d::UnitY());
  const Eigen::AngleAxisd roll(att.roll_rad, Eigen::Vector3d::UnitX());
  return (yaw * pitch * roll).toRotationMatrix();
}

/// C_n^b: navigation (ENU) to body (FLU).
inline Eigen::Matrix3d enu_to_body(const Attitude& att) { return body_to_enu(att).transpose(); }

/// C_m^b: odometer frame to body frame (FLU). x_b = C_m^b * x_m.
/// C_m^b = Rz(a_h) * Ry(-a_p): the odometer forward axis e1 maps to
/// (cos a_h cos a_p, sin a_h cos a_p, sin a_p) in the body frame.
inline Eigen::Matrix3d odometer_to_body(const Misalignment& mis) {
  const Eigen::AngleAxisd yaw(mis.heading_rad, Eigen::Vector3d::UnitZ());
  const Eigen::AngleAxisd pitch(-mis.pitch_rad, Eigen::Vector3d::UnitY());
  return (yaw * pitch).toRotationMatrix();
}

/// Unit vector of the odometer forward axis in the body frame (FLU).
inline Eigen::Vector3d odometer_axis_in_body(const Misalignment& mis) {
  return Eigen::Vector3d(std::cos(mis.heading_rad) * std::cos(mis.pitch_rad),
                         std::sin(mis.heading_rad) * std::cos(mis.pitch_rad), std::sin(mis.pitch_rad));
}

/// Speed along the odometer forward axis (m/s) of an ENU velocity (m/s), exact rotation:
/// v_odo = e1 . (C_m^b)^T C_n^b v_n.
inline double forward_speed_along_odometer(const Eigen::Vector3d& v_enu_mps, const Attitude& att,
                                           const Misalignment& mis) {
  return odometer_axis_in_body(mis).dot(enu_to_body(att) * v_enu_mps);
}

/// Interpolates two attitudes at fraction f in [0, 1] (heading on the shortest arc).
inline Attitude interpolate_attitude(const Attitude& a, const Attitude& b, double f) {
  Attitude r;
  r.heading_rad = wrap_two_pi(a.heading_rad + f * wrap_pi(b.heading_rad - a.heading_rad));
  r.pitch_rad = a.pitch_rad + f * (b.pitch_rad - a.pitch_rad);
  r.roll_rad = a.roll_rad + f * wrap_pi(b.roll_rad - a.roll_rad);
  return r;
}

/// Angular rate of the body (rad/s, body frame FLU) between two attitudes dt_s apart, evaluated at
/// the attitude `mid`: the axial vector of C_mid^T (C_after - C_before) / dt_s, with C = C_b^n.
/// dt_s > 0; the attitudes a few tens of milliseconds apart (a finite difference).
inline Eigen::Vector3d body_rate_rad_s(const Attitude& before, const Attitude& mid, const Attitude& after,
                                       double dt_s) {
  const Eigen::Matrix3d c_dot = (body_to_enu(after) - body_to_enu(before)) / dt_s;
  const Eigen::Matrix3d omega = body_to_enu(mid).transpose() * c_dot;  // ~ skew(omega_b)
  // Antisymmetric part: the finite difference adds a small symmetric error that is not a rotation.
  return Eigen::Vector3d(0.5 * (omega(2, 1) - omega(1, 2)), 0.5 * (omega(0, 2) - omega(2, 0)),
                         0.5 * (omega(1, 0) - omega(0, 1)));
}

}  // namespace odonav
