// Bad input end to end: what one component or the dataset reader does with garbage, on
// simulated drives with known truth. Nothing crashes, good data is kept, every rejection is counted.
#include <gtest/gtest.h>
#include <spdlog/spdlog.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "child_process.hpp"
#include "odonav/simulator/simulator.hpp"
#include "odonav/dataset.hpp"
#include "odonav/dead_reckoning/dead_reckoner.hpp"
#include "odonav/identification/identification_core.hpp"
#include "scratch_dir.hpp"

namespace fs = std::filesystem;
using namespace odonav;

namespace {

// --- identification on a simulated straight run ---------------------------------------------

struct IdentificationRun {
  SampleBuilderCounters counters;
  double final_k = 0.0;          ///< mean of K^ over the last 60 s of accepted epochs (m/pulse)
  double min_lambda = 1.0;       ///< smallest VFF lambda once the window was full
  int epochs_at_lambda_min = 0;  ///< epochs whose lambda sat at lambda_min
  double lambda_min = 0.0;
};

IdentificationRun identify(const Dataset& d, const simulator::SimulationConfig& cfg, bool use_ins) {
  identification::IdentificationParams p;
  p.builder.use_ins = use_ins;
  if (use_ins) p.builder.lever_arm_body_m = cfg.lever_arm_m;
  identification::IdentificationCore core(p);
  if (use_ins) core.add_misalignment(d.odometer.front().t_s, cfg.misalignment);
  for (const auto& s : d.odometer) core.add_odometer(s);
  for (const auto& s : d.gnss) core.add_gnss(s);
  if (use_ins)
    for (const auto& s : d.ins) core.add_ins(s);
  const auto out = core.finish();
  IdentificationRun r;
  r.lambda_min = p.estimator.lambda_min;
  const double t_end = d.gnss.back().t_s;
  double sum_k = 0.0;
  int n_k = 0;
  for (const auto& o : out) {
    if (o.samples_accepted > p.estimator.window_length) {
      r.min_lambda = std::min(r.min_lambda, o.main.forgetting_factor);
      if (o.main.forgetting_factor <= p.estimator.lambda_min) ++r.epochs_at_lambda_min;
    }
    if (o.t_s > t_end - 60.0 && o.epoch_status == EpochStatus::kAccepted) {
      sum_k += o.main.k_m_per_pulse;
      ++n_k;
    }
  }
  r.counters = core.builder_counters();
  r.final_k = n_k > 0 ? sum_k / n_k : std::nan("");
  return r;
}

simulator::SimulationConfig straight_config() {
  simulator::SimulationConfig cfg = simulator::scenario_config("straight");
  cfg.seed = 11;
  return cfg;
}

// --- running a real executable ----------------------------------------------------------------

using test::binary;
using test::ScratchDir;
/// A shell command's exit status and its output (stdout and stderr).
test::CommandResult run(const std::string& command_line) { return test::run_command(command_line); }

}  // namespace

// GNSS velocity spikes of 10 m/s on a simulated straight run: the gates reject them and count them,
// the forgetting factor does not collapse, and K ends within 0.2 % of the truth.
TEST(BadInput, GnssVelocitySpikesOfTenMetresPerSecondAreRejectedAndKStaysWithinPointTwoPercent) {
  const simulator::SimulationConfig cfg = straight_config();
  const Dataset clean = simulator::simulate(cfg);
  Dataset spiked = clean;
  // 60 epochs while moving (> 3 m/s), each 10 m/s in a random horizontal direction (fixed seed).
  std::vector<std::size_t> moving;
  for (std::size_t i = 0; i < spiked.gnss.size(); ++i)
    if (spiked.gnss[i].vel_enu_mps.head<2>().norm() > 3.0) moving.push_back(i);
  ASSERT_GT(moving.size(), 1000u);
  std::mt19937 rng(20261121);
  std::shuffle(moving.begin(), moving.end(), rng);
  std::uniform_real_distribution<double> azimuth(0.0, 2.0 * kPi);
  int along_track = 0;   // spikes whose forward component exceeds the speed-jump bound (1.6 m/s)
  int beyond_bound = 0;  // ... exceeds it even over two GNSS intervals (2.2 m/s)
  for (std::size_t j = 0; j < 60; ++j) {
    GnssSample& g = spiked.gnss[moving[j]];
    const double a = azimuth(rng);
    const Eigen::Vector3d spike(10.0 * std::sin(a), 10.0 * std::cos(a), 0.0);
    const double forward_mps = std::abs(spike.dot(g.vel_enu_mps.normalized()));
    if (forward_mps > 1.6) ++along_track;
    if (forward_mps > 2.2) ++beyond_bound;
    g.vel_enu_mps += spike;
  }

  const IdentificationRun ref = identify(clean, cfg, true);
  const IdentificationRun run = identify(spiked, cfg, true);
  const double k_true = cfg.k_true_m_per_pulse;
  // A spike against the motion larger than the speed itself shows as a negative forward speed.
  // Sideways spikes are caught by the cross-track gate.
  const uint64_t rejected =
      run.counters.speed_jump + run.counters.innovation + run.counters.negative_speed + run.counters.cross_track;
  const uint64_t rejected_ref =
      ref.counters.speed_jump + ref.counters.innovation + ref.counters.negative_speed + ref.counters.cross_track;
  std::printf(
      "spikes: 60 (%d with a forward component > 1.6 m/s, %d > 2.2 m/s); rejected %llu (clean run %llu); "
      "accepted %llu (clean %llu)\n",
      along_track, beyond_bound, static_cast<unsigned long long>(rejected),
      static_cast<unsigned long long>(rejected_ref), static_cast<unsigned long long>(run.counters.accepted),
      static_cast<unsigned long long>(ref.counters.accepted));
  std::printf("lambda: min %.5f with spikes, %.5f clean, lambda_min %.3f; epochs at lambda_min %d (clean %d)\n",
              run.min_lambda, ref.min_lambda, run.lambda_min, run.epochs_at_lambda_min, ref.epochs_at_lambda_min);
  std::printf("K: %.4f %% from truth with spikes, %.4f %% clean\n", 100.0 * (run.final_k / k_true - 1.0),
              100.0 * (ref.final_k / k_true - 1.0));
  // Every spike that moves the forward speed by more than the speed-jump bound at twice the GNSS
  // interval (6 m/s^2 * 0.2 s + 1 m/s = 2.2 m/s, the bound when the previous epoch was rejected) is
  // caught; smaller ones (1.6-2.2 m/s forward, or sideways) may pass the gates and move y by ~0.1 m.
  EXPECT_GE(rejected, rejected_ref + static_cast<uint64_t>(beyond_bound));
  EXPECT_GE(beyond_bound, 40);
  // The forgetting factor does not collapse: a spike that passes the gates is one sample, so it can
  // pull lambda to lambda_min at most once; every rejected one never reaches the estimator.
  EXPECT_LE(static_cast<uint64_t>(run.epochs_at_lambda_min), 60u - (rejected - rejected_ref));
  EXPECT_GE(run.min_lambda, run.lambda_min);
  EXPECT_NEAR(run.final_k / k_true - 1.0, 0.0, 0.002);
  EXPECT_NEAR(run.final_k / ref.final_k - 1.0, 0.0, 0.0005);
}

// INS missing (docs/DATASET.md degraded mode): K from the GNSS ground speed, dead reckoning along the
// GNSS course, both flagged; nothing is rejected for want of an attitude.
TEST(BadInput, WithoutInsTheDegradedModeIdentifiesKAndDeadReckons) {
  const simulator::SimulationConfig cfg = straight_config();
  Dataset d = simulator::simulate(cfg);
  d.ins.clear();
  const IdentificationRun run = identify(d, cfg, false);
  std::printf("degraded: K %.4f %% from truth, %llu samples accepted\n",
              100.0 * (run.final_k / cfg.k_true_m_per_pulse - 1.0),
              static_cast<unsigned long long>(run.counters.accepted));
  EXPECT_EQ(run.counters.no_attitude, 0u);
  // Fewer than with INS (1851 on this run): the yaw-rate gate works on the GNSS course here, whose
  // noise (0.05 m/s at 10 m/s: 0.3 deg per epoch) alone reaches the 3 deg/s gate now and then.
  EXPECT_GT(run.counters.accepted, 800u);
  EXPECT_NEAR(run.final_k / cfg.k_true_m_per_pulse - 1.0, 0.0, 0.002);

  dead_reckoning::DeadReckonerParams p;
  p.use_ins = false;
  p.nominal_k_m_per_pulse = cfg.k_true_m_per_pulse;
  dead_reckoning::DeadReckoner dr(p);
  for (const auto& s : d.odometer) dr.add_odometer(s);
  for (const auto& s : d.gnss) dr.add_gnss(s);
  const auto out = dr.finish();
  ASSERT_GT(out.size(), 10000u);
  EXPECT_TRUE(
      std::all_of(out.begin(), out.end(), [](const dead_reckoning::DeadReckoningOutput& o) { return o.degraded; }));
  // The last output with a GNSS reference (the odometer runs on after the last GNSS epoch).
  const auto last = std::find_if(out.rbegin(), out.rend(),
                                 [](const dead_reckoning::DeadReckoningOutput& o) { return o.gnss_reference; });
  ASSERT_NE(last, out.rend());
  std::printf("degraded DR: %.1f m travelled, final error %.2f m\n", last->distance_m, last->horizontal_error_m);
  // GNSS positions carry metres of correlated noise: the end is within 10 m after about 1.8 km.
  EXPECT_GT(last->distance_m, 1500.0);
  EXPECT_LT(last->horizontal_error_m, 10.0);
}

// NaN and infinity in every field of every dataset file: under fail the exact place, under skip the
// row rejected, counted under its column, and every good row kept.
TEST(BadInput, NanAndInfinityInEveryFieldOfEveryFileAreBadRows) {
  struct File {
    const char* name;
    const char* header;
    const char* good_row;  // "{t}" is replaced by the row time
  };
  const File files[] = {
      {"odometer.csv", "t,pulses,direction", "{t},{n},1"},
      {"gnss.csv", "t,lat_deg,lon_deg,height_m,ve,vn,vu,pos_std_m,vel_std_mps,fix",
       "{t},52.5,13.4,40,1,2,0,0.5,0.05,4"},
      {"ins.csv", "t,heading_deg,pitch_deg,roll_deg,ve,vn,vu", "{t},30,1,-1,1,2,0"},
      {"truth.csv", "t,lat_deg,lon_deg,height_m,heading_deg,pitch_deg,roll_deg,k_true,distance_m",
       "{t},52.5,13.4,40,30,1,-1,0.0125,{n}"},
  };
  auto row = [](const char* pattern, int i) {
    std::string r = pattern;
    r.replace(r.find("{t}"), 3, std::to_string(i) + ".0");
    if (const auto n = r.find("{n}"); n != std::string::npos) r.replace(n, 3, std::to_string(100 * i));
    return r;
  };
  // Each skipped row is logged as a warning: 87 of them would only hide the test's own output.
  const auto level = spdlog::get_level();
  spdlog::set_level(spdlog::level::err);
  int cases = 0;
  for (const File& f : files) {
    std::vector<std::string> columns;
    std::stringstream header(f.header);
    for (std::string c; std::getline(header, c, ',');) columns.push_back(c);
    for (std::size_t col = 0; col < columns.size(); ++col) {
      for (const char* token : {"nan", "inf", "-inf"}) {
        SCOPED_TRACE(std::string(f.name) + " column " + columns[col] + " = " + token);
        ScratchDir dir;
        for (const File& other : files) {
          std::string text = std::string(other.header) + "\n";
          for (int i = 0; i < 4; ++i) {
            std::string r = row(other.good_row, i);
            if (&other == &f && i == 2) {  // line 4: replace field `col`
              std::vector<std::string> fields;
              std::stringstream rs(r);
              for (std::string x; std::getline(rs, x, ',');) fields.push_back(x);
              fields[col] = token;
              r.clear();
              for (std::size_t k = 0; k < fields.size(); ++k) r += (k ? "," : "") + fields[k];
            }
            text += r + "\n";
          }
          dir.write(other.name, text);
        }
        const std::string where = dir.file(f.name) + ":4: column '" + columns[col] + "'";
        try {
          read_dataset(dir.str(), BadRowPolicy::kFail);
          ADD_FAILURE() << "accepted under fail";
        } catch (const DatasetError& e) {
          EXPECT_EQ(std::string(e.what()).rfind(where, 0), 0u) << e.what();
        }
        DatasetReadReport report;
        const Dataset d = read_dataset(dir.str(), BadRowPolicy::kSkip, &report);
        EXPECT_EQ(report.total_bad(), 1u);
        ASSERT_EQ(report.bad_rows.size(), 1u);
        EXPECT_EQ(report.bad_rows[0].column, columns[col]);
        EXPECT_EQ(report.bad_rows[0].line, 4u);
        const std::string name = f.name;
        EXPECT_EQ(d.odometer.size(), name == "odometer.csv" ? 3u : 4u);
        EXPECT_EQ(d.gnss.size(), name == "gnss.csv" ? 3u : 4u);
        EXPECT_EQ(d.ins.size(), name == "ins.csv" ? 3u : 4u);
        EXPECT_EQ(d.truth.size(), name == "truth.csv" ? 3u : 4u);
        ++cases;
      }
    }
  }
  spdlog::set_level(level);
  EXPECT_EQ(cases, 3 * (3 + 10 + 7 + 9));
}

// A malformed configuration file: odonav-offline exits 2 naming the file, the line and what is wrong.
TEST(BadInput, MalformedConfigFileMakesTheToolExitTwoNamingFileAndLine) {
  ScratchDir dir;
  const std::string dataset = dir.file("straight");
  simulator::SimulationConfig cfg = straight_config();
  cfg.straight_length_m = 100.0;
  write_dataset(dataset, simulator::simulate(cfg));
  const std::string tool = binary("odonav-offline") + " " + dataset + " --out " + dir.file("out") + " --config ";
  struct Case {
    std::string text;
    std::string expected;  // after "<file>:"
  };
  const Case cases[] = {
      {"# identification\nwindow 100\n", "2: expected 'key = value', got 'window 100'"},
      {"window = 100\nwindow = 50\n", "2: duplicate key 'window' (first at line 1)"},
      {"no-such-key = 1\n", "1: unknown key 'no-such-key'"},
      {"window = ten\n", "1: window = ten"},
      {"lambda-min = nan\n", "1: lambda-min = nan"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.text);
    const std::string conf = dir.file("bad.conf");
    dir.write("bad.conf", c.text);
    const test::CommandResult r = run(tool + conf);
    EXPECT_EQ(r.status, 2) << r.output;
    EXPECT_NE(r.output.find(conf + ":" + c.expected), std::string::npos) << r.output;
  }
  EXPECT_FALSE(fs::exists(dir.file("out/scale_factor.csv")));
  const test::CommandResult missing = run(tool + dir.file("nowhere.conf"));
  EXPECT_EQ(missing.status, 2) << missing.output;
  EXPECT_NE(missing.output.find("cannot read config file '" + dir.file("nowhere.conf") + "'"), std::string::npos)
      << missing.output;
}

// A malformed XML profile: a component exits nonzero at once, with the file's path in the message.
TEST(BadInput, MalformedXmlProfileMakesAComponentExitNonzeroNamingThePath) {
  ScratchDir dir;
  dir.write("broken.xml", "<dds><profiles><participant profile_name=\"broken\">\n");  // never closed
  const std::string component = binary("odonav-dead-reckoning") + " --domain 110 --vehicle-id bad-input --profile ";
  const test::CommandResult broken = run(component + dir.file("broken.xml"));
  EXPECT_NE(broken.status, 0) << broken.output;
  EXPECT_NE(broken.status, -1) << "killed by a signal: " << broken.output;
  EXPECT_NE(broken.output.find(dir.file("broken.xml")), std::string::npos) << broken.output;
  const test::CommandResult missing = run(component + dir.file("missing.xml"));
  EXPECT_NE(missing.status, 0) << missing.output;
  EXPECT_NE(missing.status, -1) << missing.output;
  EXPECT_NE(missing.output.find(dir.file("missing.xml")), std::string::npos) << missing.output;
}

// One wrong GNSS velocity row in a 60 s ring, through the real odonav-offline. 1e6 m/s is beyond
// what a land vehicle can do: the reader names the row (strict) or skips it (skip). 30 m/s east is
// possible but 30 m/s off the track: the calibrator's outlier gate keeps it out, so the misalignment
// is the clean one (without the gate: 1e6 gave heading -89.2 deg "converged", 30 m/s 0.5 deg and no
// convergence; 1e308 stopped the run on non-finite angles).
TEST(BadInput, OneWrongGnssVelocityRowDoesNotMoveTheMisalignment) {
  ScratchDir dir;
  const std::string dataset = dir.file("ring");
  ASSERT_EQ(run(binary("odonav-simulator") + " ring --duration-s 60 --out " + dataset + " --log-level error").status,
            0);
  const auto heading_error_deg = [&](const std::string& out, const std::string& flags = "") {
    const test::CommandResult r =
        run(binary("odonav-offline") + " " + dataset + " --out " + out + " --log-level warn " + flags);
    EXPECT_EQ(r.status, 0) << r.output;
    std::ifstream in(out + "/summary.json");
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const std::size_t at = text.find("\"heading_error_deg\"");
    EXPECT_NE(at, std::string::npos) << text.substr(0, 400);
    return at == std::string::npos ? 1e9 : std::stod(text.substr(text.find(':', at) + 1));
  };
  const double clean = heading_error_deg(dir.file("clean"));
  EXPECT_LT(std::abs(clean), 0.1);
  // Column 5 of gnss.csv is ve (docs/DATASET.md); line 301 is t = 29.9 s at 10 Hz.
  const auto replace_ve = [&](int line, const std::string& value) {
    std::ifstream in(dataset + "/gnss.csv");
    std::vector<std::string> lines;
    for (std::string l; std::getline(in, l);) lines.push_back(l);
    ASSERT_GT(lines.size(), static_cast<std::size_t>(line));
    std::vector<std::string> fields;
    std::stringstream ss(lines[line - 1]);
    for (std::string f; std::getline(ss, f, ',');) fields.push_back(f);
    fields.at(4) = value;
    std::string joined;
    for (std::size_t i = 0; i < fields.size(); ++i) joined += (i ? "," : "") + fields[i];
    lines[line - 1] = joined;
    std::ofstream o(dataset + "/gnss.csv");
    for (const auto& l : lines) o << l << '\n';
  };
  replace_ve(301, "30");
  const double spiked = heading_error_deg(dir.file("spiked"));
  EXPECT_LT(std::abs(spiked), 0.1);
  EXPECT_NEAR(spiked, clean, 0.01);
  replace_ve(302, "1e6");
  const test::CommandResult strict = run(binary("odonav-offline") + " " + dataset + " --out " + dir.file("strict"));
  EXPECT_EQ(strict.status, 1);
  EXPECT_NE(
      strict.output.find("gnss.csv:302: column 've': velocity (m/s) of a land vehicle outside [-500, 500]: '1e6'"),
      std::string::npos)
      << strict.output;
  EXPECT_NEAR(heading_error_deg(dir.file("skipped"), "--on-bad-row=skip"), clean, 0.01);
}

// Plausible row by row, wrong as a whole: an INS heading counted the other way round, and a truth
// file of another place. The run says so (log and summary.json), keeps every output, exits 0.
TEST(BadInput, AHeadingOfTheOtherConventionAndAForeignTruthAreNamedAndNothingGoodIsLost) {
  ScratchDir dir;
  const std::string dataset = dir.file("terrain");
  ASSERT_EQ(
      run(binary("odonav-simulator") + " terrain --duration-s 200 --out " + dataset + " --log-level error").status, 0);
  const auto lines_of = [](const std::string& file) {
    std::ifstream in(file);
    std::size_t n = 0;
    for (std::string l; std::getline(in, l);) ++n;
    return n;
  };
  const auto read_all = [](const std::string& file) {
    std::ifstream in(file);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  };
  // Rewrites one column of a CSV file of the dataset with f(value).
  const auto rewrite = [&](const std::string& file, const std::string& column, double (*f)(double)) {
    std::ifstream in(dataset + "/" + file);
    std::vector<std::string> lines;
    for (std::string l; std::getline(in, l);) lines.push_back(l);
    std::vector<std::string> header;
    std::stringstream hs(lines[0]);
    for (std::string h; std::getline(hs, h, ',');) header.push_back(h);
    const std::size_t c = static_cast<std::size_t>(std::find(header.begin(), header.end(), column) - header.begin());
    ASSERT_LT(c, header.size()) << column;
    std::ofstream out(dataset + "/" + file);
    out << lines[0] << '\n';
    for (std::size_t i = 1; i < lines.size(); ++i) {
      std::vector<std::string> fields;
      std::stringstream ss(lines[i]);
      for (std::string v; std::getline(ss, v, ',');) fields.push_back(v);
      char text[32];
      std::snprintf(text, sizeof text, "%.17g", f(std::stod(fields.at(c))));
      fields[c] = text;
      for (std::size_t k = 0; k < fields.size(); ++k) out << (k ? "," : "") << fields[k];
      out << '\n';
    }
  };
  const test::CommandResult clean =
      run(binary("odonav-offline") + " " + dataset + " --out " + dir.file("clean") + " --log-level warn");
  ASSERT_EQ(clean.status, 0) << clean.output;
  EXPECT_EQ(clean.output.find("inconsistent"), std::string::npos) << clean.output;

  rewrite("ins.csv", "heading_deg", [](double h) { return std::fmod(360.0 - h, 360.0); });
  rewrite("truth.csv", "lat_deg", [](double lat) { return lat + 5.0; });
  const test::CommandResult bad =
      run(binary("odonav-offline") + " " + dataset + " --out " + dir.file("bad") + " --log-level warn");
  EXPECT_EQ(bad.status, 0) << bad.output;
  EXPECT_NE(bad.output.find("INS heading turns opposite to the GNSS course"), std::string::npos) << bad.output;
  EXPECT_NE(bad.output.find("heading sign convention?"), std::string::npos) << bad.output;
  EXPECT_NE(bad.output.find("truth.csv is 55"), std::string::npos) << bad.output;  // 5 deg: 556 km
  const std::string summary = read_all(dir.file("bad") + "/summary.json");
  EXPECT_NE(summary.find("\"inconsistent_heading_rate\""), std::string::npos);
  EXPECT_NE(summary.find("\"converged_withdrawn\""), std::string::npos);
  EXPECT_NE(summary.find("\"truth_refused\""), std::string::npos);
  for (const char* f : {"misalignment.csv", "scale_factor.csv", "dead_reckoning.csv", "navigation_position.csv"})
    EXPECT_EQ(lines_of(dir.file("bad") + "/" + f), lines_of(dir.file("clean") + "/" + f)) << f;
}
