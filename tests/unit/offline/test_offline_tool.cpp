// odonav-offline as a user runs it: the files and columns it writes, the summary, bad input, and the
// output files reading back exactly.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "odonav/simulator/simulator.hpp"
#include "odonav/dataset.hpp"
#include "odonav/offline/offline_runner.hpp"
#include "child_process.hpp"
#include "odonav/results/output_files.hpp"
#include "scratch_dir.hpp"

namespace fs = std::filesystem;
using namespace odonav;

namespace {

/// odonav-offline with `args`: its exit status and its output (stdout and stderr).
test::CommandResult run(const std::string& args) {
  return test::run_command(test::binary("odonav-offline") + " " + args);
}

std::string header_of(const fs::path& file) {
  std::ifstream in(file);
  std::string line;
  std::getline(in, line);
  return line;
}

class OfflineTool : public ::testing::Test {
 protected:
  void SetUp() override {
    simulator::SimulationConfig cfg = simulator::scenario_config("straight");
    cfg.seed = 5;
    write_dataset((dir_ / "straight").string(), simulator::simulate(cfg));
  }
  test::ScratchDir scratch_;
  fs::path dir_ = scratch_.path();
};

}  // namespace

TEST_F(OfflineTool, WritesEveryFileWithItsColumnsAndASummary) {
  const test::CommandResult r = run((dir_ / "straight").string() + " --out " + (dir_ / "out").string());
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("odonav summary"), std::string::npos) << r.output;
  EXPECT_EQ(header_of(dir_ / "out/misalignment.csv")
                .rfind("t,heading_deg,pitch_deg,heading_std_deg,pitch_std_deg,converged", 0),
            0u);
  EXPECT_EQ(header_of(dir_ / "out/scale_factor.csv")
                .rfind("t,k_rls,k_ff_rls,k_lm_rls,k_vff_lm_rls,k_coarse,k_kf_rw,lambda_vff_lm_rls", 0),
            0u);
  for (const char* f : {"dead_reckoning.csv", "dead_reckoning_coarse.csv"})
    EXPECT_EQ(header_of(dir_ / "out" / f).rfind("t,lat_deg,lon_deg,height_m,distance_m,k_m_per_pulse", 0), 0u) << f;
  EXPECT_EQ(header_of(dir_ / "out/navigation_position.csv"),
            "t,lat_deg,lon_deg,height_m,east_m,north_m,up_m,var_east_m2,var_north_m2,var_up_m2,status,last_fix_t,"
            "distance_since_fix_m");
  ASSERT_TRUE(fs::exists(dir_ / "out/summary.json"));
  // One scale-factor and one misalignment row per GNSS epoch; one DR row per odometer sample after
  // the DR start.
  const Dataset d = read_dataset((dir_ / "straight").string(), BadRowPolicy::kFail);
  const results::OutputRows rows = results::read_output_rows((dir_ / "out").string());
  EXPECT_EQ(rows.scale_factor.size(), d.gnss.size());
  EXPECT_EQ(rows.misalignment.size(), d.gnss.size());
  EXPECT_GT(rows.dead_reckoning.size(), d.odometer.size() - 20);
  EXPECT_EQ(rows.dead_reckoning.size(), rows.dead_reckoning_coarse.size());
}

TEST_F(OfflineTool, OutputFilesReadBackExactly) {
  const Dataset d = read_dataset((dir_ / "straight").string(), BadRowPolicy::kFail);
  offline::OfflineParams p;
  p.dead_reckoning.nominal_k_m_per_pulse = 0.0125;
  const results::OutputRows rows = offline::to_output_rows(offline::run_offline(d, p), "vff_lm_rls");
  fs::create_directories(dir_ / "rows");
  results::write_output_rows((dir_ / "rows").string(), rows);
  const results::OutputRows back = results::read_output_rows((dir_ / "rows").string());
  ASSERT_EQ(back.scale_factor.size(), rows.scale_factor.size());
  for (std::size_t i = 0; i < rows.scale_factor.size(); ++i) {
    EXPECT_EQ(back.scale_factor[i].t_s, rows.scale_factor[i].t_s);
    EXPECT_EQ(back.scale_factor[i].k_m_per_pulse, rows.scale_factor[i].k_m_per_pulse);
    EXPECT_EQ(back.scale_factor[i].samples_accepted, rows.scale_factor[i].samples_accepted);
  }
  ASSERT_EQ(back.dead_reckoning.size(), rows.dead_reckoning.size());
  for (std::size_t i = 0; i < rows.dead_reckoning.size(); i += 97) {
    EXPECT_EQ(back.dead_reckoning[i].distance_m, rows.dead_reckoning[i].distance_m);
    // Degrees in the file: one rounding each way, well below a nanometre.
    EXPECT_NEAR(back.dead_reckoning[i].lat_rad, rows.dead_reckoning[i].lat_rad, 1e-15);
  }
}

TEST_F(OfflineTool, BadRowFailsNamingFileLineAndColumnOrIsSkippedAndCounted) {
  // Corrupt one odometer row: a NaN pulse count on line 101.
  const fs::path odo = dir_ / "straight/odometer.csv";
  std::ifstream in(odo);
  std::stringstream text;
  std::string line;
  for (int n = 1; std::getline(in, line); ++n)
    text << (n == 101 ? line.substr(0, line.find(',')) + ",nan,1" : line) << "\n";
  in.close();
  std::ofstream(odo) << text.str();

  const test::CommandResult fail = run((dir_ / "straight").string() + " --out " + (dir_ / "out").string());
  EXPECT_EQ(fail.status, 1);
  EXPECT_NE(fail.output.find("odometer.csv:101: column 'pulses'"), std::string::npos) << fail.output;
  EXPECT_FALSE(fs::exists(dir_ / "out/scale_factor.csv")) << "nothing written on a failed run";

  const test::CommandResult skip =
      run((dir_ / "straight").string() + " --out " + (dir_ / "out").string() + " --on-bad-row=skip");
  EXPECT_EQ(skip.status, 0) << skip.output;
  EXPECT_NE(skip.output.find("skipped 1 bad rows"), std::string::npos) << skip.output;
}

TEST_F(OfflineTool, BadOptionsExitWithUsageError) {
  EXPECT_EQ(run((dir_ / "straight").string()).status, 2);  // no --out
  const test::CommandResult r = run((dir_ / "straight").string() + " --out x --window=0");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.output.find("--window"), std::string::npos) << r.output;
  EXPECT_EQ(run("/nonexistent-dataset --out " + (dir_ / "o").string()).status, 1);
  EXPECT_EQ(run("--help").status, 0);
}
