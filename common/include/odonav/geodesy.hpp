#pragma once
// Geodesy on the WGS-84 ellipsoid, through GeographicLib.
// Latitudes and longitudes in radians inside the program (degrees only in files), heights are
// ellipsoidal heights in metres, local coordinates are East-North-Up metres.
#include <Eigen/Dense>
#include <memory>

namespace odonav {

/// A WGS-84 geodetic position. lat_rad in [-pi/2, pi/2], lon_rad any (wrapped by users), height_m
/// ellipsoidal.
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

/// Moves a geodetic position by a small displacement in the local ENU frame at that position
/// (metres): lat += dN / (R_M + h), lon += dE / ((R_N + h) cos lat), h += dU. Radii taken at the
/// start latitude; the caller keeps steps small (a few metres) so this is exact to well below 1 mm.
/// Valid away from the poles (|lat| < 89.9 deg).
Geodetic move_geodetic(const Geodetic& start, const Eigen::Vector3d& delta_enu_m);

/// Horizontal distance in metres between two geodetic positions (geodesic on WGS-84).
double horizontal_distance_m(const Geodetic& a, const Geodetic& b);

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
  /// Local ENU (metres) to geodetic (radians, metres).
  Geodetic to_geodetic(const Eigen::Vector3d& enu_m) const;

 private:
  struct Impl;
  Geodetic origin_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace odonav
