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

// ---- anywhere on Earth: longitude 180 and the poles ----

namespace {
// A point distance_m from the North (or South) Pole along the meridian lon_deg, on the ellipsoid.
Geodetic from_pole(bool north, double distance_m, double lon_deg) {
  const double dlat = distance_m / wgs84_radii(0.5 * kPi).meridian_m;
  return Geodetic{north ? 0.5 * kPi - dlat : -0.5 * kPi + dlat, deg_to_rad(lon_deg), 0.0};
}
// Azimuth (rad, clockwise from north) at p of the ECEF direction dir.
double azimuth_at(const Geodetic& p, const Eigen::Vector3d& dir) {
  const Eigen::Matrix3d r = enu_from_ecef(p);
  return std::atan2(r.row(0).dot(dir), r.row(1).dot(dir));
}
}  // namespace

TEST(Geodesy, LongitudeIsNormalisedToMinus180To180) {
  EXPECT_EQ(normalize_lon_rad(0.0), 0.0);
  for (double v : {1.0, -1.0, 3.14159, -3.14159, -kPi, std::nextafter(kPi, 0.0)})
    EXPECT_EQ(normalize_lon_rad(v), v) << v;
  EXPECT_EQ(normalize_lon_rad(kPi), -kPi);
  EXPECT_NEAR(normalize_lon_rad(deg_to_rad(190.0)), deg_to_rad(-170.0), 1e-15);
  EXPECT_NEAR(normalize_lon_rad(deg_to_rad(-190.0)), deg_to_rad(170.0), 1e-15);
  EXPECT_NEAR(normalize_lon_rad(deg_to_rad(298.8)), deg_to_rad(-61.2), 1e-14);
  EXPECT_NEAR(normalize_lon_rad(deg_to_rad(720.0 + 45.0)), deg_to_rad(45.0), 1e-14);
  EXPECT_TRUE(std::isnan(normalize_lon_rad(std::nan(""))));
  const Geodetic beyond = normalized(Geodetic{std::nextafter(0.5 * kPi, 4.0), kPi, 3.0});
  EXPECT_EQ(beyond.lat_rad, 0.5 * kPi);
  EXPECT_EQ(beyond.lon_rad, -kPi);
  EXPECT_EQ(beyond.height_m, 3.0);
}

TEST(Geodesy, StepsEastAcrossLongitude180StayInRangeAndMeasureTheirLength) {
  // 65 N, 2 m west of 180: 400 steps of 0.01 m and 396 of 1 m east cross it after 2 m.
  const CurvatureRadii r = wgs84_radii(deg_to_rad(65.0));
  const Geodetic start{deg_to_rad(65.0), kPi - 2.0 / (r.prime_vertical_m * std::cos(deg_to_rad(65.0))), 0.0};
  Geodetic p = start;
  for (int i = 0; i < 400; ++i) p = move_geodetic(p, Eigen::Vector3d(0.01, 0.0, 0.0));
  for (int i = 0; i < 396; ++i) {
    p = move_geodetic(p, Eigen::Vector3d(1.0, 0.0, 0.0));
    ASSERT_GE(p.lon_rad, -kPi);
    ASSERT_LT(p.lon_rad, kPi);
  }
  EXPECT_LT(p.lon_rad, -kPi + 1e-3);  // just east of 180: about -179.99 deg
  EXPECT_NEAR(horizontal_distance_m(start, p), 400.0, 1e-3);
  EXPECT_NEAR(p.lat_rad, start.lat_rad, 1e-15);  // along the parallel, as the formula moves
}

TEST(Geodesy, PolarStepIsTheEcefTangentStep) {
  // In the polar cap the step is the ECEF one: the same horizontal position as the exact local
  // frame's, at 1e-8 m (the geodesic's own resolution), wherever the start is (on the pole itself
  // too), and h += dU.
  for (const Geodetic& start :
       {Geodetic{0.5 * kPi, 0.3, 5.0}, Geodetic{-0.5 * kPi, -2.0, -30.0}, from_pole(true, 0.5, 170.0),
        from_pole(false, 3.0, -179.0), from_pole(true, 1200.0, 10.0), Geodetic{deg_to_rad(80.0), 1.0, 0.0}}) {
    for (const Eigen::Vector3d& d :
         {Eigen::Vector3d(1.0, 0.0, 0.0), Eigen::Vector3d(0.0, -2.0, 0.1), Eigen::Vector3d(-3.0, 4.0, -0.2)}) {
      const Geodetic moved = move_geodetic(start, d);
      const Geodetic exact = LocalEnuFrame(start).to_geodetic(d);
      EXPECT_LT(horizontal_distance_m(moved, exact), 1e-8) << start.lat_rad << " " << start.lon_rad;
      EXPECT_EQ(moved.height_m, start.height_m + d.z());
      EXPECT_GE(moved.lon_rad, -kPi);
      EXPECT_LT(moved.lon_rad, kPi);
      EXPECT_LE(std::abs(moved.lat_rad), 0.5 * kPi);
    }
  }
}

TEST(Geodesy, AStraightWalkThroughTheNorthPoleEndsOnTheOtherMeridian) {
  // 200 steps of 1 m along one straight line (fixed ECEF direction, its azimuth taken at each
  // position, as an INS heading would be) from 100 m before the pole on meridian 20 E: 100 m
  // beyond it on meridian 160 W. The 100th step lands on the pole itself.
  const Geodetic start = from_pole(true, 100.0, 20.0);
  const Eigen::Vector3d dir = enu_from_ecef(start).row(1).transpose();  // north at the start
  Geodetic p = start;
  double closest_m = 1e9;
  for (int i = 0; i < 200; ++i) {
    const double psi = azimuth_at(p, dir);
    p = move_geodetic(p, Eigen::Vector3d(std::sin(psi), std::cos(psi), 0.0));
    ASSERT_TRUE(std::isfinite(p.lat_rad) && std::isfinite(p.lon_rad));
    ASSERT_LE(p.lat_rad, 0.5 * kPi);
    closest_m = std::min(closest_m, distance_to_pole_m(p));
  }
  EXPECT_LT(closest_m, 1e-6);
  EXPECT_LT(horizontal_distance_m(p, from_pole(true, 100.0, -160.0)), 1e-3);
  EXPECT_NEAR(horizontal_distance_m(start, p), 200.0, 1e-3);
}

TEST(Geodesy, InterpolationAcross180AndThroughAPole) {
  const Geodetic west{deg_to_rad(65.0), deg_to_rad(179.9999), 10.0},
      east{deg_to_rad(65.0), deg_to_rad(-179.9999), 20.0};
  const Geodetic mid = interpolate_geodetic(west, east, 0.5);
  EXPECT_NEAR(std::abs(rad_to_deg(mid.lon_rad)), 180.0, 1e-9);
  EXPECT_GE(mid.lon_rad, -kPi);
  EXPECT_LT(mid.lon_rad, kPi);
  EXPECT_NEAR(horizontal_distance_m(west, mid), 0.5 * horizontal_distance_m(west, east), 1e-6);
  EXPECT_EQ(mid.height_m, 15.0);
  // Mid-latitudes away from 180: bit for bit the linear formula.
  const Geodetic a{0.9, 0.2, 1.0}, b{0.9000001, 0.2000002, 2.0};
  const Geodetic q = interpolate_geodetic(a, b, 0.3);
  EXPECT_EQ(q.lat_rad, a.lat_rad + 0.3 * (b.lat_rad - a.lat_rad));
  EXPECT_EQ(q.lon_rad, a.lon_rad + 0.3 * (b.lon_rad - a.lon_rad));
  // Either side of the South Pole, 5 m each: the midpoint is the pole.
  const Geodetic s1 = from_pole(false, 5.0, 45.0), s2 = from_pole(false, 5.0, -135.0);
  EXPECT_LT(distance_to_pole_m(interpolate_geodetic(s1, s2, 0.5)), 1e-6);
  EXPECT_NEAR(horizontal_distance_m(s1, interpolate_geodetic(s1, s2, 0.25)), 2.5, 1e-6);
}

TEST(Geodesy, DistancesAndFramesAtThePoles) {
  EXPECT_NEAR(distance_to_pole_m(from_pole(true, 1500.0, 30.0)), 1500.0, 1e-3);
  EXPECT_NEAR(distance_to_pole_m(from_pole(false, 50.0, -60.0)), 50.0, 1e-4);
  // Latitude pi/2 in radians is a hair above 90 deg in degrees: still a distance.
  EXPECT_NEAR(horizontal_distance_m(Geodetic{0.5 * kPi, 0.0, 0.0}, from_pole(true, 7.0, 90.0)), 7.0, 1e-6);
  // A local frame on the pole itself: round trip, and its origin keeps its longitude.
  const Geodetic pole{0.5 * kPi, deg_to_rad(-75.0), 12.0};
  const LocalEnuFrame frame(pole);
  EXPECT_EQ(frame.to_geodetic(Eigen::Vector3d::Zero()).lon_rad, pole.lon_rad);
  for (const Eigen::Vector3d& enu : {Eigen::Vector3d(3.0, -4.0, 0.5), Eigen::Vector3d(-800.0, 1200.0, -2.0)})
    EXPECT_LT((frame.to_enu(frame.to_geodetic(enu)) - enu).norm(), 1e-8);
  // Across the pole the local frame is turned by 180 deg about the vertical.
  const Eigen::Matrix3d r = frame.rotation_from_local(from_pole(true, 30.0, 105.0));
  EXPECT_LT((r - Eigen::Vector3d(-1.0, -1.0, 1.0).asDiagonal().toDenseMatrix()).norm(), 1e-5);
  EXPECT_LT((frame.rotation_from_local(pole) - Eigen::Matrix3d::Identity()).norm(), 1e-15);
  EXPECT_LT((enu_rotation(pole, from_pole(true, 30.0, 105.0)) - r.transpose()).norm(), 1e-15);
}
