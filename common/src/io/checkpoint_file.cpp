// The checkpoint file's envelope, checksum, identity checks and load policy (checkpoint_file.hpp).
#include "odonav/checkpoint_file.hpp"

#include <cstdio>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace odonav {

namespace {

/// The compact text the checksum covers (and the file holds): keys sorted, invalid UTF-8 replaced
/// rather than thrown on.
std::string compact(const StateJson& j) { return j.dump(-1, ' ', false, StateJson::error_handler_t::replace); }

const StateJson& envelope_field(const StateJson& doc, const char* key) {
  const auto it = doc.find(key);
  if (it == doc.end()) throw CheckpointError(std::string("envelope field '") + key + "' is missing");
  return *it;
}

std::string envelope_text(const StateJson& doc, const char* key) {
  const StateJson& j = envelope_field(doc, key);
  if (!j.is_string() || j.get_ref<const std::string&>().empty())
    throw CheckpointError(std::string("envelope field '") + key + "' is not a non-empty text");
  return j.get<std::string>();
}

/// The first line of a text checkpoint of the format before JSON ("odonav-<component>-checkpoint
/// <n>"), or "".
std::string old_text_head(const std::string& text) {
  if (text.rfind("odonav-", 0) != 0) return {};
  std::string line = text.substr(0, std::min(text.find('\n'), std::size_t{80}));
  return line.find("-checkpoint ") == std::string::npos ? std::string() : line;
}

}  // namespace

uint64_t checkpoint_fnv1a64(const std::string& text, uint64_t h) {
  for (unsigned char c : text) {
    h ^= c;
    h *= 1099511628211ULL;
  }
  return h;
}

std::string checkpoint_hex16(uint64_t v) {
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(v));
  return buf;
}

std::string seal_checkpoint(const CheckpointIdentity& id, StateJson payload) {
  if (id.component.empty() || id.vehicle_id.empty() || id.config_hash.empty())
    throw std::invalid_argument("checkpoint: component, vehicle id or config hash is empty");
  StateJson doc = StateJson::object();
  doc["format"] = kCheckpointFormat;
  doc["component"] = id.component;
  doc["version"] = id.version;
  doc["vehicle"] = id.vehicle_id;
  doc["config_hash"] = id.config_hash;
  doc["payload"] = std::move(payload);
  doc["checksum"] = checkpoint_hex16(checkpoint_fnv1a64(compact(doc)));
  return compact(doc) + "\n";
}

CheckpointContents unseal_checkpoint(const std::string& text) {
  if (text.empty()) throw CheckpointError("empty file");
  StateJson doc;
  try {
    doc = StateJson::parse(text);
  } catch (const StateJson::parse_error& e) {
    if (const std::string head = old_text_head(text); !head.empty())
      throw CheckpointError("an older text checkpoint ('" + head + "'), not the JSON version this build reads");
    if (e.byte >= text.size()) throw CheckpointError("truncated: the JSON ends early (" + std::string(e.what()) + ")");
    throw CheckpointError(std::string("not an odonav checkpoint (not JSON: ") + e.what() + ")");
  }
  if (!doc.is_object() || doc.value("format", StateJson()) != kCheckpointFormat)
    throw CheckpointError(std::string("not an odonav checkpoint (no \"format\": \"") + kCheckpointFormat + "\")");
  const auto sum = doc.find("checksum");
  if (sum == doc.end() || !sum->is_string()) throw CheckpointError("no checksum (truncated or not a checkpoint file)");
  const std::string stored = sum->get<std::string>();
  doc.erase("checksum");
  if (stored != checkpoint_hex16(checkpoint_fnv1a64(compact(doc))))
    throw CheckpointError("checksum mismatch: the file is corrupt");

  CheckpointContents c;
  c.identity.component = envelope_text(doc, "component");
  const StateJson& version = envelope_field(doc, "version");
  if (!version.is_number_integer()) throw CheckpointError("envelope field 'version' is not a whole number");
  c.identity.version = version.get<int>();
  c.identity.vehicle_id = envelope_text(doc, "vehicle");
  c.identity.config_hash = envelope_text(doc, "config_hash");
  c.payload = std::move(envelope_field(doc, "payload"));
  if (!c.payload.is_object()) throw CheckpointError("envelope field 'payload' is not an object");
  return c;
}

void check_checkpoint_identity(const CheckpointIdentity& file, const CheckpointIdentity& expected) {
  if (file.component != expected.component)
    throw CheckpointError("made by odonav-" + file.component + ", this is odonav-" + expected.component);
  if (file.version != expected.version)
    throw CheckpointError("checkpoint version " + std::to_string(file.version) + ", this build reads version " +
                          std::to_string(expected.version));
  if (file.vehicle_id != expected.vehicle_id)
    throw CheckpointError("made for vehicle '" + file.vehicle_id + "', this is '" + expected.vehicle_id + "'");
  if (file.config_hash != expected.config_hash)
    throw CheckpointError("made with another configuration (hash " + file.config_hash + ", now " +
                          expected.config_hash + ")");
}

const std::vector<std::string>& checkpoint_neutral_options() {
  static const std::vector<std::string> names{
      "checkpoint-every-s", "config", "domain", "log-level", "max-wait-s", "profile", "profile-name", "security-dir",
      "security-identity", "state-dir", "vehicle-id",
      // Hot standby and command checks: they do not change the estimate, and a standby may take
      // over a primary's checkpoint.
      "instance", "ownership-strength", "nominal-k"};
  return names;
}

std::string config_hash_of(const std::vector<std::string>& values_as_text) {
  const auto& neutral = checkpoint_neutral_options();
  uint64_t h = checkpoint_fnv1a64("");
  for (const std::string& line : values_as_text) {
    const std::string name = line.substr(0, line.find('='));
    if (std::find(neutral.begin(), neutral.end(), name) != neutral.end()) continue;
    h = checkpoint_fnv1a64(line + "\n", h);
  }
  return checkpoint_hex16(h);
}

std::string CheckpointKind::path(const std::string& state_dir, const std::string& vehicle_id) const {
  check_checkpoint_vehicle_id(vehicle_id);
  return (std::filesystem::path(state_dir) / (std::string(component) + "-" + vehicle_id + ".ckpt")).string();
}

void check_checkpoint_vehicle_id(const std::string& vehicle_id) {
  if (vehicle_id.empty()) throw std::invalid_argument("checkpoint: the vehicle id is empty");
  for (char c : vehicle_id) {
    const bool ok =
        (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '.' || c == '_' || c == '-';
    if (!ok)
      throw std::invalid_argument("checkpoint: vehicle id '" + vehicle_id +
                                  "' cannot be part of a file name (letters, digits, '.', '_', '-' only)");
  }
}

std::string move_checkpoint_aside(const std::string& path, int64_t unix_time_s) {
  const std::string base = path + ".bad-" + std::to_string(unix_time_s);
  std::string target = base;
  for (int i = 2; std::filesystem::exists(target); ++i) target = base + "-" + std::to_string(i);
  if (::rename(path.c_str(), target.c_str()) != 0)
    throw std::runtime_error("checkpoint: cannot move aside to '" + target + "' '" + path +
                             "': " + std::strerror(errno));
  return target;
}

CheckpointFileLoad load_checkpoint_file(const std::string& path, int64_t unix_time_s,
                                        const CheckpointIdentity& expected,
                                        const std::function<void(const StateJson& payload)>& restore) {
  CheckpointFileLoad result;
  result.path = path;
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) return result;  // fresh start
  try {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw CheckpointError("cannot be opened for reading");
    std::ostringstream s;
    s << in.rdbuf();
    if (in.bad()) throw CheckpointError("read error");
    const CheckpointContents c = unseal_checkpoint(s.str());
    check_checkpoint_identity(c.identity, expected);
    restore(c.payload);
    result.status = CheckpointLoadStatus::kRestored;
    return result;
  } catch (const std::exception& e) {
    result.reason = e.what();
  }
  result.status = CheckpointLoadStatus::kMovedAside;
  try {
    result.moved_to = move_checkpoint_aside(path, unix_time_s);
  } catch (const std::exception& e) {
    result.reason += "; " + std::string(e.what());
  }
  return result;
}

}  // namespace odonav
