// libFuzzer target: the option parser (Options, config.hpp) fed a configuration file text, with the
// options of odonav-offline declared (identification, calibration, dead reckoning, lever arm and
// some of each type), then the typed readers that turn the values into parameters.
//
// Input layout: the config file text, optionally followed by a NUL and command-line arguments
// separated by NULs (they override the file, as on a real command line).
// Seeds in fuzz/seeds/config_parser/ (see the README there).
//
// Findings: any crash or sanitizer report, and any exception other than ConfigError (the documented
// user error): values that pass the option ranges must make valid parameters or be refused with a
// ConfigError naming the option, never escape as another exception type.
#include <cstdint>
#include <sstream>
#include <string>
#include <vector>

#include "fuzz_support.hpp"
#include "odonav/calibration/calibration_options.hpp"
#include "odonav/config.hpp"
#include "odonav/dead_reckoning/dead_reckoning_options.hpp"
#include "odonav/identification/identification_options.hpp"
#include "odonav/lever_arm_option.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, std::size_t size) {
  const auto parts = odonav::fuzz::split_at_nul(data, size, 64);
  const std::string path = odonav::fuzz::scratch_dir() + "/fuzz.conf";
  odonav::fuzz::write_file(path, parts[0]);

  odonav::Options options("odonav-fuzz", "Options as odonav-offline declares them.");
  options.add_positional("dataset", "dataset directory", false);
  options.add_string("out", "", "output directory");
  options.add_choice("on-bad-row", "fail", {"fail", "skip"}, "bad row policy");
  options.add_int("count", 3, "an integer option", -5, 1000000);
  options.add_bool("verbose", false, "a switch");
  odonav::identification::add_identification_options(options);
  odonav::calibration::add_calibration_options(options);
  odonav::dead_reckoning::add_dead_reckoning_options(options);
  odonav::add_lever_arm_option(options);

  std::vector<std::string> args{"--config", path};
  for (std::size_t i = 1; i < parts.size(); ++i) args.emplace_back(parts[i]);
  std::ostringstream help;
  try {
    if (options.parse(args, help) == odonav::ParseResult::kHelp) return 0;
    (void)odonav::identification::identification_params_from(options);
    (void)odonav::calibration::calibration_params_from(options);
    (void)odonav::dead_reckoning::dead_reckoning_params_from(options);
    (void)odonav::lever_arm_from(options);
    (void)options.values_as_text();
  } catch (const odonav::ConfigError&) {
    // the documented answer to a bad configuration
  }
  return 0;
}
