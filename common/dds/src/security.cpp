// DDS Security material: paths, checks, environment and the Fast DDS properties (security.hpp).
#include "odonav/dds/security.hpp"

#include <cstdlib>
#include <fstream>
#include <stdexcept>

#include "odonav/config.hpp"

namespace odonav::dds {

namespace {

std::string env_or_empty(const char* name) {
  const char* value = std::getenv(name);
  return value == nullptr ? std::string() : std::string(value);
}

bool is_plain_name(const std::string& name) {
  if (name.empty() || name == "." || name == "..") return false;
  for (const char c : name) {
    const bool ok =
        (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '-' || c == '_' || c == '.';
    if (!ok) return false;
  }
  return true;
}

std::string join(const std::string& directory, const std::string& name) {
  if (!directory.empty() && directory.back() == '/') return directory + name;
  return directory + "/" + name;
}

}  // namespace

std::string SecurityMaterial::describe() const {
  return "DDS Security identity '" + identity + "' from '" + directory + "'";
}

SecurityMaterial security_material_paths(const std::string& directory, const std::string& identity) {
  if (directory.empty()) throw std::invalid_argument("DDS Security: the security directory is empty");
  if (!is_plain_name(identity)) {
    throw std::invalid_argument("DDS Security: identity '" + identity +
                                "' is not a plain name (letters, digits, '-', '_', '.'): it names a "
                                "subdirectory of the security directory '" +
                                directory + "'");
  }
  SecurityMaterial m;
  m.directory = directory;
  m.identity = identity;
  m.identity_ca_file = join(directory, "identity_ca.cert.pem");
  m.permissions_ca_file = join(directory, "permissions_ca.cert.pem");
  m.governance_file = join(directory, "governance.p7s");
  const std::string own = join(directory, identity);
  m.certificate_file = join(own, "cert.pem");
  m.private_key_file = join(own, "key.pem");
  m.permissions_file = join(own, "permissions.p7s");
  return m;
}

void check_security_material(const SecurityMaterial& m) {
  const std::pair<const std::string*, const char*> files[] = {
      {&m.identity_ca_file, "identity CA certificate"},
      {&m.permissions_ca_file, "permissions CA certificate"},
      {&m.governance_file, "signed governance document"},
      {&m.certificate_file, "identity certificate"},
      {&m.private_key_file, "private key"},
      {&m.permissions_file, "signed permissions document"},
  };
  for (const auto& [path, what] : files) {
    std::ifstream in(*path);
    if (!in.good() || in.peek() == std::ifstream::traits_type::eof()) {
      throw std::runtime_error("DDS Security: cannot read the " + std::string(what) + " '" + *path + "' of " +
                               m.describe() +
                               " (missing, empty or not readable by this user; make it with "
                               "deploy/security/make-pki)");
    }
  }
}

std::optional<SecurityMaterial> resolve_security_material(const std::string& directory_option,
                                                          const std::string& identity_option,
                                                          const std::string& participant_name) {
  const std::string directory = directory_option.empty() ? env_or_empty(kSecurityDirEnv) : directory_option;
  if (directory.empty()) return std::nullopt;
  std::string identity = identity_option.empty() ? env_or_empty(kSecurityIdentityEnv) : identity_option;
  if (identity.empty()) identity = participant_name;
  if (identity.empty()) {
    throw std::invalid_argument("DDS Security: security directory '" + directory +
                                "' given but no identity: set --security-identity, " + kSecurityIdentityEnv +
                                " or a participant name");
  }
  return security_material_paths(directory, identity);
}

std::vector<std::pair<std::string, std::string>> security_properties(const SecurityMaterial& m) {
  const std::string auth = "dds.sec.auth.builtin.PKI-DH.";
  const std::string access = "dds.sec.access.builtin.Access-Permissions.";
  return {
      {"dds.sec.auth.plugin", "builtin.PKI-DH"},
      {auth + "identity_ca", "file://" + m.identity_ca_file},
      {auth + "identity_certificate", "file://" + m.certificate_file},
      {auth + "private_key", "file://" + m.private_key_file},
      {"dds.sec.access.plugin", "builtin.Access-Permissions"},
      {access + "permissions_ca", "file://" + m.permissions_ca_file},
      {access + "governance", "file://" + m.governance_file},
      {access + "permissions", "file://" + m.permissions_file},
      {"dds.sec.crypto.plugin", "builtin.AES-GCM-GMAC"},
  };
}

void add_security_options(Options& o) {
  o.add_string("security-dir", "",
               std::string("DDS Security material directory (deploy/security/make-pki layout); empty = $") +
                   kSecurityDirEnv + ", else no DDS Security");
  o.add_string("security-identity", "",
               std::string("identity (subdirectory of the security directory); empty = $") + kSecurityIdentityEnv +
                   ", else the component name");
}

std::pair<std::string, std::string> security_options_from(const Options& o) {
  return {o.get_string("security-dir"), o.get_string("security-identity")};
}

}  // namespace odonav::dds
