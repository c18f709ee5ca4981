#pragma once
// The virtual vehicle network of the multi-host test: one Linux network namespace per host (the
// ECUs and the ground station) plus a "switch" namespace holding a bridge, joined by veth pairs.
//
// Isolation, and why:
// - Addresses (10.0.0.0/24) exist only inside the namespaces; the root namespace gets nothing, and
//   no namespace has a route off the bridge, so nothing can leave.
// - Multicast: the bridge has IGMP snooping off (mcast_snooping 0: no querier on this network, a
//   snooping bridge would drop the discovery multicast), and each host routes 224.0.0.0/4 to its
//   vehicle interface (there is no default route).
// - Shared memory: /dev/shm is NOT per network namespace, and Fast DDS's SHM transport only checks
//   a 16-bit host id hashed from the machine's addresses. To make "another host" really another
//   host, every process runs with a private /dev/shm: its host's directory bind-mounted over
//   /dev/shm inside the mount namespace `ip netns exec` creates (propagation slave, so the root
//   namespace never sees it). Components of one host share that directory, so SHM still works
//   within a host, as on a real ECU; between hosts only UDP over the bridge is left, and cutting a
//   host's link really cuts its data.
// - Cleanup: the destructor, and a SIGINT/SIGTERM/SIGHUP handler, run one generated shell script
//   that SIGKILLs every process inside the namespaces (`ip netns pids`), deletes the namespaces and
//   the shared-memory directories, and runs `fastdds shm clean`. Namespaces left by a test process
//   that was SIGKILLed (prefix odn-<pid>- with that pid gone) are removed at the next start.
#include <filesystem>
#include <string>
#include <vector>

namespace odonav::multihost {

/// One host of the virtual vehicle network.
struct Host {
  std::string name;     ///< short name, e.g. "ecu1" (letters and digits, at most 8 characters)
  std::string address;  ///< IPv4 address in 10.0.0.0/24, e.g. "10.0.0.11"
};

class VirtualNetwork {
 public:
  /// Creates the namespaces odn-<pid>-<host> and odn-<pid>-sw, the bridge, the links and the
  /// per-host shared-memory directories under work_dir/shm/<host>. Needs root. Throws
  /// std::runtime_error naming the failing command (its output is in work_dir/network.log).
  VirtualNetwork(const std::filesystem::path& work_dir, const std::vector<Host>& hosts);
  /// Kills every process in the namespaces, deletes them, removes the shm directories.
  ~VirtualNetwork();
  VirtualNetwork(const VirtualNetwork&) = delete;
  VirtualNetwork& operator=(const VirtualNetwork&) = delete;

  /// The namespace name of a host. Throws std::invalid_argument for an unknown host.
  std::string namespace_of(const std::string& host) const;
  /// The address of a host.
  std::string address_of(const std::string& host) const;
  /// The private /dev/shm directory of a host.
  std::filesystem::path shm_dir(const std::string& host) const;

  /// argv that runs `command` inside `host` (its network namespace, its private /dev/shm), with
  /// stdout to out_file and stderr to err_file. The process keeps the pid of the spawned argv
  /// (`ip netns exec` and the shell both exec), so signals reach the command itself.
  std::vector<std::string> exec_argv(const std::string& host, const std::filesystem::path& out_file,
                                     const std::filesystem::path& err_file,
                                     const std::vector<std::string>& command) const;

  /// Link of `host` to the switch up or down (the switch-side veth, so the host's own interface,
  /// address and routes stay configured, as when a cable is pulled). Throws on failure.
  void set_link(const std::string& host, bool up);

  /// Runs the cleanup now (idempotent; the destructor calls it).
  void cleanup();

 private:
  std::string run_checked(const std::string& command);
  const Host& host(const std::string& name) const;

  std::filesystem::path work_dir_;
  std::vector<Host> hosts_;
  std::string prefix_;  // odn-<pid>-
  std::filesystem::path cleanup_script_;
  bool cleaned_ = false;
};

/// A participant profile instantiated for one host: every ECU_ADDRESS of template_file replaced by
/// `address`, written into dir with the qos.xml beside the template copied beside it (the DDS layer
/// reads the QoS profiles from the profile's folder). Returns the profile's path. Throws
/// std::runtime_error when the template has no ECU_ADDRESS.
std::filesystem::path instantiate_profile(const std::filesystem::path& template_file, const std::filesystem::path& dir,
                                          const std::string& address);

/// Deletes namespaces named odn-<pid>-* whose test process <pid> no longer exists (a run that was
/// SIGKILLed, e.g. by a CTest timeout, cannot clean up after itself).
void remove_stale_namespaces();

}  // namespace odonav::multihost
