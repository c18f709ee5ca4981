#pragma once
// The DDS participant of a process, created from an XML participant profile, with the odonav QoS
// profiles (qos.xml) loaded. Every failing step throws std::runtime_error naming the file, the
// profile and the domain, so a misconfigured deployment says what is wrong.
#include <fastdds/dds/domain/DomainParticipant.hpp>
#include <fastdds/dds/domain/DomainParticipantListener.hpp>
#include <fastdds/dds/publisher/Publisher.hpp>
#include <fastdds/dds/subscriber/Subscriber.hpp>
#include <fastdds/dds/topic/Topic.hpp>
#include <fastdds/dds/topic/TypeSupport.hpp>

#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "odonav/peer_tracker.hpp"

#include "odonav/dds/secure_discovery.hpp"
#include "odonav/dds/security.hpp"

namespace odonav::dds {

/// Where the participant comes from.
struct ParticipantOptions {
  /// Fast DDS XML file holding the participant profile. Empty: the file named by the environment
  /// variable FASTRTPS_DEFAULT_PROFILES_FILE (an error if that is unset too).
  std::string profiles_file;
  /// Name of the <participant profile_name="..."> in profiles_file.
  std::string participant_profile = "loopback_only";
  /// Fast DDS XML file with the data_writer / data_reader profiles. Empty: "qos.xml" in the
  /// directory of profiles_file (deploy/profiles/ keeps both side by side).
  std::string qos_file;
  /// DDS domain id, 0..232. Participants only see each other within one domain.
  int domain_id = 0;
  /// Participant name shown by discovery tools (e.g. "odonav-gateway"). Empty: the profile's.
  std::string participant_name;
  /// DDS Security material directory (layout: security.hpp). Empty: $ODONAV_SECURITY_DIR; if that
  /// is unset or empty too, the participant is exactly what the profile says (no security added).
  std::string security_dir;
  /// Identity in security_dir. Empty: $ODONAV_SECURITY_IDENTITY, else participant_name.
  std::string security_identity;
};

/// The participant profiles file: `given`, else $FASTRTPS_DEFAULT_PROFILES_FILE; nullopt when both
/// are empty. The one lookup of the programs' --profile and of Participant.
std::optional<std::string> profiles_file_or_environment(const std::string& given);

/// Environment variable that sets the verbosity of Fast DDS's own log (printed on standard
/// output by Fast DDS): "error" (the default), "warning" or "info" (info needs a Fast DDS built
/// with it; the Debian one prints warnings and errors only). Discovery and security problems
/// between hosts show up at "warning".
inline constexpr const char* kFastDdsLogEnv = "ODONAV_FASTDDS_LOG";

namespace detail {

/// Held while this layer loads a Fast DDS XML profiles file or reads a QoS profile from the loaded
/// ones: Fast DDS 2.9 keeps them in one process-wide table without a lock, and a process may build
/// participants and endpoints on several threads at once.
std::mutex& xml_profiles_mutex();

/// Logs, through spdlog, what the participant learns about the others of its domain: a
/// participant discovered, left (removed) or lost (dropped: its lease expired, e.g. a dead ECU or a
/// cut link), and with DDS Security whether each one was authenticated (a refused one is warned
/// about once, its retries go to debug). Without this a peer that never authenticates is silent:
/// its endpoints simply never match.
///
/// With DDS Security it also spaces the set-up of newly discovered participants (SetupSpacing,
/// secure_discovery.hpp): Fast DDS 2.9 prepares the security handshake of a new participant in
/// whichever receive thread its first announcement arrived on (multicast, unicast, shared memory),
/// right after this callback, and that preparation fills temporaries shared by the whole
/// participant without a lock (SecurityManager::match_builtin_endpoints). Two participants
/// discovered at the same moment on two threads can then leave one pair unable to exchange
/// handshake messages for as long as both live: no error, the handshake is resent every second
/// and ignored (seen in the multi-host test in about 1 run of 3). The discovery callback runs just
/// before that preparation, serialized by Fast DDS, so holding it until the previous participant's
/// preparation on ANOTHER thread is long done serializes them.
///
/// A participant without DDS Security credentials (no identity token) is refused by Fast DDS
/// before any preparation, so it is never held: a flood of them costs the receive thread nothing
/// here, and their log lines are budgeted (LogBudget): a few per 10 s plus the count left out.
class ParticipantEventLog : public eprosima::fastdds::dds::DomainParticipantListener {
 public:
  /// own_name: this participant's name, for the messages. space_secure_discoveries: apply the
  /// spacing above (participants with DDS Security).
  ParticipantEventLog(std::string own_name, bool space_secure_discoveries)
      : own_name_(std::move(own_name)), space_secure_discoveries_(space_secure_discoveries) {}
  ~ParticipantEventLog() override;
  /// Minimum time between the set-ups of two newly discovered participants with DDS Security
  /// handed to two different receive threads. The preparation it protects takes about a
  /// millisecond (two endpoint matches after our announcement is resent to every known
  /// participant); 100 ms leaves room for a loaded machine. Set-ups on one thread never wait.
  static constexpr std::chrono::milliseconds kSecureDiscoverySpacing{100};
  /// Log lines per kStrangerLogWindow about participants refused, or without credentials, and
  /// about them leaving; the rest is counted and the count given with the next line.
  static constexpr std::size_t kStrangerLogBurst = 5;
  static constexpr std::chrono::seconds kStrangerLogWindow{10};
  /// At most this many refused or unauthenticated participants are kept by name (for Health);
  /// beyond it they are only counted (a flood of fresh identities must not grow memory unbounded).
  static constexpr std::size_t kMaxTrackedStrangers = 1024;

  /// What this participant saw since it was created (all zero without DDS Security).
  struct Counts {
    std::uint64_t discovered = 0;           ///< participants discovered
    std::uint64_t without_credentials = 0;  ///< of them, announced no DDS Security identity
    std::uint64_t refused = 0;              ///< authentication refusals (first one per participant)
    std::uint64_t authenticated = 0;        ///< authentications that succeeded
    std::uint64_t setups_spaced = 0;        ///< handshake set-ups passed through SetupSpacing
    std::uint64_t setups_delayed = 0;       ///< of them, held back (another thread's was < 100 ms ago)
    double setup_wait_s = 0.0;              ///< total time they were held back (steady clock)
    std::uint64_t untracked = 0;            ///< strangers beyond kMaxTrackedStrangers, not kept
  };
  Counts counts() const;

  /// A participant of the domain this secure participant does not exchange data with: refused by
  /// DDS Security (certificate not from our CA, bad permissions: an intruder or a misconfigured
  /// peer), or discovered a while ago with a handshake that neither succeeded nor failed (a peer
  /// that refused OUR certificate, i.e. one of another PKI, or the Fast DDS race of the class
  /// comment, or a network path that drops one direction). Kept until it leaves.
  struct UnauthenticatedParticipant {
    std::string name;      ///< the name it announced
    std::string guid;      ///< its GUID prefix
    bool refused = false;  ///< refused (true) or handshake incomplete (false)
    double age_s = 0.0;    ///< seconds since it was discovered (steady clock)
  };
  /// The refused ones, and those with a handshake pending for at least pending_for; the longest
  /// known first. Always empty without DDS Security.
  std::vector<UnauthenticatedParticipant> unauthenticated(std::chrono::steady_clock::duration pending_for) const;

  /// The name a participant of the domain announced, by its GUID prefix as text ("" if it is not
  /// known: not discovered, gone, or beyond kMaxNamedParticipants). Kept for every participant,
  /// secure or not, so endpoints can say whose writer is silent or which reader was lost.
  std::string name_of(const std::string& guid_prefix) const;
  static constexpr std::size_t kMaxNamedParticipants = 4096;

  void on_participant_discovery(eprosima::fastdds::dds::DomainParticipant* participant,
                                eprosima::fastrtps::rtps::ParticipantDiscoveryInfo&& info) override;
  /// Remembers whether each remote reader is RELIABLE (a writer's lost reader only lost data if it
  /// was: a best-effort display never acknowledges anything).
  void on_subscriber_discovery(eprosima::fastdds::dds::DomainParticipant* participant,
                               eprosima::fastrtps::rtps::ReaderDiscoveryInfo&& info) override;
  /// Whether the remote reader `guid` asked for RELIABLE delivery (true when it is not known).
  bool reader_is_reliable(const eprosima::fastrtps::rtps::GUID_t& guid) const;
#if HAVE_SECURITY
  void onParticipantAuthentication(eprosima::fastdds::dds::DomainParticipant* participant,
                                   eprosima::fastrtps::rtps::ParticipantAuthenticationInfo&& info) override;
#endif

 private:
  std::string own_name_;
  bool space_secure_discoveries_ = false;
  // Held while a discovery waits out the spacing; mutex_ is taken under it only after the wait,
  // so neither the authentication callbacks nor unauthenticated() (a component's worker thread)
  // ever wait for a spacing.
  std::mutex spacing_mutex_;
  SetupSpacing spacing_{kSecureDiscoverySpacing};  // under spacing_mutex_
  struct Peer {
    std::string name;
    std::chrono::steady_clock::time_point discovered;
    enum class Auth { kPending, kAuthenticated, kRefused } auth = Auth::kPending;
    bool credentials = true;  // announced a DDS Security identity token
    std::uint64_t refusals = 0;
  };
  // Records the discovery of a participant (secure participants only); false if it is not kept
  // (a stranger beyond kMaxTrackedStrangers).
  bool remember(const std::string& guid, const std::string& name, bool credentials);
  void on_discovered_secure(const std::string& name, const std::string& guid, bool credentials);
  void on_left(const std::string& name, const std::string& guid, bool lease_expired);
  mutable std::mutex mutex_;                                          // peers_, counts_, the budgets, names_
  std::map<std::string, std::string> names_;                          // GUID prefix -> announced name, until it leaves
  std::map<eprosima::fastrtps::rtps::GUID_t, bool> reader_reliable_;  // remote readers, until removed
  std::map<std::string, Peer> peers_;  // GUID prefix -> peer, secure participants only, until it leaves
  Counts counts_;
  LogBudget stranger_log_{kStrangerLogBurst, kStrangerLogWindow};
  LogBudget stranger_left_log_{kStrangerLogBurst, kStrangerLogWindow};
};

/// The DDS entities of a participant. Shared by the Participant and its endpoints, so the
/// participant is torn down only after its last endpoint is gone, whatever the destruction order.
class ParticipantCore {
 public:
  /// security: the DDS Security material the participant was created with, if any.
  /// event_log: the participant's listener (owned here so it outlives the participant), or null.
  ParticipantCore(eprosima::fastdds::dds::DomainParticipant* participant, std::string description,
                  std::optional<SecurityMaterial> security = std::nullopt,
                  std::unique_ptr<ParticipantEventLog> event_log = nullptr);
  ~ParticipantCore();
  ParticipantCore(const ParticipantCore&) = delete;
  ParticipantCore& operator=(const ParticipantCore&) = delete;

  eprosima::fastdds::dds::DomainParticipant& participant() const { return *participant_; }
  eprosima::fastdds::dds::Publisher& publisher() const { return *publisher_; }
  eprosima::fastdds::dds::Subscriber& subscriber() const { return *subscriber_; }
  /// "participant profile 'p' of file 'f', QoS file 'q', domain d", for error messages.
  const std::string& description() const { return description_; }
  /// The DDS Security material in use, nullopt for a participant without the layer's security.
  const std::optional<SecurityMaterial>& security() const { return security_; }
  /// The participant's event log (null if none was given).
  const ParticipantEventLog* event_log() const { return event_log_.get(); }
  /// "odonav-gateway (01.0f.3a...)": the name of the participant owning a remote endpoint (writer
  /// or reader GUID), or its GUID prefix alone when the name is not known.
  std::string participant_name(const eprosima::fastrtps::rtps::GUID_t& endpoint) const;
  /// The matched writers of this participant's data readers and whether they are silent
  /// (odonav/peer_tracker.hpp; silence 2 s). Readers of health and commands are not tracked: their
  /// writers are silent by design between messages.
  PeerTracker& peers() const { return *peers_; }

  /// The topic `topic_name` of `type`, registering the type and creating the topic on first use.
  /// Throws if registration or creation fails, or if the topic exists with another type.
  eprosima::fastdds::dds::Topic& topic(const std::string& topic_name, eprosima::fastdds::dds::TypeSupport type);

 private:
  eprosima::fastdds::dds::DomainParticipant* participant_;
  eprosima::fastdds::dds::Publisher* publisher_ = nullptr;
  eprosima::fastdds::dds::Subscriber* subscriber_ = nullptr;
  std::string description_;
  std::optional<SecurityMaterial> security_;
  std::unique_ptr<ParticipantEventLog> event_log_;
  std::unique_ptr<PeerTracker> peers_ = std::make_unique<PeerTracker>(2.0);
  std::mutex mutex_;  // topic creation and type registration
};
}  // namespace detail

/// A DDS domain participant of a process (one per process is the usual case).
/// Teardown: delete_contained_entities(), then delete_participant, once the Participant and all
/// endpoints created from it are destroyed.
class Participant {
 public:
  /// Loads the participant profile file and the QoS file, then creates the participant. With
  /// DDS Security material (options or environment, see ParticipantOptions::security_dir), adds
  /// the dds.sec.* properties (security_properties) on top of the profile's.
  /// Throws std::runtime_error naming what failed: a file missing or not parseable, an unknown
  /// participant profile, a domain id out of 0..232, a security file missing or an identity that
  /// is not a plain name, or participant creation refused (with security: the likely reasons).
  explicit Participant(const ParticipantOptions& options);

  const std::string& profiles_file() const { return profiles_file_; }
  const std::string& qos_file() const { return qos_file_; }
  int domain_id() const { return domain_id_; }
  /// The DDS Security material added by the layer (nullopt: none; the profile may still have its own).
  const std::optional<SecurityMaterial>& security() const { return core_->security(); }
  /// With DDS Security: the participants of the domain it does not exchange data with
  /// (ParticipantEventLog::unauthenticated). Components report them in their Health (WARN).
  std::vector<detail::ParticipantEventLog::UnauthenticatedParticipant> unauthenticated_participants(
      std::chrono::steady_clock::duration pending_for) const;

  /// The Fast DDS participant, for what this thin layer does not wrap.
  eprosima::fastdds::dds::DomainParticipant& native() const { return core_->participant(); }
  /// Shared with the endpoints (see detail::ParticipantCore).
  const std::shared_ptr<detail::ParticipantCore>& core() const { return core_; }

 private:
  std::string profiles_file_;
  std::string qos_file_;
  int domain_id_ = 0;
  std::shared_ptr<detail::ParticipantCore> core_;
};

}  // namespace odonav::dds
