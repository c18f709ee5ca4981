#include "odonav/ground/web_api.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <fstream>
#include <stdexcept>

#include <nlohmann/json.hpp>

namespace odonav::ground {

std::optional<std::string> authorization_error(const std::string& token, const std::string& authorization) {
  if (token.empty()) {
    return std::string("commands are disabled: odonav-ground serve was started without --token or --token-file");
  }
  const std::string prefix = "Bearer ";
  if (authorization.compare(0, prefix.size(), prefix) != 0 || authorization.size() == prefix.size()) {
    return std::string("a command needs the token (header 'Authorization: Bearer <token>')");
  }
  const std::string given = authorization.substr(prefix.size());
  unsigned diff = given.size() == token.size() ? 0u : 1u;
  for (std::size_t i = 0; i < given.size(); ++i)
    diff |= static_cast<unsigned char>(given[i]) ^ static_cast<unsigned char>(token[i % token.size()]);
  if (diff != 0) return std::string("wrong token");
  return std::nullopt;
}

WebCommand parse_web_command(const std::string& body) {
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(body);
  } catch (const nlohmann::json::exception& e) {
    throw std::invalid_argument(std::string("command: the body is not JSON (") + e.what() + ")");
  }
  if (!j.is_object()) throw std::invalid_argument("command: the body must be a JSON object");
  WebCommand c;
  for (const auto& [field, target] : {std::pair<const char*, std::string*>{"vehicle", &c.vehicle},
                                      {"component", &c.component},
                                      {"command", &c.command}}) {
    if (!j.contains(field) || !j[field].is_string() || j[field].get<std::string>().empty()) {
      throw std::invalid_argument(std::string("command: field '") + field + "' must be a non-empty string");
    }
    *target = j[field].get<std::string>();
  }
  if (c.command == "set-k") {
    if (!j.contains("value") || !j["value"].is_number() || !std::isfinite(j["value"].get<double>()) ||
        j["value"].get<double>() <= 0.0) {
      throw std::invalid_argument("command set-k: field 'value' must be a positive number of metres per pulse");
    }
    c.value = j["value"].get<double>();
  } else if (j.contains("value") && !j["value"].is_null()) {
    throw std::invalid_argument("command " + c.command + ": takes no 'value'");
  }
  return c;
}

std::string read_token_file(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("--token-file '" + path + "': cannot be read");
  std::string line;
  std::getline(in, line);
  const auto b = line.find_first_not_of(" \t\r");
  const auto e = line.find_last_not_of(" \t\r");
  if (b == std::string::npos) throw std::runtime_error("--token-file '" + path + "': the first line holds no token");
  return line.substr(b, e - b + 1);
}

std::string target_path(const std::string& target) { return target.substr(0, target.find('?')); }

std::string query_parameter(const std::string& target, const std::string& name) {
  const auto q = target.find('?');
  if (q == std::string::npos) return "";
  std::size_t pos = q + 1;
  while (pos <= target.size()) {
    const auto end = std::min(target.find('&', pos), target.size());
    const std::string item = target.substr(pos, end - pos);
    const auto eq = item.find('=');
    if (item.substr(0, eq) == name) {
      const std::string raw = eq == std::string::npos ? "" : item.substr(eq + 1);
      std::string out;
      for (std::size_t i = 0; i < raw.size(); ++i) {
        if (raw[i] == '%' && i + 2 < raw.size() + 0 && std::isxdigit(static_cast<unsigned char>(raw[i + 1])) &&
            std::isxdigit(static_cast<unsigned char>(raw[i + 2]))) {
          out.push_back(static_cast<char>(std::stoi(raw.substr(i + 1, 2), nullptr, 16)));
          i += 2;
        } else {
          out.push_back(raw[i] == '+' ? ' ' : raw[i]);
        }
      }
      return out;
    }
    pos = end + 1;
  }
  return "";
}

}  // namespace odonav::ground
