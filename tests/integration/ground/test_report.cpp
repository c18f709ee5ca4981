// odonav-report on the output folder of odonav-offline over a short simulated drive (odonav-sim
// terrain, 120 s): the page exists, every figure file is non-empty and referenced by the page; a
// folder with a missing file fails naming it.
#include <gtest/gtest.h>

#include <regex>
#include <set>

#include "ground_test_support.hpp"

using namespace odonav::test;
namespace fs = std::filesystem;

TEST(Report, HtmlWithEveryFigureFromAnOfflineRun) {
  const fs::path dir = scratch_dir("report");
  const RunResult sim = run(binary("odonav-sim"), {"terrain", "--duration-s", "120", "--out", (dir / "data").string()}, dir, "sim");
  ASSERT_EQ(sim.exit_code, 0) << sim.err;
  const RunResult off = run(binary("odonav-offline"), {(dir / "data").string(), "--out", (dir / "out").string()}, dir, "offline");
  ASSERT_EQ(off.exit_code, 0) << off.err;

  const fs::path page = dir / "html" / "report.html";
  const RunResult rep = run(binary("odonav-report"),
                            {(dir / "out").string(), "--out", page.string(), "--dataset", (dir / "data").string()}, dir, "report");
  ASSERT_EQ(rep.exit_code, 0) << rep.err;
  const std::string html = read_text(page);
  ASSERT_FALSE(html.empty());
  // Every figure file is non-empty, a PNG, and referenced by the page; every reference exists.
  std::set<std::string> referenced;
  const std::regex img("<img src=\"([^\"]+)\"");
  for (auto it = std::sregex_iterator(html.begin(), html.end(), img); it != std::sregex_iterator(); ++it)
    referenced.insert((*it)[1]);
  std::set<std::string> files;
  for (const auto& e : fs::directory_iterator(dir / "html" / "report_figures")) {
    files.insert("report_figures/" + e.path().filename().string());
    EXPECT_GT(fs::file_size(e.path()), 1000u) << e.path();
    EXPECT_EQ(read_text(e.path()).substr(1, 3), "PNG") << e.path();
  }
  EXPECT_EQ(referenced, files);
  for (const char* f : {"misalignment.png", "scale_factor.png", "forgetting_factor.png", "gnss_speed.png", "tracks.png",
                        "error_vs_distance.png"})
    EXPECT_EQ(files.count(std::string("report_figures/") + f), 1u) << f;
  // The summary table comes from summary.json: the main estimator's final K is on the page.
  EXPECT_NE(html.find("K vff_lm_rls"), std::string::npos);
  EXPECT_NE(html.find("DR online k"), std::string::npos);

  // A folder with a missing file: exit 1, the message names it.
  fs::remove(dir / "out" / "scale_factor.csv");
  const RunResult bad = run(binary("odonav-report"), {(dir / "out").string(), "--out", (dir / "bad.html").string()}, dir, "bad");
  EXPECT_EQ(bad.exit_code, 1);
  EXPECT_NE(bad.err.find((dir / "out" / "scale_factor.csv").string()), std::string::npos) << bad.err;
  EXPECT_FALSE(fs::exists(dir / "bad.html"));
}
