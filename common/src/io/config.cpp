// Command-line flags and `key = value` config files (see odonav/config.hpp), on CLI11.
//
// CLI11 splits the command line: flag names, `--name=value` / `--name value`, `--no-name`, `--`,
// positionals, subcommands. Checked here, because CLI11 does it otherwise: the values (strict,
// locale-independent numbers; CLI11 reads "nan" and uses strtod), their ranges (errors naming the
// flag and its range), a value that is missing (CLI11 takes the next word, even a flag, and reads
// `--name=` as `--name`), --help winning over every error, and the config file (CLI11's reader
// names no line, ignores the file's value of a flag given on the command line without checking
// it, and would block on a FIFO).
#include "odonav/config.hpp"
#include "odonav/tool_output.hpp"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <sstream>

#include "text_util.hpp"

namespace odonav {

using io_detail::format_double;
using io_detail::format_number;
using io_detail::NumberStatus;
using io_detail::printable_excerpt;
using io_detail::trim;

namespace {

enum class Type { kString, kDouble, kInt, kBool, kChoice, kPositional, kRenamed };

struct Option {
  std::string name;
  Type type = Type::kString;
  std::string help;
  std::string text;  // the value as text: default, then as given (normalised for numbers)
  double double_value = 0.0;
  int64_t int_value = 0;
  bool bool_value = false;
  double default_double = 0.0;
  double min_double = 0.0, max_double = 0.0;
  int64_t min_int = 0, max_int = 0;
  std::vector<std::string> choices;  // kChoice; kRenamed: the new name
  std::string default_text;
  bool required = false;  // positionals only
  bool set = false;
  CLI::Option* cli = nullptr;
};

// A value and where it came from: "--name=value", "<name>" or "file:line: name = value", the
// prefix of any error about it.
struct Assignment {
  std::string value;
  std::string where;
};

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

std::string renamed_message(const std::string& old_name, const std::string& new_name) {
  return "--" + old_name + " was renamed --" + new_name;
}

// Converts and checks one value.
void assign(Option& o, const Assignment& a) {
  const std::string value(trim(a.value));
  const auto error = [&](const std::string& what) { return ConfigError(a.where + ": " + what); };
  switch (o.type) {
    case Type::kString:
    case Type::kPositional: o.text = a.value; break;
    case Type::kRenamed: throw error(renamed_message(o.name, o.choices.front()));
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

}  // namespace

struct Options::Impl {
  std::string program;  // "odonav-ground", or for a subcommand "odonav-ground monitor"
  std::string name;     // the subcommand's name; empty for the tool
  std::string description;
  std::unique_ptr<CLI::App> owned_app;  // the tool's; a subcommand's App is owned by its parent's
  CLI::App* app = nullptr;
  CLI::Option* config = nullptr;  // --config (the tool only)
  Impl* parent = nullptr;
  std::vector<Option> options;  // declaration order (for the usage); positionals among them
  std::vector<std::unique_ptr<Options>> subcommands;
  const Options* chosen = nullptr;  // the subcommand given
  bool parsed = false;

  // The option `name` (not a positional) here or, for a subcommand, in the tool.
  Option* find_option(const std::string& name) {
    for (Option& o : options)
      if (o.name == name && o.type != Type::kPositional) return &o;
    return parent ? parent->find_option(name) : nullptr;
  }
  const Option* find_option(const std::string& name) const { return const_cast<Impl*>(this)->find_option(name); }
  const Option* find_any(const std::string& name) const {
    for (const Option& o : options)
      if (o.name == name) return &o;
    return parent ? parent->find_any(name) : nullptr;
  }
  // The subcommand that declares option `name`, if any.
  const Impl* subcommand_declaring(const std::string& name) const {
    for (const auto& s : subcommands)
      for (const Option& o : s->impl_->options)
        if (o.name == name && o.type != Type::kPositional) return s->impl_.get();
    return nullptr;
  }
  const Impl* subcommand_named(const std::string& word) const {
    for (const auto& s : subcommands)
      if (s->impl_->name == word) return s->impl_.get();
    return nullptr;
  }
  std::string subcommand_names() const {
    std::vector<std::string> names;
    for (const auto& s : subcommands) names.push_back(s->impl_->name);
    return io_detail::join(names);
  }

  Option& declare(const std::string& name, Type type, const std::string& help);
  const Option& find(const std::string& name, std::initializer_list<Type> allowed) const;
  void check_values_present(const std::vector<std::string>& args) const;
  std::string unknown_argument_message(const std::string& arg, const Impl* scope) const;
  std::map<std::string, Assignment> load_config_file(const std::string& path, Impl& scope) const;
};

Options::Options(std::string program, std::string description) : impl_(std::make_unique<Impl>()) {
  impl_->program = std::move(program);
  impl_->description = std::move(description);
  impl_->owned_app = std::make_unique<CLI::App>(impl_->description, impl_->program);
  impl_->app = impl_->owned_app.get();
  // --help is answered before CLI11 parses (it wins over every error); unknown words are ours to
  // report (see Impl::unknown_argument_message).
  impl_->app->set_help_flag();
  impl_->app->allow_extras();
  impl_->config = impl_->app->add_option("--config", "read 'name = value' lines from a file; command-line flags win");
  impl_->config->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
}

Options::Options(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Options::~Options() = default;
Options::Options(Options&&) noexcept = default;
Options& Options::operator=(Options&&) noexcept = default;

Option& Options::Impl::declare(const std::string& name, Type type, const std::string& help) {
  if (parsed) throw std::logic_error("Options: '" + name + "' declared after parse()");
  if (!valid_name(name) || reserved(name)) throw std::logic_error("Options: invalid option name '" + name + "'");
  const auto clash = [&](const Impl& scope) {
    for (const Option& o : scope.options) {
      if (o.name == name) throw std::logic_error("Options: '" + name + "' declared twice");
      // A bool "x" owns "--no-x"; a separate option named "no-x" would be ambiguous.
      if ((o.type == Type::kBool && name == "no-" + o.name) || (type == Type::kBool && o.name == "no-" + name)) {
        throw std::logic_error("Options: '" + name + "' clashes with the negated form of a bool option");
      }
    }
  };
  clash(*this);
  if (parent) clash(*parent);
  for (const auto& s : subcommands) clash(*s->impl_);
  Option o;
  o.name = name;
  o.type = type;
  o.help = help;
  if (type == Type::kPositional) {
    o.cli = app->add_option(name, help);
  } else if (type == Type::kBool) {
    o.cli = app->add_flag("--" + name + ",!--no-" + name, help);
  } else {
    o.cli = app->add_option("--" + name, help);
  }
  o.cli->multi_option_policy(CLI::MultiOptionPolicy::TakeLast);
  if (type == Type::kRenamed) o.cli->group("");  // hidden
  options.push_back(o);
  return options.back();
}

void Options::add_positional(const std::string& name, const std::string& help, bool required) {
  if (required) {
    for (const Option& o : impl_->options) {
      if (o.type == Type::kPositional && !o.required) {
        throw std::logic_error("Options: required positional '" + name + "' after an optional one");
      }
    }
  }
  Option& o = impl_->declare(name, Type::kPositional, help);
  o.required = required;
}

void Options::add_string(const std::string& name, const std::string& default_value, const std::string& help) {
  Option& o = impl_->declare(name, Type::kString, help);
  o.text = o.default_text = default_value;
}

void Options::add_double(const std::string& name, double default_value, const std::string& help, double min_value,
                         double max_value) {
  if (!(min_value <= default_value && default_value <= max_value)) {
    throw std::logic_error("Options: default of '" + name + "' outside its range");
  }
  Option& o = impl_->declare(name, Type::kDouble, help);
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
  Option& o = impl_->declare(name, Type::kInt, help);
  o.int_value = default_value;
  o.min_int = min_value;
  o.max_int = max_value;
  o.text = o.default_text = int_text(default_value);
}

void Options::add_bool(const std::string& name, bool default_value, const std::string& help) {
  Option& o = impl_->declare(name, Type::kBool, help);
  o.bool_value = default_value;
  o.text = o.default_text = default_value ? "true" : "false";
}

void Options::add_choice(const std::string& name, const std::string& default_value,
                         const std::vector<std::string>& choices, const std::string& help) {
  if (std::find(choices.begin(), choices.end(), default_value) == choices.end()) {
    throw std::logic_error("Options: default of '" + name + "' is not one of its choices");
  }
  Option& o = impl_->declare(name, Type::kChoice, help);
  o.choices = choices;
  o.text = o.default_text = default_value;
}

void Options::add_renamed(const std::string& old_name, const std::string& new_name) {
  if (!impl_->find_any(new_name)) throw std::logic_error("Options: '" + old_name + "' renamed to an undeclared name");
  Option& o = impl_->declare(old_name, Type::kRenamed, "renamed --" + new_name);
  o.choices = {new_name};
}

Options& Options::add_subcommand(const std::string& name, const std::string& description) {
  if (impl_->parent) throw std::logic_error("Options: a subcommand of a subcommand");
  if (!valid_name(name) || impl_->subcommand_named(name)) {
    throw std::logic_error("Options: invalid or repeated subcommand '" + name + "'");
  }
  for (const Option& o : impl_->options) {
    if (o.type == Type::kPositional) throw std::logic_error("Options: subcommands and positionals of the tool");
  }
  auto sub = std::make_unique<Impl>();
  sub->program = impl_->program + " " + name;
  sub->name = name;
  sub->description = description;
  sub->app = impl_->app->add_subcommand(name, description);
  sub->app->set_help_flag();
  sub->app->allow_extras();
  sub->app->fallthrough();  // the tool's options after the subcommand's name
  sub->parent = impl_.get();
  impl_->app->require_subcommand(0, 1);  // one at most: a second subcommand name is an unexpected argument
  impl_->subcommands.push_back(std::unique_ptr<Options>(new Options(std::move(sub))));
  return *impl_->subcommands.back();
}

const Options* Options::subcommand() const { return impl_->chosen; }
const std::string& Options::name() const { return impl_->name; }
const std::string& Options::program() const { return impl_->program; }

const Option& Options::Impl::find(const std::string& name, std::initializer_list<Type> allowed) const {
  const Option* o = find_any(name);
  if (!o) throw std::logic_error("Options: '" + name + "' was never declared");
  if (std::find(allowed.begin(), allowed.end(), o->type) == allowed.end()) {
    throw std::logic_error("Options: '" + name + "' read with the wrong type");
  }
  return *o;
}

// A value option without its value: CLI11 would take the next word (even a flag) as the value,
// and read `--name=` as `--name` followed by the next word.
void Options::Impl::check_values_present(const std::vector<std::string>& args) const {
  const Impl* scope = this;
  for (std::size_t i = 0; i < args.size(); ++i) {
    const std::string& arg = args[i];
    if (arg == "--") return;
    if (arg.rfind("--", 0) != 0) {
      if (scope == this && subcommand_named(arg)) scope = subcommand_named(arg);
      continue;
    }
    const std::size_t eq = arg.find('=');
    const std::string name = arg.substr(2, eq == std::string::npos ? std::string::npos : eq - 2);
    const Option* o = scope->find_option(name);
    if (o && o->type == Type::kRenamed) throw ConfigError(renamed_message(name, o->choices.front()));
    if (name != "config" && !o) {
      const Option* negated = name.rfind("no-", 0) == 0 ? scope->find_option(name.substr(3)) : nullptr;
      if (negated && negated->type == Type::kRenamed) {
        throw ConfigError(renamed_message(name, "no-" + negated->choices.front()));
      }
      if (negated && negated->type == Type::kBool && eq != std::string::npos) {
        throw ConfigError("--" + name + " takes no value");
      }
      continue;
    }
    if (o && o->type == Type::kBool) continue;
    if (eq != std::string::npos) {
      if (eq + 1 == arg.size()) {
        throw ConfigError(name == "config" ? "option '--config' needs a value" : arg + ": missing value");
      }
      continue;
    }
    if (i + 1 >= args.size() || args[i + 1].rfind("--", 0) == 0) {
      throw ConfigError("option '--" + name + "' needs a value");
    }
    ++i;
  }
}

// The message for a word CLI11 left over: an unknown flag, a flag of another subcommand (the
// spelling of a tool with flat options), or a positional too many.
std::string Options::Impl::unknown_argument_message(const std::string& arg, const Impl* scope) const {
  if (arg.rfind("--", 0) == 0) {
    const std::string name = arg.substr(2, arg.find('=') == std::string::npos ? std::string::npos : arg.find('=') - 2);
    const auto declares = [&](const Impl& level) {
      return std::any_of(level.options.begin(), level.options.end(),
                         [&](const Option& o) { return o.name == name && o.type != Type::kPositional; });
    };
    // Given before the subcommand's name, or given to another subcommand.
    if (scope != this && declares(*scope)) {
      return "--" + name + " is an option of '" + scope->program + "': write " + scope->program + " ... --" + name;
    }
    if (const Impl* owner = subcommand_declaring(name)) {
      return "--" + name + " is an option of '" + owner->program + "'" +
             (scope == this ? ": write " + owner->program + " ... --" + name : ", not of '" + scope->program + "'");
    }
    return "unknown option '--" + name + "'";
  }
  double number = 0.0;
  if (arg.size() > 1 && arg[0] == '-' && io_detail::parse_double(arg, number) != NumberStatus::kOk) {
    return "unknown option '" + arg + "' (options are written --name)";
  }
  return "unexpected argument '" + arg + "'";
}

std::map<std::string, Assignment> Options::Impl::load_config_file(const std::string& path, Impl& scope) const {
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
  std::map<std::string, Assignment> from_file;
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
    if (!scope.find_option(key)) {
      const Impl* owner = subcommand_declaring(key);
      throw ConfigError(at + ": " +
                        (scope.find_any(key) ? "'" + key + "' is a positional argument, give it on the command line"
                         : owner
                             ? "'" + key + "' is an option of '" + owner->program + "', not of '" + scope.program + "'"
                             : "unknown key '" + key + "'"));
    }
    if (const auto it = first_line.find(key); it != first_line.end()) {
      throw ConfigError(at + ": duplicate key '" + key + "' (first at line " + std::to_string(it->second) + ")");
    }
    first_line[key] = line_no;
    from_file[key] = Assignment{value, at + ": " + key + " = " + value};
  }
  if (in.bad()) throw ConfigError("cannot read config file '" + path + "': read error");
  return from_file;
}

ParseResult Options::parse(int argc, const char* const* argv, std::ostream& help_out) {
  std::vector<std::string> args;
  for (int i = 1; i < argc; ++i) args.emplace_back(argv[i]);
  return parse(args, help_out);
}

ParseResult Options::parse(int argc, const char* const* argv) { return parse(argc, argv, tool_output()); }

ParseResult Options::parse(const std::vector<std::string>& args, std::ostream& help_out) {
  Impl& root = *impl_;
  if (root.parent) throw std::logic_error("Options: parse() of a subcommand");
  if (root.parsed) throw std::logic_error("Options: parse() called twice");
  root.parsed = true;
  for (auto& s : root.subcommands) s->impl_->parsed = true;
  // --help wins over everything else on the line, even over errors; after a subcommand's name it
  // is that subcommand's usage.
  const Options* help_of = this;
  for (const std::string& a : args) {
    if (a == "--") break;
    if (const Impl* s = root.subcommand_named(a); s && help_of == this) {
      for (const auto& sub : root.subcommands)
        if (sub->impl_.get() == s) help_of = sub.get();
    }
    if (a == "--help" || a == "-h") {
      help_out << help_of->usage();
      return ParseResult::kHelp;
    }
  }
  root.check_values_present(args);

  try {
    std::vector<std::string> reversed(args.rbegin(), args.rend());  // CLI11 takes them last first
    root.app->parse(reversed);
  } catch (const CLI::Error& e) {  // not expected after the checks above; still a user error
    throw ConfigError(e.what());
  }

  // The subcommand, then anything CLI11 did not place.
  Impl* scope = &root;
  for (const auto& s : root.subcommands) {
    if (s->impl_->app->parsed()) {
      root.chosen = s.get();
      scope = s->impl_.get();
    }
  }
  if (!root.subcommands.empty() && !root.chosen) {
    throw ConfigError("missing the subcommand: " + root.subcommand_names());
  }
  const auto marker = std::find(args.begin(), args.end(), "--");
  for (const std::string& left : root.app->remaining(true)) {
    if (left == "--") continue;  // CLI11 keeps the marker
    // After "--" every word is a positional, even one that looks like a flag.
    if (std::find(args.begin(), args.end(), left) > marker) throw ConfigError("unexpected argument '" + left + "'");
    throw ConfigError(root.unknown_argument_message(left, scope));
  }
  if (root.config->count() > 1) throw ConfigError("--config given more than once");

  // The file first (every value checked, even one the command line overrides), the command line
  // over it.
  if (root.config->count() == 1) {
    for (const auto& [name, a] : root.load_config_file(root.config->results().front(), *scope)) {
      assign(*scope->find_option(name), a);
    }
  }
  std::vector<Impl*> levels{&root};
  if (scope != &root) levels.push_back(scope);
  for (Impl* level : levels) {
    for (Option& o : level->options) {
      if (o.type == Type::kPositional) {
        if (o.cli->count() > 0) {
          assign(o, Assignment{o.cli->results().back(), "<" + o.name + ">"});
        } else if (o.required) {
          throw ConfigError("missing required argument <" + o.name + "> (" + o.help + ")");
        }
      } else if (o.cli->count() > 0) {
        const std::string& value = o.cli->results().back();
        assign(o, Assignment{value, "--" + o.name + "=" + value});
      }
    }
  }
  return ParseResult::kRun;
}

std::string Options::get_string(const std::string& name) const {
  return impl_->find(name, {Type::kString, Type::kChoice, Type::kPositional}).text;
}
double Options::get_double(const std::string& name) const { return impl_->find(name, {Type::kDouble}).double_value; }
int64_t Options::get_int(const std::string& name) const { return impl_->find(name, {Type::kInt}).int_value; }
bool Options::get_bool(const std::string& name) const { return impl_->find(name, {Type::kBool}).bool_value; }

bool Options::was_set(const std::string& name) const {
  return impl_->find(name, {Type::kString, Type::kDouble, Type::kInt, Type::kBool, Type::kChoice, Type::kPositional})
      .set;
}

bool Options::declared(const std::string& name) const { return impl_->find_any(name) != nullptr; }

std::vector<std::string> Options::values_as_text() const {
  std::vector<std::string> lines;
  for (const Impl* level = impl_.get(); level; level = level->parent) {
    for (const Option& o : level->options)
      if (o.type != Type::kRenamed) lines.push_back(o.name + "=" + o.text);
  }
  std::sort(lines.begin(), lines.end());
  return lines;
}

std::string Options::usage() const {
  const Impl& me = *impl_;
  struct Row {
    std::string left, right;
  };
  std::vector<Row> arguments, commands, flags, shared;
  std::string synopsis = "Usage: " + me.program + (me.subcommands.empty() ? "" : " <subcommand>") + " [options]";
  for (const auto& s : me.subcommands) commands.push_back({s->impl_->name, s->impl_->description});
  const auto option_rows = [&](const Impl& level, std::vector<Row>& rows) {
    for (const Option& o : level.options) {
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
        case Type::kPositional:
        case Type::kRenamed: continue;
      }
      rows.push_back({left, o.help + " (" + details + ")"});
    }
  };
  option_rows(me, flags);
  if (me.parent) {
    option_rows(*me.parent, shared);
  } else {
    flags.push_back({"--config <file>", "read 'name = value' lines from a file; command-line flags win"});
    flags.push_back({"--help, -h", "print this help and exit"});
  }

  std::size_t width = 0;
  for (const auto* rows : {&arguments, &commands, &flags, &shared}) {
    for (const Row& r : *rows) width = std::max(width, r.left.size());
  }
  std::ostringstream out;
  out << synopsis << "\n\n" << me.description << "\n";
  const auto print = [&](const std::string& title, const std::vector<Row>& rows) {
    if (rows.empty()) return;
    out << "\n" << title << ":\n";
    for (const Row& r : rows) out << "  " << r.left << std::string(width + 2 - r.left.size(), ' ') << r.right << "\n";
  };
  print("Subcommands (" + me.program + " <subcommand> --help for its options)", commands);
  print("Arguments", arguments);
  print(me.parent ? "Options of " + me.program : std::string("Options"), flags);
  if (me.parent) print("Options of " + me.parent->program + " (before or after '" + me.name + "')", shared);
  if (me.parent) out << "  --config <file>, --help, -h\n";
  return out.str();
}

}  // namespace odonav
