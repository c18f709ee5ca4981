#include "odonav/identification/checkpoint.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace odonav {

namespace {

constexpr const char* kMagic = "odonav-identification-checkpoint";
constexpr int kVersion = 1;

uint64_t fnv1a64(const std::string& text, uint64_t h = 1469598103934665603ULL) {
  for (unsigned char c : text) {
    h ^= c;
    h *= 1099511628211ULL;
  }
  return h;
}

std::string hex16(uint64_t v) {
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(v));
  return buf;
}

bool has_line_break(const std::string& s) { return s.find_first_of("\r\n") != std::string::npos; }

std::string system_error(const std::string& what, const std::string& path) {
  return what + " '" + path + "': " + std::strerror(errno);
}

/// Reads lines of a checkpoint text front to back; every failure names the field.
class Reader {
 public:
  explicit Reader(const std::string& text) : text_(text) {}

  /// The next line, which must start with "<key> "; returns the rest.
  std::string field(const std::string& key) {
    const std::string line = next_line(key);
    if (line.compare(0, key.size() + 1, key + " ") != 0)
      throw CheckpointError("expected field '" + key + "', found '" + line.substr(0, 40) + "'");
    return line.substr(key.size() + 1);
  }
  uint64_t unsigned_field(const std::string& key) {
    const std::string v = field(key);
    uint64_t out = 0;
    const auto r = std::from_chars(v.data(), v.data() + v.size(), out);
    if (v.empty() || r.ec != std::errc() || r.ptr != v.data() + v.size())
      throw CheckpointError("field '" + key + "' is not an unsigned integer: '" + v + "'");
    return out;
  }
  double double_field(const std::string& key) {
    const std::string v = field(key);
    double out = 0.0;
    const auto r = std::from_chars(v.data(), v.data() + v.size(), out);
    if (v.empty() || r.ec != std::errc() || r.ptr != v.data() + v.size() || !std::isfinite(out))
      throw CheckpointError("field '" + key + "' is not a finite number: '" + v + "'");
    return out;
  }
  /// Exactly n characters, then a line break.
  std::string block(std::size_t n, const std::string& what) {
    if (text_.size() - pos_ < n + 1) throw CheckpointError("truncated inside the " + what);
    std::string out = text_.substr(pos_, n);
    pos_ += n;
    if (text_[pos_] != '\n') throw CheckpointError("the " + what + " is longer than announced");
    ++pos_;
    return out;
  }
  std::size_t position() const { return pos_; }

 private:
  std::string next_line(const std::string& key) {
    const std::size_t end = text_.find('\n', pos_);
    if (end == std::string::npos) throw CheckpointError("truncated before field '" + key + "'");
    std::string line = text_.substr(pos_, end - pos_);
    pos_ = end + 1;
    return line;
  }
  const std::string& text_;
  std::size_t pos_ = 0;
};

}  // namespace

const std::vector<std::string>& checkpoint_neutral_options() {
  static const std::vector<std::string> names{
      "checkpoint-every-s", "config",   "domain",        "log-level", "max-wait-s", "profile",
      "profile-name",       "security-dir", "security-identity", "state-dir", "vehicle-id",
      // Hot standby and command checks: they do not change the estimate, and a standby may take
      // over a primary's checkpoint.
      "instance",           "ownership-strength", "nominal-k"};
  return names;
}

std::string config_hash_of(const std::vector<std::string>& values_as_text) {
  const auto& neutral = checkpoint_neutral_options();
  uint64_t h = fnv1a64("");
  for (const std::string& line : values_as_text) {
    const std::string name = line.substr(0, line.find('='));
    if (std::find(neutral.begin(), neutral.end(), name) != neutral.end()) continue;
    h = fnv1a64(line + "\n", h);
  }
  return hex16(h);
}

std::string checkpoint_path(const std::string& state_dir, const std::string& vehicle_id) {
  if (vehicle_id.empty()) throw std::invalid_argument("checkpoint: the vehicle id is empty");
  for (char c : vehicle_id) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '.' ||
                    c == '_' || c == '-';
    if (!ok)
      throw std::invalid_argument("checkpoint: vehicle id '" + vehicle_id +
                                  "' cannot be part of a file name (letters, digits, '.', '_', '-' only)");
  }
  return (std::filesystem::path(state_dir) / ("identification-" + vehicle_id + ".ckpt")).string();
}

std::string serialize_checkpoint(const IdentificationCheckpoint& c) {
  if (c.vehicle_id.empty() || has_line_break(c.vehicle_id))
    throw std::invalid_argument("checkpoint: vehicle id is empty or holds a line break");
  if (c.estimator_name.empty() || has_line_break(c.estimator_name))
    throw std::invalid_argument("checkpoint: estimator name is empty or holds a line break");
  if (c.config_hash.empty() || has_line_break(c.config_hash))
    throw std::invalid_argument("checkpoint: config hash is empty or holds a line break");
  if (!std::isfinite(c.last_sample_t_s)) throw std::invalid_argument("checkpoint: last_sample_t_s is not finite");
  char t[40];
  std::snprintf(t, sizeof t, "%.17g", c.last_sample_t_s);
  std::ostringstream s;
  s << kMagic << ' ' << kVersion << '\n'
    << "vehicle " << c.vehicle_id << '\n'
    << "config_hash " << c.config_hash << '\n'
    << "estimator " << c.estimator_name << '\n'
    << "last_sample_t_s " << t << '\n'
    << "samples_accepted " << c.samples_accepted << '\n'
    << "samples_rejected " << c.samples_rejected << '\n'
    << "state_chars " << c.estimator_state.size() << '\n'
    << c.estimator_state << '\n';
  const std::string body = s.str();
  return body + "checksum " + hex16(fnv1a64(body)) + "\n";
}

IdentificationCheckpoint parse_checkpoint(const std::string& text) {
  if (text.empty()) throw CheckpointError("empty file");
  // The checksum first: a truncated or bit-flipped file is named as such, not by the first field
  // that happens to look wrong.
  const std::size_t at = text.rfind("checksum ");
  if (at == std::string::npos || (at != 0 && text[at - 1] != '\n'))
    throw CheckpointError("truncated: no checksum line (or not a checkpoint file)");
  const std::string stored = text.substr(at + 9);
  if (stored.size() != 17 || stored.back() != '\n')
    throw CheckpointError("truncated or malformed checksum line");
  const std::string body = text.substr(0, at);
  if (stored.substr(0, 16) != hex16(fnv1a64(body)))
    throw CheckpointError("checksum mismatch: the file is corrupt");

  Reader r(body);
  const std::string version = r.field(kMagic);
  if (version != std::to_string(kVersion))
    throw CheckpointError("unknown checkpoint version '" + version + "' (this build reads " +
                          std::to_string(kVersion) + ")");
  IdentificationCheckpoint c;
  c.vehicle_id = r.field("vehicle");
  c.config_hash = r.field("config_hash");
  c.estimator_name = r.field("estimator");
  c.last_sample_t_s = r.double_field("last_sample_t_s");
  c.samples_accepted = r.unsigned_field("samples_accepted");
  c.samples_rejected = r.unsigned_field("samples_rejected");
  const uint64_t n = r.unsigned_field("state_chars");
  c.estimator_state = r.block(static_cast<std::size_t>(n), "estimator state");
  if (r.position() != body.size()) throw CheckpointError("unexpected text after the estimator state");
  if (c.vehicle_id.empty() || c.estimator_name.empty() || c.config_hash.empty())
    throw CheckpointError("empty vehicle, estimator or config hash");
  return c;
}

std::string move_checkpoint_aside(const std::string& path, int64_t unix_time_s) {
  const std::string base = path + ".bad-" + std::to_string(unix_time_s);
  std::string target = base;
  for (int i = 2; std::filesystem::exists(target); ++i) target = base + "-" + std::to_string(i);
  if (::rename(path.c_str(), target.c_str()) != 0)
    throw std::runtime_error(system_error("checkpoint: cannot move aside to '" + target + "'", path));
  return target;
}

CheckpointLoadResult load_identification_checkpoint(const std::string& path, const std::string& vehicle_id,
                                                    const std::string& config_hash, ScaleFactorEstimator& estimator,
                                                    int64_t unix_time_s) {
  CheckpointLoadResult result;
  result.path = path;
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) return result;  // fresh start

  std::string reason;
  try {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw CheckpointError("cannot be opened for reading");
    std::ostringstream s;
    s << in.rdbuf();
    if (in.bad()) throw CheckpointError("read error");
    IdentificationCheckpoint c = parse_checkpoint(s.str());
    if (c.vehicle_id != vehicle_id)
      throw CheckpointError("made for vehicle '" + c.vehicle_id + "', this is '" + vehicle_id + "'");
    if (c.config_hash != config_hash)
      throw CheckpointError("made with another configuration (hash " + c.config_hash + ", now " + config_hash + ")");
    if (c.estimator_name != estimator.name())
      throw CheckpointError("made by estimator '" + c.estimator_name + "', this is '" + estimator.name() + "'");
    try {
      estimator.restore_state(c.estimator_state);  // unchanged when it throws
    } catch (const std::exception& e) {
      throw CheckpointError(std::string("estimator state refused: ") + e.what());
    }
    result.status = CheckpointLoadStatus::kRestored;
    result.checkpoint = std::move(c);
    return result;
  } catch (const std::exception& e) {
    reason = e.what();
  }
  result.status = CheckpointLoadStatus::kMovedAside;
  result.reason = reason;
  try {
    result.moved_to = move_checkpoint_aside(path, unix_time_s);
  } catch (const std::exception& e) {
    result.reason += "; " + std::string(e.what());
  }
  return result;
}

std::string describe(const CheckpointLoadResult& r, const ScaleFactorEstimator& estimator) {
  switch (r.status) {
    case CheckpointLoadStatus::kNone:
      return "no checkpoint " + r.path + ": starting from nominal K";
    case CheckpointLoadStatus::kRestored: {
      const ScaleFactorEstimate e = estimator.estimate();
      char buf[160];
      if (e.valid)
        std::snprintf(buf, sizeof buf, "restored K=%.9g m/pulse from checkpoint (t=%.3f s)", e.k_m_per_pulse,
                      r.checkpoint->last_sample_t_s);
      else
        std::snprintf(buf, sizeof buf, "restored estimator (no K yet) from checkpoint (t=%.3f s)",
                      r.checkpoint->last_sample_t_s);
      return buf;
    }
    case CheckpointLoadStatus::kMovedAside:
      return "checkpoint " + r.path + " was corrupt (" + r.reason + "): moved aside" +
             (r.moved_to.empty() ? std::string(" FAILED") : " to " + r.moved_to) + "; starting from nominal K";
  }
  return {};
}

}  // namespace odonav
