#pragma once
// DDS Security material of a participant (so that only authenticated, authorized components exchange
// data on a vehicle network): which files, where they come from, and the
// Fast DDS 2.9 properties that switch the builtin plugins on (PKI-DH authentication,
// Access-Permissions access control, AES-GCM-GMAC cryptography).
//
// Design: security is orthogonal to the transport profile. Any participant profile (loopback.xml in
// tests, vehicle.xml on an ECU, the discovery-server clients) becomes a secure participant when a
// security directory is given: the layer adds the dds.sec.* properties on top of the profile's QoS,
// overriding any the XML already set. Without a security directory nothing changes (profiles that
// carry their own dds.sec.* properties, like secure.xml, still work as written).
//
// Security directory layout (what deploy/security/make-pki writes, and what the layer reads):
//   <dir>/identity_ca.cert.pem            CA that signed every identity certificate
//   <dir>/permissions_ca.cert.pem         CA that signed governance and every permissions document
//   <dir>/governance.p7s                  domain governance, S/MIME signed
//   <dir>/<identity>/cert.pem             the identity's certificate (subject CN = identity)
//   <dir>/<identity>/key.pem              its private key (readable by the service user only)
//   <dir>/<identity>/permissions.p7s      its grants, S/MIME signed
// <identity> is the component name ("odonav-gateway", "odonav-ground", ...).
//
// Sources, first found wins: ParticipantOptions::security_dir / security_identity (the
// --security-dir / --security-identity flags, see add_security_options), then the environment
// variables ODONAV_SECURITY_DIR / ODONAV_SECURITY_IDENTITY (systemd EnvironmentFile), and for the
// identity finally the participant name.
//
// No DDS headers here: tools that only declare the flags need not include Fast DDS.
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace odonav {
class Options;
}

namespace odonav::dds {

/// Environment variable naming the security directory (absolute or relative to the working
/// directory). Unset or empty: no security unless given by option.
inline constexpr const char* kSecurityDirEnv = "ODONAV_SECURITY_DIR";
/// Environment variable naming the identity (subdirectory of the security directory).
inline constexpr const char* kSecurityIdentityEnv = "ODONAV_SECURITY_IDENTITY";

/// The files of one secure participant (paths as given, not canonicalised).
struct SecurityMaterial {
  std::string directory;            ///< the security directory
  std::string identity;             ///< the identity name (subdirectory)
  std::string identity_ca_file;     ///< <dir>/identity_ca.cert.pem
  std::string permissions_ca_file;  ///< <dir>/permissions_ca.cert.pem
  std::string governance_file;      ///< <dir>/governance.p7s
  std::string certificate_file;     ///< <dir>/<identity>/cert.pem
  std::string private_key_file;     ///< <dir>/<identity>/key.pem
  std::string permissions_file;     ///< <dir>/<identity>/permissions.p7s

  /// "DDS Security identity 'odonav-gateway' from '/etc/odonav/security'", for messages.
  std::string describe() const;
};

/// The paths of `identity`'s material in `directory` (layout in the file comment). Checks nothing.
/// Throws std::invalid_argument if directory or identity is empty, or if identity is not a plain
/// name (letters, digits, '-', '_', '.'; not "." or ".."), since it becomes a path component.
SecurityMaterial security_material_paths(const std::string& directory, const std::string& identity);

/// Checks that every file of `material` can be read. Throws std::runtime_error naming the first
/// missing or unreadable file and what it is (Fast DDS itself only fails participant creation
/// without saying why).
void check_security_material(const SecurityMaterial& material);

/// Resolves the material of a participant from explicit values and the environment:
/// directory = `directory_option` if not empty, else $ODONAV_SECURITY_DIR, else none (returns
/// nullopt: not secure); identity = `identity_option` if not empty, else $ODONAV_SECURITY_IDENTITY,
/// else `participant_name`. Throws std::invalid_argument when a directory is set but no identity
/// can be found (all three empty) or the identity is not a plain name.
std::optional<SecurityMaterial> resolve_security_material(const std::string& directory_option,
                                                          const std::string& identity_option,
                                                          const std::string& participant_name);

/// The Fast DDS 2.9 participant properties (name, value) that enable the builtin security plugins
/// with `material`: dds.sec.auth.plugin = builtin.PKI-DH and its identity_ca /
/// identity_certificate / private_key, dds.sec.access.plugin = builtin.Access-Permissions and its
/// permissions_ca / governance / permissions, dds.sec.crypto.plugin = builtin.AES-GCM-GMAC.
/// File values are "file://" + the path as given (what Fast DDS 2.9 parses: "file:///abs/path").
std::vector<std::pair<std::string, std::string>> security_properties(const SecurityMaterial& material);

/// Declares --security-dir (empty = $ODONAV_SECURITY_DIR, else no DDS Security) and
/// --security-identity (empty = $ODONAV_SECURITY_IDENTITY, else the component name) on a tool's
/// options. Read them back with security_options_from.
void add_security_options(Options& options);
/// The two values declared by add_security_options: {directory, identity}, possibly empty.
std::pair<std::string, std::string> security_options_from(const Options& options);

}  // namespace odonav::dds
