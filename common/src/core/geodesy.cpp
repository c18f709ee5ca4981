#include "odonav/geodesy.hpp"

#include <GeographicLib/Constants.hpp>
#include <GeographicLib/Geodesic.hpp>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstring>

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

namespace {

// Geodetic (radians, metres) to ECEF (metres), long double.
void geodetic_to_ecef_ld(long double lat, long double lon, long double h, long double& x, long double& y,
                         long double& z) {
  const long double a = kWgs84A, e2 = kWgs84E2;
  const long double s = std::sin(lat), c = std::cos(lat);
  const long double n = a / std::sqrt(1.0L - e2 * s * s);
  x = (n + h) * c * std::cos(lon);
  y = (n + h) * c * std::sin(lon);
  z = (n * (1.0L - e2) + h) * s;
}

// Within this distance (m) of the polar axis a point's longitude is taken from the caller: the
// ECEF x and y there are rounding noise, and any longitude describes the point.
constexpr long double kOnAxisM = 1e-9L;

// ECEF (metres) to geodetic, long double: fixed-point iteration on latitude (converges to long-double
// precision in a few steps for points within a few hundred km of the surface, the poles included:
// on the axis it starts and stays at +-pi/2); the height formula is stable at the poles.
void ecef_to_geodetic_ld(long double x, long double y, long double z, long double lon_on_axis, long double& lat,
                         long double& lon, long double& h) {
  const long double a = kWgs84A, e2 = kWgs84E2;
  const long double p = std::sqrt(x * x + y * y);
  lat = std::atan2(z, p * (1.0L - e2));
  for (int i = 0; i < 8; ++i) {
    const long double s = std::sin(lat);
    const long double n = a / std::sqrt(1.0L - e2 * s * s);
    lat = std::atan2(z + e2 * n * s, p);
  }
  const long double s = std::sin(lat), c = std::cos(lat);
  h = p * c + z * s - a * std::sqrt(1.0L - e2 * s * s);
  lon = p < kOnAxisM ? lon_on_axis : std::atan2(y, x);
}

// Rows: east, north, up unit vectors in ECEF at (lat, lon).
void enu_axes_ld(long double lat, long double lon, long double r[3][3]) {
  const long double sp = std::sin(lat), cp = std::cos(lat), sl = std::sin(lon), cl = std::cos(lon);
  const long double rows[3][3] = {{-sl, cl, 0.0L}, {-sp * cl, -sp * sl, cp}, {cp * cl, cp * sl, sp}};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) r[i][j] = rows[i][j];
}

}  // namespace

namespace {
// value brought to [-half_turn, half_turn) by whole turns; unchanged (bit for bit) when already
// there or not finite.
double wrap_half_open(double value, double half_turn) {
  if (!std::isfinite(value) || (value >= -half_turn && value < half_turn)) return value;
  double a = std::fmod(value + half_turn, 2.0 * half_turn);
  if (a < 0.0) a += 2.0 * half_turn;
  const double out = a - half_turn;
  return out >= half_turn ? -half_turn : out;
}
}  // namespace

double normalize_lon_rad(double lon_rad) { return wrap_half_open(lon_rad, kPi); }

double normalize_lon_deg(double lon_deg) { return wrap_half_open(lon_deg, 180.0); }

Geodetic normalized(const Geodetic& p) {
  Geodetic out = p;
  out.lon_rad = normalize_lon_rad(p.lon_rad);
  if (out.lat_rad > 0.5 * kPi) out.lat_rad = 0.5 * kPi;
  if (out.lat_rad < -0.5 * kPi) out.lat_rad = -0.5 * kPi;
  return out;
}

Eigen::Vector3d to_ecef_m(const Geodetic& p) {
  long double x, y, z;
  geodetic_to_ecef_ld(p.lat_rad, p.lon_rad, p.height_m, x, y, z);
  return Eigen::Vector3d(static_cast<double>(x), static_cast<double>(y), static_cast<double>(z));
}

Geodetic from_ecef_m(const Eigen::Vector3d& ecef_m, double lon_on_axis_rad) {
  long double lat, lon, h;
  ecef_to_geodetic_ld(ecef_m.x(), ecef_m.y(), ecef_m.z(), lon_on_axis_rad, lat, lon, h);
  return normalized(Geodetic{static_cast<double>(lat), static_cast<double>(lon), static_cast<double>(h)});
}

Eigen::Matrix3d enu_from_ecef(const Geodetic& p) {
  long double r[3][3];
  enu_axes_ld(p.lat_rad, p.lon_rad, r);
  Eigen::Matrix3d m;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) m(i, j) = static_cast<double>(r[i][j]);
  return m;
}

Eigen::Matrix3d enu_rotation(const Geodetic& from, const Geodetic& to) {
  long double rf[3][3], rt[3][3];
  enu_axes_ld(from.lat_rad, from.lon_rad, rf);
  enu_axes_ld(to.lat_rad, to.lon_rad, rt);
  Eigen::Matrix3d m;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      m(i, j) = static_cast<double>(rt[i][0] * rf[j][0] + rt[i][1] * rf[j][1] + rt[i][2] * rf[j][2]);
  return m;
}

Geodetic move_geodetic(const Geodetic& start, const Eigen::Vector3d& delta_enu_m) {
  if (std::abs(start.lat_rad) < kPolarCapLatRad) {
    const CurvatureRadii r = wgs84_radii(start.lat_rad);
    Geodetic out;
    out.lat_rad = start.lat_rad + delta_enu_m.y() / (r.meridian_m + start.height_m);
    out.lon_rad = start.lon_rad + delta_enu_m.x() / ((r.prime_vertical_m + start.height_m) * std::cos(start.lat_rad));
    out.height_m = start.height_m + delta_enu_m.z();
    out.lon_rad = normalize_lon_rad(out.lon_rad);
    return out;
  }
  // Near a pole the longitude formula divides by cos lat: the step is taken in ECEF instead.
  long double x, y, z, r[3][3];
  geodetic_to_ecef_ld(start.lat_rad, start.lon_rad, start.height_m, x, y, z);
  enu_axes_ld(start.lat_rad, start.lon_rad, r);
  const long double d[3] = {delta_enu_m.x(), delta_enu_m.y(), delta_enu_m.z()};
  x += r[0][0] * d[0] + r[1][0] * d[1] + r[2][0] * d[2];
  y += r[0][1] * d[0] + r[1][1] * d[1] + r[2][1] * d[2];
  z += r[0][2] * d[0] + r[1][2] * d[1] + r[2][2] * d[2];
  long double lat, lon, h;
  ecef_to_geodetic_ld(x, y, z, start.lon_rad, lat, lon, h);
  return normalized(Geodetic{static_cast<double>(lat), static_cast<double>(lon), start.height_m + delta_enu_m.z()});
}

Geodetic interpolate_geodetic(const Geodetic& a, const Geodetic& b, double f) {
  const double height_m = a.height_m + f * (b.height_m - a.height_m);
  if (std::abs(a.lat_rad) < kPolarCapLatRad && std::abs(b.lat_rad) < kPolarCapLatRad) {
    double dlon = b.lon_rad - a.lon_rad;
    if (dlon > kPi)
      dlon -= 2.0 * kPi;
    else if (dlon < -kPi)
      dlon += 2.0 * kPi;
    return Geodetic{a.lat_rad + f * (b.lat_rad - a.lat_rad), normalize_lon_rad(a.lon_rad + f * dlon), height_m};
  }
  long double xa, ya, za, xb, yb, zb;
  geodetic_to_ecef_ld(a.lat_rad, a.lon_rad, a.height_m, xa, ya, za);
  geodetic_to_ecef_ld(b.lat_rad, b.lon_rad, b.height_m, xb, yb, zb);
  const long double fl = f;
  long double lat, lon, h;
  ecef_to_geodetic_ld(xa + fl * (xb - xa), ya + fl * (yb - ya), za + fl * (zb - za), a.lon_rad, lat, lon, h);
  return normalized(Geodetic{static_cast<double>(lat), static_cast<double>(lon), height_m});
}

namespace {
// Latitude in degrees for GeographicLib, which refuses (NaN) anything beyond +-90: pi/2 in radians
// can come back as 90.00000000000001 deg.
double lat_deg_for_geodesic(double lat_rad) { return std::max(-90.0, std::min(90.0, rad_to_deg(lat_rad))); }
}  // namespace

double horizontal_distance_m(const Geodetic& a, const Geodetic& b) {
  double s12 = 0.0;
  GeographicLib::Geodesic::WGS84().Inverse(lat_deg_for_geodesic(a.lat_rad), rad_to_deg(a.lon_rad),
                                           lat_deg_for_geodesic(b.lat_rad), rad_to_deg(b.lon_rad), s12);
  return s12;
}

double distance_to_pole_m(const Geodetic& p) {
  double s12 = 0.0;
  const double lat_deg = lat_deg_for_geodesic(p.lat_rad);
  GeographicLib::Geodesic::WGS84().Inverse(lat_deg, 0.0, lat_deg >= 0.0 ? 90.0 : -90.0, 0.0, s12);
  return s12;
}

// The local frame is computed in long double (64-bit mantissa): with doubles, ECEF coordinates of
// ~6.4e6 m carry ~1e-9 m of rounding each way, which is the whole round-trip budget. GeographicLib's
// LocalCartesian (double) is the independent reference in the tests.
struct LocalEnuFrame::Impl {
  long double x0, y0, z0;  // origin in ECEF, metres
  long double r[3][3];     // rows: east, north, up unit vectors in ECEF
  // Identifies the frame's numbers for the to_enu memo below: a fresh value for every frame built
  // from an origin; a copy keeps it (same numbers, same answers).
  uint64_t memo_id;

  /// The computation behind to_enu (no memo).
  Eigen::Vector3d compute_enu(const Geodetic& p) const;
};

namespace {
std::atomic<uint64_t> next_frame_memo_id{1};

// to_enu's long-double sin/cos (with argument reduction: ~100 ns a call) dominated dead reckoning,
// which converts the same two bracketing GNSS fixes again for each of the ~10 odometer samples
// between them. This per-thread memo of the last few (frame, position) -> ENU answers returns
// exactly what the computation would (it IS that computation's earlier result), so outputs do not
// change by a bit; being per thread, concurrent const calls stay safe. Keys compare bit patterns,
// so -0.0 / 0.0 and NaN payloads are told apart exactly as the arithmetic could tell them apart.
struct EnuMemoEntry {
  uint64_t frame = 0;  // 0: empty
  uint64_t lat_bits = 0, lon_bits = 0, height_bits = 0;
  uint64_t last_use = 0;
  Eigen::Vector3d enu;
};
constexpr int kEnuMemoSize = 4;  // the DR needs 2 fixes + its own position; 4 leaves slack
struct EnuMemo {
  EnuMemoEntry entries[kEnuMemoSize];
  uint64_t clock = 0;
};
thread_local EnuMemo enu_memo;

uint64_t bits_of(double v) {
  uint64_t b;
  std::memcpy(&b, &v, sizeof b);
  return b;
}
}  // namespace

LocalEnuFrame::LocalEnuFrame(const Geodetic& origin) : origin_(origin), impl_(new Impl) {
  impl_->memo_id = next_frame_memo_id.fetch_add(1, std::memory_order_relaxed);
  geodetic_to_ecef_ld(origin.lat_rad, origin.lon_rad, origin.height_m, impl_->x0, impl_->y0, impl_->z0);
  enu_axes_ld(origin.lat_rad, origin.lon_rad, impl_->r);
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
  EnuMemo& memo = enu_memo;
  const uint64_t lat = bits_of(p.lat_rad), lon = bits_of(p.lon_rad), height = bits_of(p.height_m);
  EnuMemoEntry* oldest = &memo.entries[0];
  for (EnuMemoEntry& e : memo.entries) {
    if (e.frame == impl_->memo_id && e.lat_bits == lat && e.lon_bits == lon && e.height_bits == height) {
      e.last_use = ++memo.clock;
      return e.enu;
    }
    if (e.last_use < oldest->last_use) oldest = &e;
  }
  const Eigen::Vector3d enu = impl_->compute_enu(p);
  *oldest = EnuMemoEntry{impl_->memo_id, lat, lon, height, ++memo.clock, enu};
  return enu;
}

Eigen::Vector3d LocalEnuFrame::Impl::compute_enu(const Geodetic& p) const {
  long double x, y, z;
  geodetic_to_ecef_ld(p.lat_rad, p.lon_rad, p.height_m, x, y, z);
  const long double d[3] = {x - x0, y - y0, z - z0};
  Eigen::Vector3d out;
  for (int i = 0; i < 3; ++i) out[i] = static_cast<double>(r[i][0] * d[0] + r[i][1] * d[1] + r[i][2] * d[2]);
  return out;
}

Geodetic LocalEnuFrame::to_geodetic(const Eigen::Vector3d& enu_m) const {
  // ECEF = origin + R^T enu
  long double e[3] = {enu_m.x(), enu_m.y(), enu_m.z()};
  const long double x = impl_->x0 + impl_->r[0][0] * e[0] + impl_->r[1][0] * e[1] + impl_->r[2][0] * e[2];
  const long double y = impl_->y0 + impl_->r[0][1] * e[0] + impl_->r[1][1] * e[1] + impl_->r[2][1] * e[2];
  const long double z = impl_->z0 + impl_->r[0][2] * e[0] + impl_->r[1][2] * e[1] + impl_->r[2][2] * e[2];
  long double lat, lon, h;
  ecef_to_geodetic_ld(x, y, z, origin_.lon_rad, lat, lon, h);
  return normalized(Geodetic{static_cast<double>(lat), static_cast<double>(lon), static_cast<double>(h)});
}

Eigen::Matrix3d LocalEnuFrame::rotation_from_local(const Geodetic& at) const {
  // In double: it turns vectors of metres (an offset, a lever arm), where 1e-16 relative is far
  // below anything measured, and the dead reckoning asks for it at every odometer sample.
  const double sp = std::sin(at.lat_rad), cp = std::cos(at.lat_rad), sl = std::sin(at.lon_rad),
               cl = std::cos(at.lon_rad);
  const double ra[3][3] = {{-sl, cl, 0.0}, {-sp * cl, -sp * sl, cp}, {cp * cl, cp * sl, sp}};
  Eigen::Matrix3d m;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      m(i, j) = static_cast<double>(impl_->r[i][0]) * ra[j][0] + static_cast<double>(impl_->r[i][1]) * ra[j][1] +
                static_cast<double>(impl_->r[i][2]) * ra[j][2];
  return m;
}

}  // namespace odonav
