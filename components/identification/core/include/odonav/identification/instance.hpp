#pragma once
// Which identification instance this is (hot standby, README "Hot standby") and the names derived
// from it that must stay the same across restarts: the checkpoint file, and the names an earlier
// version gave its Fast DDS persistence (SQLite file, persistence GUID; the scale-factor writer has
// no persistence any more, docs/DDS.md section 5). Middleware-free: plain strings.
#include <string>

namespace odonav::identification {

/// The instance name a lone identification publishes as ScaleFactor.source.
inline constexpr const char* kDefaultIdentificationInstance = "identification";

/// Throws std::invalid_argument naming the instance when it is empty, longer than 64 characters,
/// holds anything but letters, digits, '.', '_', '-' and '/', starts or ends with '/', holds "//"
/// or "..", or is "command" (reserved: a commanded K is not published by an identification).
void validate_identification_instance(const std::string& instance);

/// The instance as one file-name part: '/' becomes '_' ("identification/standby" ->
/// "identification_standby"). Validates first (std::invalid_argument).
std::string instance_file_part(const std::string& instance);

/// The checkpoint file of one instance: `<state_dir>/identification-<vehicle>.ckpt` for the default
/// instance (the name checkpoint_path() gives, so existing state is kept), else
/// `<state_dir>/<instance_file_part>-<vehicle>.ckpt`: two instances may share a state directory.
/// Throws std::invalid_argument for a bad vehicle id (checkpoint_path) or instance.
std::string instance_checkpoint_path(const std::string& state_dir, const std::string& vehicle_id,
                                     const std::string& instance);

/// The SQLite file an earlier version's TRANSIENT scale-factor writer kept (not used by the node):
/// `<state_dir>/<vehicle>-<instance_file_part>.db`. Same checks as instance_checkpoint_path.
std::string persistence_db_path(const std::string& state_dir, const std::string& vehicle_id,
                                const std::string& instance);

/// The fixed Fast DDS persistence GUID (property dds.persistence.guid) of the scale-factor writer
/// of (vehicle, instance), in Fast DDS's text form "p0.p1.....p11|e0.e1.e2.e3" (lower-case hex).
/// Derivation (stable across restarts, builds and hosts; different for every vehicle and instance):
///   bytes 0-1  = 'o', 'd' (6f.64): never eProsima's vendor prefix 01.0f, so it cannot collide with
///                a live participant's GUID prefix;
///   bytes 2-9  = FNV-1a 64 of "odonav-persistence\n<vehicle>\n<instance>", big-endian;
///   bytes 10-11 = the two high bytes of FNV-1a 64 of "<instance>\n<vehicle>" (a second hash, so
///                two names colliding in the first one still differ);
///   entity id  = 00.00.01.02: a user-defined writer of a keyed topic (RTPS entity kind 0x02).
/// Validates the instance (std::invalid_argument) and the vehicle (non-empty).
std::string persistence_guid(const std::string& vehicle_id, const std::string& instance);

}  // namespace odonav::identification
