#pragma once
// The fixture of the checkpoint and restart tests of the checkpointing components (calibration,
// identification, dead reckoning): a state directory per test on real files, the vehicle, the
// configuration hash and the wall clock they start with, and the checks every component's restart
// policy must pass the same way (a corrupt or foreign checkpoint moved aside and named; the
// downtime's outputs caught up).
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdint>
#include <filesystem>
#include <string>

#include "odonav/restart_policy.hpp"
#include "text_files.hpp"

namespace odonav::test {

inline constexpr const char* kVehicle = "vehicle-07";
inline constexpr const char* kHash = "0123456789abcdef";  // the configuration hash
inline constexpr int64_t kUnixTime_s = 1700000000;        // the wall clock at every start
inline constexpr double kHistory_s = 30.0;                // the producers' history handed to a restarted reader

/// A state directory under the system temp dir, named after the running test and this process:
/// absent at the start (the component creates it) and removed at the end; `checkpoint_file` is the
/// component's checkpoint in it ("calibration-vehicle-07.ckpt").
class StateDirTest : public ::testing::Test {
 protected:
  explicit StateDirTest(const std::string& checkpoint_file) : checkpoint_file_(checkpoint_file) {}
  void SetUp() override {
    const ::testing::TestInfo* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = std::filesystem::temp_directory_path() /
           ("odonav-" + std::string(info->test_suite_name()) + "-" + info->name() + "-" + std::to_string(::getpid()));
    std::filesystem::remove_all(dir_);
    ckpt_ = dir_ / checkpoint_file_;
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  /// Checkpoints every `every_s` of event time into the state directory, made with configuration `hash`.
  CheckpointSettings settings(double every_s = 5.0, const std::string& hash = kHash) const {
    return CheckpointSettings{dir_.string(), every_s, hash};
  }

  /// A state directory holding nothing but a checkpoint file with `text`.
  void write_checkpoint(const std::string& text) const {
    std::filesystem::remove_all(dir_);
    std::filesystem::create_directories(dir_);
    write_text(ckpt_, text);
  }

  /// Where a start at kUnixTime_s moves an unusable checkpoint.
  std::filesystem::path aside() const { return ckpt_.string() + ".bad-" + std::to_string(kUnixTime_s); }

  /// A start (steady clock 10 s) on the unusable checkpoint `text`: moved aside byte for byte, never
  /// deleted, and the health WARNs "checkpoint <file> was corrupt: moved aside; <fresh_start>" for its
  /// 30 s.
  void expect_moved_aside(const RestartPolicy& p, const std::string& text, const std::string& fresh_start) const {
    EXPECT_TRUE(p.checkpoint_moved_aside());
    ASSERT_TRUE(std::filesystem::exists(aside())) << "moved aside, never deleted";
    EXPECT_EQ(read_text(aside()), text);
    std::string reason;
    bool warn = false;
    apply_restart_notes(p.health_notes(), 39.9, reason, warn);
    EXPECT_TRUE(warn);
    EXPECT_EQ(reason, "checkpoint " + ckpt_.string() + " was corrupt: moved aside; " + fresh_start);
  }

  std::filesystem::path dir_, ckpt_;

 private:
  std::string checkpoint_file_;
};

/// A restart whose history reached back to the checkpoint, after it went live: the downtime's
/// outputs were published as catch-up from the first after the checkpoint (first_t_s), nothing was
/// lost, the samples the checkpoint held were skipped.
inline void expect_caught_up(const RestartPolicy& p, double first_t_s) {
  EXPECT_GT(p.catch_up_outputs(), 0u);
  EXPECT_EQ(*p.catch_up_first_t_s(), first_t_s);
  EXPECT_EQ(p.catch_up_lost_s(), 0.0);
  EXPECT_GT(p.skipped_before_checkpoint(), 0u);
  EXPECT_FALSE(p.catching_up());
  EXPECT_NE(p.health_notes().catch_up_note.find("caught up after restart: "), std::string::npos);
}

}  // namespace odonav::test
