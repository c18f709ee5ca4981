#include "odonav/checkpoint_file.hpp"

#include <cstdio>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace odonav {

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

std::string checkpoint_hex_double(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%a", v);
  return buf;
}

double checkpoint_parse_double(const std::string& text, const std::string& field) {
  errno = 0;
  char* end = nullptr;
  const double v = std::strtod(text.c_str(), &end);
  if (text.empty() || end != text.c_str() + text.size() || errno == ERANGE)
    throw CheckpointError("field '" + field + "' is not a number: '" + text + "'");
  return v;
}

namespace {
/// The space-separated tokens of text; exactly n of them (CheckpointError naming field).
std::vector<std::string> checkpoint_tokens(const std::string& text, const std::string& field, std::size_t n) {
  std::vector<std::string> tokens;
  std::size_t at = 0;
  while (at <= text.size()) {
    const std::size_t end = std::min(text.find(' ', at), text.size());
    tokens.push_back(text.substr(at, end - at));
    at = end + 1;
  }
  if (tokens.size() != n)
    throw CheckpointError("field '" + field + "' has " + std::to_string(tokens.size()) + " values, not " +
                          std::to_string(n));
  return tokens;
}
}  // namespace

std::vector<double> checkpoint_parse_finite_doubles(const std::string& text, const std::string& field, std::size_t n) {
  std::vector<double> out;
  for (const std::string& token : checkpoint_tokens(text, field, n)) {
    const double v = checkpoint_parse_double(token, field);
    if (!std::isfinite(v)) throw CheckpointError("field '" + field + "' is not finite");
    out.push_back(v);
  }
  return out;
}

std::string seal_checkpoint(const std::string& body) {
  return body + "checksum " + checkpoint_hex16(checkpoint_fnv1a64(body)) + "\n";
}

std::string unseal_checkpoint(const std::string& text) {
  if (text.empty()) throw CheckpointError("empty file");
  const std::size_t at = text.rfind("checksum ");
  if (at == std::string::npos || (at != 0 && text[at - 1] != '\n'))
    throw CheckpointError("truncated: no checksum line (or not a checkpoint file)");
  const std::string stored = text.substr(at + 9);
  if (stored.size() != 17 || stored.back() != '\n') throw CheckpointError("truncated or malformed checksum line");
  std::string body = text.substr(0, at);
  if (stored.substr(0, 16) != checkpoint_hex16(checkpoint_fnv1a64(body)))
    throw CheckpointError("checksum mismatch: the file is corrupt");
  return body;
}

std::string CheckpointReader::next_line(const std::string& key) {
  const std::size_t end = text_.find('\n', pos_);
  if (end == std::string::npos) throw CheckpointError("truncated before field '" + key + "'");
  std::string line = text_.substr(pos_, end - pos_);
  pos_ = end + 1;
  return line;
}

std::string CheckpointReader::field(const std::string& key) {
  const std::string line = next_line(key);
  if (line.compare(0, key.size() + 1, key + " ") != 0)
    throw CheckpointError("expected field '" + key + "', found '" + line.substr(0, 40) + "'");
  return line.substr(key.size() + 1);
}

uint64_t CheckpointReader::unsigned_field(const std::string& key) {
  const std::string v = field(key);
  uint64_t out = 0;
  const auto r = std::from_chars(v.data(), v.data() + v.size(), out);
  if (v.empty() || r.ec != std::errc() || r.ptr != v.data() + v.size())
    throw CheckpointError("field '" + key + "' is not an unsigned integer: '" + v + "'");
  return out;
}

double CheckpointReader::double_field(const std::string& key) {
  const std::string v = field(key);
  double out = 0.0;
  const auto r = std::from_chars(v.data(), v.data() + v.size(), out);
  if (v.empty() || r.ec != std::errc() || r.ptr != v.data() + v.size() || !std::isfinite(out))
    throw CheckpointError("field '" + key + "' is not a finite number: '" + v + "'");
  return out;
}

std::vector<double> CheckpointReader::finite_doubles(const std::string& key, std::size_t n) {
  return checkpoint_parse_finite_doubles(field(key), key, n);
}

std::vector<double> CheckpointReader::exact_values(const std::string& key, std::size_t n) {
  std::vector<double> v = value_list(key, n, n);
  if (v.size() != n) throw CheckpointError("field '" + key + "' does not hold " + std::to_string(n) + " values");
  return v;
}

std::vector<double> CheckpointReader::value_list(const std::string& key, std::size_t stride, std::size_t max_n) {
  const std::string text = field(key);
  const std::size_t space = text.find(' ');
  const std::string count = text.substr(0, space);
  std::size_t n = 0;
  const auto r = std::from_chars(count.data(), count.data() + count.size(), n);
  if (count.empty() || r.ec != std::errc() || r.ptr != count.data() + count.size() || n > max_n ||
      (stride > 0 && n % stride != 0))
    throw CheckpointError("field '" + key + "' has a bad value count '" + count + "'");
  std::vector<double> out;
  if (n == 0) {
    if (space != std::string::npos) throw CheckpointError("field '" + key + "' holds values after a count of 0");
    return out;
  }
  if (space == std::string::npos) throw CheckpointError("field '" + key + "' has no values");
  out.reserve(n);
  for (const std::string& token : checkpoint_tokens(text.substr(space + 1), key, n))
    out.push_back(checkpoint_parse_double(token, key));
  return out;
}

std::vector<uint64_t> CheckpointReader::unsigned_list(const std::string& key, std::size_t n) {
  std::vector<uint64_t> out;
  for (const std::string& token : checkpoint_tokens(field(key), key, n)) {
    uint64_t v = 0;
    const auto r = std::from_chars(token.data(), token.data() + token.size(), v);
    if (token.empty() || r.ec != std::errc() || r.ptr != token.data() + token.size())
      throw CheckpointError("field '" + key + "' holds '" + token + "', not an unsigned integer");
    out.push_back(v);
  }
  return out;
}

std::string CheckpointReader::block(std::size_t n, const std::string& what) {
  if (text_.size() - pos_ < n + 1) throw CheckpointError("truncated inside the " + what);
  std::string out = text_.substr(pos_, n);
  pos_ += n;
  if (text_[pos_] != '\n') throw CheckpointError("the " + what + " is longer than announced");
  ++pos_;
  return out;
}

void check_checkpoint_version(CheckpointReader& reader, const std::string& magic, int version) {
  const std::string v = reader.field(magic);
  if (v != std::to_string(version))
    throw CheckpointError("unknown checkpoint version '" + v + "' (this build reads " + std::to_string(version) + ")");
}

std::string checkpoint_head(const std::string& magic, int version, const std::string& vehicle_id,
                            const std::string& config_hash) {
  auto bad = [](const std::string& v) { return v.empty() || v.find_first_of("\r\n") != std::string::npos; };
  if (bad(vehicle_id)) throw std::invalid_argument("checkpoint: vehicle id is empty or holds a line break");
  if (bad(config_hash)) throw std::invalid_argument("checkpoint: config hash is empty or holds a line break");
  return magic + " " + std::to_string(version) + "\nvehicle " + vehicle_id + "\nconfig_hash " + config_hash + "\n";
}

CheckpointHead read_checkpoint_head(CheckpointReader& reader, const std::string& magic, int version) {
  check_checkpoint_version(reader, magic, version);
  CheckpointHead h;
  h.vehicle_id = reader.field("vehicle");
  h.config_hash = reader.field("config_hash");
  if (h.vehicle_id.empty() || h.config_hash.empty()) throw CheckpointError("empty vehicle or config hash");
  return h;
}

std::string checkpoint_time_line(const std::string& key, double t_s) {
  if (!std::isfinite(t_s)) throw std::invalid_argument("checkpoint: " + key + " is not finite");
  char t[40];
  std::snprintf(t, sizeof t, "%.17g", t_s);
  return key + " " + t + "\n";
}

std::string checkpoint_value_list(const std::string& key, const std::vector<double>& values) {
  std::string s = key + " " + std::to_string(values.size());
  for (double v : values) s += " " + checkpoint_hex_double(v);
  return s + "\n";
}

std::string checkpoint_state_block(const std::string& state) {
  return "state_chars " + std::to_string(state.size()) + "\n" + state + "\n";
}

std::string read_checkpoint_state_block(CheckpointReader& reader, const std::string& what) {
  const uint64_t n = reader.unsigned_field("state_chars");
  return reader.block(static_cast<std::size_t>(n), what);
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

void check_checkpoint_identity(const std::string& file_vehicle, const std::string& file_hash,
                               const std::string& vehicle_id, const std::string& config_hash) {
  if (file_vehicle != vehicle_id)
    throw CheckpointError("made for vehicle '" + file_vehicle + "', this is '" + vehicle_id + "'");
  if (file_hash != config_hash)
    throw CheckpointError("made with another configuration (hash " + file_hash + ", now " + config_hash + ")");
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
                                        const std::function<void(const std::string& text)>& restore) {
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
    restore(s.str());
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
