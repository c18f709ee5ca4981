#include "odonav/ground/ros2msg_schema.hpp"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <functional>
#include <set>
#include <sstream>
#include <stdexcept>

namespace odonav::ground {

namespace fs = std::filesystem;

namespace {

const std::set<std::string>& builtin_types() {
  static const std::set<std::string> types{"bool",    "byte",   "char",    "int8",  "uint8",   "int16",
                                           "uint16",  "int32",  "uint32",  "int64", "uint64",  "float32",
                                           "float64", "string", "wstring", "time",  "duration"};
  return types;
}

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t\r");
  if (b == std::string::npos) return "";
  const auto e = s.find_last_not_of(" \t\r");
  return s.substr(b, e - b + 1);
}

/// "pkg/Type" or "pkg/msg/Type" -> "pkg/msg/Type"; a bare "Type" -> "<package>/msg/Type".
std::string qualify(const std::string& type, const std::string& package) {
  const auto first = type.find('/');
  if (first == std::string::npos) return package + "/msg/" + type;
  const auto last = type.rfind('/');
  return type.substr(0, first) + "/msg/" + type.substr(last + 1);
}

/// "pkg/msg/Type" -> "pkg/Type", the name rosbag2 writes after "MSG: ".
std::string short_name(const std::string& type_name) {
  const auto first = type_name.find('/');
  const auto last = type_name.rfind('/');
  if (first == std::string::npos) return type_name;
  return type_name.substr(0, first) + "/" + type_name.substr(last + 1);
}

std::string package_of(const std::string& type_name) { return type_name.substr(0, type_name.find('/')); }

}  // namespace

MsgLibrary load_msg_library(const std::string& idl_dir) {
  if (!fs::is_directory(idl_dir)) throw std::runtime_error("msg library: folder '" + idl_dir + "' does not exist");
  MsgLibrary library;
  for (const auto& entry : fs::recursive_directory_iterator(idl_dir)) {
    if (!entry.is_regular_file() || entry.path().extension() != ".msg") continue;
    const fs::path msg_dir = entry.path().parent_path();
    if (msg_dir.filename() != "msg") continue;
    const std::string package = msg_dir.parent_path().filename().string();
    std::ifstream in(entry.path());
    std::ostringstream text;
    text << in.rdbuf();
    library[package + "/msg/" + entry.path().stem().string()] = text.str();
  }
  if (library.empty()) throw std::runtime_error("msg library: no <pkg>/msg/<Type>.msg file under '" + idl_dir + "'");
  return library;
}

std::vector<std::string> msg_dependencies(const std::string& msg_text, const std::string& package) {
  std::vector<std::string> deps;
  std::istringstream lines(msg_text);
  std::string raw;
  int line_number = 0;
  while (std::getline(lines, raw)) {
    ++line_number;
    std::string line = trim(raw.substr(0, raw.find('#')));
    if (line.empty()) continue;
    std::istringstream tokens(line);
    std::string type, name;
    if (!(tokens >> type >> name)) {
      throw std::runtime_error("msg: line " + std::to_string(line_number) + " is not '<type> <name>': '" + trim(raw) +
                               "'");
    }
    type = type.substr(0, type.find('['));   // arrays: T[], T[N], T[<=N]
    type = type.substr(0, type.find("<="));  // bounded strings: string<=N
    // builtin_interfaces/Time is not in the list: parsers treat it as builtin, but ROS 2 still appends
    // its definition, so it is kept as a dependency.
    if (builtin_types().count(type)) continue;
    const std::string qualified = qualify(type, package);
    if (std::find(deps.begin(), deps.end(), qualified) == deps.end()) deps.push_back(qualified);
  }
  return deps;
}

std::string ros2msg_schema(const MsgLibrary& library, const std::string& type_name) {
  const auto main = library.find(type_name);
  if (main == library.end()) throw std::runtime_error("ros2msg schema: no .msg for type '" + type_name + "'");
  std::string schema = main->second;
  std::vector<std::string> appended;
  std::function<void(const std::string&, const std::string&)> append_dependencies = [&](const std::string& of_type,
                                                                                        const std::string& text) {
    for (const std::string& dep : msg_dependencies(text, package_of(of_type))) {
      if (dep == type_name || std::find(appended.begin(), appended.end(), dep) != appended.end()) continue;
      const auto it = library.find(dep);
      if (it == library.end()) {
        throw std::runtime_error("ros2msg schema of '" + type_name + "': type '" + dep + "' used by '" + of_type +
                                 "' has no .msg");
      }
      appended.push_back(dep);
      if (!schema.empty() && schema.back() != '\n') schema += '\n';
      schema += std::string(80, '=') + "\nMSG: " + short_name(dep) + "\n" + it->second;
      append_dependencies(dep, it->second);
    }
  };
  append_dependencies(type_name, main->second);
  return schema;
}

}  // namespace odonav::ground
