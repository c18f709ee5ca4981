#pragma once
// What every component checkpoint file has in common (odonav-identification's estimator,
// odonav-calibration's calibrator), middleware-free: the checksum envelope, the line reader that
// names the field that is wrong, the configuration hash, the identity checks (vehicle,
// configuration) and the load policy (an unusable file is moved aside, never deleted or
// overwritten). Each component writes its own versioned text (a magic line "<magic> <version>",
// then "key value" lines, then its state as a counted block) and restart_policy.hpp decides when.
//
// Envelope: the text ends with "checksum <16 hex digits>\n", FNV-1a 64 of every byte before it.
// Files are written with write_file_atomically (safe_output.hpp): temporary name, fsync, rename over
// the previous checkpoint, fsync of the directory, so a kill -9 leaves the old or the new one.
#include <cstdint>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

namespace odonav {

/// A checkpoint text that cannot be used; what() says why (truncated, checksum, version, field...).
class CheckpointError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// FNV-1a 64 of text, continuing from h.
uint64_t checkpoint_fnv1a64(const std::string& text, uint64_t h = 1469598103934665603ULL);
/// v as 16 lower-case hex digits.
std::string checkpoint_hex16(uint64_t v);
/// A double as C99 hex float ("%a"): exact round trip, no locale.
std::string checkpoint_hex_double(double v);
/// Parses checkpoint_hex_double's text (or any strtod number). Throws CheckpointError naming `field`
/// when it is empty, malformed or out of range.
double checkpoint_parse_double(const std::string& text, const std::string& field);
/// Exactly n space-separated finite numbers (checkpoint_parse_double each). Throws CheckpointError
/// naming `field` when the count differs or a value is malformed or not finite.
std::vector<double> checkpoint_parse_finite_doubles(const std::string& text, const std::string& field, std::size_t n);

/// body + "checksum <FNV-1a 64 of body>\n".
std::string seal_checkpoint(const std::string& body);
/// The body of a sealed text. Throws CheckpointError: "empty file", truncated (no or a short
/// checksum line), "checksum mismatch: the file is corrupt". The checksum is checked first, so a
/// truncated or bit-flipped file is named as such, not by the first field that looks wrong.
std::string unseal_checkpoint(const std::string& text);

/// Reads the lines of a checkpoint body front to back; every failure names the field.
class CheckpointReader {
 public:
  explicit CheckpointReader(const std::string& text) : text_(text) {}
  /// The next line, which must start with "<key> "; returns the rest.
  std::string field(const std::string& key);
  uint64_t unsigned_field(const std::string& key);
  /// A finite decimal number (std::from_chars; written with %.17g it round-trips exactly).
  double double_field(const std::string& key);
  /// The next line "<key> v1 ... vn": exactly n finite numbers (checkpoint_parse_finite_doubles).
  std::vector<double> finite_doubles(const std::string& key, std::size_t n);
  /// The next line "<key> u1 ... un": exactly n unsigned integers.
  std::vector<uint64_t> unsigned_list(const std::string& key, std::size_t n);
  /// The next line "<key> <n> v1 ... vn" (checkpoint_value_list): n numbers, any value (NaN and
  /// infinities too), n a multiple of `stride` (records of stride values) and at most max_n.
  std::vector<double> value_list(const std::string& key, std::size_t stride = 1, std::size_t max_n = 10000000);
  /// value_list holding exactly n values (CheckpointError "field '<key>' does not hold <n> values").
  std::vector<double> exact_values(const std::string& key, std::size_t n);
  /// Exactly n characters, then a line break.
  std::string block(std::size_t n, const std::string& what);
  bool at_end() const { return pos_ == text_.size(); }

 private:
  std::string next_line(const std::string& key);
  const std::string& text_;
  std::size_t pos_ = 0;
};

/// Checks the magic line "<magic> <version>" (CheckpointError "unknown checkpoint version ...").
void check_checkpoint_version(CheckpointReader& reader, const std::string& magic, int version);

/// The head of every component checkpoint: "<magic> <version>\nvehicle <vehicle_id>\nconfig_hash
/// <config_hash>\n". Throws std::invalid_argument when the vehicle or hash is empty or holds a line
/// break.
std::string checkpoint_head(const std::string& magic, int version, const std::string& vehicle_id,
                            const std::string& config_hash);
struct CheckpointHead {
  std::string vehicle_id;
  std::string config_hash;
};
/// Reads checkpoint_head's lines (CheckpointError: version, missing or empty field).
CheckpointHead read_checkpoint_head(CheckpointReader& reader, const std::string& magic, int version);
/// "<key> <%.17g of t_s: exact round trip>\n". Throws std::invalid_argument when t_s is not finite.
std::string checkpoint_time_line(const std::string& key, double t_s);
/// "<key> <n> v1 ... vn\n": a list of any length of doubles, each as checkpoint_hex_double (exact,
/// NaN and infinities kept), read back with CheckpointReader::value_list. For the variable parts of
/// a state (buffers, queues, optional values as lists of 0 or 1 record).
std::string checkpoint_value_list(const std::string& key, const std::vector<double>& values);
/// A component's state as a counted block: "state_chars <n>\n<state>\n" (read back with
/// read_checkpoint_state_block).
std::string checkpoint_state_block(const std::string& state);
/// Reads checkpoint_state_block's lines; `what` names the state in errors ("truncated inside the ...").
std::string read_checkpoint_state_block(CheckpointReader& reader, const std::string& what);

/// Options that do not change any estimate (transport, logging, where state lives, how often it is
/// saved, hot standby): left out of the configuration hash so that changing them keeps a checkpoint
/// valid. vehicle-id is left out too because it is checked on its own (a clearer reason).
const std::vector<std::string>& checkpoint_neutral_options();

/// Hash (16 lower-case hex digits, FNV-1a 64) of Options::values_as_text() lines ("name=value"),
/// skipping the options of checkpoint_neutral_options(). Order-sensitive: pass the sorted lines.
std::string config_hash_of(const std::vector<std::string>& values_as_text);

/// Throws std::invalid_argument when vehicle_id is empty or holds anything but letters, digits, '.',
/// '_' and '-' (it becomes part of a file name).
void check_checkpoint_vehicle_id(const std::string& vehicle_id);

/// Throws CheckpointError when the file was made for another vehicle or configuration hash.
void check_checkpoint_identity(const std::string& file_vehicle, const std::string& file_hash,
                               const std::string& vehicle_id, const std::string& config_hash);

/// Renames `path` to `<path>.bad-<unix_time_s>` (with `-2`, `-3`... if that exists). Never deletes.
/// Returns the new name. Throws std::runtime_error when the rename fails.
std::string move_checkpoint_aside(const std::string& path, int64_t unix_time_s);

/// What loading a checkpoint did.
enum class CheckpointLoadStatus {
  kNone,        ///< no file: fresh start.
  kRestored,    ///< the state was restored from it.
  kMovedAside,  ///< unusable (reason): moved aside to moved_to, fresh start.
};

struct CheckpointFileLoad {
  CheckpointLoadStatus status = CheckpointLoadStatus::kNone;
  std::string path;      ///< the checkpoint file looked at.
  std::string reason;    ///< why it was moved aside (kMovedAside).
  std::string moved_to;  ///< its new name (kMovedAside; empty if the move failed).
};

/// Reads `path` and hands its text to `restore`, which parses, checks and restores, and throws
/// (anything) when the file cannot be used, leaving the component's state untouched. No file: kNone.
/// When the file cannot be read or `restore` throws, the file is moved aside (unix_time_s names it)
/// and the reason returned. Never throws for file contents.
CheckpointFileLoad load_checkpoint_file(const std::string& path, int64_t unix_time_s,
                                        const std::function<void(const std::string& text)>& restore);

}  // namespace odonav
