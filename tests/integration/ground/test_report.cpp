// odonav-report on the output folder of odonav-offline over a short simulated drive (odonav-simulator
// terrain, 120 s): the page exists, every figure file is non-empty and referenced by the page; a
// folder with a missing file fails naming it.
#include <gtest/gtest.h>

#include <fstream>
#include <regex>
#include <set>
#include <sstream>
#include <vector>

#include "ground_test_support.hpp"

using namespace odonav::test;

TEST(Report, HtmlWithEveryFigureFromAnOfflineRun) {
  const fs::path dir = scratch_dir("report");
  const RunResult sim =
      run(binary("odonav-simulator"), {"terrain", "--duration-s", "120", "--out", (dir / "data").string()}, dir, "sim");
  ASSERT_EQ(sim.exit_code, 0) << sim.err;
  const RunResult off =
      run(binary("odonav-offline"), {(dir / "data").string(), "--out", (dir / "out").string()}, dir, "offline");
  ASSERT_EQ(off.exit_code, 0) << off.err;

  const fs::path page = dir / "html" / "report.html";
  const RunResult rep =
      run(binary("odonav-report"),
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
  // The GNSS-anchored position beside the pure DR and the GNSS fixes (summary.json's navigation_position).
  EXPECT_NE(html.find("horizontal RMS vs truth while valid [m]: anchored / pure DR / GNSS"), std::string::npos);

  // A folder with a missing file: exit 1, the message names it.
  fs::remove(dir / "out" / "scale_factor.csv");
  const RunResult bad =
      run(binary("odonav-report"), {(dir / "out").string(), "--out", (dir / "bad.html").string()}, dir, "bad");
  EXPECT_EQ(bad.exit_code, 1);
  EXPECT_NE(bad.err.find((dir / "out" / "scale_factor.csv").string()), std::string::npos) << bad.err;
  EXPECT_FALSE(fs::exists(dir / "bad.html"));
}

// Hostile and careless inputs: odonav-report never traces back, never writes over an input, a link
// or a file that is not its own, and refuses results of another vehicle or time span.
TEST(Report, RefusesWhatItMustNotWriteAndNeverTracesBack) {
  const fs::path dir = scratch_dir("report-hostile");
  ASSERT_EQ(
      run(binary("odonav-simulator"), {"straight", "--duration-s", "60", "--out", (dir / "data").string()}, dir, "sim")
          .exit_code,
      0);
  // A drive whose every fix is invalid: dead reckoning never starts (summary.json has nulls).
  {
    const std::string gnss = read_text(dir / "data" / "gnss.csv");
    std::stringstream in(gnss), out;
    std::string line;
    std::getline(in, line);
    out << line << "\n";
    while (std::getline(in, line)) out << line.substr(0, line.rfind(',')) << ",0\n";  // fix is the last column
    std::ofstream(dir / "data" / "gnss.csv") << out.str();
  }
  const RunResult off =
      run(binary("odonav-offline"), {(dir / "data").string(), "--out", (dir / "out").string()}, dir, "offline");
  ASSERT_EQ(off.exit_code, 3) << off.err;  // no usable result
  const auto report = [&](std::vector<std::string> args, const std::string& name) {
    args.insert(args.begin(), (dir / "out").string());
    return run(binary("odonav-report"), args, dir, name);
  };
  const RunResult never_started =
      report({"--out", (dir / "r.html").string(), "--dataset", (dir / "data").string()}, "ns");
  EXPECT_EQ(never_started.exit_code, 0) << never_started.err;
  EXPECT_NE(read_text(dir / "r.html").find("dead reckoning never started"), std::string::npos);
  EXPECT_NE(read_text(dir / "r.html").find("no_k"), std::string::npos) << "the run's warnings are on the page";

  const std::string gnss_before = read_text(dir / "data" / "gnss.csv");
  const RunResult over_input =
      report({"--out", (dir / "data" / "gnss.csv").string(), "--dataset", (dir / "data").string()}, "oi");
  EXPECT_EQ(over_input.exit_code, 1);
  EXPECT_NE(over_input.err.find("inside the dataset"), std::string::npos) << over_input.err;
  EXPECT_EQ(read_text(dir / "data" / "gnss.csv"), gnss_before);
  const RunResult over_results = report({"--out", (dir / "out" / "scale_factor.csv").string()}, "or");
  EXPECT_NE(over_results.err.find("it is an input of this report"), std::string::npos) << over_results.err;
  std::ofstream(dir / "notes.html") << "my notes";
  const RunResult foreign = report({"--out", (dir / "notes.html").string()}, "fo");
  EXPECT_NE(foreign.err.find("is not an odonav report"), std::string::npos) << foreign.err;
  EXPECT_EQ(read_text(dir / "notes.html"), "my notes");
  fs::create_symlink(dir / "notes.html", dir / "link.html");
  EXPECT_NE(report({"--out", (dir / "link.html").string()}, "ln").err.find("symbolic link"), std::string::npos);
  EXPECT_EQ(read_text(dir / "notes.html"), "my notes");
  // Our own page may be replaced.
  EXPECT_EQ(report({"--out", (dir / "r.html").string()}, "again").exit_code, 0);

  // Another vehicle's results (run.json) against this dataset.
  std::string run_json = read_text(dir / "out" / "run.json");
  run_json.replace(run_json.find("sim-"), 4, "xxx-");
  std::ofstream(dir / "out" / "run.json") << run_json;
  const RunResult other = report({"--out", (dir / "o.html").string(), "--dataset", (dir / "data").string()}, "ov");
  EXPECT_EQ(other.exit_code, 1);
  EXPECT_NE(other.err.find("does not belong to"), std::string::npos) << other.err;

  // Not UTF-8, and not odonav output at all: a message, no traceback.
  std::ofstream(dir / "out" / "misalignment.csv", std::ios::binary) << "t,heading_deg\n0,\xff\xfe\n";
  const RunResult binary_file = report({"--out", (dir / "b.html").string()}, "bin");
  EXPECT_EQ(binary_file.exit_code, 1);
  EXPECT_NE(binary_file.err.find("not UTF-8"), std::string::npos) << binary_file.err;
  EXPECT_EQ(binary_file.err.find("Traceback"), std::string::npos) << binary_file.err;
}
