// Command-line flags and `key = value` config files (see odonav/config.hpp).
#include "odonav/config.hpp"
#include "odonav/tool_output.hpp"

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>

#include "text_util.hpp"

namespace odonav {

using io_detail::format_double;
using io_detail::format_number;
using io_detail::NumberStatus;
using io_detail::printable_excerpt;
using io_detail::trim;

namespace {

bool valid_name(const std::string& name) {
  if (name.empty() || name.front() < 'a' || name.front() > 'z') return false;
  return std::all_of(name.begin(), name.end(),
                     [](char c) { return (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '-' || c == '_'; });
}

// The flags parse() handles itself, never declared by a tool.
bool reserved(const std::string& name) { return name == "help" || name == "config"; }

std::string int_text(int64_t v) { return std::to_string(v); }

bool full_double_range(double lo, double hi) {
  return lo == -std::numeric_limits<double>::max() && hi == std::numeric_limits<double>::max();
}
bool full_int_range(int64_t lo, int64_t hi) {
  return lo == std::numeric_limits<int64_t>::min() && hi == std::numeric_limits<int64_t>::max();
}

}  // namespace

Options::Options(std::string program, std::string description)
    : program_(std::move(program)), description_(std::move(description)) {}

Options::Option& Options::declare(const std::string& name, Type type, const std::string& help) {
  if (parsed_) throw std::logic_error("Options: '" + name + "' declared after parse()");
  if (!valid_name(name) || reserved(name)) throw std::logic_error("Options: invalid option name '" + name + "'");
  for (const Option& o : options_) {
    if (o.name == name) throw std::logic_error("Options: '" + name + "' declared twice");
    // A bool "x" owns "--no-x"; a separate option named "no-x" would be ambiguous.
    if ((o.type == Type::kBool && name == "no-" + o.name) || (type == Type::kBool && o.name == "no-" + name)) {
      throw std::logic_error("Options: '" + name + "' clashes with the negated form of a bool option");
    }
  }
  Option o;
  o.name = name;
  o.type = type;
  o.help = help;
  options_.push_back(o);
  return options_.back();
}

void Options::add_positional(const std::string& name, const std::string& help, bool required) {
  if (required) {
    for (const Option& o : options_) {
      if (o.type == Type::kPositional && !o.required) {
        throw std::logic_error("Options: required positional '" + name + "' after an optional one");
      }
    }
  }
  Option& o = declare(name, Type::kPositional, help);
  o.required = required;
}

void Options::add_string(const std::string& name, const std::string& default_value, const std::string& help) {
  Option& o = declare(name, Type::kString, help);
  o.text = o.default_text = default_value;
}

void Options::add_double(const std::string& name, double default_value, const std::string& help, double min_value,
                         double max_value) {
  if (!(min_value <= default_value && default_value <= max_value)) {
    throw std::logic_error("Options: default of '" + name + "' outside its range");
  }
  Option& o = declare(name, Type::kDouble, help);
  o.double_value = o.default_double = default_value;
  o.min_double = min_value;
  o.max_double = max_value;
  o.text = o.default_text = format_double(default_value);
}

void Options::add_int(const std::string& name, int64_t default_value, const std::string& help, int64_t min_value,
                      int64_t max_value) {
  if (!(min_value <= default_value && default_value <= max_value)) {
    throw std::logic_error("Options: default of '" + name + "' outside its range");
  }
  Option& o = declare(name, Type::kInt, help);
  o.int_value = default_value;
  o.min_int = min_value;
  o.max_int = max_value;
  o.text = o.default_text = int_text(default_value);
}

void Options::add_bool(const std::string& name, bool default_value, const std::string& help) {
  Option& o = declare(name, Type::kBool, help);
  o.bool_value = default_value;
  o.text = o.default_text = default_value ? "true" : "false";
}

void Options::add_choice(const std::string& name, const std::string& default_value,
                         const std::vector<std::string>& choices, const std::string& help) {
  if (std::find(choices.begin(), choices.end(), default_value) == choices.end()) {
    throw std::logic_error("Options: default of '" + name + "' is not one of its choices");
  }
  Option& o = declare(name, Type::kChoice, help);
  o.choices = choices;
  o.text = o.default_text = default_value;
}

Options::Option* Options::find_option(const std::string& name) {
  for (Option& o : options_) {
    if (o.name == name && o.type != Type::kPositional) return &o;
  }
  return nullptr;
}

const Options::Option& Options::find(const std::string& name, std::initializer_list<Type> allowed) const {
  for (const Option& o : options_) {
    if (o.name != name) continue;
    if (std::find(allowed.begin(), allowed.end(), o.type) == allowed.end()) {
      throw std::logic_error("Options: '" + name + "' read with the wrong type");
    }
    return o;
  }
  throw std::logic_error("Options: '" + name + "' was never declared");
}

// Converts and checks one value; the error prefix `where` says where it came from.
void Options::assign(Option& o, const Assignment& a) {
  const std::string value(trim(a.value));
  const auto error = [&](const std::string& what) { return ConfigError(a.where + ": " + what); };
  switch (o.type) {
    case Type::kString:
    case Type::kPositional: o.text = a.value; break;
    case Type::kChoice:
      if (std::find(o.choices.begin(), o.choices.end(), value) == o.choices.end()) {
        throw error("must be one of " + io_detail::join(o.choices));
      }
      o.text = value;
      break;
    case Type::kBool:
      if (value == "true" || value == "1" || value == "yes" || value == "on")
        o.bool_value = true;
      else if (value == "false" || value == "0" || value == "no" || value == "off")
        o.bool_value = false;
      else
        throw error("must be true or false");
      o.text = o.bool_value ? "true" : "false";
      break;
    case Type::kDouble: {
      double v = 0.0;
      switch (io_detail::parse_double(value, v)) {
        case NumberStatus::kOk: break;
        case NumberStatus::kEmpty: throw error("missing value");
        case NumberStatus::kNotFinite: throw error("not a finite number");
        case NumberStatus::kOutOfRange: throw error("number out of range of a double");
        case NumberStatus::kNotNumber: throw error("not a number");
      }
      if (v < o.min_double || v > o.max_double) {
        throw error("must be in [" + format_number(o.min_double) + ", " + format_number(o.max_double) + "]");
      }
      o.double_value = v;
      o.text = format_double(v);
      break;
    }
    case Type::kInt: {
      int64_t v = 0;
      const NumberStatus status = io_detail::parse_int64(value, v);
      if (status == NumberStatus::kEmpty) throw error("missing value");
      if (status == NumberStatus::kNotNumber) throw error("not an integer");
      if (status != NumberStatus::kOk || v < o.min_int || v > o.max_int) {
        throw error("must be in [" + int_text(o.min_int) + ", " + int_text(o.max_int) + "]");
      }
      o.int_value = v;
      o.text = int_text(v);
      break;
    }
  }
  o.set = true;
}

void Options::load_config_file(const std::string& path, std::map<std::string, Assignment>& from_file) {
  // Only a regular file of bounded size: a FIFO or /dev/zero would block or grow without end.
  constexpr std::uintmax_t kMaxConfigBytes = 1 << 20;
  std::error_code ec;
  const std::filesystem::file_status st = std::filesystem::status(path, ec);
  if (std::filesystem::is_directory(st)) throw ConfigError("config file '" + path + "' is a directory");
  if (std::filesystem::exists(st) && !std::filesystem::is_regular_file(st))
    throw ConfigError("config file '" + path + "' is not a regular file (a FIFO, socket or device)");
  if (std::filesystem::exists(st) && std::filesystem::file_size(path, ec) > kMaxConfigBytes)
    throw ConfigError("config file '" + path + "' is larger than " + std::to_string(kMaxConfigBytes) + " bytes");
  std::ifstream in(path);
  if (!in) throw ConfigError("cannot read config file '" + path + "': " + std::strerror(errno));
  std::map<std::string, std::size_t> first_line;
  std::string raw;
  std::size_t line_no = 0;
  while (std::getline(in, raw)) {
    ++line_no;
    if (!raw.empty() && raw.back() == '\r') raw.pop_back();
    const std::string_view line = trim(raw);
    if (line.empty() || line.front() == '#') continue;
    const std::string at = path + ":" + std::to_string(line_no);
    const std::size_t eq = line.find('=');
    if (eq == std::string_view::npos) {
      throw ConfigError(at + ": expected 'key = value', got '" + printable_excerpt(line) + "'");
    }
    const std::string key(trim(line.substr(0, eq)));
    const std::string value(trim(line.substr(eq + 1)));
    if (key == "config") throw ConfigError(at + ": 'config' cannot be set in a config file");
    Option* o = find_option(key);
    if (!o) {
      const bool positional =
          std::any_of(options_.begin(), options_.end(), [&](const Option& p) { return p.name == key; });
      throw ConfigError(at + ": " +
                        (positional ? "'" + key + "' is a positional argument, give it on the command line"
                                    : "unknown key '" + key + "'"));
    }
    if (const auto it = first_line.find(key); it != first_line.end()) {
      throw ConfigError(at + ": duplicate key '" + key + "' (first at line " + std::to_string(it->second) + ")");
    }
    first_line[key] = line_no;
    from_file[key] = Assignment{value, at + ": " + key + " = " + value, true};
  }
  if (in.bad()) throw ConfigError("cannot read config file '" + path + "': read error");
}

ParseResult Options::parse(int argc, const char* const* argv, std::ostream& help_out) {
  std::vector<std::string> args;
  for (int i = 1; i < argc; ++i) args.emplace_back(argv[i]);
  return parse(args, help_out);
}

ParseResult Options::parse(int argc, const char* const* argv) { return parse(argc, argv, tool_output()); }

ParseResult Options::parse(const std::vector<std::string>& args, std::ostream& help_out) {
  if (parsed_) throw std::logic_error("Options: parse() called twice");
  parsed_ = true;
  // --help wins over everything else on the line, even over errors.
  for (const std::string& a : args) {
    if (a == "--") break;
    if (a == "--help" || a == "-h") {
      help_out << usage();
      return ParseResult::kHelp;
    }
  }

  std::map<std::string, Assignment> from_command_line;  // last one wins
  std::vector<std::string> positionals;
  std::string config_path;
  bool have_config = false;
  bool only_positionals = false;
  for (std::size_t i = 0; i < args.size(); ++i) {
    const std::string& arg = args[i];
    if (only_positionals || arg.size() < 2 || arg[0] != '-') {
      positionals.push_back(arg);
      continue;
    }
    if (arg == "--") {
      only_positionals = true;
      continue;
    }
    if (arg.rfind("--", 0) != 0) {
      // A single dash: a negative number is a positional value, anything else a mistyped flag.
      double number = 0.0;
      if (io_detail::parse_double(arg, number) == NumberStatus::kOk) {
        positionals.push_back(arg);
        continue;
      }
      throw ConfigError("unknown option '" + arg + "' (options are written --name)");
    }
    const std::size_t eq = arg.find('=');
    const std::string name = arg.substr(2, eq == std::string::npos ? std::string::npos : eq - 2);
    const bool inline_value = eq != std::string::npos;
    std::string value = inline_value ? arg.substr(eq + 1) : "";

    Option* o = find_option(name);
    if (name == "config") {
      if (have_config) throw ConfigError("--config given more than once");
    } else if (!o) {
      // --no-name for a bool option
      Option* negated = name.rfind("no-", 0) == 0 ? find_option(name.substr(3)) : nullptr;
      if (negated && negated->type == Type::kBool) {
        if (inline_value) throw ConfigError("--" + name + " takes no value");
        from_command_line[negated->name] = Assignment{"false", "--" + name, false};
        continue;
      }
      throw ConfigError("unknown option '--" + name + "'");
    }
    if (!inline_value) {
      if (o && o->type == Type::kBool) {
        from_command_line[name] = Assignment{"true", "--" + name, false};
        continue;
      }
      if (i + 1 >= args.size() || args[i + 1].rfind("--", 0) == 0) {
        throw ConfigError("option '--" + name + "' needs a value");
      }
      value = args[++i];
    }
    if (name == "config") {
      if (value.empty()) throw ConfigError("option '--config' needs a value");
      config_path = value;
      have_config = true;
      continue;
    }
    from_command_line[name] = Assignment{value, "--" + name + "=" + value, false};
  }

  // The file first, the command line over it.
  if (have_config) {
    std::map<std::string, Assignment> from_file;
    load_config_file(config_path, from_file);
    for (const auto& [name, a] : from_file) assign(*find_option(name), a);
  }
  for (const auto& [name, a] : from_command_line) assign(*find_option(name), a);

  std::size_t next = 0;
  for (Option& o : options_) {
    if (o.type != Type::kPositional) continue;
    if (next < positionals.size()) {
      assign(o, Assignment{positionals[next], "<" + o.name + ">", false});
      ++next;
    } else if (o.required) {
      throw ConfigError("missing required argument <" + o.name + "> (" + o.help + ")");
    }
  }
  if (next < positionals.size()) throw ConfigError("unexpected argument '" + positionals[next] + "'");
  return ParseResult::kRun;
}

std::string Options::get_string(const std::string& name) const {
  return find(name, {Type::kString, Type::kChoice, Type::kPositional}).text;
}
double Options::get_double(const std::string& name) const { return find(name, {Type::kDouble}).double_value; }
int64_t Options::get_int(const std::string& name) const { return find(name, {Type::kInt}).int_value; }
bool Options::get_bool(const std::string& name) const { return find(name, {Type::kBool}).bool_value; }

bool Options::was_set(const std::string& name) const {
  return find(name, {Type::kString, Type::kDouble, Type::kInt, Type::kBool, Type::kChoice, Type::kPositional}).set;
}

bool Options::declared(const std::string& name) const {
  for (const Option& o : options_)
    if (o.name == name) return true;
  return false;
}

std::vector<std::string> Options::values_as_text() const {
  std::vector<std::string> lines;
  for (const Option& o : options_) lines.push_back(o.name + "=" + o.text);
  std::sort(lines.begin(), lines.end());
  return lines;
}

std::string Options::usage() const {
  struct Row {
    std::string left, right;
  };
  std::vector<Row> arguments, flags;
  std::string synopsis = "Usage: " + program_ + " [options]";
  for (const Option& o : options_) {
    if (o.type == Type::kPositional) {
      synopsis += o.required ? " <" + o.name + ">" : " [<" + o.name + ">]";
      arguments.push_back({"<" + o.name + ">", o.help + (o.required ? "" : " (optional)")});
      continue;
    }
    std::string left, details;
    switch (o.type) {
      case Type::kString:
        left = "--" + o.name + " <string>";
        details = "default: \"" + o.default_text + "\"";
        break;
      case Type::kDouble:
        left = "--" + o.name + " <number>";
        details = "default: " + format_number(o.default_double);
        if (!full_double_range(o.min_double, o.max_double)) {
          details += ", range: [" + format_number(o.min_double) + ", " + format_number(o.max_double) + "]";
        }
        break;
      case Type::kInt:
        left = "--" + o.name + " <integer>";
        details = "default: " + o.default_text;
        if (!full_int_range(o.min_int, o.max_int)) {
          details += ", range: [" + int_text(o.min_int) + ", " + int_text(o.max_int) + "]";
        }
        break;
      case Type::kBool:
        left = "--[no-]" + o.name;
        details = "default: " + o.default_text;
        break;
      case Type::kChoice:
        left = "--" + o.name + " <choice>";
        details = "default: " + o.default_text + ", choices: " + io_detail::join(o.choices);
        break;
      case Type::kPositional: break;
    }
    flags.push_back({left, o.help + " (" + details + ")"});
  }
  flags.push_back({"--config <file>", "read 'name = value' lines from a file; command-line flags win"});
  flags.push_back({"--help, -h", "print this help and exit"});

  std::size_t width = 0;
  for (const auto* rows : {&arguments, &flags}) {
    for (const Row& r : *rows) width = std::max(width, r.left.size());
  }
  std::ostringstream out;
  out << synopsis << "\n\n" << description_ << "\n";
  const auto print = [&](const char* title, const std::vector<Row>& rows) {
    if (rows.empty()) return;
    out << "\n" << title << ":\n";
    for (const Row& r : rows) out << "  " << r.left << std::string(width + 2 - r.left.size(), ' ') << r.right << "\n";
  };
  print("Arguments", arguments);
  print("Options", flags);
  return out.str();
}

}  // namespace odonav
