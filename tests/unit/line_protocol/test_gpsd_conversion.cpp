// The gpsd source's pure parts: TPV -> GnssSample, the event-time gate, the source spec, back-off.
#include <gtest/gtest.h>

#include <cmath>

#include "odonav/gateway/gpsd_source.hpp"
#include "odonav/config.hpp"
#include "odonav/frames.hpp"

namespace odonav::gateway {
namespace {

GpsdReport moving_3d_fix() {
  GpsdReport r;
  r.time_utc_s = 1767225612.5;
  r.mode = 3;
  r.lat_deg = 52.5;
  r.lon_deg = 13.4;
  r.alt_msl_m = 40.0;
  r.geoid_sep_m = 39.5;
  r.speed_mps = 10.0;
  r.track_deg = 30.0;  // north-north-east
  r.eph_m = 6.0;
  r.eps_mps = 0.4;
  return r;
}

TEST(GpsdConversion, ThreeDimensionalFixFromSpeedTrackAndMslPlusSeparation) {
  const auto s = gnss_sample_from(moving_3d_fix(), 1767225600.0);
  ASSERT_TRUE(s);
  EXPECT_DOUBLE_EQ(s->t_s, 12.5);
  EXPECT_EQ(s->fix, 1);  // status left out by gpsd's JSON (0, unknown) with a fix: plain GPS
  EXPECT_TRUE(s->valid());
  EXPECT_DOUBLE_EQ(s->position.height_m, 79.5);  // MSL + separation
  EXPECT_NEAR(s->vel_enu_mps.x(), 5.0, 1e-12);   // 10 sin 30
  EXPECT_NEAR(s->vel_enu_mps.y(), 10.0 * std::sqrt(3.0) / 2.0, 1e-12);
  EXPECT_EQ(s->vel_enu_mps.z(), 0.0);    // no climb reported
  EXPECT_DOUBLE_EQ(*s->pos_std_m, 3.0);  // eph / 2
  EXPECT_DOUBLE_EQ(*s->vel_std_mps, 0.2);
}

TEST(GpsdConversion, GstSigmasAndEcefVelocityWinOverTheEstimates) {
  GpsdReport r = moving_3d_fix();
  r.alt_hae_m = 80.0;
  r.gst_lat_std_m = 0.3;
  r.gst_lon_std_m = 0.4;
  // ECEF velocity of 2 m/s due east at lon 13.4 deg: (-sin lon, cos lon, 0) * 2.
  r.ecef_vx_mps = -2.0 * std::sin(deg_to_rad(13.4));
  r.ecef_vy_mps = 2.0 * std::cos(deg_to_rad(13.4));
  r.ecef_vz_mps = 0.0;
  const auto s = gnss_sample_from(r, 0.0);
  ASSERT_TRUE(s);
  EXPECT_DOUBLE_EQ(s->position.height_m, 80.0);  // altHAE first
  EXPECT_NEAR(*s->pos_std_m, 0.5, 1e-15);
  EXPECT_NEAR(s->vel_enu_mps.x(), 2.0, 1e-12);
  EXPECT_NEAR(s->vel_enu_mps.y(), 0.0, 1e-12);
  EXPECT_NEAR(s->vel_enu_mps.z(), 0.0, 1e-12);
}

TEST(GpsdConversion, NoFixIsInvalidNeverZerosAndTwoDimensionalHasNoHeight) {
  GpsdReport r = moving_3d_fix();
  r.mode = 1;
  auto s = gnss_sample_from(r, 0.0);
  ASSERT_TRUE(s);
  EXPECT_EQ(s->fix, 0);
  EXPECT_FALSE(s->valid());
  EXPECT_TRUE(std::isnan(s->position.lat_rad));
  EXPECT_TRUE(std::isnan(s->vel_enu_mps.x()));
  r.mode = 2;
  s = gnss_sample_from(r, 0.0);
  EXPECT_TRUE(std::isnan(s->position.height_m));  // published invalid (not finite)
  r.time_utc_s = GpsdReport::kUnknown;
  EXPECT_FALSE(gnss_sample_from(r, 0.0));
}

TEST(GpsdConversion, MissingCourseStandingVersusMoving) {
  GpsdReport r = moving_3d_fix();
  r.track_deg = GpsdReport::kUnknown;
  r.speed_mps = 0.06;
  auto s = gnss_sample_from(r, 0.0);
  EXPECT_EQ(s->vel_enu_mps.x(), 0.0);
  EXPECT_EQ(s->vel_enu_mps.y(), 0.0);
  EXPECT_DOUBLE_EQ(*s->vel_std_mps, 0.2);  // max(eps / 2, speed)
  r.speed_mps = 3.0;
  s = gnss_sample_from(r, 0.0);
  EXPECT_TRUE(std::isnan(s->vel_enu_mps.x()));
}

TEST(GpsdConversion, StatusGivesTheFixQuality) {
  GpsdReport r = moving_3d_fix();
  const int expected[] = {1, 1, 2, 4, 5, 6, 1};
  for (int status = 0; status <= 6; ++status) {
    r.status = status;
    EXPECT_EQ(gnss_sample_from(r, 0.0)->fix, expected[status]) << status;
  }
}

TEST(GpsdTimeGate, DropsBackwardAndRepeatedTimes) {
  GnssTimeGate g;
  EXPECT_EQ(g.admit(10.0), GnssTimeGate::Verdict::kAccept);
  EXPECT_EQ(g.admit(11.0), GnssTimeGate::Verdict::kAccept);
  EXPECT_EQ(g.admit(11.0), GnssTimeGate::Verdict::kRepeated);
  EXPECT_EQ(g.admit(5.0), GnssTimeGate::Verdict::kBackwards);
  EXPECT_EQ(g.admit(10.5), GnssTimeGate::Verdict::kBackwards);  // still behind 11
  EXPECT_EQ(g.admit(12.0), GnssTimeGate::Verdict::kAccept);
}

TEST(GpsdSourceSpec, LoopbackOnlyUnlessAllowed) {
  EXPECT_EQ(parse_gpsd_source("gpsd:", false).port, 2947);
  const GpsdSourceSpec s = parse_gpsd_source("gpsd:127.0.0.2:3000", false);
  EXPECT_EQ(s.host, "127.0.0.2");
  EXPECT_EQ(s.port, 3000);
  EXPECT_EQ(parse_gpsd_source("gpsd:localhost:2947", false).host, "localhost");
  EXPECT_THROW(parse_gpsd_source("gpsd:0.0.0.0:2947", false), ConfigError);
  EXPECT_EQ(parse_gpsd_source("gpsd:0.0.0.0:2947", true).host, "0.0.0.0");
  EXPECT_THROW(parse_gpsd_source("gpsd:127.0.0.1:0", false), ConfigError);
  EXPECT_THROW(parse_gpsd_source("gpsd:127.0.0.1:x", false), ConfigError);
}

TEST(GpsdSourceSpec, ReconnectBackOffDoublesToThirtySeconds) {
  const double expected[] = {1, 2, 4, 8, 16, 30, 30, 30};
  for (int n = 1; n <= 8; ++n) EXPECT_EQ(gpsd_reconnect_backoff_s(n), expected[n - 1]) << n;
}

}  // namespace
}  // namespace odonav::gateway
