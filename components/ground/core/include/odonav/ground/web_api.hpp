#pragma once
// The fleet page's API rules without network code: who may send commands (the token), what a
// command request must hold, and the query of GET /api/fleet.
#include <optional>
#include <string>

namespace odonav::ground {

/// Whether an Authorization header value carries the token ("Bearer <token>"). nullopt when it
/// does, else why not (no token configured: commands disabled; header missing; wrong token). The
/// comparison takes the same time for any token of the same length.
std::optional<std::string> authorization_error(const std::string& configured_token, const std::string& authorization);

/// POST /api/command body: {"vehicle": ID, "component": NAME, "command": "reset" | "set-k" |
/// "freeze" | "unfreeze" | "release-k", "value": K} ("value" for set-k only, a positive number).
struct WebCommand {
  std::string vehicle, component, command;
  double value = 0.0;
};
/// Throws std::invalid_argument naming the field that is missing or wrong (not JSON, not an
/// object, a field of the wrong type, set-k without a positive finite value, a value for another
/// command). Whether `command` is a known one is for the command sender to say.
WebCommand parse_web_command(const std::string& body);

/// The token from a --token-file: its first line without surrounding blanks. Throws
/// std::runtime_error naming the file when it cannot be read or the token is empty.
std::string read_token_file(const std::string& path);

/// The value of one query parameter of a target ("/api/fleet?history=vehicle-01"), percent-decoded;
/// empty when absent.
std::string query_parameter(const std::string& target, const std::string& name);
/// The path of a target (without the query).
std::string target_path(const std::string& target);

}  // namespace odonav::ground
