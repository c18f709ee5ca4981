#include "odonav/geodesy.hpp"

#include <GeographicLib/Constants.hpp>
#include <GeographicLib/Geodesic.hpp>
#include <cmath>

#include "odonav/frames.hpp"

namespace odonav {

namespace {
constexpr double kWgs84A = 6378137.0;
constexpr double kWgs84F = 1.0 / 298.257223563;
constexpr double kWgs84E2 = kWgs84F * (2.0 - kWgs84F);
}  // namespace

CurvatureRadii wgs84_radii(double lat_rad) {
  const double s = std::sin(lat_rad);
  const double w2 = 1.0 - kWgs84E2 * s * s;
  const double w = std::sqrt(w2);
  CurvatureRadii r;
  r.prime_vertical_m = kWgs84A / w;
  r.meridian_m = kWgs84A * (1.0 - kWgs84E2) / (w2 * w);
  return r;
}

Geodetic move_geodetic(const Geodetic& start, const Eigen::Vector3d& delta_enu_m) {
  const CurvatureRadii r = wgs84_radii(start.lat_rad);
  Geodetic out;
  out.lat_rad = start.lat_rad + delta_enu_m.y() / (r.meridian_m + start.height_m);
  out.lon_rad = start.lon_rad + delta_enu_m.x() / ((r.prime_vertical_m + start.height_m) * std::cos(start.lat_rad));
  out.height_m = start.height_m + delta_enu_m.z();
  return out;
}

double horizontal_distance_m(const Geodetic& a, const Geodetic& b) {
  double s12 = 0.0;
  GeographicLib::Geodesic::WGS84().Inverse(rad_to_deg(a.lat_rad), rad_to_deg(a.lon_rad),
                                           rad_to_deg(b.lat_rad), rad_to_deg(b.lon_rad), s12);
  return s12;
}

// The local frame is computed in long double (64-bit mantissa): with doubles, ECEF coordinates of
// ~6.4e6 m carry ~1e-9 m of rounding each way, which is the whole round-trip budget. GeographicLib's
// LocalCartesian (double) is the independent reference in the tests.
struct LocalEnuFrame::Impl {
  long double x0, y0, z0;  // origin in ECEF, metres
  long double r[3][3];     // rows: east, north, up unit vectors in ECEF

  static void geodetic_to_ecef(long double lat, long double lon, long double h, long double& x, long double& y,
                               long double& z) {
    const long double a = kWgs84A, e2 = kWgs84E2;
    const long double s = std::sin(lat), c = std::cos(lat);
    const long double n = a / std::sqrt(1.0L - e2 * s * s);
    x = (n + h) * c * std::cos(lon);
    y = (n + h) * c * std::sin(lon);
    z = (n * (1.0L - e2) + h) * s;
  }
};

LocalEnuFrame::LocalEnuFrame(const Geodetic& origin) : origin_(origin), impl_(new Impl) {
  Impl::geodetic_to_ecef(origin.lat_rad, origin.lon_rad, origin.height_m, impl_->x0, impl_->y0, impl_->z0);
  const long double sp = std::sin(static_cast<long double>(origin.lat_rad));
  const long double cp = std::cos(static_cast<long double>(origin.lat_rad));
  const long double sl = std::sin(static_cast<long double>(origin.lon_rad));
  const long double cl = std::cos(static_cast<long double>(origin.lon_rad));
  const long double rows[3][3] = {{-sl, cl, 0.0L}, {-sp * cl, -sp * sl, cp}, {cp * cl, cp * sl, sp}};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) impl_->r[i][j] = rows[i][j];
}
LocalEnuFrame::~LocalEnuFrame() = default;
LocalEnuFrame::LocalEnuFrame(const LocalEnuFrame& other) : origin_(other.origin_), impl_(new Impl(*other.impl_)) {}
LocalEnuFrame& LocalEnuFrame::operator=(const LocalEnuFrame& other) {
  if (this != &other) {
    origin_ = other.origin_;
    impl_.reset(new Impl(*other.impl_));
  }
  return *this;
}

Eigen::Vector3d LocalEnuFrame::to_enu(const Geodetic& p) const {
  long double x, y, z;
  Impl::geodetic_to_ecef(p.lat_rad, p.lon_rad, p.height_m, x, y, z);
  const long double d[3] = {x - impl_->x0, y - impl_->y0, z - impl_->z0};
  Eigen::Vector3d out;
  for (int i = 0; i < 3; ++i)
    out[i] = static_cast<double>(impl_->r[i][0] * d[0] + impl_->r[i][1] * d[1] + impl_->r[i][2] * d[2]);
  return out;
}

Geodetic LocalEnuFrame::to_geodetic(const Eigen::Vector3d& enu_m) const {
  // ECEF = origin + R^T enu
  long double e[3] = {enu_m.x(), enu_m.y(), enu_m.z()};
  const long double x = impl_->x0 + impl_->r[0][0] * e[0] + impl_->r[1][0] * e[1] + impl_->r[2][0] * e[2];
  const long double y = impl_->y0 + impl_->r[0][1] * e[0] + impl_->r[1][1] * e[1] + impl_->r[2][1] * e[2];
  const long double z = impl_->z0 + impl_->r[0][2] * e[0] + impl_->r[1][2] * e[1] + impl_->r[2][2] * e[2];
  // Fixed-point iteration on latitude (converges to long-double precision in a few steps for
  // points within a few hundred km of the surface); the height formula is stable at the poles.
  const long double a = kWgs84A, e2 = kWgs84E2;
  const long double p = std::sqrt(x * x + y * y);
  long double lat = std::atan2(z, p * (1.0L - e2));
  for (int i = 0; i < 8; ++i) {
    const long double s = std::sin(lat);
    const long double n = a / std::sqrt(1.0L - e2 * s * s);
    lat = std::atan2(z + e2 * n * s, p);
  }
  const long double s = std::sin(lat), c = std::cos(lat);
  const long double h = p * c + z * s - a * std::sqrt(1.0L - e2 * s * s);
  return {static_cast<double>(lat), static_cast<double>(std::atan2(y, x)), static_cast<double>(h)};
}

}  // namespace odonav
