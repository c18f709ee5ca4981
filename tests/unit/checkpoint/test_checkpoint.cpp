// The identification checkpoint: a restored estimator continues bit-identically, and every kind of
// unusable file (truncated, garbage, bit flip, other vehicle, other configuration) is moved aside
// with a reason naming what is wrong, leaving the estimator at its fresh state.
#include <gtest/gtest.h>
#include <unistd.h>

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
#include "odonav/identification/identification_options.hpp"

namespace {

using namespace odonav;
namespace fs = std::filesystem;

constexpr double kTrueK = 0.0125;  // m/pulse
constexpr const char* kVehicle = "vehicle-07";

/// Regression samples of a 10 Hz GNSS at 8-12 m/s: phi pulses counted, y = K phi + GNSS noise.
std::vector<ScaleFactorSample> samples(std::size_t n, uint32_t seed, double t0_s) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> speed(8.0, 12.0);
  std::normal_distribution<double> noise(0.0, 0.01);
  std::vector<ScaleFactorSample> out;
  for (std::size_t i = 0; i < n; ++i) {
    ScaleFactorSample s;
    s.dt_s = 0.1;
    s.t_s = t0_s + 0.1 * static_cast<double>(i + 1);
    s.phi_pulses = std::round(speed(rng) * s.dt_s / kTrueK);
    s.y_m = kTrueK * s.phi_pulses + noise(rng);
    out.push_back(s);
  }
  return out;
}

std::string read_text(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

void write_text(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out << text;
}

class Checkpoint : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("odonav-checkpoint-" + std::to_string(::getpid()) + "-" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    path_ = checkpoint_path(dir_.string(), kVehicle);
  }
  void TearDown() override { fs::remove_all(dir_); }

  /// A valid checkpoint of a vff_lm_rls estimator fed 300 samples.
  IdentificationCheckpoint valid_checkpoint(const ScaleFactorEstimator& e) const {
    IdentificationCheckpoint c;
    c.vehicle_id = kVehicle;
    c.config_hash = "0123456789abcdef";
    c.estimator_name = e.name();
    c.last_sample_t_s = 30.1;
    c.samples_accepted = 300;
    c.samples_rejected = 17;
    c.estimator_state = e.save_state();
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
  /// containing `why`, and the estimator untouched (no estimate).
  void expect_moved_aside(const std::string& text, const std::string& vehicle, const std::string& hash,
                          const std::string& why) {
    write_text(path_, text);
    auto fresh = make_scale_factor_estimator("vff_lm_rls", {});
    const CheckpointLoadResult r = load_identification_checkpoint(path_, vehicle, hash, *fresh, 1700000000);
    EXPECT_EQ(r.status, CheckpointLoadStatus::kMovedAside);
    EXPECT_NE(r.reason.find(why), std::string::npos) << "reason: " << r.reason;
    EXPECT_FALSE(r.checkpoint.has_value());
    EXPECT_FALSE(fs::exists(path_)) << "the bad file must not stay under the checkpoint name";
    EXPECT_EQ(r.moved_to, path_ + ".bad-1700000000");
    EXPECT_EQ(read_text(r.moved_to), text) << "moved aside, not altered";
    EXPECT_FALSE(fresh->estimate().valid) << "a refused checkpoint must leave the estimator at nominal";
    EXPECT_EQ(fresh->estimate().samples_used, 0u);
    const std::string line = describe(r, *fresh);
    EXPECT_NE(line.find("was corrupt"), std::string::npos) << line;
    EXPECT_NE(line.find("moved aside"), std::string::npos) << line;
    EXPECT_NE(line.find("starting from nominal K"), std::string::npos) << line;
  }

  fs::path dir_;
  std::string path_;
};

TEST_F(Checkpoint, PathIsPerVehicleAndRejectsUnsafeIds) {
  EXPECT_EQ(checkpoint_path("/var/lib/odonav", "vehicle-01"), "/var/lib/odonav/identification-vehicle-01.ckpt");
  EXPECT_THROW(checkpoint_path("/tmp", ""), std::invalid_argument);
  EXPECT_THROW(checkpoint_path("/tmp", "../etc/passwd"), std::invalid_argument);
  EXPECT_THROW(checkpoint_path("/tmp", "a b"), std::invalid_argument);
}

TEST_F(Checkpoint, RestoredEstimatorContinuesBitIdentically) {
  // Reference: one estimator fed 800 samples. Restarted: 300 samples, checkpoint written to disk,
  // a new estimator restored from the file, the remaining 500 samples. Every estimate after the
  // restart must equal the reference bit for bit (the window, its weights and sums are restored,
  // not re-estimated).
  const auto all = samples(800, 42, 0.0);
  auto reference = make_scale_factor_estimator("vff_lm_rls", {});
  auto before = make_scale_factor_estimator("vff_lm_rls", {});
  for (std::size_t i = 0; i < 300; ++i) {
    reference->update(all[i]);
    before->update(all[i]);
  }
  const IdentificationCheckpoint written = valid_checkpoint(*before);
  write_file_atomically(path_, serialize_checkpoint(written));
  EXPECT_TRUE(moved_aside().empty());
  EXPECT_EQ(std::distance(fs::directory_iterator(dir_), fs::directory_iterator()), 1)
      << "no temporary file left behind";

  auto restarted = make_scale_factor_estimator("vff_lm_rls", {});
  const CheckpointLoadResult r =
      load_identification_checkpoint(path_, kVehicle, written.config_hash, *restarted, 1700000000);
  ASSERT_EQ(r.status, CheckpointLoadStatus::kRestored) << r.reason;
  ASSERT_TRUE(r.checkpoint.has_value());
  EXPECT_EQ(r.checkpoint->last_sample_t_s, 30.1);
  EXPECT_EQ(r.checkpoint->samples_accepted, 300u);
  EXPECT_EQ(r.checkpoint->samples_rejected, 17u);
  EXPECT_TRUE(fs::exists(path_)) << "a good checkpoint stays where it is";
  EXPECT_EQ(restarted->estimate().k_m_per_pulse, reference->estimate().k_m_per_pulse);
  EXPECT_NE(describe(r, *restarted).find("restored K="), std::string::npos) << describe(r, *restarted);
  EXPECT_NE(describe(r, *restarted).find("(t=30.100 s)"), std::string::npos) << describe(r, *restarted);

  for (std::size_t i = 300; i < all.size(); ++i) {
    reference->update(all[i]);
    restarted->update(all[i]);
    const ScaleFactorEstimate a = reference->estimate(), b = restarted->estimate();
    ASSERT_EQ(a.k_m_per_pulse, b.k_m_per_pulse) << "sample " << i;
    ASSERT_EQ(a.sigma_m_per_pulse, b.sigma_m_per_pulse) << "sample " << i;
    ASSERT_EQ(a.forgetting_factor, b.forgetting_factor) << "sample " << i;
  }
  // And the estimate is a real one: within 4 of its own sigmas (a window of ~1 m samples with 1 cm
  // noise: sigma ~0.1 %) of the K that made the samples.
  const ScaleFactorEstimate last = restarted->estimate();
  ASSERT_GT(last.sigma_m_per_pulse, 0.0);
  EXPECT_LT(last.sigma_m_per_pulse / kTrueK, 3e-3);
  EXPECT_NEAR(last.k_m_per_pulse, kTrueK, 4.0 * last.sigma_m_per_pulse);
}

TEST_F(Checkpoint, OverwriteKeepsOneFileWithTheNewestState) {
  auto e = make_scale_factor_estimator("vff_lm_rls", {});
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
  auto e = make_scale_factor_estimator("vff_lm_rls", {});
  IdentificationCheckpoint c = valid_checkpoint(*e);
  c.last_sample_t_s = 1700000123.456789012345;  // a Unix-epoch stamp: needs all 17 digits
  EXPECT_EQ(parse_checkpoint(serialize_checkpoint(c)).last_sample_t_s, c.last_sample_t_s);
}

TEST_F(Checkpoint, MissingFileIsAFreshStart) {
  auto e = make_scale_factor_estimator("vff_lm_rls", {});
  const CheckpointLoadResult r = load_identification_checkpoint(path_, kVehicle, "0123456789abcdef", *e, 1);
  EXPECT_EQ(r.status, CheckpointLoadStatus::kNone);
  EXPECT_TRUE(moved_aside().empty());
  EXPECT_FALSE(e->estimate().valid);
}

TEST_F(Checkpoint, TruncatedFileIsMovedAside) {
  auto e = make_scale_factor_estimator("vff_lm_rls", {});
  for (const auto& s : samples(300, 1, 0.0)) e->update(s);
  const std::string text = serialize_checkpoint(valid_checkpoint(*e));
  // Cut inside the estimator state (the write of a non-atomic writer killed half way).
  expect_moved_aside(text.substr(0, text.size() / 2), kVehicle, "0123456789abcdef", "truncated");
}

TEST_F(Checkpoint, TruncatedChecksumLineIsMovedAside) {
  auto e = make_scale_factor_estimator("vff_lm_rls", {});
  const std::string text = serialize_checkpoint(valid_checkpoint(*e));
  expect_moved_aside(text.substr(0, text.size() - 5), kVehicle, "0123456789abcdef", "truncated");
}

TEST_F(Checkpoint, GarbageIsMovedAside) {
  std::mt19937 rng(7);
  std::string garbage(4096, '\0');
  for (char& c : garbage) c = static_cast<char>(rng() & 0xff);
  expect_moved_aside(garbage, kVehicle, "0123456789abcdef", "truncated: no checksum line");
}

TEST_F(Checkpoint, FlippedByteIsACorruptChecksum) {
  auto e = make_scale_factor_estimator("vff_lm_rls", {});
  for (const auto& s : samples(50, 3, 0.0)) e->update(s);
  std::string text = serialize_checkpoint(valid_checkpoint(*e));
  text[text.find("samples_accepted 300") + 17] = '9';  // 300 -> 900: still well-formed
  expect_moved_aside(text, kVehicle, "0123456789abcdef", "checksum mismatch");
}

TEST_F(Checkpoint, OtherVehicleIsMovedAside) {
  auto e = make_scale_factor_estimator("vff_lm_rls", {});
  for (const auto& s : samples(50, 3, 0.0)) e->update(s);
  expect_moved_aside(serialize_checkpoint(valid_checkpoint(*e)), "vehicle-08", "0123456789abcdef",
                     "made for vehicle 'vehicle-07', this is 'vehicle-08'");
}

TEST_F(Checkpoint, OtherConfigurationIsMovedAside) {
  auto e = make_scale_factor_estimator("vff_lm_rls", {});
  for (const auto& s : samples(50, 3, 0.0)) e->update(s);
  expect_moved_aside(serialize_checkpoint(valid_checkpoint(*e)), kVehicle, "fedcba9876543210",
                     "made with another configuration (hash 0123456789abcdef, now fedcba9876543210)");
}

TEST_F(Checkpoint, OtherEstimatorIsMovedAside) {
  auto rls = make_scale_factor_estimator("rls", {});
  for (const auto& s : samples(50, 3, 0.0)) rls->update(s);
  expect_moved_aside(serialize_checkpoint(valid_checkpoint(*rls)), kVehicle, "0123456789abcdef",
                     "made by estimator 'rls', this is 'vff_lm_rls'");
}

TEST_F(Checkpoint, SecondBadFileDoesNotOverwriteTheFirst) {
  write_text(path_, "garbage one");
  auto e = make_scale_factor_estimator("vff_lm_rls", {});
  const auto r1 = load_identification_checkpoint(path_, kVehicle, "h", *e, 5);
  write_text(path_, "garbage two");
  const auto r2 = load_identification_checkpoint(path_, kVehicle, "h", *e, 5);
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
  EXPECT_NE(hash({"--min-speed", "2.5"}), base);
}

}  // namespace

TEST(CheckpointValueList, KeepsEveryDoubleExactlyAndNamesABadCount) {
  const std::vector<double> v{0.1, -0.0, std::nan(""), -std::numeric_limits<double>::infinity(), 5e-324, 1e308};
  const std::string text = odonav::checkpoint_value_list("k", v) + odonav::checkpoint_value_list("empty", {});
  odonav::CheckpointReader r(text);
  const std::vector<double> back = r.value_list("k", 2);
  ASSERT_EQ(back.size(), v.size());
  for (std::size_t i = 0; i < v.size(); ++i)
    EXPECT_TRUE(std::memcmp(&back[i], &v[i], sizeof(double)) == 0 || (std::isnan(back[i]) && std::isnan(v[i]))) << i;
  EXPECT_TRUE(r.value_list("empty").empty());
  EXPECT_TRUE(r.at_end());
  odonav::CheckpointReader odd(text);
  try {
    odd.value_list("k", 4);  // 6 values are not records of 4
    FAIL() << "accepted";
  } catch (const odonav::CheckpointError& e) {
    EXPECT_EQ(std::string(e.what()), "field 'k' has a bad value count '6'");
  }
  const std::string short_text = "k 3 0x1p+0 0x1p+1\n";
  odonav::CheckpointReader short_list(short_text);
  EXPECT_THROW(short_list.value_list("k"), odonav::CheckpointError);
}
