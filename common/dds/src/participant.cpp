#include "odonav/dds/participant.hpp"

#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/dds/domain/qos/DomainParticipantQos.hpp>
#include <fastdds/dds/log/Log.hpp>
#include <fastdds/rtps/common/Guid.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cstdlib>
#include <functional>
#include <fstream>
#include <sstream>
#include <thread>
#include <stdexcept>
#include <utility>
#include <vector>

namespace odonav::dds {

using eprosima::fastdds::dds::DomainParticipant;
using eprosima::fastdds::dds::DomainParticipantFactory;
using eprosima::fastdds::dds::DomainParticipantQos;
using eprosima::fastrtps::types::ReturnCode_t;

namespace {

constexpr int kMaxDomainId = 232;  // RTPS port mapping limit with the default port parameters

std::string directory_of(const std::string& path) {
  const auto slash = path.find_last_of('/');
  if (slash == std::string::npos) return ".";
  if (slash == 0) return "/";
  return path.substr(0, slash);
}

// Fast DDS only logs why an XML file failed; check readability first for a precise message.
void load_xml_file(const std::string& path, const char* what) {
  if (!std::ifstream(path).good()) {
    throw std::runtime_error(std::string("odonav::dds::Participant: cannot read the ") + what + " file '" + path +
                             "' (missing or not readable)");
  }
  if (DomainParticipantFactory::get_instance()->load_XML_profiles_file(path) != ReturnCode_t::RETCODE_OK) {
    throw std::runtime_error(std::string("odonav::dds::Participant: Fast DDS rejected the ") + what + " file '" + path +
                             "' (not a valid Fast DDS XML profiles file; see the Fast DDS log)");
  }
}

// Sets each (name, value) in the participant's property policy, replacing a property of the same
// name the XML profile may already carry (the layer's material wins over the profile's).
void add_or_replace_properties(DomainParticipantQos& qos,
                               const std::vector<std::pair<std::string, std::string>>& properties) {
  auto& list = qos.properties().properties();
  for (const auto& [name, value] : properties) {
    bool replaced = false;
    for (auto& p : list) {
      if (p.name() == name) {
        p.value() = value;
        replaced = true;
      }
    }
    if (!replaced) list.emplace_back(name, value);
  }
}

// Fast DDS's own log verbosity from ODONAV_FASTDDS_LOG (see participant.hpp). Unknown values are
// an error: a typo must not silently leave the log quiet while someone is debugging discovery.
void apply_fast_dds_log_verbosity() {
  using eprosima::fastdds::dds::Log;
  const char* env = std::getenv(kFastDdsLogEnv);
  if (env == nullptr || *env == '\0') return;
  const std::string level = env;
  if (level == "error") {
    Log::SetVerbosity(Log::Kind::Error);
  } else if (level == "warning") {
    Log::SetVerbosity(Log::Kind::Warning);
  } else if (level == "info") {
    Log::SetVerbosity(Log::Kind::Info);
  } else {
    throw std::runtime_error(std::string("odonav::dds::Participant: ") + kFastDdsLogEnv + "='" + level +
                             "' is not one of error, warning, info");
  }
}

std::string guid_text(const eprosima::fastrtps::rtps::GUID_t& guid) {
  std::ostringstream s;
  s << guid.guidPrefix;
  return s.str();
}

bool has_property(const DomainParticipantQos& qos, const std::string& name) {
  for (const auto& p : qos.properties().properties())
    if (p.name() == name) return true;
  return false;
}

}  // namespace

namespace detail {

std::mutex& xml_profiles_mutex() {
  static std::mutex m;
  return m;
}

ParticipantEventLog::~ParticipantEventLog() {
  if (!space_secure_discoveries_) return;
  const Counts c = counts();
  // One line with what the participant met over its life: the figures behind "a flood of strangers
  // at start-up cost nothing" (docs/DDS.md §6).
  spdlog::info(
      "odonav::dds: {}: DDS Security summary: {} participants discovered, {} without credentials, "
      "{} refused, {} authenticated; {} handshake set-ups spaced, {} held back for {:.3f} s in total; "
      "{} strangers not tracked",
      own_name_, c.discovered, c.without_credentials, c.refused, c.authenticated, c.setups_spaced, c.setups_delayed,
      c.setup_wait_s, c.untracked);
}

ParticipantEventLog::Counts ParticipantEventLog::counts() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return counts_;
}

bool ParticipantEventLog::remember(const std::string& guid, const std::string& name, bool credentials) {
  ++counts_.discovered;
  if (!credentials) ++counts_.without_credentials;
  if (peers_.size() >= kMaxTrackedStrangers && peers_.find(guid) == peers_.end()) {
    ++counts_.untracked;
    return false;
  }
  Peer& peer = peers_[guid];
  peer.name = name;
  peer.discovered = std::chrono::steady_clock::now();
  peer.credentials = credentials;
  return true;
}

void ParticipantEventLog::on_discovered_secure(const std::string& name, const std::string& guid, bool credentials) {
  if (!credentials) {
    // Fast DDS refuses it right after this callback, before any handshake set-up: nothing to
    // space, and a flood of them is logged within a budget.
    LogBudget::Grant grant;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      remember(guid, name, false);
      grant = stranger_log_.take(std::chrono::steady_clock::now());
    }
    if (grant.log) {
      spdlog::warn(
          "odonav::dds: {} discovered participant '{}' ({}) without DDS Security credentials: refused, "
          "it gets no data{}",
          own_name_, name, guid,
          grant.left_out == 0 ? std::string() : " (" + std::to_string(grant.left_out) + " more refusals not logged)");
    }
    return;
  }
  spdlog::info("odonav::dds: {} discovered participant '{}' ({})", own_name_, name, guid);
  {
    std::lock_guard<std::mutex> lock(mutex_);
    remember(guid, name, true);
  }
  // Fast DDS prepares the new participant's handshake right after this returns, on this thread
  // (see the class comment): wait if another thread's preparation may still be running.
  std::lock_guard<std::mutex> spacing(spacing_mutex_);
  const auto now = std::chrono::steady_clock::now();
  const auto start = spacing_.admit(std::hash<std::thread::id>{}(std::this_thread::get_id()), now);
  if (start > now) std::this_thread::sleep_until(start);
  std::lock_guard<std::mutex> lock(mutex_);
  counts_.setups_spaced = spacing_.admitted();
  counts_.setups_delayed = spacing_.delayed();
  counts_.setup_wait_s = std::chrono::duration<double>(spacing_.waited()).count();
}

void ParticipantEventLog::on_left(const std::string& name, const std::string& guid, bool lease_expired) {
  bool stranger = false;
  LogBudget::Grant grant;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    auto peer = peers_.find(guid);
    if (peer != peers_.end()) {
      // Refused, or never able to authenticate: a peer with credentials whose handshake is still
      // pending is one of ours (perhaps caught by the race), so its loss stays a warning.
      stranger = !peer->second.credentials || peer->second.auth == Peer::Auth::kRefused;
      peers_.erase(peer);
    }
    if (stranger) grant = stranger_left_log_.take(std::chrono::steady_clock::now());
  }
  if (stranger) {
    // Someone refused is gone: no loss to us, and a flood's end must not bury the log in warnings.
    if (grant.log) {
      spdlog::info("odonav::dds: {}: refused participant '{}' ({}) {}{}", own_name_, name, guid,
                   lease_expired ? "gone (lease expired)" : "left",
                   grant.left_out == 0 ? std::string() : " (" + std::to_string(grant.left_out) + " more not logged)");
    }
    return;
  }
  if (!lease_expired) {
    spdlog::info("odonav::dds: {}: participant '{}' ({}) left", own_name_, name, guid);
  } else {
    spdlog::warn(
        "odonav::dds: {}: participant '{}' ({}) lost: its lease expired (process dead, host down "
        "or link cut)",
        own_name_, name, guid);
  }
}

void ParticipantEventLog::on_participant_discovery(DomainParticipant* /*participant*/,
                                                   eprosima::fastrtps::rtps::ParticipantDiscoveryInfo&& info) {
  using Status = eprosima::fastrtps::rtps::ParticipantDiscoveryInfo::DISCOVERY_STATUS;
  // Runs for every announcement of every participant (CHANGED_QOS each second): nothing is
  // formatted before the status says it is needed.
  switch (info.status) {
    case Status::DISCOVERED_PARTICIPANT: {
      const std::string name = info.info.m_participantName.to_string();
      const std::string guid = guid_text(info.info.m_guid);
      {
        std::lock_guard<std::mutex> lock(mutex_);
        if (names_.size() < kMaxNamedParticipants) names_[guid] = name;
      }
      if (!space_secure_discoveries_) {
        spdlog::info("odonav::dds: {} discovered participant '{}' ({})", own_name_, name, guid);
        break;
      }
#if HAVE_SECURITY
      // Fast DDS 2.9 (PKIDH::validate_remote_identity) refuses a participant without an identity
      // token before it prepares anything for it.
      const bool credentials = !info.info.identity_token_.is_nil();
#else
      const bool credentials = true;
#endif
      on_discovered_secure(name, guid, credentials);
      break;
    }
    case Status::CHANGED_QOS_PARTICIPANT: break;
    case Status::REMOVED_PARTICIPANT:
    case Status::DROPPED_PARTICIPANT: {
      std::lock_guard<std::mutex> lock(mutex_);
      names_.erase(guid_text(info.info.m_guid));
    }
      on_left(info.info.m_participantName.to_string(), guid_text(info.info.m_guid),
              info.status == Status::DROPPED_PARTICIPANT);
      break;
  }
}

#if HAVE_SECURITY
void ParticipantEventLog::onParticipantAuthentication(DomainParticipant* /*participant*/,
                                                      eprosima::fastrtps::rtps::ParticipantAuthenticationInfo&& info) {
  using Status = eprosima::fastrtps::rtps::ParticipantAuthenticationInfo::AUTHENTICATION_STATUS;
  const std::string guid = guid_text(info.guid);
  const bool authorized = info.status == Status::AUTHORIZED_PARTICIPANT;
  std::uint64_t refusals = 0;
  bool credentials = true;
  LogBudget::Grant grant;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    auto peer = peers_.find(guid);
    if (peer == peers_.end() && peers_.size() < kMaxTrackedStrangers)
      peer = peers_.emplace(guid, Peer{"", std::chrono::steady_clock::now()}).first;
    if (peer != peers_.end()) {
      peer->second.auth = authorized ? Peer::Auth::kAuthenticated : Peer::Auth::kRefused;
      credentials = peer->second.credentials;
      if (!authorized) refusals = ++peer->second.refusals;
    } else if (!authorized) {
      refusals = 1;  // not tracked: counted as a first refusal
    }
    if (authorized) {
      ++counts_.authenticated;
    } else if (refusals == 1) {
      ++counts_.refused;
      // Without credentials the discovery line already said it; a foreign identity gets its own
      // line, within the same budget.
      if (credentials) grant = stranger_log_.take(std::chrono::steady_clock::now());
    }
  }
  if (authorized) {
    spdlog::info("odonav::dds: {} authenticated participant {}", own_name_, guid);
    return;
  }
  // A refused participant keeps announcing itself, and may be refused again: warn once.
  if (grant.log) {
    spdlog::warn(
        "odonav::dds: {}: participant {} failed DDS Security authentication (certificate not from "
        "our identity CA, or invalid permissions): it gets no data{}",
        own_name_, guid,
        grant.left_out == 0 ? std::string() : " (" + std::to_string(grant.left_out) + " more refusals not logged)");
  } else if (refusals > 1) {
    spdlog::debug("odonav::dds: {}: participant {} refused again ({} times)", own_name_, guid, refusals);
  }
}
#endif

std::vector<ParticipantEventLog::UnauthenticatedParticipant> ParticipantEventLog::unauthenticated(
    std::chrono::steady_clock::duration pending_for) const {
  const auto now = std::chrono::steady_clock::now();
  std::vector<UnauthenticatedParticipant> out;
  std::lock_guard<std::mutex> lock(mutex_);
  for (const auto& [guid, peer] : peers_) {
    const auto age = now - peer.discovered;
    const bool refused = peer.auth == Peer::Auth::kRefused;
    if (refused || (peer.auth == Peer::Auth::kPending && age >= pending_for))
      out.push_back({peer.name, guid, refused, std::chrono::duration<double>(age).count()});
  }
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) { return a.age_s > b.age_s; });
  return out;
}

void ParticipantEventLog::on_subscriber_discovery(DomainParticipant* /*participant*/,
                                                  eprosima::fastrtps::rtps::ReaderDiscoveryInfo&& info) {
  using Status = eprosima::fastrtps::rtps::ReaderDiscoveryInfo::DISCOVERY_STATUS;
  std::lock_guard<std::mutex> lock(mutex_);
  if (info.status == Status::REMOVED_READER) {
    reader_reliable_.erase(info.info.guid());
  } else if (reader_reliable_.size() < 16 * kMaxNamedParticipants || reader_reliable_.count(info.info.guid()) > 0) {
    reader_reliable_[info.info.guid()] =
        info.info.m_qos.m_reliability.kind == eprosima::fastdds::dds::RELIABLE_RELIABILITY_QOS;
  }
}

bool ParticipantEventLog::reader_is_reliable(const eprosima::fastrtps::rtps::GUID_t& guid) const {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = reader_reliable_.find(guid);
  return it == reader_reliable_.end() || it->second;
}

std::string ParticipantEventLog::name_of(const std::string& guid_prefix) const {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = names_.find(guid_prefix);
  return it == names_.end() ? std::string() : it->second;
}

ParticipantCore::ParticipantCore(DomainParticipant* participant, std::string description,
                                 std::optional<SecurityMaterial> security,
                                 std::unique_ptr<ParticipantEventLog> event_log)
    : participant_(participant),
      description_(std::move(description)),
      security_(std::move(security)),
      event_log_(std::move(event_log)) {
  publisher_ = participant_->create_publisher(eprosima::fastdds::dds::PUBLISHER_QOS_DEFAULT);
  subscriber_ = participant_->create_subscriber(eprosima::fastdds::dds::SUBSCRIBER_QOS_DEFAULT);
  if (publisher_ == nullptr || subscriber_ == nullptr) {
    participant_->delete_contained_entities();
    participant_->set_listener(nullptr);
    DomainParticipantFactory::get_instance()->delete_participant(participant_);
    throw std::runtime_error("odonav::dds::Participant: cannot create the publisher/subscriber of " + description_);
  }
}

ParticipantCore::~ParticipantCore() {
  // Endpoints hold this core, so none is left: delete what remains (topics, publisher, subscriber).
  if (participant_->delete_contained_entities() != ReturnCode_t::RETCODE_OK) {
    spdlog::error("odonav::dds: delete_contained_entities failed for {}", description_);
  }
  participant_->set_listener(nullptr);  // the listener dies with this core
  if (DomainParticipantFactory::get_instance()->delete_participant(participant_) != ReturnCode_t::RETCODE_OK) {
    spdlog::error("odonav::dds: delete_participant failed for {}", description_);
  }
}

std::string ParticipantCore::participant_name(const eprosima::fastrtps::rtps::GUID_t& endpoint) const {
  const std::string prefix = guid_text(endpoint);
  const std::string name = event_log_ ? event_log_->name_of(prefix) : std::string();
  return name.empty() ? prefix : name + " (" + prefix + ")";
}

eprosima::fastdds::dds::Topic& ParticipantCore::topic(const std::string& topic_name,
                                                      eprosima::fastdds::dds::TypeSupport type) {
  std::lock_guard<std::mutex> lock(mutex_);
  const std::string type_name = type.get_type_name();
  if (participant_->find_type(type_name).empty()) {
    if (type.register_type(participant_) != ReturnCode_t::RETCODE_OK) {
      throw std::runtime_error("odonav::dds: cannot register type '" + type_name + "' in " + description_);
    }
  }
  if (auto* existing = participant_->lookup_topicdescription(topic_name)) {
    auto* topic = dynamic_cast<eprosima::fastdds::dds::Topic*>(existing);
    if (topic == nullptr || existing->get_type_name() != type_name) {
      throw std::runtime_error("odonav::dds: topic '" + topic_name + "' already exists with type '" +
                               existing->get_type_name() + "', not '" + type_name + "' (" + description_ + ")");
    }
    return *topic;
  }
  auto* topic = participant_->create_topic(topic_name, type_name, eprosima::fastdds::dds::TOPIC_QOS_DEFAULT);
  if (topic == nullptr) {
    throw std::runtime_error("odonav::dds: cannot create topic '" + topic_name + "' of type '" + type_name + "' in " +
                             description_);
  }
  return *topic;
}

}  // namespace detail

std::optional<std::string> profiles_file_or_environment(const std::string& given) {
  if (!given.empty()) return given;
  const char* env = std::getenv("FASTRTPS_DEFAULT_PROFILES_FILE");
  if (env == nullptr || *env == '\0') return std::nullopt;
  return std::string(env);
}

Participant::Participant(const ParticipantOptions& options) : domain_id_(options.domain_id) {
  const std::optional<std::string> file = profiles_file_or_environment(options.profiles_file);
  if (!file)
    throw std::runtime_error(
        "odonav::dds::Participant: no participant profiles file given and FASTRTPS_DEFAULT_PROFILES_FILE is not set");
  profiles_file_ = *file;
  qos_file_ = options.qos_file.empty() ? directory_of(profiles_file_) + "/qos.xml" : options.qos_file;
  std::optional<SecurityMaterial> security;
  try {
    security = resolve_security_material(options.security_dir, options.security_identity, options.participant_name);
  } catch (const std::invalid_argument& e) {
    throw std::runtime_error(std::string("odonav::dds::Participant: ") + e.what());
  }
  std::string description = "participant profile '" + options.participant_profile + "' of file '" + profiles_file_ +
                            "', QoS file '" + qos_file_ + "', domain " + std::to_string(domain_id_);
  if (security) description += ", " + security->describe();
  if (domain_id_ < 0 || domain_id_ > kMaxDomainId) {
    throw std::runtime_error("odonav::dds::Participant: domain id " + std::to_string(domain_id_) + " is outside 0.." +
                             std::to_string(kMaxDomainId) + " (" + description + ")");
  }

  apply_fast_dds_log_verbosity();
  std::unique_lock<std::mutex> profiles_lock(detail::xml_profiles_mutex());
  load_xml_file(profiles_file_, "participant profiles");
  load_xml_file(qos_file_, "QoS profiles");

  auto* factory = DomainParticipantFactory::get_instance();
  DomainParticipantQos qos;
  const bool has_profile =
      factory->get_participant_qos_from_profile(options.participant_profile, qos) == ReturnCode_t::RETCODE_OK;
  profiles_lock.unlock();
  if (!has_profile) {
    throw std::runtime_error("odonav::dds::Participant: no participant profile named '" + options.participant_profile +
                             "' in '" + profiles_file_ + "' (or in another loaded XML file)");
  }
  if (!options.participant_name.empty()) qos.name(options.participant_name);
  if (security) {
    check_security_material(*security);
    add_or_replace_properties(qos, security_properties(*security));
  } else if (has_property(qos, "dds.sec.auth.plugin") &&
             !has_property(qos, "dds.sec.auth.builtin.PKI-DH.identity_certificate")) {
    // secure.xml names the plugins and the shared files only: the identity comes from the layer.
    throw std::runtime_error("odonav::dds::Participant: " + description +
                             " enables DDS Security but names no identity certificate: give the security "
                             "directory (--security-dir or " +
                             std::string(kSecurityDirEnv) + ")");
  }
  // The listener takes no status (StatusMask::none()): endpoint statuses stay with the endpoints;
  // participant discovery and authentication reach it regardless of the mask.
  auto event_log = std::make_unique<detail::ParticipantEventLog>(
      options.participant_name.empty() ? options.participant_profile : options.participant_name,
      has_property(qos, "dds.sec.auth.plugin"));
  DomainParticipant* participant =
      factory->create_participant(domain_id_, qos, event_log.get(), eprosima::fastdds::dds::StatusMask::none());
  if (participant == nullptr) {
    std::string why = " (see the Fast DDS log)";
    if (security) {
      // Fast DDS 2.9 refuses a secure participant without saying why (docs/DDS.md §6).
      why =
          " (DDS Security refused it: check that the certificate is signed by identity_ca.cert.pem and "
          "matches key.pem, that governance and permissions are signed by permissions_ca.cert.pem, that "
          "the permissions subject_name is the certificate subject in RFC 2253 order (CN=...,O=...,C=...) "
          "and still valid, and that they grant domain " +
          std::to_string(domain_id_) + "; see the Fast DDS log)";
    }
    throw std::runtime_error("odonav::dds::Participant: Fast DDS could not create the participant from " + description +
                             why);
  }
  if (security) spdlog::info("odonav::dds: participant in domain {} uses {}", domain_id_, security->describe());
  core_ = std::make_shared<detail::ParticipantCore>(participant, description, security, std::move(event_log));
}

std::vector<detail::ParticipantEventLog::UnauthenticatedParticipant> Participant::unauthenticated_participants(
    std::chrono::steady_clock::duration pending_for) const {
  const auto* log = core_->event_log();
  return log == nullptr ? std::vector<detail::ParticipantEventLog::UnauthenticatedParticipant>{}
                        : log->unauthenticated(pending_for);
}

}  // namespace odonav::dds
