// Geodesy: ENU <-> geodetic round trips, radii of curvature against GeographicLib's own values,
// and the small-step position update against the exact local frame.
#include <GeographicLib/Ellipsoid.hpp>
#include <GeographicLib/LocalCartesian.hpp>
#include <gtest/gtest.h>

#include <random>

#include "odonav/frames.hpp"
#include "odonav/geodesy.hpp"

using namespace odonav;

TEST(Geodesy, RadiiMatchGeographicLibAtSeveralLatitudes) {
  const GeographicLib::Ellipsoid& wgs84 = GeographicLib::Ellipsoid::WGS84();
  for (double lat_deg : {-89.0, -60.0, -33.3, 0.0, 10.0, 45.0, 52.5, 70.0, 89.0}) {
    const CurvatureRadii r = wgs84_radii(deg_to_rad(lat_deg));
    EXPECT_NEAR(r.meridian_m, wgs84.MeridionalCurvatureRadius(lat_deg), 1e-6) << lat_deg;
    EXPECT_NEAR(r.prime_vertical_m, wgs84.TransverseCurvatureRadius(lat_deg), 1e-6) << lat_deg;
  }
  // Known values: at the equator R_N = a, R_M = a (1 - e^2).
  EXPECT_NEAR(wgs84_radii(0.0).prime_vertical_m, 6378137.0, 1e-6);
  EXPECT_NEAR(wgs84_radii(0.0).meridian_m, 6335439.327, 1e-3);
}

// The geodetic side is held in double radians; a half-ulp of lat/lon is itself up to ~1.4e-9 m at
// |lon| ~ 3 rad. The round trip is asserted to 1e-9 m beyond that representation limit, and to 1e-9 m
// flat in the operating region |lat|, |lon| < 60 deg where the representation costs < 0.5e-9 m.
static double representation_limit_m(const Geodetic& p) {
  const double r = 6.4e6;
  const double ulp_lat = std::nextafter(std::abs(p.lat_rad), 10.0) - std::abs(p.lat_rad);
  const double ulp_lon = std::nextafter(std::abs(p.lon_rad), 10.0) - std::abs(p.lon_rad);
  return 0.5 * r * (ulp_lat + ulp_lon) + 0.5 * (std::nextafter(std::abs(p.height_m), 1e9) - std::abs(p.height_m));
}

TEST(Geodesy, EnuGeodeticRoundTripTo1e9Metres) {
  std::mt19937 rng(42);
  std::uniform_real_distribution<double> lat(-80.0, 80.0), lon(-180.0, 180.0), h(-100.0, 3000.0), d(-20000.0, 20000.0);
  for (int i = 0; i < 500; ++i) {
    const Geodetic origin{deg_to_rad(lat(rng)), deg_to_rad(lon(rng)), h(rng)};
    const LocalEnuFrame frame(origin);
    const Eigen::Vector3d enu(d(rng), d(rng), d(rng) / 20.0);
    const Geodetic p = frame.to_geodetic(enu);
    const Eigen::Vector3d back = frame.to_enu(p);
    EXPECT_LT((back - enu).norm(), 1e-9 + representation_limit_m(p))
        << "origin " << origin.lat_rad << " " << origin.lon_rad;
    const Geodetic p2 = frame.to_geodetic(back);
    EXPECT_LT(std::abs(p2.lat_rad - p.lat_rad) * 6.4e6, 1e-9 + representation_limit_m(p));
    EXPECT_LT(std::abs(p2.height_m - p.height_m), 1e-9 + representation_limit_m(p));
  }
  std::uniform_real_distribution<double> lat60(-60.0, 60.0), lon60(-60.0, 60.0);
  for (int i = 0; i < 500; ++i) {
    const LocalEnuFrame frame(Geodetic{deg_to_rad(lat60(rng)), deg_to_rad(lon60(rng)), h(rng)});
    const Eigen::Vector3d enu(d(rng), d(rng), d(rng) / 20.0);
    EXPECT_LT((frame.to_enu(frame.to_geodetic(enu)) - enu).norm(), 1e-9);
  }
  // The origin maps to zero.
  const Geodetic origin{deg_to_rad(52.5), deg_to_rad(13.37), 76.0};
  EXPECT_LT(LocalEnuFrame(origin).to_enu(origin).norm(), 1e-9);
}

TEST(Geodesy, LocalFrameAgreesWithGeographicLib) {
  // GeographicLib's LocalCartesian is the independent reference (double precision: ~1e-8 m).
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> lat(-85.0, 85.0), lon(-180.0, 180.0), h(-100.0, 3000.0), d(-50000.0, 50000.0);
  for (int i = 0; i < 200; ++i) {
    const double lat0 = lat(rng), lon0 = lon(rng), h0 = h(rng);
    const LocalEnuFrame frame(Geodetic{deg_to_rad(lat0), deg_to_rad(lon0), h0});
    const GeographicLib::LocalCartesian reference(lat0, lon0, h0);
    const Eigen::Vector3d enu(d(rng), d(rng), d(rng) / 50.0);
    double lat1, lon1, h1;
    reference.Reverse(enu.x(), enu.y(), enu.z(), lat1, lon1, h1);
    const Geodetic p = frame.to_geodetic(enu);
    EXPECT_NEAR(rad_to_deg(p.lat_rad), lat1, 1e-12);
    EXPECT_NEAR(rad_to_deg(wrap_pi(p.lon_rad - deg_to_rad(lon1))), 0.0, 1e-12);
    EXPECT_NEAR(p.height_m, h1, 1e-7);
  }
}

TEST(Geodesy, SmallStepUpdateAgreesWithGeodesicDistance) {
  // 1000 steps of 1 m along a meridian and along a parallel (where a constant local bearing is also
  // the geodesic or the parallel itself): the radius-of-curvature update must give 1000 m to 1 mm.
  // (A diagonal constant bearing is a rhumb line and drifts from the origin frame's straight line by
  // meridian convergence, ~5 cm per km at 52 deg, so it is not a test of this update.)
  // On the ellipsoid (h = 0): the geodesic distance is measured there, not at height.
  const Geodetic origin{deg_to_rad(52.5), deg_to_rad(13.37), 0.0};
  Geodetic north = origin, east = origin;
  for (int i = 0; i < 1000; ++i) {
    north = move_geodetic(north, Eigen::Vector3d(0.0, 1.0, 0.0));
    east = move_geodetic(east, Eigen::Vector3d(1.0, 0.0, 0.0));
  }
  EXPECT_NEAR(horizontal_distance_m(origin, north), 1000.0, 1e-3);
  EXPECT_NEAR(north.lon_rad, origin.lon_rad, 1e-15);
  EXPECT_NEAR(north.height_m, 0.0, 1e-12);
  EXPECT_NEAR(east.lat_rad, origin.lat_rad, 1e-15);
  // Along the parallel: arc length (R_N + h) cos(lat) dlon is exactly the distance walked.
  const CurvatureRadii r = wgs84_radii(origin.lat_rad);
  EXPECT_NEAR((r.prime_vertical_m + origin.height_m) * std::cos(origin.lat_rad) * (east.lon_rad - origin.lon_rad),
              1000.0, 1e-6);
  // The geodesic chord is shorter than the parallel arc by well under a millimetre at 1 km.
  EXPECT_NEAR(horizontal_distance_m(origin, east), 1000.0, 1e-3);
}
