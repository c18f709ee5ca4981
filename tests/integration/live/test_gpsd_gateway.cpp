// odonav-gateway --source gpsd:... against a real gpsd: gpsfake (Debian gpsd-clients) replays NMEA
// into a gpsd on a loopback port, the gateway publishes GnssFix on loopback DDS (domains 120-121).
//  - the simulator's NMEA of a scenario: every fix must equal the scenario's GNSS row within what
//    NMEA and gpsd's JSON carry;
//  - real receivers' logs (tests/data/nmea): every fix must equal the log's own sentences, parsed
//    here independently, and the log whose time goes backward must give counted, dropped fixes.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <map>
#include <sstream>

#include "live_test_support.hpp"
#include "odonav/frames.hpp"

namespace odonav::test {
namespace {

using namespace std::chrono_literals;
namespace fs = std::filesystem;

struct GpsdRun {
  std::vector<msg::GnssFix> fixes;
  std::optional<msg::Health> last_health;  ///< the gateway's "stopping" Health
};

/// Starts gpsfake on `input`, then the gateway reading it, until gpsfake is done; returns what the
/// gateway published. Fails the test (no skip) when gpsfake is not installed.
GpsdRun run_gpsd_gateway(int domain, const fs::path& input, const std::vector<std::string>& extra) {
  GpsdRun run;
  if (::access(kGpsfake, X_OK) != 0) {
    ADD_FAILURE() << kGpsfake << " not found: install gpsd and gpsd-clients (scripts/install-deps)";
    return run;
  }
  shm_clean();
  dds::Participant p(test_participant(domain));
  Collector<msg::GnssFix> gnss(p, topics::kGnssFix);
  Collector<msg::Health> health(p, topics::kHealth);
  const int port = free_loopback_port(SOCK_STREAM);
  GpsfakeProcess fake(gpsfake_args(port, input));
  EXPECT_TRUE(fake.started());
  EXPECT_TRUE(wait_tcp_listening(port, 15s)) << "gpsfake's gpsd never listened on 127.0.0.1:" << port;
  std::vector<std::string> args{"--source", "gpsd:127.0.0.1:" + std::to_string(port)};
  args.insert(args.end(), extra.begin(), extra.end());
  ChildProcess gw(binary("odonav-gateway"), node_args(domain, 1.0, args));
  EXPECT_TRUE(gw.started());
  // gpsfake exits after the log (-1); the trailer gives the gateway time to read the last fix.
  EXPECT_TRUE(fake.wait_exit(50s)) << "gpsfake did not finish within 50 s";  // exit 1 after -W: expected
  std::this_thread::sleep_for(500ms);
  gw.signal(SIGINT);
  EXPECT_TRUE(gw.wait_exit(15s));
  EXPECT_EQ(gw.exit_code(), 0);
  health.wait_until(
      [](const auto& v) {
        for (const auto& h : v)
          if (h.component() == "odonav-gateway" && h.state() == msg::HEALTH_STATE_STOPPING) return true;
        return false;
      },
      5s);
  for (const auto& h : health.samples())
    if (h.component() == "odonav-gateway") run.last_health = h;
  run.fixes = gnss.samples();
  shm_clean();
  return run;
}

double stamp_s(const msg::GnssFix& m) { return dds::to_seconds(m.header().stamp()); }

TEST(GpsdGateway, SimulatorNmeaThroughGpsdMatchesTheScenarioGnss) {
  const fs::path dir = fresh_live_dir("gpsd-sim");
  ChildProcess sim(binary("odonav-simulator"),
                   {"straight", "--seed", "5", "--duration-s", "12", "--out", (dir / "dataset").string(), "--nmea",
                    (dir / "drive.nmea").string(), "--log-level", "warn"});
  ASSERT_TRUE(sim.wait_exit(60s));
  ASSERT_EQ(sim.exit_code(), 0);
  const Dataset d = read_dataset((dir / "dataset").string(), BadRowPolicy::kFail);
  ASSERT_GT(d.gnss.size(), 100u);
  write_gpsfake_input(dir / "drive.nmea", dir / "gpsfake-input.nmea");
  // t = UTC - the writer's epoch: the dataset's own time base.
  const GpsdRun run = run_gpsd_gateway(120, dir / "gpsfake-input.nmea", {"--gnss-utc-origin-s", "1767225600"});

  // Tolerances: what NMEA and gpsd's JSON carry.
  //  t: NMEA 0.01 s (exact here: fixes every 0.1 s), UTC as a double ~2e-7 s -> 1e-6 s.
  //  lat/lon: NMEA 1e-7 minute (8.3e-10 deg rounding) + JSON 9 decimals (5e-10 deg) -> 2e-9 deg (0.2 mm).
  //  height: GGA 0.001 m + JSON 4 decimals -> 6e-4 m (GGA carries h as MSL with separation 0).
  //  ve, vn: speed 0.001 knot (2.6e-4 m/s) + JSON 0.001 m/s, track 0.01 deg (8.7e-5 rad of the
  //  speed) -> 8e-4 m/s + 1e-4 * speed. vu is not compared: NMEA has no vertical velocity field
  //  and gpsd derives climb from height differences.
  //  pos_std: GST axes 0.001 m each, combined -> 1e-3 m.
  const double kTimeTol = 1e-6, kDegTol = 2e-9, kHeightTol = 6e-4, kStdTol = 1e-3;
  std::map<long long, const msg::GnssFix*> by_centis;
  std::size_t lead_in = 0;
  for (const auto& m : run.fixes) {
    if (stamp_s(m) < -kTimeTol) {
      ++lead_in;
      continue;
    }
    by_centis[std::llround(stamp_s(m) * 100.0)] = &m;
  }
  ASSERT_EQ(lead_in, 0u) << "the lead-in carries no time; nothing before t=0 may be published";
  ASSERT_EQ(run.fixes.size(), d.gnss.size()) << "every fix of the scenario, once";
  double worst_deg = 0, worst_h = 0, worst_v = 0;
  for (std::size_t i = 0; i < d.gnss.size(); ++i) {
    const GnssSample& s = d.gnss[i];
    const auto it = by_centis.find(std::llround(s.t_s * 100.0));
    ASSERT_NE(it, by_centis.end()) << "no fix published for t=" << s.t_s;
    const msg::GnssFix& m = *it->second;
    EXPECT_NEAR(stamp_s(m), s.t_s, kTimeTol) << i;
    EXPECT_EQ(m.valid(), s.valid()) << i;
    EXPECT_EQ(m.fix_quality(), s.fix) << i;
    const double dlat = std::abs(m.latitude_deg() - rad_to_deg(s.position.lat_rad));
    const double dlon = std::abs(m.longitude_deg() - rad_to_deg(s.position.lon_rad));
    EXPECT_LE(dlat, kDegTol) << i;
    EXPECT_LE(dlon, kDegTol) << i;
    EXPECT_NEAR(m.height_m(), s.position.height_m, kHeightTol) << i;
    const double speed = std::hypot(s.vel_enu_mps.x(), s.vel_enu_mps.y());
    const double vel_tol = 8e-4 + 1e-4 * speed;
    EXPECT_NEAR(m.velocity_east_mps(), s.vel_enu_mps.x(), vel_tol) << i;
    EXPECT_NEAR(m.velocity_north_mps(), s.vel_enu_mps.y(), vel_tol) << i;
    ASSERT_TRUE(s.pos_std_m);
    // The session's first epoch: gpsd reports its GST before it knows the date (GST and GGA come
    // before the first RMC), so the first fix has gpsd's own estimate (eph / 2) instead.
    if (i > 0) {
      EXPECT_NEAR(m.position_std_m(), *s.pos_std_m, kStdTol) << i << " (the GST of the epoch)";
    }
    worst_deg = std::max({worst_deg, dlat, dlon});
    worst_h = std::max(worst_h, std::abs(m.height_m() - s.position.height_m));
    worst_v = std::max({worst_v, std::abs(m.velocity_east_mps() - s.vel_enu_mps.x()),
                        std::abs(m.velocity_north_mps() - s.vel_enu_mps.y())});
  }
  ASSERT_TRUE(run.last_health);
  EXPECT_EQ(counter(*run.last_health, "gnss_published"), static_cast<double>(d.gnss.size()));
  EXPECT_EQ(counter(*run.last_health, "gnss_time_backwards"), 0.0);
  std::printf("gpsd sim: %zu fixes, worst |dlat|,|dlon| %.3g deg, |dh| %.3g m, |dv| %.3g m/s\n", d.gnss.size(),
              worst_deg, worst_h, worst_v);
}

/// One position sentence of a log, parsed here independently of gpsd.
struct LogFix {
  int time_of_day_s = 0;  ///< hhmmss as seconds of the day (the logs have whole seconds)
  double lat_deg = 0, lon_deg = 0;
  bool valid = false;                  ///< RMC/GLL status A, GGA quality > 0
  std::optional<double> msl_m, sep_m;  ///< GGA altitude and geoid separation when given
  /// RMC: a course, or a speed below the gateway's 1 m/s "standing" bound without one.
  bool has_velocity = false;
};

double nmea_angle(const std::string& v, const std::string& hemi) {
  const double raw = std::stod(v);
  const double deg = std::floor(raw / 100.0);
  const double value = deg + (raw - deg * 100.0) / 60.0;
  return hemi == "S" || hemi == "W" ? -value : value;
}

std::vector<std::string> fields_of(const std::string& sentence) {
  std::vector<std::string> f;
  std::string body = sentence.substr(1, sentence.find('*') - 1);
  std::stringstream ss(body);
  std::string x;
  while (std::getline(ss, x, ',')) f.push_back(x);
  if (!body.empty() && body.back() == ',') f.push_back("");
  return f;
}

/// The GGA, RMC and GLL sentences of a log, in order.
std::vector<LogFix> log_fixes(const fs::path& log) {
  std::vector<LogFix> out;
  std::ifstream in(log);
  std::string line;
  while (std::getline(in, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.size() < 7 || line[0] != '$') continue;
    const std::string type = line.substr(3, 3);
    if (type != "GGA" && type != "RMC" && type != "GLL") continue;
    const auto f = fields_of(line);
    LogFix x;
    auto tod = [](const std::string& t) {
      return std::stoi(t.substr(0, 2)) * 3600 + std::stoi(t.substr(2, 2)) * 60 + std::stoi(t.substr(4, 2));
    };
    if (type == "GGA") {
      if (f[2].empty()) continue;
      x = {tod(f[1]), nmea_angle(f[2], f[3]), nmea_angle(f[4], f[5]), std::stoi(f[6]) > 0, {}, {}};
      if (!f[9].empty()) x.msl_m = std::stod(f[9]);
      if (!f[11].empty()) x.sep_m = std::stod(f[11]);
    } else if (type == "RMC") {
      if (f[3].empty()) continue;
      x = {tod(f[1]), nmea_angle(f[3], f[4]), nmea_angle(f[5], f[6]), f[2] == "A", {}, {}};
      x.has_velocity = !f[8].empty() || (!f[7].empty() && std::stod(f[7]) * 1852.0 / 3600.0 < 1.0);
    } else {
      if (f[1].empty()) continue;
      x = {tod(f[5]), nmea_angle(f[1], f[2]), nmea_angle(f[3], f[4]), f[6] == "A", {}, {}};
    }
    out.push_back(x);
  }
  return out;
}

struct LogExpectation {
  std::size_t epochs_in_order = 0;   ///< distinct epochs that move time forward
  std::size_t epochs_backwards = 0;  ///< epochs earlier than one already seen (the glitch)
};
LogExpectation expectation_of(const std::vector<LogFix>& fixes) {
  LogExpectation e;
  std::optional<int> last, max;
  for (const LogFix& f : fixes) {
    if (last && f.time_of_day_s == *last) continue;  // another sentence of the same epoch
    last = f.time_of_day_s;
    if (max && f.time_of_day_s < *max) {
      ++e.epochs_backwards;
      continue;
    }
    ++e.epochs_in_order;
    max = f.time_of_day_s;
  }
  return e;
}

/// Replays one real log; checks every published fix against the log's sentences of its epoch.
void check_real_log(int domain, const std::string& name, std::size_t expected_backwards, std::size_t expected_valid) {
  const fs::path log = fs::path(ODONAV_SOURCE_DIR) / "tests" / "data" / "nmea" / name;
  ASSERT_TRUE(fs::exists(log)) << log;
  const std::vector<LogFix> sentences = log_fixes(log);
  const LogExpectation expect = expectation_of(sentences);
  ASSERT_EQ(expect.epochs_backwards, expected_backwards) << "the log itself (independent parse)";
  const fs::path dir = fresh_live_dir("gpsd-" + name);
  write_gpsfake_input(log, dir / "gpsfake-input.nmea");
  const GpsdRun run = run_gpsd_gateway(domain, dir / "gpsfake-input.nmea", {});
  ASSERT_TRUE(run.last_health);

  // gpsd needs a few sentences to learn the receiver's cycle, so its first epochs may be merged;
  // after that every epoch is one fix.
  std::size_t published_valid = 0, with_position = 0;
  double last_t = -1e300;
  std::size_t cursor = 0;
  for (const msg::GnssFix& m : run.fixes) {
    const double t = stamp_s(m);
    EXPECT_GT(t, last_t) << "published time must increase";
    last_t = t;
    if (!std::isfinite(m.latitude_deg())) {
      EXPECT_FALSE(m.valid());
      continue;
    }
    ++with_position;
    // gpsd's UTC (its date may differ: GPS week roll-over handling) -> seconds of the day. The
    // epoch is the next run of sentences with that time in the log (the glitch repeats times);
    // gpsd keeps the latest sentence of the run.
    const int tod = static_cast<int>(std::llround(std::fmod(t, 86400.0)));
    while (cursor < sentences.size() && sentences[cursor].time_of_day_s != tod) ++cursor;
    ASSERT_LT(cursor, sentences.size()) << "a fix at " << tod << " s of the day that the log does not hold next";
    const std::size_t run_begin = cursor;
    while (cursor + 1 < sentences.size() && sentences[cursor + 1].time_of_day_s == tod) ++cursor;
    const LogFix* match = &sentences[cursor];
    // A reference needs a 3D position and a velocity in the same epoch: a GGA with an altitude and
    // an RMC with a course (or standing). gpsd does not carry either over to the next epoch.
    bool has_height = false, has_velocity = false, all_valid = true;
    for (std::size_t k = run_begin; k <= cursor; ++k) {
      has_height = has_height || sentences[k].msl_m.has_value();
      has_velocity = has_velocity || sentences[k].has_velocity;
      all_valid = all_valid && sentences[k].valid;
    }
    EXPECT_EQ(m.valid(), has_height && has_velocity && all_valid) << tod;
    EXPECT_NEAR(m.latitude_deg(), match->lat_deg, 1e-8) << tod;
    EXPECT_NEAR(m.longitude_deg(), match->lon_deg, 1e-8) << tod;
    if (m.valid()) {
      ++published_valid;
      EXPECT_TRUE(match->valid) << tod;
      // A valid fix is 3D: at a GGA epoch with a separation, its height is the GGA's altitude +
      // separation; otherwise gpsd keeps the last altitude and, without a separation in the log,
      // adds its own geoid model: checked to 50 m of the log's GGA altitudes.
      const LogFix* gga = nullptr;
      double nearest_msl_m = 1e300;
      for (const LogFix& f : sentences) {
        if (f.msl_m && f.time_of_day_s == tod) gga = &f;
        if (f.msl_m && std::abs(*f.msl_m - m.height_m()) < std::abs(nearest_msl_m - m.height_m()))
          nearest_msl_m = *f.msl_m;
      }
      if (gga && gga->sep_m)
        EXPECT_NEAR(m.height_m(), *gga->msl_m + *gga->sep_m, 1e-3) << tod;
      else
        EXPECT_NEAR(m.height_m(), nearest_msl_m, 50.0) << tod;
    }
  }
  const double backwards = counter(*run.last_health, "gnss_time_backwards");
  EXPECT_EQ(backwards, static_cast<double>(expected_backwards)) << "backward fixes dropped and counted";
  EXPECT_EQ(counter(*run.last_health, "gnss_published"), static_cast<double>(run.fixes.size()));
  EXPECT_LE(run.fixes.size(), expect.epochs_in_order);
  EXPECT_GE(run.fixes.size() + 4, expect.epochs_in_order) << "at most 4 epochs merged while gpsd learns the cycle";
  EXPECT_EQ(published_valid, expected_valid) << "complete epochs of the log";
  std::printf(
      "%s: %zu epochs in order, %zu backwards in the log; published %zu fixes (%zu with a position, %zu "
      "valid), %.0f backward fixes dropped\n",
      name.c_str(), expect.epochs_in_order, expect.epochs_backwards, run.fixes.size(), with_position, published_valid,
      backwards);
}

TEST(GpsdGateway, HumminbirdLogWithTimeGoingBackward) { check_real_log(121, "humminbird-M37.log", 9, 0); }

TEST(GpsdGateway, UbloxNeoM8nLog) { check_real_log(121, "neo-m8n.log", 0, 22); }

}  // namespace
}  // namespace odonav::test
