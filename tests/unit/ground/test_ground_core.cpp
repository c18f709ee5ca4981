// odonav-ground's middleware-free core: the MCAP writer's bytes checked by an independent parser
// written from the spec, ros2msg schemas from the real .msg twins, the fleet state's staleness and
// rates on a synthetic clock, topic selection, QoS metadata, dashboard size.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "odonav/ground/fleet_state.hpp"
#include "odonav/ground/mcap_writer.hpp"
#include "odonav/ground/recording.hpp"
#include "odonav/ground/ros2msg_schema.hpp"

using namespace odonav::ground;
namespace fs = std::filesystem;

namespace {

std::string read_file(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

/// A minimal MCAP reader from the spec, independent of the writer's code.
struct Record {
  std::uint8_t opcode;
  std::uint64_t offset;  // of the opcode byte
  std::string content;
};
std::uint64_t le(const std::string& s, std::size_t at, int bytes) {
  std::uint64_t v = 0;
  for (int i = bytes - 1; i >= 0; --i) v = (v << 8) | static_cast<std::uint8_t>(s[at + static_cast<std::size_t>(i)]);
  return v;
}
std::string str_at(const std::string& s, std::size_t& at) {
  const auto n = static_cast<std::size_t>(le(s, at, 4));
  std::string r = s.substr(at + 4, n);
  at += 4 + n;
  return r;
}
const std::string kMagic("\x89MCAP0\r\n", 8);

/// Records from offset 8 until the end (or a cut record); `rest` gets the bytes left unparsed.
std::vector<Record> parse_records(const std::string& file, std::size_t end, std::size_t* rest = nullptr) {
  std::vector<Record> records;
  std::size_t at = 8;
  while (at + 9 <= end) {
    const std::uint64_t length = le(file, at + 1, 8);
    if (at + 9 + length > end) break;
    records.push_back({static_cast<std::uint8_t>(file[at]), at, file.substr(at + 9, length)});
    at += 9 + length;
  }
  if (rest) *rest = end - at;
  return records;
}

fs::path temp_file(const std::string& name) {
  const fs::path dir = fs::path(ODONAV_BINARY_DIR) / "tests" / "ground" / "core";
  fs::create_directories(dir);
  return dir / name;
}

}  // namespace

TEST(McapWriter, Crc32IsTheStandardOne) {
  const std::string check = "123456789";
  EXPECT_EQ(crc32_update(0, reinterpret_cast<const std::uint8_t*>(check.data()), check.size()), 0xCBF43926u);
  // Continuation equals one pass.
  const auto a = crc32_update(0, reinterpret_cast<const std::uint8_t*>(check.data()), 4);
  EXPECT_EQ(crc32_update(a, reinterpret_cast<const std::uint8_t*>(check.data()) + 4, 5), 0xCBF43926u);
}

TEST(McapWriter, FileLayoutFollowsTheSpec) {
  const fs::path path = temp_file("layout.mcap");
  McapWriter w(path.string());
  const auto schema = w.add_schema("odonav/msg/Odometer", "ros2msg", "uint32 pulses\n");
  const auto c0 = w.add_channel(schema, "/odonav/odometer", "cdr", {{"k", "v"}, {"a", "b"}});
  const auto c1 = w.add_channel(schema, "/odonav/odometer2", "cdr", {});
  EXPECT_EQ(schema, 1);
  EXPECT_EQ(c0, 0);
  EXPECT_EQ(c1, 1);
  const std::uint8_t p1[] = {0, 1, 0, 0, 42, 0, 0, 0};
  const std::uint8_t p2[] = {0, 1, 0, 0, 7, 0, 0, 0};
  w.write_message(c0, 3000, 2999, p1, sizeof p1);
  w.write_message(c1, 1000, 1000, p2, sizeof p2);
  w.write_message(c0, 5000, 5000, p2, sizeof p2);
  // Nothing but the magic and Header reaches the file before a flush.
  const std::string before = read_file(path);
  EXPECT_EQ(before.substr(0, 8), kMagic);
  std::size_t rest = 1;
  auto records = parse_records(before, before.size(), &rest);
  ASSERT_EQ(records.size(), 1u);
  EXPECT_EQ(records[0].opcode, 0x01);
  EXPECT_EQ(rest, 0u);
  // After a flush the file holds whole records only: what a crash would leave.
  w.flush();
  const std::string flushed = read_file(path);
  records = parse_records(flushed, flushed.size(), &rest);
  EXPECT_EQ(rest, 0u);
  ASSERT_EQ(records.size(), 7u);  // header, schema, 2 channels, 3 messages
  w.close();

  const std::string f = read_file(path);
  ASSERT_GE(f.size(), 16u);
  EXPECT_EQ(f.substr(f.size() - 8), kMagic);
  records = parse_records(f, f.size() - 8, &rest);
  EXPECT_EQ(rest, 0u);
  std::vector<int> opcodes;
  for (const auto& r : records) opcodes.push_back(r.opcode);
  EXPECT_EQ(opcodes, (std::vector<int>{0x01, 0x03, 0x04, 0x04, 0x05, 0x05, 0x05, 0x0F, 0x03, 0x04, 0x04, 0x0B, 0x0E,
                                       0x0E, 0x0E, 0x02}));
  // Header: profile "ros2".
  std::size_t at = 0;
  EXPECT_EQ(str_at(records[0].content, at), "ros2");
  // Schema: id 1, name, encoding, data.
  at = 2;
  EXPECT_EQ(le(records[1].content, 0, 2), 1u);
  EXPECT_EQ(str_at(records[1].content, at), "odonav/msg/Odometer");
  EXPECT_EQ(str_at(records[1].content, at), "ros2msg");
  EXPECT_EQ(str_at(records[1].content, at), "uint32 pulses\n");
  // Channel 0: metadata map of two entries, sorted by key.
  const std::string& ch = records[2].content;
  at = 4;
  EXPECT_EQ(le(ch, 0, 2), 0u);
  EXPECT_EQ(le(ch, 2, 2), 1u);
  EXPECT_EQ(str_at(ch, at), "/odonav/odometer");
  EXPECT_EQ(str_at(ch, at), "cdr");
  const auto map_bytes = le(ch, at, 4);
  at += 4;
  EXPECT_EQ(map_bytes, ch.size() - at);
  EXPECT_EQ(str_at(ch, at), "a");
  EXPECT_EQ(str_at(ch, at), "b");
  EXPECT_EQ(str_at(ch, at), "k");
  EXPECT_EQ(str_at(ch, at), "v");
  // Messages: channel, per-channel sequence, log and publish time, payload.
  const std::string& m1 = records[4].content;
  EXPECT_EQ(le(m1, 0, 2), 0u);
  EXPECT_EQ(le(m1, 2, 4), 1u);
  EXPECT_EQ(le(m1, 6, 8), 3000u);
  EXPECT_EQ(le(m1, 14, 8), 2999u);
  EXPECT_EQ(m1.substr(22), std::string(reinterpret_cast<const char*>(p1), sizeof p1));
  EXPECT_EQ(le(records[5].content, 0, 2), 1u);
  EXPECT_EQ(le(records[5].content, 2, 4), 1u);  // first on channel 1
  EXPECT_EQ(le(records[6].content, 2, 4), 2u);  // second on channel 0
  // DataEnd: CRC32 of everything before it, magic included.
  const std::uint64_t data_end_at = records[7].offset;
  EXPECT_EQ(le(records[7].content, 0, 4),
            crc32_update(0, reinterpret_cast<const std::uint8_t*>(f.data()), static_cast<std::size_t>(data_end_at)));
  // Statistics: 3 messages, 1 schema, 2 channels, times 1000..5000, counts per channel 2 and 1.
  const std::string& st = records[11].content;
  EXPECT_EQ(le(st, 0, 8), 3u);
  EXPECT_EQ(le(st, 8, 2), 1u);
  EXPECT_EQ(le(st, 10, 4), 2u);
  EXPECT_EQ(le(st, 26, 8), 1000u);
  EXPECT_EQ(le(st, 34, 8), 5000u);
  EXPECT_EQ(le(st, 42, 4), 2u * (2 + 8));
  EXPECT_EQ(le(st, 46, 2), 0u);
  EXPECT_EQ(le(st, 48, 8), 2u);
  EXPECT_EQ(le(st, 56, 2), 1u);
  EXPECT_EQ(le(st, 58, 8), 1u);
  // Footer: summary start = the record after DataEnd, summary offsets start, CRC.
  const std::string& footer = records.back().content;
  const std::uint64_t summary_start = le(footer, 0, 8);
  const std::uint64_t offsets_start = le(footer, 8, 8);
  EXPECT_EQ(summary_start, records[8].offset);
  EXPECT_EQ(offsets_start, records[12].offset);
  const std::size_t footer_at = static_cast<std::size_t>(records.back().offset);
  EXPECT_EQ(le(footer, 16, 4), crc32_update(0, reinterpret_cast<const std::uint8_t*>(f.data()) + summary_start,
                                            footer_at + 1 + 8 + 16 - static_cast<std::size_t>(summary_start)));
  // Summary offsets point at their groups: schemas, channels, statistics.
  const std::vector<std::pair<int, std::size_t>> groups{{0x03, 8}, {0x04, 9}, {0x0B, 11}};
  for (std::size_t g = 0; g < groups.size(); ++g) {
    const std::string& so = records[12 + g].content;
    EXPECT_EQ(static_cast<std::uint8_t>(so[0]), groups[g].first);
    EXPECT_EQ(le(so, 1, 8), records[groups[g].second].offset);
  }
  EXPECT_EQ(w.message_count(), 3u);
  EXPECT_EQ(w.channel_message_count(0), 2u);
  EXPECT_THROW(w.write_message(0, 1, 1, p1, sizeof p1), std::logic_error);
}

TEST(McapWriter, BadUseAndBadPathAreClearErrors) {
  try {
    McapWriter w("/nonexistent-dir/x.mcap");
    ADD_FAILURE() << "no error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent-dir/x.mcap"), std::string::npos);
  }
  McapWriter w(temp_file("bad.mcap").string());
  EXPECT_THROW(w.add_channel(3, "/t", "cdr", {}), std::invalid_argument);
  const std::uint8_t b = 0;
  EXPECT_THROW(w.write_message(0, 0, 0, &b, 1), std::invalid_argument);
}

TEST(Ros2MsgSchema, HealthCarriesItsDependenciesOnceInRos2Order) {
  const MsgLibrary library = load_msg_library(std::string(ODONAV_SOURCE_DIR) + "/idl");
  // The build embeds exactly the .msg files of idl/ and of the ground station's standard types.
  MsgLibrary expected = library;
  for (const auto& [type, text] : load_msg_library(std::string(ODONAV_SOURCE_DIR) + "/components/ground/msg"))
    expected[type] = text;
  EXPECT_EQ(expected, embedded_msg_library());
  const std::string schema = ros2msg_schema(library, "odonav/msg/Health");
  EXPECT_EQ(schema.rfind(library.at("odonav/msg/Health"), 0), 0u);  // starts with its own text
  const std::string sep = std::string(80, '=') + "\n";
  const auto header = schema.find(sep + "MSG: std_msgs/Header\n");
  const auto time = schema.find(sep + "MSG: builtin_interfaces/Time\n");
  const auto counter = schema.find(sep + "MSG: odonav/Counter\n");
  ASSERT_NE(header, std::string::npos);
  ASSERT_NE(time, std::string::npos);
  ASSERT_NE(counter, std::string::npos);
  EXPECT_LT(header, time);  // depth first: Header's own dependency right after it
  EXPECT_LT(time, counter);
  EXPECT_EQ(schema.find("MSG: std_msgs/Header", header + sep.size() + 5), std::string::npos);  // once
  // Every type of the contract has a schema; Time only once even when reached twice.
  for (const char* t :
       {"odonav/msg/Odometer", "odonav/msg/InsAttitude", "odonav/msg/GnssFix", "odonav/msg/Misalignment",
        "odonav/msg/ScaleFactor", "odonav/msg/DeadReckoning", "odonav/msg/Command"}) {
    const std::string s = ros2msg_schema(library, t);
    EXPECT_NE(s.find("MSG: builtin_interfaces/Time"), std::string::npos) << t;
    EXPECT_EQ(s.find("MSG: odonav/Counter"), std::string::npos) << t;
  }
}

TEST(Ros2MsgSchema, DependenciesAndErrors) {
  EXPECT_EQ(msg_dependencies("# c\nCounter[] a  # x\nstring<=8 s\nfloat64[3] v\npkg/Other b\nother_pkg/msg/T[<=2] c\n"
                             "uint8 K=3\n",
                             "mine"),
            (std::vector<std::string>{"mine/msg/Counter", "pkg/msg/Other", "other_pkg/msg/T"}));
  EXPECT_THROW(msg_dependencies("float64\n", "p"), std::runtime_error);
  const MsgLibrary lib{{"p/msg/A", "p/B b\n"}};
  try {
    ros2msg_schema(lib, "p/msg/A");
    ADD_FAILURE() << "no error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("'p/msg/B' used by 'p/msg/A'"), std::string::npos) << e.what();
  }
}

TEST(FleetState, StaleByDeadlineEdgeOrByAgeAndRatesOverTheWindow) {
  FleetState fleet;  // health stale after 4.5 s, rate window 2 s
  HealthView h;
  h.vehicle_id = "v1";
  h.component = "odonav-gateway";
  h.state = 1;
  fleet.on_health(h, 10.0);
  h.component = "odonav-calibration";
  fleet.on_health(h, 10.0);
  auto comp = [&](double now, const std::string& c) {
    const FleetSnapshot snap = fleet.snapshot(now);
    for (const auto& x : snap.vehicles.at(0).components)
      if (x.health.component == c) return x;
    throw std::runtime_error("missing " + c);
  };
  EXPECT_FALSE(comp(14.4, "odonav-gateway").stale);
  EXPECT_TRUE(comp(14.6, "odonav-gateway").stale);
  EXPECT_NEAR(comp(14.6, "odonav-gateway").age_s, 4.6, 1e-12);
  // The deadline edge marks it at once, the next sample clears it.
  fleet.on_silence("v1", Stream::kHealth, "odonav-calibration", true);
  EXPECT_TRUE(comp(10.5, "odonav-calibration").stale);
  EXPECT_FALSE(comp(10.5, "odonav-gateway").stale);
  EXPECT_TRUE(fleet.snapshot(10.5).vehicles[0].stale);
  fleet.on_health(h, 11.0);
  EXPECT_FALSE(comp(11.0, "odonav-calibration").stale);
  // 100 odometer arrivals at 100 Hz ending at t=20: 2 s window holds them all -> 50 Hz over 2 s... all 100
  // within [19.01, 20] are inside the window: 100 / 2 s = 50 Hz.
  for (int i = 1; i <= 100; ++i) fleet.on_arrival("v1", Stream::kOdometer, 19.0 + 0.01 * i);
  EXPECT_DOUBLE_EQ(fleet.snapshot(20.0).vehicles[0].rate_hz[0], 50.0);
  EXPECT_DOUBLE_EQ(fleet.snapshot(21.505).vehicles[0].rate_hz[0], 25.0);  // only the 50 in [19.51, 20] remain
  EXPECT_DOUBLE_EQ(fleet.snapshot(23.0).vehicles[0].rate_hz[0], 0.0);
  // Filter by vehicle.
  EXPECT_TRUE(fleet.snapshot(20.0, {"other"}).vehicles.empty());
}

TEST(FleetState, JsonAndDashboardOfManyVehiclesFitEightyByTwentyFour) {
  FleetState fleet;
  for (int v = 0; v < 5; ++v) {
    const std::string id = "vehicle-" + std::to_string(v);
    for (const char* c : {"odonav-gateway", "odonav-calibration", "odonav-identification", "odonav-dead-reckoning"}) {
      HealthView h;
      h.vehicle_id = id;
      h.component = c;
      h.level = 1;
      h.reason = "a long reason that would not fit into eighty columns when printed after the name and state";
      fleet.on_health(h, 1.0);
    }
    ScaleFactorView k;
    k.vehicle_id = id;
    k.row.k_m_per_pulse = 0.0126875;
    k.row.sigma_m_per_pulse = std::nullopt;  // unknown (-1 on the wire)
    k.source = v == 0 ? "identification/standby" : "identification";
    fleet.on_scale_factor(k, 1.0);
    DeadReckoningView d;
    d.vehicle_id = id;
    d.row.k_source = "identified";
    d.row.distance_m = 1234.0;
    fleet.on_dead_reckoning(d, 1.0);
    if (v == 0) {
      NavigationPositionView n;
      n.vehicle_id = id;
      n.row.status = "dead_reckoning";  // bridging an outage
      n.row.var_east_m2 = 2.25;
      n.row.var_north_m2 = 1.75;
      n.row.var_up_m2 = std::nan("");  // unknown
      n.row.distance_since_fix_m = 412.5;
      fleet.on_navigation(n, 1.0);
    }
  }
  const FleetSnapshot snap = fleet.snapshot(1.5);
  const std::string text = render_dashboard(snap, 80, 24, false, "odonav-ground test");
  std::istringstream lines(text);
  std::string line;
  int n = 0;
  while (std::getline(lines, line)) {
    ++n;
    EXPECT_LE(line.size(), 80u);
  }
  EXPECT_LE(n, 24);
  EXPECT_NE(text.find("more vehicle(s)"), std::string::npos) << text;
  EXPECT_EQ(text.find('\x1b'), std::string::npos);
  const nlohmann::json j = snapshot_json(snap);
  ASSERT_EQ(j.at("vehicles").size(), 5u);
  EXPECT_TRUE(j["vehicles"][0]["scale_factor"]["sigma_m_per_pulse"].is_null());  // -1 = unknown
  EXPECT_EQ(j["vehicles"][0]["components"].size(), 4u);
  EXPECT_TRUE(j["vehicles"][0]["misalignment"].is_null());
  // The anchored position: status, sqrt(2.25 + 1.75) = 2 m horizontal sigma, distance since the fix.
  EXPECT_EQ(j["vehicles"][0]["navigation"]["status"], "dead_reckoning");
  EXPECT_DOUBLE_EQ(j["vehicles"][0]["navigation"]["horizontal_sigma_m"].get<double>(), 2.0);
  EXPECT_DOUBLE_EQ(j["vehicles"][0]["navigation"]["distance_since_fix_m"].get<double>(), 412.5);
  EXPECT_TRUE(j["vehicles"][1]["navigation"].is_null());
  // Every column of the output files is in the JSON, by the file's name: the one field table.
  for (const std::string& column : odonav::results::scale_factor_columns())
    EXPECT_TRUE(j["vehicles"][0]["scale_factor"].contains(column)) << column;
  for (const std::string& column : odonav::results::dead_reckoning_columns())
    EXPECT_TRUE(j["vehicles"][0]["dead_reckoning"].contains(column)) << column;
  for (const std::string& column : odonav::results::navigation_position_columns())
    EXPECT_TRUE(j["vehicles"][0]["navigation"].contains(column)) << column;
  EXPECT_DOUBLE_EQ(j["vehicles"][0]["scale_factor"]["k_m_per_pulse"].get<double>(), 0.0126875);
  EXPECT_EQ(j["vehicles"][0]["dead_reckoning"]["k_source"], "identified");
  EXPECT_DOUBLE_EQ(j["vehicles"][0]["navigation"]["var_east_m2"].get<double>(), 2.25);
  EXPECT_TRUE(j["vehicles"][0]["navigation"]["var_up_m2"].is_null());  // unknown: empty in the file
  // Which instance publishes K: in the JSON and on the DR line of the dashboard.
  EXPECT_EQ(j["vehicles"][0]["scale_factor"]["source"], "identification/standby");
  EXPECT_EQ(j["vehicles"][1]["scale_factor"]["source"], "identification");
  EXPECT_NE(text.find("dist 1234 m K identified from identification/standby"), std::string::npos) << text;
}

TEST(FleetState, GapsInTheDeadReckoningOutputsArePerVehicleInTheJsonAndOnTheDashboard) {
  FleetState fleet;
  DeadReckoningView d;
  d.row.k_source = "identified";
  // v1: 100 Hz from t = 40.00 s, then nothing from 45.23 to 50.00 s (a stalled dead reckoning:
  // 477 outputs t=45.230-49.990 s never arrived), then on again; repeats are not gaps.
  d.vehicle_id = "v1";
  for (int i = 0; i <= 522; ++i) {
    d.row.t_s = 40.0 + 0.01 * i;
    fleet.on_dead_reckoning(d, 1.0);
  }
  fleet.on_dead_reckoning(d, 1.0);  // a repeat of t = 45.22 s
  for (int i = 0; i <= 100; ++i) {
    d.row.t_s = 50.0 + 0.01 * i;
    fleet.on_dead_reckoning(d, 2.0);
  }
  // v2: continuous.
  d.vehicle_id = "v2";
  for (int i = 0; i <= 300; ++i) {
    d.row.t_s = 10.0 + 0.01 * i;
    fleet.on_dead_reckoning(d, 2.0);
  }
  const FleetSnapshot snap = fleet.snapshot(2.0);
  ASSERT_EQ(snap.vehicles.size(), 2u);
  const VehicleSnapshot& v1 = snap.vehicles[0];
  EXPECT_EQ(v1.dead_reckoning_missed, 477u);
  EXPECT_EQ(v1.dead_reckoning_gaps, 1u);
  ASSERT_TRUE(v1.dead_reckoning_last_gap);
  EXPECT_NEAR(v1.dead_reckoning_last_gap->first_missing_t_s, 45.23, 1e-9);
  EXPECT_NEAR(v1.dead_reckoning_last_gap->last_missing_t_s, 49.99, 1e-9);
  EXPECT_EQ(snap.vehicles[1].dead_reckoning_missed, 0u);
  EXPECT_FALSE(snap.vehicles[1].dead_reckoning_last_gap);

  const nlohmann::json j = snapshot_json(snap);
  const auto& g1 = j["vehicles"][0]["gaps"]["dead_reckoning"];
  EXPECT_EQ(g1["missed"], 477);
  EXPECT_EQ(g1["gaps"], 1);
  EXPECT_EQ(g1["last"], "missed 477 dead-reckoning outputs t=45.230-49.990 s");
  EXPECT_NEAR(g1["last_first_missing_t_s"].get<double>(), 45.23, 1e-9);
  const auto& g2 = j["vehicles"][1]["gaps"]["dead_reckoning"];
  EXPECT_EQ(g2["missed"], 0);
  EXPECT_TRUE(g2["last"].is_null());

  const std::string text = render_dashboard(snap, 120, 40, false, "gaps");
  EXPECT_NE(text.find("missed 477 in 1 gap(s), last t=45.23-49.99 s"), std::string::npos) << text;
  EXPECT_EQ(text.find("missed 0"), std::string::npos) << text;
}

TEST(Recording, TopicSelectionAndQosMetadata) {
  const auto chosen = select_topics("gnss/fix, /odonav/health,rt/odonav/odometer,gnss/fix");
  ASSERT_EQ(chosen.size(), 3u);
  EXPECT_STREQ(chosen[0].name, "rt/odonav/gnss/fix");
  EXPECT_STREQ(chosen[1].name, "rt/odonav/health");
  EXPECT_STREQ(chosen[2].name, "rt/odonav/odometer");
  EXPECT_EQ(select_topics("").size(), 9u);  // every topic of the contract
  // Recordings read the estimates with the deep recorder profiles, the rest with the topic's own.
  EXPECT_STREQ(recording_reader_profile(odonav::topics::kScaleFactor), "odonav_scale_factor_recorder_reader");
  EXPECT_STREQ(recording_reader_profile(odonav::topics::kMisalignment), "odonav_misalignment_recorder_reader");
  EXPECT_STREQ(recording_reader_profile(odonav::topics::kGnssFix), odonav::topics::kGnssFix.reader_profile);
  EXPECT_STREQ(recording_reader_profile(odonav::topics::kScaleFactor, true),
               odonav::topics::kGroundBestEffortReaderProfile);
  EXPECT_STREQ(recording_reader_profile(odonav::topics::kOdometer, true),
               odonav::topics::kGroundBestEffortReaderProfile);
  try {
    select_topics("odometer,bogus");
    ADD_FAILURE() << "no error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("'bogus'"), std::string::npos);
  }
  OfferedQos q;
  q.reliable = false;
  q.transient_local = true;
  q.depth = 7;
  q.deadline_s = 1.5;
  const std::string y = offered_qos_profiles_yaml(q);
  EXPECT_NE(
      y.find(
          "- history: 1\n  depth: 7\n  reliability: 2\n  durability: 1\n  deadline:\n    sec: 1\n    nsec: 500000000\n"),
      std::string::npos)
      << y;
}
