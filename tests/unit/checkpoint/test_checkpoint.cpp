// The identification checkpoint: a restored identification core (sample builder with its GNSS
// latency estimate, estimator, counters) continues bit-identically, and every kind of unusable file
// (truncated, garbage, bit flip, an older version, other vehicle, other configuration, other
// estimator) is moved aside with a reason naming what is wrong, leaving the core at its fresh state.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <fstream>
#include <random>
#include <sstream>

#include "odonav/config.hpp"
#include "odonav/estimators.hpp"
#include "odonav/identification/checkpoint.hpp"
#include "odonav/consumer_rules.hpp"
#include "odonav/identification/identification_lifecycle.hpp"
#include "odonav/identification/identification_options.hpp"
#include "scratch_dir.hpp"
#include "fed_core.hpp"

namespace {

using namespace odonav;
using namespace odonav::identification;
using odonav::test::read_text;
using odonav::test::write_text;
using odonav::test::fed_core;
namespace fs = std::filesystem;

constexpr double kTrueK = 0.0125;  // m/pulse
constexpr const char* kVehicle = "vehicle-07";

IdentificationParams params_with(const std::string& estimator) {
  IdentificationParams p;
  p.estimator_name = estimator;
  return p;
}

class Checkpoint : public ::testing::Test {
 protected:
  void SetUp() override { path_ = checkpoint_path(dir_.string(), kVehicle); }

  /// A valid checkpoint of a core.
  IdentificationCheckpoint valid_checkpoint(const IdentificationCore& core) const {
    IdentificationCheckpoint c;
    c.vehicle_id = kVehicle;
    c.config_hash = "0123456789abcdef";
    c.estimator_name = core.main_estimator_name();
    c.last_sample_t_s = 30.1;
    c.samples_accepted = 300;
    c.samples_rejected = 17;
    c.fed_until_s = {30.3, 30.1, 30.25, std::nullopt};
    c.misalignments_applied = 0;
    c.core_state = core.save_state();
    return c;
  }

  /// Files in the state directory whose name starts with the checkpoint's name + ".bad-".
  std::vector<fs::path> moved_aside() const {
    std::vector<fs::path> out;
    const std::string prefix = fs::path(path_).filename().string() + ".bad-";
    for (const auto& entry : fs::directory_iterator(dir_))
      if (entry.path().filename().string().rfind(prefix, 0) == 0) out.push_back(entry.path());
    return out;
  }

  /// Loads the file written with `text`; expects it moved aside (content kept) with a reason
  /// containing `why`, and the core untouched (no estimate, nothing buffered).
  void expect_moved_aside(const std::string& text, const std::string& vehicle, const std::string& hash,
                          const std::string& why) {
    write_text(path_, text);
    IdentificationCore fresh(params_with("vff_lm_rls"));
    const StateJson fresh_state = fresh.save_state();
    const CheckpointLoadResult r = load_identification_checkpoint(path_, vehicle, hash, fresh, 1700000000);
    EXPECT_EQ(r.status, CheckpointLoadStatus::kMovedAside);
    EXPECT_NE(r.reason.find(why), std::string::npos) << "reason: " << r.reason;
    EXPECT_FALSE(r.checkpoint.has_value());
    EXPECT_FALSE(fs::exists(path_)) << "the bad file must not stay under the checkpoint name";
    EXPECT_EQ(r.moved_to, path_ + ".bad-1700000000");
    EXPECT_EQ(read_text(r.moved_to), text) << "moved aside, not altered";
    EXPECT_FALSE(fresh.main_estimator().estimate().valid) << "a refused checkpoint must leave the core at nominal";
    EXPECT_EQ(fresh.save_state(), fresh_state);
    const std::string line = describe(r, fresh.main_estimator());
    EXPECT_NE(line.find("was corrupt"), std::string::npos) << line;
    EXPECT_NE(line.find("moved aside"), std::string::npos) << line;
    EXPECT_NE(line.find("starting from nominal K"), std::string::npos) << line;
  }

  test::ScratchDir scratch_;
  fs::path dir_ = scratch_.path();
  std::string path_;
};

TEST_F(Checkpoint, PathIsPerVehicleAndRejectsUnsafeIds) {
  EXPECT_EQ(checkpoint_path("/var/lib/odonav", "vehicle-01"), "/var/lib/odonav/identification-vehicle-01.ckpt");
  EXPECT_THROW(checkpoint_path("/tmp", ""), std::invalid_argument);
  EXPECT_THROW(checkpoint_path("/tmp", "../etc/passwd"), std::invalid_argument);
  EXPECT_THROW(checkpoint_path("/tmp", "a b"), std::invalid_argument);
}

TEST_F(Checkpoint, RoundTripKeepsEveryField) {
  const auto core = fed_core(300);
  IdentificationCheckpoint c = valid_checkpoint(*core);
  c.misalignments_applied = 4;
  c.held_misalignment_t_s = 29.7;
  write_file_atomically(path_, serialize_checkpoint(c));
  EXPECT_EQ(std::distance(fs::directory_iterator(dir_), fs::directory_iterator()), 1)
      << "no temporary file left behind";
  const IdentificationCheckpoint back = parse_checkpoint(read_text(path_));
  EXPECT_EQ(back.estimator_name, "vff_lm_rls");
  EXPECT_EQ(back.last_sample_t_s, 30.1);
  EXPECT_EQ(back.samples_accepted, 300u);
  EXPECT_EQ(back.samples_rejected, 17u);
  EXPECT_EQ(back.fed_until_s, c.fed_until_s);
  EXPECT_EQ(back.misalignments_applied, 4u);
  EXPECT_EQ(back.held_misalignment_t_s, std::optional<double>(29.7));
  EXPECT_EQ(back.core_state, core->save_state());

  IdentificationCore restarted(params_with("vff_lm_rls"));
  const CheckpointLoadResult r = load_identification_checkpoint(path_, kVehicle, c.config_hash, restarted, 1700000000);
  ASSERT_EQ(r.status, CheckpointLoadStatus::kRestored) << r.reason;
  EXPECT_TRUE(fs::exists(path_)) << "a good checkpoint stays where it is";
  EXPECT_EQ(restarted.save_state(), core->save_state());
  EXPECT_EQ(restarted.main_estimator().estimate().k_m_per_pulse, core->main_estimator().estimate().k_m_per_pulse);
  EXPECT_NE(describe(r, restarted.main_estimator()).find("restored K="), std::string::npos);
  EXPECT_NE(describe(r, restarted.main_estimator()).find("(t=30.100 s)"), std::string::npos);
}

// ---- a killed identification resumes exactly ------------------------------------------------

namespace {
constexpr double kHoldOff_s = 0.2;       // the misalignment of epoch g applies from g + d
constexpr double kEstimateLag_s = 0.05;  // the calibration's output arrives this long after its epoch
constexpr double kLatency_s = 0.05;      // the receiver stamps its fixes this late

enum class Kind { kOdometer, kGnss, kIns, kMisalignment };
struct Event {
  double arrival_s;
  double t_s;
  Kind kind;
  std::size_t index;
};
struct Drive {
  synthetic::SyntheticData d;
  std::vector<std::pair<double, Misalignment>> misalignment;  // stamp = GNSS epoch
  std::vector<Event> events;                                  // in arrival order
};

/// 150 s of a speed that changes all the time (the signal the latency is read from) with a 0.05 s
/// receiver latency, 2 cm/s velocity noise, a GNSS outage t=100-103 s and the calibration's
/// converging misalignment at every epoch.
Drive drive() {
  synthetic::SensorConfig c;
  c.duration_s = 150.0;
  c.velocity_noise_mps = 0.02;
  c.gnss_latency_s = kLatency_s;
  c.misalignment = Misalignment{deg_to_rad(0.6), deg_to_rad(-0.4)};
  Drive r{synthetic::simulate(synthetic::wavy_drive(), c), {}, {}};
  auto& g = r.d.gnss;
  g.erase(std::remove_if(g.begin(), g.end(), [](const GnssSample& x) { return x.t_s > 100.0 && x.t_s < 103.0; }),
          g.end());
  for (const GnssSample& x : g) {
    const double f = std::exp(-x.t_s / 15.0);
    r.misalignment.emplace_back(
        x.t_s, Misalignment{c.misalignment.heading_rad * (1.0 - f), c.misalignment.pitch_rad * (1.0 - f)});
  }
  auto& e = r.events;
  for (std::size_t i = 0; i < r.d.odometer.size(); ++i)
    e.push_back({r.d.odometer[i].t_s, r.d.odometer[i].t_s, Kind::kOdometer, i});
  for (std::size_t i = 0; i < g.size(); ++i) e.push_back({g[i].t_s, g[i].t_s, Kind::kGnss, i});
  for (std::size_t i = 0; i < r.d.ins.size(); ++i) e.push_back({r.d.ins[i].t_s, r.d.ins[i].t_s, Kind::kIns, i});
  for (std::size_t i = 0; i < r.misalignment.size(); ++i)
    e.push_back({r.misalignment[i].first + kEstimateLag_s, r.misalignment[i].first, Kind::kMisalignment, i});
  std::stable_sort(e.begin(), e.end(), [](const Event& a, const Event& b) { return a.arrival_s < b.arrival_s; });
  return r;
}

/// The identification node's handling of its inputs, in one process: each sample through the
/// lifecycle's skip rule into the core, the core processed up to what every sensor stream has
/// reached, outputs through the lifecycle, a checkpoint when due.
struct NodeModel {
  IdentificationCore core{IdentificationParams{}};
  IdentificationLifecycle lifecycle;
  std::vector<IdentificationOutput> published;
  double odometer_s = -1e9, ins_s = -1e9, gnss_s = -1e9;

  NodeModel(const std::string& dir, const char* vehicle)
      : lifecycle(CheckpointSettings{dir, 5.0, "0123456789abcdef"}, vehicle) {
    lifecycle.start(core, 1700000000, 0.0);
    if (auto o = lifecycle.take_restored_output()) published.push_back(*o);
  }
  void feed(const Drive& r, const Event& e) {
    switch (e.kind) {
      case Kind::kOdometer:
        odometer_s = e.t_s;
        if (!lifecycle.skip_sample(IdentificationInput::kOdometer, e.t_s)) core.add_odometer(r.d.odometer[e.index]);
        break;
      case Kind::kGnss:
        gnss_s = e.t_s;
        if (!lifecycle.skip_sample(IdentificationInput::kGnss, e.t_s)) core.add_gnss(r.d.gnss[e.index]);
        break;
      case Kind::kIns:
        ins_s = e.t_s;
        if (!lifecycle.skip_sample(IdentificationInput::kIns, e.t_s)) core.add_ins(r.d.ins[e.index]);
        break;
      case Kind::kMisalignment:
        if (!lifecycle.skip_sample(IdentificationInput::kMisalignment, e.t_s)) {
          core.add_misalignment(estimate_applies_from_s(e.t_s, kHoldOff_s), r.misalignment[e.index].second);
          lifecycle.note_misalignment_applied(e.t_s);
        }
        break;
    }
    // Misalignments arrive 0.05 s after their epoch and apply 0.2 s after it: every one that
    // applies up to this watermark has arrived.
    const double watermark = std::min({odometer_s, ins_s, gnss_s});
    for (IdentificationOutput& o : lifecycle.outputs_to_publish(core.process_until(watermark)))
      published.push_back(std::move(o));
    lifecycle.checkpoint_if_due(core);
  }
};

bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

void expect_identical(const IdentificationOutput& a, const IdentificationOutput& b, const std::string& where) {
  EXPECT_TRUE(same_bits(a.t_s, b.t_s)) << where;
  EXPECT_EQ(a.epoch_status, b.epoch_status) << where;
  EXPECT_TRUE(same_bits(a.main.k_m_per_pulse, b.main.k_m_per_pulse))
      << where << ": K " << a.main.k_m_per_pulse << " vs " << b.main.k_m_per_pulse;
  EXPECT_TRUE(same_bits(a.main.sigma_m_per_pulse, b.main.sigma_m_per_pulse)) << where;
  EXPECT_EQ(a.main.converged, b.main.converged) << where;
  EXPECT_EQ(a.samples_accepted, b.samples_accepted) << where;
  EXPECT_EQ(a.samples_rejected, b.samples_rejected) << where;
  EXPECT_TRUE(same_bits(a.latency.applied_s, b.latency.applied_s))
      << where << ": latency " << a.latency.applied_s << " vs " << b.latency.applied_s;
  EXPECT_TRUE(same_bits(a.latency.estimate_s, b.latency.estimate_s)) << where;
  EXPECT_TRUE(same_bits(a.latency.sigma_s, b.latency.sigma_s)) << where;
  EXPECT_EQ(a.latency.samples, b.latency.samples) << where;
  EXPECT_EQ(a.latency.blocks_left_out, b.latency.blocks_left_out) << where;
}
}  // namespace

TEST_F(Checkpoint, AKilledIdentificationResumesExactlyWithItsLatencyEstimate) {
  const Drive r = drive();
  std::vector<IdentificationOutput> reference;
  {
    NodeModel uninterrupted("", kVehicle);
    for (const Event& e : r.events) uninterrupted.feed(r, e);
    for (IdentificationOutput& o : uninterrupted.lifecycle.outputs_to_publish(uninterrupted.core.finish()))
      uninterrupted.published.push_back(std::move(o));
    reference = uninterrupted.published;
  }
  ASSERT_GT(reference.size(), 1400u);
  // The drive is one on which a restart used to lose the latency: it is applied mid-drive.
  const auto applied = std::find_if(reference.begin(), reference.end(),
                                    [](const IdentificationOutput& o) { return o.latency.applied_s != 0.0; });
  ASSERT_NE(applied, reference.end()) << "the latency is never applied: the drive tests nothing";
  EXPECT_NEAR(reference.back().latency.applied_s, kLatency_s, 0.005);
  std::cerr << "latency applied from t=" << applied->t_s << " s\n";

  // Killed at: before the latency is applied, just after, in the GNSS outage, late.
  for (const double kill_s : {40.0, applied->t_s + 3.05, 101.5, 140.0}) {
    SCOPED_TRACE("killed at t=" + std::to_string(kill_s));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    std::vector<IdentificationOutput> published;
    {
      NodeModel first(dir_.string(), kVehicle);
      for (const Event& e : r.events)
        if (e.arrival_s <= kill_s) first.feed(r, e);
      published = first.published;  // everything after its last checkpoint is lost with the process
      ASSERT_GT(first.lifecycle.checkpoints_written(), 0u);
    }
    NodeModel second(dir_.string(), kVehicle);
    ASSERT_TRUE(second.lifecycle.restored_t_s());
    const double restored_s = *second.lifecycle.restored_t_s();
    EXPECT_GT(restored_s, kill_s - 10.0);  // every 5 s of processed epochs; none in the outage
    // The producers hand over their 30 s history, then the live data follows.
    for (const Event& e : r.events)
      if (e.t_s >= kill_s - 30.0) second.feed(r, e);
    for (IdentificationOutput& o : second.lifecycle.outputs_to_publish(second.core.finish()))
      second.published.push_back(std::move(o));
    EXPECT_EQ(second.lifecycle.catch_up_lost_s(), 0.0);
    // The restored output repeats the checkpoint's epoch; every later one is the reference's.
    ASSERT_FALSE(second.published.empty());
    EXPECT_EQ(second.published.front().t_s, restored_s);
    std::size_t compared = 0;
    for (std::size_t i = 1; i < second.published.size(); ++i) {
      const IdentificationOutput& b = second.published[i];
      const auto a = std::find_if(reference.begin(), reference.end(),
                                  [&](const IdentificationOutput& o) { return o.t_s == b.t_s; });
      ASSERT_NE(a, reference.end()) << "an output at t=" << b.t_s << " s the uninterrupted run does not have";
      expect_identical(*a, b, "t=" + std::to_string(b.t_s));
      ++compared;
    }
    // Nothing missing: the first run's outputs up to the checkpoint and the second's after it.
    std::size_t before = 0;
    for (const auto& o : published) before += o.t_s <= restored_s ? 1 : 0;
    EXPECT_EQ(before + compared, reference.size());
  }
}

TEST_F(Checkpoint, OverwriteKeepsOneFileWithTheNewestState) {
  auto e = fed_core(10);
  IdentificationCheckpoint c = valid_checkpoint(*e);
  write_file_atomically(path_, serialize_checkpoint(c));
  c.last_sample_t_s = 45.5;
  c.samples_accepted = 455;
  write_file_atomically(path_, serialize_checkpoint(c));
  const IdentificationCheckpoint back = parse_checkpoint(read_text(path_));
  EXPECT_EQ(back.last_sample_t_s, 45.5);
  EXPECT_EQ(back.samples_accepted, 455u);
  EXPECT_EQ(std::distance(fs::directory_iterator(dir_), fs::directory_iterator()), 1);
}

TEST_F(Checkpoint, TimeRoundTripsExactly) {
  auto e = fed_core(10);
  IdentificationCheckpoint c = valid_checkpoint(*e);
  c.last_sample_t_s = 1700000123.456789012345;  // a Unix-epoch stamp: needs all 17 digits
  EXPECT_EQ(parse_checkpoint(serialize_checkpoint(c)).last_sample_t_s, c.last_sample_t_s);
}

TEST_F(Checkpoint, MissingFileIsAFreshStart) {
  IdentificationCore e(params_with("vff_lm_rls"));
  const CheckpointLoadResult r = load_identification_checkpoint(path_, kVehicle, "0123456789abcdef", e, 1);
  EXPECT_EQ(r.status, CheckpointLoadStatus::kNone);
  EXPECT_TRUE(moved_aside().empty());
  EXPECT_FALSE(e.main_estimator().estimate().valid);
}

TEST_F(Checkpoint, TruncatedFileIsMovedAside) {
  auto e = fed_core(300);
  const std::string text = serialize_checkpoint(valid_checkpoint(*e));
  // Cut inside the estimator state (the write of a non-atomic writer killed half way).
  expect_moved_aside(text.substr(0, text.size() / 2), kVehicle, "0123456789abcdef", "truncated");
}

TEST_F(Checkpoint, TruncatedChecksumLineIsMovedAside) {
  auto e = fed_core(10);
  const std::string text = serialize_checkpoint(valid_checkpoint(*e));
  expect_moved_aside(text.substr(0, text.size() - 5), kVehicle, "0123456789abcdef", "truncated");
}

TEST_F(Checkpoint, GarbageIsMovedAside) {
  std::mt19937 rng(7);
  std::string garbage(4096, '\0');
  for (char& c : garbage) c = static_cast<char>(rng() & 0xff);
  expect_moved_aside(garbage, kVehicle, "0123456789abcdef", "not an odonav checkpoint");
}

TEST_F(Checkpoint, FlippedByteIsACorruptChecksum) {
  auto e = fed_core(50);
  std::string text = serialize_checkpoint(valid_checkpoint(*e));
  text[text.find("\"samples_accepted\":300") + 19] = '9';  // 300 -> 900: still well-formed
  expect_moved_aside(text, kVehicle, "0123456789abcdef", "checksum mismatch");
}

TEST_F(Checkpoint, OtherVehicleIsMovedAside) {
  auto e = fed_core(50);
  expect_moved_aside(serialize_checkpoint(valid_checkpoint(*e)), "vehicle-08", "0123456789abcdef",
                     "made for vehicle 'vehicle-07', this is 'vehicle-08'");
}

TEST_F(Checkpoint, OtherConfigurationIsMovedAside) {
  auto e = fed_core(50);
  expect_moved_aside(serialize_checkpoint(valid_checkpoint(*e)), kVehicle, "fedcba9876543210",
                     "made with another configuration (hash 0123456789abcdef, now fedcba9876543210)");
}

TEST_F(Checkpoint, OtherEstimatorIsMovedAside) {
  auto rls = fed_core(50, "rls");
  expect_moved_aside(serialize_checkpoint(valid_checkpoint(*rls)), kVehicle, "0123456789abcdef",
                     "made by estimator 'rls', this is 'vff_lm_rls'");
}

TEST_F(Checkpoint, AnOlderVersionIsMovedAsideWithItsVersionNamed) {
  // Version 1 held the estimator's state only: a restart from it lost the builder's state (the
  // GNSS latency in force among it), so it is not resumed from; version 2 was the text format,
  // version 3 had no residual correlation.
  auto e = fed_core(50);
  const StateJson payload = StateJson::parse(serialize_checkpoint(valid_checkpoint(*e))).at("payload");
  expect_moved_aside(seal_checkpoint(CheckpointIdentity{"identification", kIdentificationCheckpointVersion - 1,
                                                        kVehicle, "0123456789abcdef"},
                                     payload),
                     kVehicle, "0123456789abcdef",
                     "checkpoint version " + std::to_string(kIdentificationCheckpointVersion - 1) +
                         ", this build reads version " + std::to_string(kIdentificationCheckpointVersion));
}

TEST_F(Checkpoint, AnOlderTextCheckpointIsMovedAsideNamedAsSuch) {
  expect_moved_aside("odonav-identification-checkpoint 2\nvehicle vehicle-07\nconfig_hash 0123456789abcdef\n", kVehicle,
                     "0123456789abcdef", "an older text checkpoint ('odonav-identification-checkpoint 2')");
}

TEST_F(Checkpoint, AnotherComponentsCheckpointIsMovedAside) {
  auto e = fed_core(50);
  const StateJson payload = StateJson::parse(serialize_checkpoint(valid_checkpoint(*e))).at("payload");
  expect_moved_aside(seal_checkpoint(CheckpointIdentity{"dead-reckoning", kIdentificationCheckpointVersion, kVehicle,
                                                        "0123456789abcdef"},
                                     payload),
                     kVehicle, "0123456789abcdef", "made by odonav-dead-reckoning, this is odonav-identification");
}

TEST_F(Checkpoint, SecondBadFileDoesNotOverwriteTheFirst) {
  write_text(path_, "garbage one");
  IdentificationCore e(params_with("vff_lm_rls"));
  const auto r1 = load_identification_checkpoint(path_, kVehicle, "h", e, 5);
  write_text(path_, "garbage two");
  const auto r2 = load_identification_checkpoint(path_, kVehicle, "h", e, 5);
  EXPECT_EQ(r1.moved_to, path_ + ".bad-5");
  EXPECT_EQ(r2.moved_to, path_ + ".bad-5-2");
  EXPECT_EQ(read_text(r1.moved_to), "garbage one");
  EXPECT_EQ(read_text(r2.moved_to), "garbage two");
}

TEST_F(Checkpoint, ConfigHashIgnoresTransportAndLoggingButNotTheEstimator) {
  auto hash = [](const std::vector<std::string>& args) {
    Options o("t", "t");
    add_identification_options(o);
    o.add_int("domain", 0, "d", 0, 232);
    o.add_string("log-level", "", "l");
    o.add_string("state-dir", "", "s");
    std::ostringstream help;
    o.parse(args, help);
    return config_hash_of(o.values_as_text());
  };
  const std::string base = hash({});
  EXPECT_EQ(base.size(), 16u);
  EXPECT_EQ(hash({"--domain", "81", "--log-level", "debug", "--state-dir", "/tmp/x"}), base);
  EXPECT_NE(hash({"--window", "77"}), base);
  EXPECT_NE(hash({"--estimator", "rls"}), base);
  EXPECT_NE(hash({"--id-min-speed", "2.5"}), base);
}

}  // namespace

TEST(CheckpointStateValues, KeepsEveryDoubleExactlyAndNamesABadCount) {
  using odonav::StateJson;
  const std::vector<double> v{0.1, -0.0, std::nan(""), -std::numeric_limits<double>::infinity(), 5e-324, 1e308};
  const StateJson j = StateJson::parse(odonav::to_state(v).dump());
  std::vector<double> back;
  odonav::from_state(j, back, "k");
  ASSERT_EQ(back.size(), v.size());
  for (std::size_t i = 0; i < v.size(); ++i)
    EXPECT_TRUE(std::memcmp(&back[i], &v[i], sizeof(double)) == 0 || (std::isnan(back[i]) && std::isnan(v[i]))) << i;
  std::vector<double> empty{1.0};
  odonav::from_state(StateJson::array(), empty, "empty");
  EXPECT_TRUE(empty.empty());
  try {
    std::array<double, 4> four{};
    odonav::from_state(j, four, "k");  // 6 values are not 4
    FAIL() << "accepted";
  } catch (const odonav::CheckpointError& e) {
    EXPECT_EQ(std::string(e.what()), "field 'k' does not hold 4 values");
  }
  std::vector<double> not_numbers;
  EXPECT_THROW(odonav::from_state(StateJson::parse("[1.0, \"x\"]"), not_numbers, "k"), odonav::CheckpointError);
}
