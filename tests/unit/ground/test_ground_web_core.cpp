// odonav-ground serve's middleware-free core: the CDR bytes of the derived standard messages read
// back field by field at the offsets CDR prescribes, diagnostics from a fleet snapshot (STALE), the
// Foxglove protocol's subprotocol choice, frames and subscriptions, channel ids and expiry, the
// web API's token and body rules, and the page's track and K history.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

#include "odonav/ground/fleet_history.hpp"
#include "odonav/ground/foxglove_protocol.hpp"
#include "odonav/ground/standard_channels.hpp"
#include "odonav/ground/web_api.hpp"
#include "odonav/frames.hpp"

using namespace odonav::ground;

namespace {

template <class T>
T at(const std::vector<std::uint8_t>& b, std::size_t payload_offset) {
  T v;
  std::memcpy(&v, b.data() + 4 + payload_offset, sizeof v);
  return v;
}

std::string str_at(const std::vector<std::uint8_t>& b, std::size_t payload_offset) {
  const auto n = at<std::uint32_t>(b, payload_offset);
  return std::string(reinterpret_cast<const char*>(b.data() + 4 + payload_offset + 4), n - 1);
}

}  // namespace

TEST(StandardChannels, NavSatFixCdrLayout) {
  DeadReckoningView dr;
  dr.vehicle_id = "v1";
  dr.row.t_s = 1234.25;
  // As the ground node reads them: the message's degrees to the row's radians, exactly back.
  dr.row.lat_rad = odonav::exact_radians_of(52.5123456789);
  dr.row.lon_rad = odonav::exact_radians_of(13.3987654321);
  dr.row.height_m = 41.5;
  const auto b = encode_cdr(navsat_from_dead_reckoning(dr));
  // Encapsulation CDR_LE, then: sec, nanosec, frame_id "wgs84" (len 6), status int8 at 18, service
  // uint16 at 20, latitude at 24 (8-aligned), longitude 32, altitude 40, covariance 48..119, type 120.
  ASSERT_EQ(b.size(), 4u + 121u);
  EXPECT_EQ(b[0], 0x00);
  EXPECT_EQ(b[1], 0x01);
  EXPECT_EQ(at<std::int32_t>(b, 0), 1234);
  EXPECT_EQ(at<std::uint32_t>(b, 4), 250000000u);
  EXPECT_EQ(str_at(b, 8), "wgs84");
  EXPECT_EQ(at<std::int8_t>(b, 18), 0);
  EXPECT_EQ(at<std::uint16_t>(b, 20), 0);
  EXPECT_EQ(at<double>(b, 24), 52.5123456789);
  EXPECT_EQ(at<double>(b, 32), 13.3987654321);
  EXPECT_EQ(at<double>(b, 40), 41.5);
  for (int i = 0; i < 9; ++i) EXPECT_EQ(at<double>(b, 48 + 8 * i), 0.0);
  EXPECT_EQ(at<std::uint8_t>(b, 120), 0);
}

TEST(StandardChannels, GnssStatusAndCovariance) {
  GnssView g;
  g.valid = true;
  g.fix_quality = 4;
  g.position_std_m = 0.5;
  auto m = navsat_from_gnss(g);
  EXPECT_EQ(m.status, 2);
  EXPECT_EQ(m.position_covariance_type, 1);
  EXPECT_DOUBLE_EQ(m.position_covariance_m2[0], 0.25);
  EXPECT_DOUBLE_EQ(m.position_covariance_m2[4], 0.25);
  EXPECT_DOUBLE_EQ(m.position_covariance_m2[1], 0.0);
  g.valid = false;
  EXPECT_EQ(navsat_from_gnss(g).status, -1);
  g.valid = true;
  g.fix_quality = 1;
  g.position_std_m = -1.0;
  m = navsat_from_gnss(g);
  EXPECT_EQ(m.status, 0);
  EXPECT_EQ(m.position_covariance_type, 0);
}

TEST(StandardChannels, DiagnosticsMarkStaleComponents) {
  FleetState state;
  HealthView h;
  h.vehicle_id = "v1";
  h.component = "odonav-identification";
  h.stamp_s = 1700000000.5;
  h.state = 1;
  h.level = 0;
  h.reason = "converged";
  h.counters = {{"epochs", 42}};
  state.on_health(h, 0.0);
  h.component = "odonav-calibration";
  h.level = 1;
  h.reason = "waiting for speed";
  state.on_health(h, 9.0);
  // At 10 s the identification (last heard at 0 s) is past 1.5 Health deadline periods (4.5 s).
  const auto snap = state.snapshot(10.0);
  ASSERT_EQ(snap.vehicles.size(), 1u);
  const DiagnosticArrayMsg d = diagnostics_from(snap.vehicles[0]);
  ASSERT_EQ(d.status.size(), 2u);
  EXPECT_EQ(d.status[0].name, "v1/odonav-calibration");
  EXPECT_EQ(d.status[0].level, 1);
  EXPECT_EQ(d.status[0].message, "waiting for speed");
  EXPECT_EQ(d.status[1].name, "v1/odonav-identification");
  EXPECT_EQ(d.status[1].level, 3);
  EXPECT_EQ(d.status[1].message, "STALE: no Health for 10 s; last: converged");
  EXPECT_EQ(d.status[1].hardware_id, "v1");
  bool has_counter = false;
  for (const auto& [k, v] : d.status[1].values) has_counter = has_counter || (k == "epochs" && v == "42");
  EXPECT_TRUE(has_counter);
  EXPECT_DOUBLE_EQ(d.stamp_s, 1700000000.5);

  // CDR: header, sequence of 2, first status: level byte, then name string (4-aligned).
  const auto b = encode_cdr(d);
  EXPECT_EQ(at<std::int32_t>(b, 0), 1700000000);
  EXPECT_EQ(at<std::uint32_t>(b, 4), 500000000u);
  EXPECT_EQ(str_at(b, 8), "");  // frame_id: length 1, NUL only
  EXPECT_EQ(at<std::uint32_t>(b, 16), 2u);
  EXPECT_EQ(at<std::uint8_t>(b, 20), 1);
  EXPECT_EQ(str_at(b, 24), "v1/odonav-calibration");
}

TEST(StandardChannels, SchemasAndTopics) {
  const std::string navsat = derived_schema(DerivedChannel::kNavSatGnss);
  EXPECT_NE(navsat.find("NavSatStatus status"), std::string::npos);
  EXPECT_NE(navsat.find("MSG: sensor_msgs/NavSatStatus"), std::string::npos);
  EXPECT_NE(navsat.find("MSG: std_msgs/Header"), std::string::npos);
  const std::string diag = derived_schema(DerivedChannel::kDiagnostics);
  EXPECT_NE(diag.find("MSG: diagnostic_msgs/DiagnosticStatus"), std::string::npos);
  EXPECT_NE(diag.find("MSG: diagnostic_msgs/KeyValue"), std::string::npos);
  EXPECT_EQ(derived_topic("vehicle-01", DerivedChannel::kNavSatNavigation), "/odonav/vehicle-01/navsat/navigation");
  EXPECT_EQ(derived_encoding(DerivedChannel::kScaleFactorPlot), "json");
  EXPECT_NO_THROW(nlohmann::json::parse(derived_schema(DerivedChannel::kScaleFactorPlot)));
  ScaleFactorView k;
  k.row.k_m_per_pulse = 0.0125;
  k.row.sigma_m_per_pulse = std::nullopt;
  EXPECT_TRUE(scale_factor_plot(k)["k_plus_sigma"].is_null());
  k.row.sigma_m_per_pulse = 0.0001;
  EXPECT_DOUBLE_EQ(scale_factor_plot(k)["k_plus_sigma"].get<double>(), 0.0126);
}

TEST(FoxgloveProtocol, SubprotocolChoice) {
  EXPECT_EQ(choose_subprotocol("foxglove.websocket.v1"), "foxglove.websocket.v1");
  EXPECT_EQ(choose_subprotocol("foxglove.sdk.v1"), "foxglove.sdk.v1");
  EXPECT_EQ(choose_subprotocol("other, foxglove.sdk.v1 ,foxglove.websocket.v1"), "foxglove.sdk.v1");
  EXPECT_FALSE(choose_subprotocol("").has_value());
  EXPECT_FALSE(choose_subprotocol("chat").has_value());
}

TEST(FoxgloveProtocol, MessageFrame) {
  const std::uint8_t payload[] = {9, 8, 7};
  const std::string f = message_frame(0x01020304u, 0x1122334455667788ull, payload, 3);
  ASSERT_EQ(f.size(), 16u);
  EXPECT_EQ(f[0], 0x01);
  EXPECT_EQ(static_cast<std::uint8_t>(f[1]), 0x04);
  EXPECT_EQ(static_cast<std::uint8_t>(f[4]), 0x01);
  EXPECT_EQ(static_cast<std::uint8_t>(f[5]), 0x88);
  EXPECT_EQ(static_cast<std::uint8_t>(f[12]), 0x11);
  EXPECT_EQ(f[13], 9);
  EXPECT_EQ(stamp_ns(1.5), 1500000000ull);
  EXPECT_EQ(stamp_ns(-1.0), 0ull);
  EXPECT_EQ(stamp_ns(std::nan("")), 0ull);
}

TEST(FoxgloveProtocol, Subscriptions) {
  ClientSubscriptions c;
  auto exists = [](std::uint32_t id) { return id == 1 || id == 2; };
  EXPECT_TRUE(
      c.handle_text(R"({"op":"subscribe","subscriptions":[{"id":0,"channelId":1},{"id":1,"channelId":2}]})", exists)
          .empty());
  EXPECT_EQ(c.subscriptions_of(1), std::vector<std::uint32_t>{0});
  auto r =
      c.handle_text(R"({"op":"subscribe","subscriptions":[{"id":0,"channelId":2},{"id":5,"channelId":7}]})", exists);
  ASSERT_EQ(r.size(), 2u);
  EXPECT_NE(r[0]["message"].get<std::string>().find("already in use"), std::string::npos);
  EXPECT_NE(r[1]["message"].get<std::string>().find("channel 7 is not advertised"), std::string::npos);
  EXPECT_TRUE(c.handle_text(R"({"op":"unsubscribe","subscriptionIds":[0]})", exists).empty());
  EXPECT_TRUE(c.subscriptions_of(1).empty());
  EXPECT_EQ(c.handle_text(R"({"op":"unsubscribe","subscriptionIds":[0]})", exists).at(0)["level"], 1);
  EXPECT_EQ(c.handle_text("not json", exists).at(0)["level"], 2);
  EXPECT_EQ(c.handle_text(R"({"op":"dance"})", exists).at(0)["level"], 2);
  EXPECT_EQ(c.handle_text(R"({"op":"advertise","channels":[]})", exists).at(0)["level"], 1);
  c.remove_channel(2);
  EXPECT_EQ(c.size(), 0u);
}

// Two subscriptions of one channel, others elsewhere: the lookup by channel, unsubscribe and a
// channel going away keep every other subscription, and the ids of one channel come back sorted.
TEST(FoxgloveProtocol, SubscriptionsByChannelStayConsistent) {
  ClientSubscriptions c;
  auto exists = [](std::uint32_t id) { return id >= 1 && id <= 3; };
  EXPECT_TRUE(c.handle_text(R"({"op":"subscribe","subscriptions":[{"id":9,"channelId":1},{"id":4,"channelId":1},)"
                            R"({"id":5,"channelId":2},{"id":6,"channelId":3}]})",
                            exists)
                  .empty());
  EXPECT_EQ(c.subscriptions_of(1), (std::vector<std::uint32_t>{4, 9}));
  EXPECT_EQ(c.channels(), (std::set<std::uint32_t>{1, 2, 3}));
  EXPECT_TRUE(c.handle_text(R"({"op":"unsubscribe","subscriptionIds":[9]})", exists).empty());
  EXPECT_EQ(c.subscriptions_of(1), std::vector<std::uint32_t>{4});
  c.remove_channel(2);
  EXPECT_TRUE(c.subscriptions_of(2).empty());
  EXPECT_EQ(c.channels(), (std::set<std::uint32_t>{1, 3}));
  EXPECT_EQ(c.size(), 2u);
  // The id of a removed channel's subscription is free again; the unsubscribed one too.
  EXPECT_TRUE(
      c.handle_text(R"({"op":"subscribe","subscriptions":[{"id":5,"channelId":3},{"id":9,"channelId":3}]})", exists)
          .empty());
  EXPECT_EQ(c.subscriptions_of(3), (std::vector<std::uint32_t>{5, 6, 9}));
  EXPECT_TRUE(c.handle_text(R"({"op":"unsubscribe","subscriptionIds":[4]})", exists).empty());
  EXPECT_TRUE(c.subscriptions_of(1).empty());
  EXPECT_EQ(c.channels(), (std::set<std::uint32_t>{3}));
}

TEST(FoxgloveProtocol, ChannelSetIdsAndExpiry) {
  ChannelSet set;
  bool added = false;
  ChannelInfo info;
  info.topic = "/a";
  EXPECT_EQ(set.get_or_add("a", info, 0.0, added).id, 1u);
  EXPECT_TRUE(added);
  EXPECT_EQ(set.get_or_add("a", info, 1.0, added).id, 1u);
  EXPECT_FALSE(added);
  info.topic = "/b";
  EXPECT_EQ(set.get_or_add("b", info, 1.0, added).id, 2u);
  EXPECT_EQ(set.touch("b", 5.0), 2u);
  const auto gone = set.expire(4.5, 3.0);  // a last seen at 1.0, b at 5.0
  ASSERT_EQ(gone.size(), 1u);
  EXPECT_EQ(gone[0].topic, "/a");
  EXPECT_FALSE(set.contains(1));
  EXPECT_TRUE(set.contains(2));
  EXPECT_EQ(set.get_or_add("a", info, 6.0, added).id, 3u);  // ids are never reused
}

TEST(WebApi, Token) {
  EXPECT_NE(authorization_error("", "Bearer x").value().find("disabled"), std::string::npos);
  EXPECT_NE(authorization_error("s3cret", "").value().find("needs the token"), std::string::npos);
  EXPECT_EQ(authorization_error("s3cret", "Bearer s3creT").value(), "wrong token");
  EXPECT_EQ(authorization_error("s3cret", "Bearer s3cre").value(), "wrong token");
  EXPECT_FALSE(authorization_error("s3cret", "Bearer s3cret").has_value());
}

TEST(WebApi, CommandBody) {
  const WebCommand c =
      parse_web_command(R"({"vehicle":"v1","component":"odonav-dead-reckoning","command":"set-k","value":0.0127})");
  EXPECT_EQ(c.vehicle, "v1");
  EXPECT_DOUBLE_EQ(c.value, 0.0127);
  auto message = [](const std::string& body) {
    try {
      parse_web_command(body);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_NE(message("{").find("not JSON"), std::string::npos);
  EXPECT_NE(message(R"({"component":"x","command":"reset"})").find("'vehicle'"), std::string::npos);
  EXPECT_NE(message(R"({"vehicle":"v","component":"x","command":"set-k"})").find("'value'"), std::string::npos);
  EXPECT_NE(message(R"({"vehicle":"v","component":"x","command":"set-k","value":-1})").find("'value'"),
            std::string::npos);
  EXPECT_NE(message(R"({"vehicle":"v","component":"x","command":"reset","value":1})").find("takes no"),
            std::string::npos);
  EXPECT_EQ(message(R"({"vehicle":"v","component":"x","command":"reset"})"), "accepted");
  EXPECT_EQ(query_parameter("/api/fleet?a=1&history=vehicle%2D01", "history"), "vehicle-01");
  EXPECT_EQ(query_parameter("/api/fleet", "history"), "");
  EXPECT_EQ(target_path("/api/fleet?x=1"), "/api/fleet");
}

TEST(FleetHistory, TrackAndK) {
  FleetHistoryConfig config;
  config.k_window_s = 100.0;
  config.max_track_points = 16;
  FleetHistory h(config);
  DeadReckoningView dr;
  dr.vehicle_id = "v1";
  dr.origin_latitude_deg = 52.0;
  dr.origin_longitude_deg = 13.0;
  for (int i = 0; i < 100; ++i) {
    dr.row.east_m = i * 1.0;
    h.on_dead_reckoning(dr);
  }
  GnssView g;
  g.vehicle_id = "v1";
  g.valid = true;
  g.latitude_deg = 52.0 + 100.0 / 111250.0;  // about 100 m north (R_M at 52 deg ~ 6.374e6 m)
  g.longitude_deg = 13.0;
  h.on_gnss(g);
  for (int i = 0; i < 300; ++i) {
    ScaleFactorView k;
    k.vehicle_id = "v1";
    k.row.t_s = i;
    k.row.k_m_per_pulse = 0.01;
    if (i >= 150) k.row.sigma_m_per_pulse = 1e-4;
    h.on_scale_factor(k);
  }
  const auto j = h.json(8)["v1"];
  ASSERT_LE(j["dr"].size(), 8u);
  EXPECT_DOUBLE_EQ(j["dr"].back()[0].get<double>(), 99.0);  // the newest point always shown
  EXPECT_DOUBLE_EQ(j["dr"].front()[0].get<double>(), 0.0);
  ASSERT_EQ(j["gnss"].size(), 1u);
  EXPECT_NEAR(j["gnss"][0][1].get<double>(), 100.0, 0.5);
  EXPECT_NEAR(j["gnss"][0][0].get<double>(), 0.0, 0.01);
  ASSERT_EQ(j["k"].size(), 8u);
  EXPECT_DOUBLE_EQ(j["k"].front()[0].get<double>(), 199.0);  // window: stamps within 100 s of 299
  EXPECT_DOUBLE_EQ(j["k"].back()[0].get<double>(), 299.0);
}
