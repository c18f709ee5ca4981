// Options: flags, config file, override order, every error kind with its message, help text.
#include <gtest/gtest.h>

#include <sstream>

#include "scratch_dir.hpp"
#include "odonav/config.hpp"

using namespace odonav;
using odonav::test::ScratchDir;

namespace {

// The options of the example in config.hpp.
Options offline_options() {
  Options opts("odonav-offline", "Runs calibration, identification and DR over a dataset.");
  opts.add_positional("dataset", "dataset directory");
  opts.add_string("out", "", "output directory");
  opts.add_double("vff-c", 4.0, "VFF residual scale", 0.0, 1e6);
  opts.add_int("window", 100, "window length in samples", 1, 100000);
  opts.add_bool("freeze", false, "freeze K during GNSS loss");
  opts.add_choice("on-bad-row", "fail", {"fail", "skip"}, "what to do with a bad dataset row");
  return opts;
}

// The ConfigError message of parsing `args` with `opts`; empty when they parse.
std::string error_of(Options opts, const std::vector<std::string>& args) {
  std::ostringstream help;
  try {
    opts.parse(args, help);
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

std::string parse_error(const std::vector<std::string>& args) { return error_of(offline_options(), args); }

// The error `error` (parse_error or the like) gives for `command --config <file>` with a config file
// holding `text`, the file's path at its start written "<file>".
template <class Error>
std::string config_file_error(Error error, const std::string& command, const std::string& text) {
  ScratchDir dir;
  dir.write("a.conf", text);
  const std::string path = dir.file("a.conf");
  std::string e = error({command, "--config", path});
  if (e.rfind(path, 0) == 0) e.replace(0, path.size(), "<file>");
  return e;
}

}  // namespace

TEST(Options, DefaultsWhenNothingIsGiven) {
  Options opts = offline_options();
  std::ostringstream help;
  ASSERT_EQ(opts.parse({"/data/run1"}, help), ParseResult::kRun);
  EXPECT_EQ(opts.get_string("dataset"), "/data/run1");
  EXPECT_EQ(opts.get_string("out"), "");
  EXPECT_EQ(opts.get_double("vff-c"), 4.0);
  EXPECT_EQ(opts.get_int("window"), 100);
  EXPECT_FALSE(opts.get_bool("freeze"));
  EXPECT_EQ(opts.get_string("on-bad-row"), "fail");
  EXPECT_TRUE(opts.was_set("dataset"));
  EXPECT_FALSE(opts.was_set("vff-c"));
  EXPECT_TRUE(help.str().empty());
}

TEST(Options, EveryFlagSyntax) {
  Options opts = offline_options();
  std::ostringstream help;
  ASSERT_EQ(
      opts.parse({"--vff-c=2.5", "--window", "250", "run1", "--out", "/tmp/o", "--freeze", "--on-bad-row=skip"}, help),
      ParseResult::kRun);
  EXPECT_EQ(opts.get_double("vff-c"), 2.5);
  EXPECT_EQ(opts.get_int("window"), 250);
  EXPECT_EQ(opts.get_string("out"), "/tmp/o");
  EXPECT_TRUE(opts.get_bool("freeze"));
  EXPECT_EQ(opts.get_string("on-bad-row"), "skip");
  EXPECT_EQ(opts.get_string("dataset"), "run1");
  EXPECT_TRUE(opts.was_set("window"));

  Options negated = offline_options();
  negated.add_bool("ins", true, "use ins.csv");
  ASSERT_EQ(negated.parse({"run", "--no-ins", "--freeze=true", "--vff-c", "-0", "--window=+7"}, help),
            ParseResult::kRun);
  EXPECT_FALSE(negated.get_bool("ins"));
  EXPECT_TRUE(negated.was_set("ins"));
  EXPECT_TRUE(negated.get_bool("freeze"));
  EXPECT_EQ(negated.get_int("window"), 7);

  // The last of a repeated flag wins; "--" makes a dash-leading word a positional.
  Options repeated = offline_options();
  ASSERT_EQ(repeated.parse({"--window=5", "--window=9", "--", "--odd-name"}, help), ParseResult::kRun);
  EXPECT_EQ(repeated.get_int("window"), 9);
  EXPECT_EQ(repeated.get_string("dataset"), "--odd-name");
}

TEST(Options, ConfigFileAndCommandLineOverride) {
  ScratchDir dir;
  dir.write("run.conf",
            "# calibration run\n"
            "vff-c = 8.5\n"
            "\n"
            "  window=300  \n"
            "freeze = true\r\n"
            "out = /tmp/from file\n");
  // The flag wins whether it comes before or after --config.
  for (const auto& args : {std::vector<std::string>{"--window=20", "--config", dir.file("run.conf"), "run1"},
                           std::vector<std::string>{"run1", "--config=" + dir.file("run.conf"), "--window", "20"}}) {
    Options opts = offline_options();
    std::ostringstream help;
    ASSERT_EQ(opts.parse(args, help), ParseResult::kRun);
    EXPECT_EQ(opts.get_int("window"), 20);
    EXPECT_EQ(opts.get_double("vff-c"), 8.5);
    EXPECT_TRUE(opts.get_bool("freeze"));
    EXPECT_EQ(opts.get_string("out"), "/tmp/from file");
    EXPECT_TRUE(opts.was_set("vff-c"));
    EXPECT_FALSE(opts.was_set("on-bad-row"));
  }
}

TEST(Options, UnknownFlagOrKey) {
  EXPECT_EQ(parse_error({"run", "--vffc=3"}), "unknown option '--vffc'");
  EXPECT_EQ(parse_error({"run", "-w", "3"}), "unknown option '-w' (options are written --name)");
  EXPECT_EQ(parse_error({"run", "--no-window"}), "unknown option '--no-window'");
  EXPECT_EQ(config_file_error(parse_error, "run", "window = 3\n# ok\nwindw = 4\n"), "<file>:3: unknown key 'windw'");
  EXPECT_EQ(config_file_error(parse_error, "run", "dataset = /x\n"),
            "<file>:1: 'dataset' is a positional argument, give it on the command line");
  EXPECT_EQ(config_file_error(parse_error, "run", "window 3\n"), "<file>:1: expected 'key = value', got 'window 3'");
}

TEST(Options, MissingValue) {
  EXPECT_EQ(parse_error({"run", "--window"}), "option '--window' needs a value");
  EXPECT_EQ(parse_error({"run", "--out", "--freeze"}), "option '--out' needs a value");
  EXPECT_EQ(parse_error({"run", "--window="}), "--window=: missing value");
  EXPECT_EQ(parse_error({"run", "--config"}), "option '--config' needs a value");
  EXPECT_EQ(config_file_error(parse_error, "run", "vff-c =\n"), "<file>:1: vff-c = : missing value");
}

TEST(Options, UnparsableValues) {
  EXPECT_EQ(parse_error({"run", "--window=12abc"}), "--window=12abc: not an integer");
  EXPECT_EQ(parse_error({"run", "--window=1.5"}), "--window=1.5: not an integer");
  EXPECT_EQ(parse_error({"run", "--vff-c=4,5"}), "--vff-c=4,5: not a number");
  EXPECT_EQ(parse_error({"run", "--vff-c=nan"}), "--vff-c=nan: not a finite number");
  EXPECT_EQ(parse_error({"run", "--vff-c", "inf"}), "--vff-c=inf: not a finite number");
  EXPECT_EQ(parse_error({"run", "--freeze=maybe"}), "--freeze=maybe: must be true or false");
  EXPECT_EQ(parse_error({"run", "--no-freeze=true"}), "--no-freeze takes no value");
  EXPECT_EQ(config_file_error(parse_error, "run", "\nwindow = ten\n"), "<file>:2: window = ten: not an integer");
}

TEST(Options, OutOfRange) {
  EXPECT_EQ(parse_error({"run", "--vff-c=-1"}), "--vff-c=-1: must be in [0, 1e6]");
  EXPECT_EQ(parse_error({"run", "--vff-c=1000000.5"}), "--vff-c=1000000.5: must be in [0, 1e6]");
  EXPECT_EQ(parse_error({"run", "--window=0"}), "--window=0: must be in [1, 100000]");
  EXPECT_EQ(parse_error({"run", "--window=99999999999999999999"}),
            "--window=99999999999999999999: must be in [1, 100000]");
  // The limits themselves are valid.
  EXPECT_EQ(parse_error({"run", "--vff-c=0", "--window=100000"}), "");
  EXPECT_EQ(parse_error({"run", "--vff-c=1e6", "--window=1"}), "");
}

TEST(Options, BadChoice) {
  EXPECT_EQ(parse_error({"run", "--on-bad-row=ignore"}), "--on-bad-row=ignore: must be one of fail, skip");
}

TEST(Options, PositionalArguments) {
  EXPECT_EQ(parse_error({"--window=3"}), "missing required argument <dataset> (dataset directory)");
  EXPECT_EQ(parse_error({"run1", "run2"}), "unexpected argument 'run2'");
  Options opts("odonav-x", "x");
  opts.add_positional("input", "input");
  opts.add_positional("output", "output", false);
  std::ostringstream help;
  ASSERT_EQ(opts.parse({"in"}, help), ParseResult::kRun);
  EXPECT_EQ(opts.get_string("input"), "in");
  EXPECT_FALSE(opts.was_set("output"));
}

TEST(Options, ConfigFileErrors) {
  ScratchDir dir;
  dir.write("dup.conf", "window = 3\nvff-c = 1\n# again\nwindow = 4\n");
  EXPECT_EQ(parse_error({"run", "--config", dir.file("dup.conf")}),
            dir.file("dup.conf") + ":4: duplicate key 'window' (first at line 1)");
  EXPECT_EQ(parse_error({"run", "--config", dir.file("absent.conf")}),
            "cannot read config file '" + dir.file("absent.conf") + "': No such file or directory");
  EXPECT_EQ(parse_error({"run", "--config", dir.file("dup.conf"), "--config", dir.file("dup.conf")}),
            "--config given more than once");
  dir.write("nest.conf", "config = other.conf\n");
  EXPECT_EQ(parse_error({"run", "--config", dir.file("nest.conf")}),
            dir.file("nest.conf") + ":1: 'config' cannot be set in a config file");
  // A bad value in the file is an error even when the command line overrides that key.
  dir.write("bad.conf", "window = 0\n");
  EXPECT_EQ(parse_error({"run", "--config", dir.file("bad.conf"), "--window=5"}),
            dir.file("bad.conf") + ":1: window = 0: must be in [1, 100000]");
}

TEST(Options, HelpListsEveryOption) {
  Options opts = offline_options();
  std::ostringstream help;
  // --help wins over an error elsewhere on the line.
  ASSERT_EQ(opts.parse({"--window=bad", "--help"}, help), ParseResult::kHelp);
  const std::string text = help.str();
  EXPECT_EQ(
      text.rfind(
          "Usage: odonav-offline [options] <dataset>\n\nRuns calibration, identification and DR over a dataset.\n", 0),
      0u)
      << text;
  for (const char* expected : {"<dataset>", "dataset directory", "--out <string>", "output directory (default: \"\")",
                               "--vff-c <number>", "VFF residual scale (default: 4, range: [0, 1e6])",
                               "--window <integer>", "window length in samples (default: 100, range: [1, 100000])",
                               "--[no-]freeze", "freeze K during GNSS loss (default: false)", "--on-bad-row <choice>",
                               "(default: fail, choices: fail, skip)", "--config <file>", "--help, -h"}) {
    EXPECT_NE(text.find(expected), std::string::npos) << expected << "\n" << text;
  }
  EXPECT_EQ(text, opts.usage());
}

TEST(Options, ValuesAsTextIsSortedAndComplete) {
  Options opts = offline_options();
  std::ostringstream help;
  ASSERT_EQ(opts.parse({"run1", "--vff-c=0.1", "--freeze"}, help), ParseResult::kRun);
  EXPECT_EQ(opts.values_as_text(), (std::vector<std::string>{"dataset=run1", "freeze=true", "on-bad-row=fail",
                                                             "out=", "vff-c=0.1", "window=100"}));
  // Numbers are normalised, so equal configurations give equal text.
  Options other = offline_options();
  ASSERT_EQ(other.parse({"run1", "--vff-c=1.0e-1", "--freeze=yes"}, help), ParseResult::kRun);
  EXPECT_EQ(other.values_as_text(), opts.values_as_text());
}

TEST(Options, ProgrammingErrorsAreLogicErrors) {
  Options opts("odonav-x", "x");
  opts.add_int("n", 1, "n", 0, 10);
  EXPECT_THROW(opts.add_int("n", 1, "again"), std::logic_error);
  EXPECT_THROW(opts.add_double("bad name", 1.0, "x"), std::logic_error);
  EXPECT_THROW(opts.add_double("help", 1.0, "x"), std::logic_error);
  EXPECT_THROW(opts.add_double("d", 11.0, "x", 0.0, 10.0), std::logic_error);
  EXPECT_THROW(opts.add_choice("c", "maybe", {"yes", "no"}, "x"), std::logic_error);
  EXPECT_THROW(opts.get_double("n"), std::logic_error);
  EXPECT_THROW(opts.get_int("absent"), std::logic_error);
}

TEST(Options, ArgvOverload) {
  Options opts = offline_options();
  const char* argv[] = {"odonav-offline", "--window", "42", "dir"};
  std::ostringstream help;
  ASSERT_EQ(opts.parse(4, argv, help), ParseResult::kRun);
  EXPECT_EQ(opts.get_int("window"), 42);
  EXPECT_EQ(opts.get_string("dataset"), "dir");
}

namespace {

// A tool with subcommands, as odonav-ground declares them.
Options ground_like_options() {
  Options opts("odonav-ground", "The ground station.");
  opts.add_int("domain", 0, "DDS domain", 0, 232);
  Options& monitor = opts.add_subcommand("monitor", "live dashboard");
  monitor.add_bool("once", false, "one snapshot");
  monitor.add_double("settle-s", 2.0, "listen this long (s)", 0.0, 3600.0);
  Options& serve = opts.add_subcommand("serve", "fleet page");
  serve.add_int("port", 8765, "TCP port", 0, 65535);
  Options& command = opts.add_subcommand("command", "operator command");
  command.add_positional("command", "reset | set-k");
  command.add_positional("value", "K", false);
  command.add_string("vehicle", "", "the vehicle");
  return opts;
}

std::string ground_error(const std::vector<std::string>& args) { return error_of(ground_like_options(), args); }

}  // namespace

TEST(Options, SubcommandWithSharedOptionsBeforeOrAfterItsName) {
  for (const auto& args : {std::vector<std::string>{"monitor", "--once", "--domain", "7", "--settle-s=3"},
                           std::vector<std::string>{"--domain=7", "monitor", "--settle-s", "3", "--once"}}) {
    Options opts = ground_like_options();
    std::ostringstream help;
    ASSERT_EQ(opts.parse(args, help), ParseResult::kRun);
    ASSERT_NE(opts.subcommand(), nullptr);
    const Options& monitor = *opts.subcommand();
    EXPECT_EQ(monitor.name(), "monitor");
    EXPECT_TRUE(monitor.get_bool("once"));
    EXPECT_EQ(monitor.get_double("settle-s"), 3.0);
    EXPECT_EQ(monitor.get_int("domain"), 7);  // the tool's option, read through the subcommand
    EXPECT_TRUE(monitor.was_set("domain"));
    EXPECT_EQ(opts.get_int("domain"), 7);
  }
  Options opts = ground_like_options();
  std::ostringstream help;
  ASSERT_EQ(opts.parse({"command", "--vehicle", "v1", "set-k", "0.42"}, help), ParseResult::kRun);
  EXPECT_EQ(opts.subcommand()->get_string("command"), "set-k");
  EXPECT_EQ(opts.subcommand()->get_string("value"), "0.42");
  EXPECT_EQ(opts.subcommand()->get_string("vehicle"), "v1");
}

TEST(Options, SubcommandErrorsNameTheNewSpelling) {
  EXPECT_EQ(ground_error({"--domain=3"}), "missing the subcommand: monitor, serve, command");
  // A subcommand's flag before the subcommand (a tool with one flat option list took that).
  EXPECT_EQ(ground_error({"--once", "monitor"}),
            "--once is an option of 'odonav-ground monitor': write odonav-ground monitor ... --once");
  EXPECT_EQ(ground_error({"monitor", "--port=80"}),
            "--port is an option of 'odonav-ground serve', not of 'odonav-ground monitor'");
  EXPECT_EQ(ground_error({"--vehicle=v1", "command", "reset"}),
            "--vehicle is an option of 'odonav-ground command': write odonav-ground command ... --vehicle");
  EXPECT_EQ(ground_error({"monitor", "serve"}), "unexpected argument 'serve'");
  EXPECT_EQ(ground_error({"monitor", "--settle-s=-1"}), "--settle-s=-1: must be in [0, 3600]");
  EXPECT_EQ(ground_error({"command", "--vehicle", "v1"}), "missing required argument <command> (reset | set-k)");
  ScratchDir dir;
  dir.write("g.conf", "domain = 4\nport = 80\n");
  EXPECT_EQ(ground_error({"monitor", "--config", dir.file("g.conf")}),
            dir.file("g.conf") + ":2: 'port' is an option of 'odonav-ground serve', not of 'odonav-ground monitor'");
  Options opts = ground_like_options();
  std::ostringstream help;
  ASSERT_EQ(opts.parse({"serve", "--config", dir.file("g.conf")}, help), ParseResult::kRun);
  EXPECT_EQ(opts.subcommand()->get_int("port"), 80);
  EXPECT_EQ(opts.get_int("domain"), 4);
}

TEST(Options, SubcommandHelp) {
  Options tool = ground_like_options();
  std::ostringstream help;
  ASSERT_EQ(tool.parse({"--help"}, help), ParseResult::kHelp);
  EXPECT_EQ(help.str().rfind("Usage: odonav-ground <subcommand> [options]\n", 0), 0u) << help.str();
  for (const char* expected : {"monitor", "live dashboard", "serve", "fleet page", "--domain <integer>"}) {
    EXPECT_NE(help.str().find(expected), std::string::npos) << expected << "\n" << help.str();
  }
  EXPECT_EQ(help.str().find("--settle-s"), std::string::npos) << help.str();

  Options sub = ground_like_options();
  std::ostringstream sub_help;
  ASSERT_EQ(sub.parse({"monitor", "--settle-s=bad", "-h"}, sub_help), ParseResult::kHelp);
  EXPECT_EQ(sub_help.str().rfind("Usage: odonav-ground monitor [options]\n", 0), 0u) << sub_help.str();
  for (const char* expected : {"--settle-s <number>", "--[no-]once", "--domain <integer>"}) {
    EXPECT_NE(sub_help.str().find(expected), std::string::npos) << expected << "\n" << sub_help.str();
  }
}

TEST(Options, RenamedFlagIsRefusedNamingTheNewOne) {
  const auto error = [](const std::vector<std::string>& args) {
    Options opts = offline_options();
    opts.add_double("id-min-speed", 0.5, "identification gate (m/s)", 0.0, 100.0);
    opts.add_renamed("min-speed", "id-min-speed");
    opts.add_bool("id-braking-stop", false, "braking stop");
    opts.add_renamed("braking-stop", "id-braking-stop");
    std::ostringstream help;
    try {
      opts.parse(args, help);
      EXPECT_EQ(opts.get_double("id-min-speed"), 2.0);
    } catch (const ConfigError& e) {
      EXPECT_EQ(opts.usage().find("--min-speed"), std::string::npos);
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_EQ(error({"run", "--id-min-speed=2"}), "");
  EXPECT_EQ(error({"run", "--min-speed=2"}), "--min-speed was renamed --id-min-speed");
  EXPECT_EQ(error({"run", "--min-speed", "2"}), "--min-speed was renamed --id-min-speed");
  EXPECT_EQ(error({"run", "--braking-stop", "--id-min-speed=2"}), "--braking-stop was renamed --id-braking-stop");
  EXPECT_EQ(error({"run", "--no-braking-stop"}), "--no-braking-stop was renamed --no-id-braking-stop");
  EXPECT_EQ(config_file_error(error, "run", "min-speed = 2\n"),
            "<file>:1: min-speed = 2: --min-speed was renamed --id-min-speed");
}

TEST(Options, CommandLineSplittingEdgeCases) {
  // A negative number is a positional value or an option's value; a word after a value option is its value.
  Options opts = offline_options();
  std::ostringstream help;
  ASSERT_EQ(opts.parse({"--vff-c", "-0e3", "-3", "--out", "-x"}, help), ParseResult::kRun);
  EXPECT_EQ(opts.get_double("vff-c"), 0.0);
  EXPECT_EQ(opts.get_string("dataset"), "-3");
  EXPECT_EQ(opts.get_string("out"), "-x");
  EXPECT_EQ(parse_error({"run", "--vff-c=-0.5"}), "--vff-c=-0.5: must be in [0, 1e6]");
  // The last of --freeze / --no-freeze wins; a value with '=' and commas stays whole.
  Options last = offline_options();
  ASSERT_EQ(last.parse({"run", "--freeze", "--no-freeze", "--out=a=b,c d"}, help), ParseResult::kRun);
  EXPECT_FALSE(last.get_bool("freeze"));
  EXPECT_EQ(last.get_string("out"), "a=b,c d");
  EXPECT_EQ(parse_error({"run", "--config="}), "option '--config' needs a value");
  EXPECT_EQ(parse_error({"run", "--help-me"}), "unknown option '--help-me'");
  EXPECT_EQ(parse_error({"run", "--", "--window=3"}), "unexpected argument '--window=3'");
}
