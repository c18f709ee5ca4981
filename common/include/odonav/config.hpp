#pragma once
// Command-line flags and an optional `key = value` configuration file for odonav tools.
//
//   odonav::Options opts("odonav-offline", "Runs calibration, identification and DR over a dataset.");
//   opts.add_positional("dataset", "dataset directory");
//   opts.add_double("vff-c", 4.0, "VFF residual scale", 0.0, 1e6);
//   if (opts.parse(argc, argv, odonav::tool_output()) == odonav::ParseResult::kHelp) return 0;
//   double c = opts.get_double("vff-c");
//
// Syntax: `--name=value` or `--name value`; a bool option is `--name`, `--name=true|false` or
// `--no-name`. `--config FILE` reads `name = value` lines (`#` starts a comment line, blank lines
// are skipped); a flag given on the command line wins over the file whatever their order. A flag
// repeated on the command line takes its last value; a key repeated in the file is an error.
// `--` ends the options (what follows is positional). `--help` / `-h` prints the usage.
// Numbers are parsed strictly and independently of the locale ("12abc", "1,5", "nan" are errors).
// The command line is split by CLI11 (Debian's libcli11-dev); the values, their ranges and the
// config file are checked here, so every error names the flag, or the file:line and key.
#include <cstdint>
#include <iosfwd>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace odonav {

/// A user error in flags, a config file or a configuration value. what() names the flag or key,
/// and for a file its file:line.
class ConfigError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// What Options::parse found: run with the values, or the usage was printed and the tool should exit 0.
enum class ParseResult { kRun, kHelp };

/// The options of one tool: declared first (add_*), then parsed once, then read (get_*).
/// Declaring an invalid or duplicate name, or reading an undeclared one or with the wrong type, is
/// a programming error: std::logic_error.
class Options {
 public:
  /// program: the tool name shown in the usage; description: one paragraph shown under it.
  Options(std::string program, std::string description);
  ~Options();
  Options(Options&&) noexcept;
  Options& operator=(Options&&) noexcept;

  /// A positional argument, in declaration order. Required unless `required` is false (optional
  /// positionals must come after required ones). Read with get_string(name).
  void add_positional(const std::string& name, const std::string& help, bool required = true);
  /// A text option. Names: lower case letters, digits and '-', starting with a letter.
  void add_string(const std::string& name, const std::string& default_value, const std::string& help);
  /// A real-valued option, valid in [min_value, max_value] inclusive (checked for the default too).
  void add_double(const std::string& name, double default_value, const std::string& help,
                  double min_value = -std::numeric_limits<double>::max(),
                  double max_value = std::numeric_limits<double>::max());
  /// An integer option, valid in [min_value, max_value] inclusive.
  void add_int(const std::string& name, int64_t default_value, const std::string& help,
               int64_t min_value = std::numeric_limits<int64_t>::min(),
               int64_t max_value = std::numeric_limits<int64_t>::max());
  /// A boolean switch: `--name`, `--no-name`, `--name=true|false` (also 1|0, yes|no, on|off).
  void add_bool(const std::string& name, bool default_value, const std::string& help);
  /// A text option restricted to `choices` (the default must be one). Read with get_string.
  void add_choice(const std::string& name, const std::string& default_value, const std::vector<std::string>& choices,
                  const std::string& help);
  /// A flag that was renamed: giving `--old_name` (or `old_name` in a config file) is an error
  /// naming `new_name`. Not shown in the usage.
  void add_renamed(const std::string& old_name, const std::string& new_name);

  /// A subcommand (`program name [its options]`), e.g. odonav-ground's `monitor`. Declare its
  /// options on the returned object (valid as long as this one); the options declared here are
  /// shared: accepted before or after the subcommand's name, and read through the subcommand's
  /// object too. When a tool has subcommands, exactly one must be given.
  Options& add_subcommand(const std::string& name, const std::string& description);
  /// After parse(): the subcommand given (its object), or nullptr when the tool has none.
  const Options* subcommand() const;
  /// The subcommand's name ("" for the tool itself).
  const std::string& name() const;

  /// Parses argv[1..argc-1]. Prints the usage to `help_out` and returns kHelp on --help/-h.
  /// Throws ConfigError on any user error. May be called once.
  ParseResult parse(int argc, const char* const* argv, std::ostream& help_out);
  /// Same, usage to standard output (for a tool's own main()).
  ParseResult parse(int argc, const char* const* argv);
  /// Same, for arguments without the program name (tests, embedding).
  ParseResult parse(const std::vector<std::string>& args, std::ostream& help_out);

  std::string get_string(const std::string& name) const;  ///< string, choice or positional
  double get_double(const std::string& name) const;
  int64_t get_int(const std::string& name) const;
  bool get_bool(const std::string& name) const;

  /// True when the user gave `name` on the command line or in the config file.
  bool was_set(const std::string& name) const;
  /// True when an option or positional `name` has been declared (a shared option that several
  /// add_* functions of one tool declare, declared once).
  bool declared(const std::string& name) const;
  /// Every option and positional as "name=value", sorted by name: a stable text of the whole
  /// configuration (doubles in shortest round-trip form), e.g. to hash it.
  std::vector<std::string> values_as_text() const;
  /// The usage text: every option with its type, default, range or choices, and help.
  std::string usage() const;
  const std::string& program() const;

 private:
  struct Impl;
  explicit Options(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace odonav
