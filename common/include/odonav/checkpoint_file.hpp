#pragma once
// The checkpoint FILE every checkpointing component shares (odonav-identification,
// odonav-calibration, odonav-dead-reckoning), middleware-free: one envelope, its checksum, the
// identity checks (component, version, vehicle, configuration), the configuration hash and the
// load policy (an unusable file is moved aside, never deleted or overwritten). The state inside is
// serialised with checkpoint_state.hpp; restart_policy.hpp decides when a checkpoint is written.
//
// A file is one JSON object and a line break:
//   {"checksum":"<16 hex digits>","component":"identification","config_hash":"<16 hex digits>",
//    "format":"odonav-checkpoint","payload":{...the component's state...},"vehicle":"vehicle-07",
//    "version":3}
// checksum: FNV-1a 64 of the compact JSON text (nlohmann dump, keys sorted) of the object without
// "checksum". A reader re-dumps what it parsed, which gives the same text for an intact file (the
// numbers round-trip exactly), so a changed value is caught even when the text stays valid JSON.
// version: the component's; it is bumped whenever anything in its payload changes, and a file of
// another version is refused (moved aside: fresh start) rather than half understood.
// Files are written with write_file_atomically (safe_output.hpp): temporary name, fsync, rename over
// the previous checkpoint, fsync of the directory, so a kill -9 leaves the old or the new one.
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "odonav/checkpoint_state.hpp"

namespace odonav {

/// "format" of every checkpoint file.
inline constexpr const char* kCheckpointFormat = "odonav-checkpoint";

/// Who wrote a checkpoint, and for what: a file is used only when all four match.
struct CheckpointIdentity {
  std::string component;    ///< "identification", "calibration", "dead-reckoning"
  int version = 0;          ///< of the component's payload
  std::string vehicle_id;   ///< the vehicle whose data made the state
  std::string config_hash;  ///< config_hash_of() of the run that wrote it
};

/// FNV-1a 64 of text, continuing from h.
uint64_t checkpoint_fnv1a64(const std::string& text, uint64_t h = 1469598103934665603ULL);
/// v as 16 lower-case hex digits.
std::string checkpoint_hex16(uint64_t v);

/// The file text of `payload` (a JSON object) under `identity`. Throws std::invalid_argument when
/// the component, vehicle or hash is empty.
std::string seal_checkpoint(const CheckpointIdentity& identity, StateJson payload);
/// An unsealed file: who wrote it, and its payload.
struct CheckpointContents {
  CheckpointIdentity identity;
  StateJson payload;
};
/// Parses a file text and checks format and checksum (not who wrote it: check_checkpoint_identity).
/// Throws CheckpointError: "empty file", "truncated ...", "not an odonav checkpoint ...", "an older
/// text checkpoint ...", "no checksum ...", "checksum mismatch: the file is corrupt", a missing or
/// malformed envelope field.
CheckpointContents unseal_checkpoint(const std::string& text);
/// Throws CheckpointError when the file was made by another component, in another version, for
/// another vehicle or with another configuration hash (each named with both values).
void check_checkpoint_identity(const CheckpointIdentity& file, const CheckpointIdentity& expected);

/// A component's checkpoint from a file's identity and payload: its state_fields read from the
/// payload, vehicle and configuration hash from the envelope. Throws CheckpointError naming a field.
template <class Checkpoint>
Checkpoint checkpoint_from_payload(const CheckpointIdentity& id, const StateJson& payload) {
  Checkpoint c;
  StateIn in(payload, "");
  state_fields(in, c);
  c.vehicle_id = id.vehicle_id;
  c.config_hash = id.config_hash;
  return c;
}

/// One component's checkpoint files: the component named in the envelope and in the file name, and
/// the version of its payload. A Checkpoint type has vehicle_id and config_hash members and a free
/// state_fields (checkpoint_state.hpp) for the rest of its payload.
struct CheckpointKind {
  const char* component;  ///< "identification", "calibration", "dead-reckoning"
  int version;            ///< of the component's payload
  CheckpointIdentity identity(const std::string& vehicle_id, const std::string& config_hash) const {
    return {component, version, vehicle_id, config_hash};
  }
  /// <state_dir>/<component>-<vehicle_id>.ckpt. Throws std::invalid_argument for a vehicle id that
  /// cannot name a file (check_checkpoint_vehicle_id).
  std::string path(const std::string& state_dir, const std::string& vehicle_id) const;
  /// The file text of checkpoint c (the caller checks its values first).
  template <class Checkpoint>
  std::string seal(const Checkpoint& c) const {
    return seal_checkpoint(identity(c.vehicle_id, c.config_hash), to_state(c));
  }
  /// A file text of this kind, for any vehicle and configuration. Throws CheckpointError when the
  /// file is damaged, of another component or version, or a field is missing or out of range.
  template <class Checkpoint>
  Checkpoint parse(const std::string& text) const {
    const CheckpointContents contents = unseal_checkpoint(text);
    const CheckpointIdentity& id = contents.identity;
    check_checkpoint_identity(id, identity(id.vehicle_id, id.config_hash));
    return checkpoint_from_payload<Checkpoint>(id, contents.payload);
  }
};

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

/// Reads `path`, unseals it, checks it was made by `expected` (component, version, vehicle,
/// configuration) and hands the payload to `restore`, which restores and throws (anything) when the
/// state cannot be used, leaving the component's state untouched. No file: kNone. When the file
/// cannot be read or used, it is moved aside (unix_time_s names it) and the reason returned. Never
/// throws for file contents.
CheckpointFileLoad load_checkpoint_file(const std::string& path, int64_t unix_time_s,
                                        const CheckpointIdentity& expected,
                                        const std::function<void(const StateJson& payload)>& restore);

}  // namespace odonav
