#pragma once
// Geodesy on the WGS-84 ellipsoid, through GeographicLib.
// Latitudes and longitudes in radians inside the program (degrees only in files), heights are
// ellipsoidal heights in metres, local coordinates are East-North-Up metres.
#include <Eigen/Dense>
#include <memory>

namespace odonav {

/// A WGS-84 geodetic position. lat_rad in [-pi/2, pi/2], lon_rad any (what odonav computes is in
/// [-pi, pi); normalized() brings any value there), height_m ellipsoidal.
struct Geodetic {
  double lat_rad = 0.0;
  double lon_rad = 0.0;
  double height_m = 0.0;
};

/// Radii of curvature of WGS-84 at a latitude.
struct CurvatureRadii {
  double meridian_m = 0.0;        ///< R_M, north-south radius of curvature.
  double prime_vertical_m = 0.0;  ///< R_N, east-west (transverse) radius of curvature.
};

/// WGS-84 radii of curvature at latitude lat_rad (radians, [-pi/2, pi/2]).
/// R_N = a / sqrt(1 - e^2 sin^2 lat), R_M = a (1 - e^2) / (1 - e^2 sin^2 lat)^(3/2).
CurvatureRadii wgs84_radii(double lat_rad);

/// Latitude beyond which (|lat| >= this, radians) move_geodetic and interpolate_geodetic work in
/// Earth-centred Cartesian coordinates instead of the latitude/longitude formulas: 80 deg. Below it
/// the formulas agree with the Cartesian form to far below a millimetre for the steps odonav makes
/// (their error grows with tan lat), and they keep the outputs of every earlier run bit for bit.
constexpr double kPolarCapLatRad = 80.0 * (3.14159265358979323846 / 180.0);

/// Longitude (radians) brought to [-pi, pi): returned unchanged (bit for bit) when already there,
/// otherwise wrapped by whole turns. Not finite: returned unchanged.
double normalize_lon_rad(double lon_rad);

/// Longitude in degrees brought to [-180, 180): unchanged (bit for bit) when already there.
double normalize_lon_deg(double lon_deg);

/// The same position with lon_rad in [-pi, pi) and lat_rad clamped to [-pi/2, pi/2] (a latitude a
/// rounding step beyond the pole); unchanged (bit for bit) when both are already in range.
Geodetic normalized(const Geodetic& p);

/// Earth-centred, Earth-fixed WGS-84 coordinates (metres) of a geodetic position.
Eigen::Vector3d to_ecef_m(const Geodetic& p);

/// Geodetic position (radians, metres; lon in [-pi, pi)) of ECEF coordinates (metres), exact at
/// the poles: on the polar axis (within 1e-9 m of it) the longitude is lon_on_axis_rad, since any
/// longitude describes that point and a caller moving through it wants to keep its own.
Geodetic from_ecef_m(const Eigen::Vector3d& ecef_m, double lon_on_axis_rad = 0.0);

/// Unit vectors of the local East-North-Up frame at p, as the rows of a matrix in ECEF: x_enu =
/// R (x_ecef). At a pole north is the direction of the meridian lon_rad (any longitude describes
/// the point; the position's own one picks the frame), so the frame is defined everywhere.
Eigen::Matrix3d enu_from_ecef(const Geodetic& p);

/// The rotation taking vectors expressed in the ENU frame at `from` into the ENU frame at `to`
/// (R_to R_from^T). The identity when both are the same point; far from each other, or across a
/// pole, the axes differ by the meridian convergence (about delta-lon sin lat about the vertical).
Eigen::Matrix3d enu_rotation(const Geodetic& from, const Geodetic& to);

/// Moves a geodetic position by a displacement given in the local ENU frame at that position
/// (metres). Valid everywhere, the poles and longitude 180 included; the result's longitude is in
/// [-pi, pi). Below kPolarCapLatRad: lat += dN / (R_M + h), lon += dE / ((R_N + h) cos lat),
/// h += dU, radii at the start latitude (for steps of metres exact to well below 1 mm). At or
/// beyond it: the ECEF position plus the displacement along the ENU axes at the start, back to
/// geodetic, and h += dU (the same height rule; the tangent step would add d^2 / 2R). Steps of up
/// to a few hundred metres: a displacement is laid along the tangent plane, not the surface.
Geodetic move_geodetic(const Geodetic& start, const Eigen::Vector3d& delta_enu_m);

/// The position at fraction f (0: a, 1: b) of the way from a to b, for two nearby positions (a
/// track's consecutive rows, metres to a few hundred metres apart). Below kPolarCapLatRad at both
/// ends: linear in latitude, longitude (the shorter way round, so across longitude 180 too) and
/// height, bit for bit the former interpolation when the longitudes do not straddle 180. Otherwise
/// along the ECEF chord, height linear. Result longitude in [-pi, pi).
Geodetic interpolate_geodetic(const Geodetic& a, const Geodetic& b, double f);

/// Horizontal distance in metres between two geodetic positions (geodesic on WGS-84; valid at the
/// poles and across longitude 180).
double horizontal_distance_m(const Geodetic& a, const Geodetic& b);

/// Distance (metres, along the meridian) from p to the nearer pole.
double distance_to_pole_m(const Geodetic& p);

/// A local East-North-Up Cartesian frame tied to an origin (GeographicLib::LocalCartesian).
/// Exact (not a flat-earth approximation) at any distance from the origin.
class LocalEnuFrame {
 public:
  explicit LocalEnuFrame(const Geodetic& origin);
  ~LocalEnuFrame();
  LocalEnuFrame(const LocalEnuFrame& other);
  LocalEnuFrame& operator=(const LocalEnuFrame& other);

  const Geodetic& origin() const { return origin_; }
  /// Geodetic (radians, metres) to local ENU (metres).
  Eigen::Vector3d to_enu(const Geodetic& p) const;
  /// Local ENU (metres) to geodetic (radians, metres; lon in [-pi, pi), the origin's longitude on
  /// the polar axis).
  Geodetic to_geodetic(const Eigen::Vector3d& enu_m) const;
  /// The rotation taking vectors of the local ENU frame at `at` into this frame's axes (exact: the
  /// two frames' axes in ECEF). Vectors a vehicle measures in its own ENU frame (a lever arm, an
  /// offset) must go through it before they are combined with this frame's coordinates.
  Eigen::Matrix3d rotation_from_local(const Geodetic& at) const;
  /// The inverse: vectors of this frame into the local ENU frame at `at`.
  Eigen::Matrix3d rotation_to_local(const Geodetic& at) const { return rotation_from_local(at).transpose(); }

 private:
  struct Impl;
  Geodetic origin_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace odonav
