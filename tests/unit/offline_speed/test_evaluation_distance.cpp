// The DR evaluation measures horizontal errors with a flat formula (WGS-84 radii of curvature at
// the mean latitude) instead of GeographicLib's geodesic inverse, for speed (evaluation.cpp). These
// tests compare evaluate_dead_reckoning's error with the geodesic computed here independently, at
// metre to ten-kilometre separations, several latitudes and azimuths, across the antimeridian, and
// beyond the flat formula's range (where the geodesic itself must come back).
#include <gtest/gtest.h>

#include <GeographicLib/Geodesic.hpp>
#include <cmath>

#include "odonav/offline/evaluation.hpp"
#include "odonav/frames.hpp"

namespace odonav::offline {
namespace {

// The error evaluate_dead_reckoning reports between a DR point a and a reference point b.
double evaluated_error_m(const Geodetic& a, const Geodetic& b) {
  const std::vector<TimedPosition> dr{{0.0, a}, {1.0, a}};
  const std::vector<TimedPosition> reference{{0.0, b}, {1.0, b}};
  const DrEvaluation e = evaluate_dead_reckoning(dr, {1000.0, 1000.0}, reference, {}, 100.0);
  EXPECT_EQ(e.epochs, 2u);
  return e.max_error_m;
}

// The point at distance s_m and azimuth az_deg from p on the ellipsoid surface (GeographicLib).
Geodetic direct(const Geodetic& p, double az_deg, double s_m) {
  double lat2 = 0.0, lon2 = 0.0;
  GeographicLib::Geodesic::WGS84().Direct(rad_to_deg(p.lat_rad), rad_to_deg(p.lon_rad), az_deg, s_m, lat2, lon2);
  return {deg_to_rad(lat2), deg_to_rad(lon2), p.height_m};
}

TEST(EvaluationDistance, AgreesWithTheGeodesicFromMetresToTenKilometres) {
  for (double lat_deg : {0.0, 30.0, 52.5, 70.0, 79.0, -45.0}) {
    const Geodetic a{deg_to_rad(lat_deg), deg_to_rad(13.4), 80.0};
    for (double az_deg : {0.0, 45.0, 90.0, 135.0, 200.0, 300.0}) {
      for (double s_m : {0.5, 3.0, 40.0, 1000.0, 9000.0}) {
        const double got = evaluated_error_m(a, direct(a, az_deg, s_m));
        // Third-order terms of the flat formula: ~ (s/R)^2 tan^2(lat) / 24 relative, below 5e-6 up to
        // 10 km at latitudes below 80 deg, and far below a micrometre at the metre scale.
        EXPECT_NEAR(got, s_m, 5e-6 * s_m + 1e-9) << "lat " << lat_deg << " az " << az_deg << " s " << s_m;
        if (s_m <= 1000.0 && std::abs(lat_deg) <= 53.0) {
          EXPECT_NEAR(got, s_m, 1e-7 * s_m + 1e-9) << "lat " << lat_deg << " az " << az_deg << " s " << s_m;
        }
      }
    }
  }
}

TEST(EvaluationDistance, AcrossTheAntimeridian) {
  const Geodetic a{deg_to_rad(-17.0), deg_to_rad(179.9999), 0.0};
  const Geodetic b = direct(a, 90.0, 250.0);  // lands at about -179.9977 deg
  ASSERT_LT(b.lon_rad, 0.0);
  EXPECT_NEAR(evaluated_error_m(a, b), 250.0, 1e-6);
}

TEST(EvaluationDistance, FarApartAndNearThePolesUseTheGeodesic) {
  const Geodetic a{deg_to_rad(52.5), deg_to_rad(13.4), 0.0};
  // 500 km: the flat formula would be off by ~1e-3 relative; the geodesic is exact to nanometres.
  EXPECT_NEAR(evaluated_error_m(a, direct(a, 60.0, 500e3)), 500e3, 1e-6);
  const Geodetic polar{deg_to_rad(89.5), deg_to_rad(20.0), 0.0};
  EXPECT_NEAR(evaluated_error_m(polar, direct(polar, 110.0, 3000.0)), 3000.0, 1e-6);
}

TEST(EvaluationDistance, HeightDoesNotCount) {
  // Horizontal error: a reference 30 m above the DR point at the same place is 0 m away.
  const Geodetic a{deg_to_rad(52.5), deg_to_rad(13.4), 80.0};
  Geodetic b = a;
  b.height_m += 30.0;
  EXPECT_NEAR(evaluated_error_m(a, b), 0.0, 1e-12);
}

}  // namespace
}  // namespace odonav::offline
