// odonav-spdp-flood: one process without DDS Security credentials announcing many DDS participants
// on the loopback, to flood the discovery of a secure domain (tests/integration/flood).
//
// It is not a DDS implementation: it writes the participant announcements of the RTPS
// specification (SPDP DATA(p): protocol version, vendor, GUID, domain, unicast locators, lease,
// builtin endpoints, name; no identity token, as a participant without DDS Security sends them;
// with --identity-token a PKI-DH token, as a participant with credentials that never answers),
// N of them per period (spread over it), to the discovery (metatraffic unicast) ports of participant ids
// 0..--ports-of-1 of the domain on 127.0.0.1, the way a peer with initial peers on the loopback
// probes them. Every fake participant names the one UDP socket of this process as its locators;
// what arrives there is counted by the RTPS GUID prefix of its sender: the participants of the
// domain that discovered the flood and announced themselves to it.
//
// Only 127.0.0.0/8 is ever written to (the destination is fixed; --address must be a loopback one).
// At the end (--duration-s, or SIGINT/SIGTERM) one JSON line on stdout:
//   {"participants": N, "rounds": r, "datagrams_sent": n, "send_errors": n, "datagrams_received": n,
//    "responders": k}
// Exit: 0 done; 2 bad flags; 3 the socket could not be set up.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <signal.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <cstring>
#include <iostream>
#include <mutex>
#include <set>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "odonav/config.hpp"
#include "stop_signals.hpp"

namespace {

using odonav::test::g_stop;

// RTPS 2.3 constants (OMG DDSI-RTPS 2.3, sections 8.3 and 9.6).
constexpr std::uint8_t kSubmessageInfoTs = 0x09;
constexpr std::uint8_t kSubmessageData = 0x15;
constexpr std::uint8_t kFlagLittleEndian = 0x01;
constexpr std::uint8_t kFlagDataPresent = 0x04;
constexpr std::uint16_t kPidSentinel = 0x0001;
constexpr std::uint16_t kPidLeaseDuration = 0x0002;
constexpr std::uint16_t kPidDomainId = 0x000f;
constexpr std::uint16_t kPidProtocolVersion = 0x0015;
constexpr std::uint16_t kPidVendorId = 0x0016;
constexpr std::uint16_t kPidDefaultUnicastLocator = 0x0031;
constexpr std::uint16_t kPidMetatrafficUnicastLocator = 0x0032;
constexpr std::uint16_t kPidParticipantGuid = 0x0050;
constexpr std::uint16_t kPidBuiltinEndpointSet = 0x0058;
constexpr std::uint16_t kPidEntityName = 0x0062;
constexpr std::uint16_t kPidIdentityToken = 0x1001;  // DDS Security 1.1, section 7.4.1.4
constexpr std::int32_t kLocatorKindUdpV4 = 1;
// Participant announcer and detector, publications and subscriptions announcer and detector,
// participant message writer and reader: what an ordinary participant offers.
constexpr std::uint32_t kBuiltinEndpoints = 0x0000003f | (1u << 10) | (1u << 11);
// Default RTPS port mapping: PB + DG * domain + d1 + PG * participant id.
constexpr int kPortBase = 7400, kDomainGain = 250, kParticipantGain = 2, kMetatrafficUnicastOffset = 10;

class Buffer {
 public:
  void u8(std::uint8_t v) { b_.push_back(v); }
  void u16(std::uint16_t v) {
    for (int i = 0; i < 2; ++i) b_.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
  }
  void u32(std::uint32_t v) {
    for (int i = 0; i < 4; ++i) b_.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
  }
  void bytes(const std::uint8_t* p, std::size_t n) { b_.insert(b_.end(), p, p + n); }
  void pad4() {
    while (b_.size() % 4 != 0) b_.push_back(0);
  }
  std::size_t size() const { return b_.size(); }
  void put_u16_at(std::size_t at, std::uint16_t v) {
    b_[at] = static_cast<std::uint8_t>(v);
    b_[at + 1] = static_cast<std::uint8_t>(v >> 8);
  }
  const std::vector<std::uint8_t>& data() const { return b_; }

 private:
  std::vector<std::uint8_t> b_;
};

struct FakeParticipant {
  std::uint8_t prefix[12];
  std::string name;
};

void locator(Buffer& b, std::uint16_t pid, std::uint16_t port, const in_addr& address) {
  b.u16(pid);
  b.u16(24);
  b.u32(static_cast<std::uint32_t>(kLocatorKindUdpV4));
  b.u32(port);
  for (int i = 0; i < 12; ++i) b.u8(0);
  b.bytes(reinterpret_cast<const std::uint8_t*>(&address.s_addr), 4);  // network order, as RTPS wants
}

void cdr_string(Buffer& b, const std::string& text) {
  b.u32(static_cast<std::uint32_t>(text.size() + 1));
  b.bytes(reinterpret_cast<const std::uint8_t*>(text.data()), text.size());
  b.u8(0);
  b.pad4();
}

/// One RTPS message: header, INFO_TS, DATA(p) with the participant's parameter list. With
/// identity_token, a PKI-DH identity token without properties: what a participant with DDS
/// Security credentials announces (the certificate itself only travels in the handshake, which
/// this process never answers).
std::vector<std::uint8_t> announcement(const FakeParticipant& p, const std::uint8_t vendor[2], int domain,
                                       std::uint16_t own_port, const in_addr& own_address, double lease_s,
                                       std::uint32_t sequence, bool identity_token) {
  Buffer b;
  for (char c : {'R', 'T', 'P', 'S'}) b.u8(static_cast<std::uint8_t>(c));
  b.u8(2);
  b.u8(3);
  b.bytes(vendor, 2);
  b.bytes(p.prefix, 12);

  const auto now = std::chrono::system_clock::now().time_since_epoch();
  const auto sec = std::chrono::duration_cast<std::chrono::seconds>(now);
  const double frac = std::chrono::duration<double>(now - sec).count();
  b.u8(kSubmessageInfoTs);
  b.u8(kFlagLittleEndian);
  b.u16(8);
  b.u32(static_cast<std::uint32_t>(sec.count()));
  b.u32(static_cast<std::uint32_t>(frac * 4294967296.0));

  b.u8(kSubmessageData);
  b.u8(kFlagLittleEndian | kFlagDataPresent);
  const std::size_t length_at = b.size();
  b.u16(0);  // octetsToNextHeader, set below
  const std::size_t body_start = b.size();
  b.u16(0);   // extra flags
  b.u16(16);  // octetsToInlineQos: reader id + writer id + sequence number
  for (std::uint8_t v : {0x00, 0x01, 0x00, 0xc7}) b.u8(v);  // SPDP builtin participant reader
  for (std::uint8_t v : {0x00, 0x01, 0x00, 0xc2}) b.u8(v);  // SPDP builtin participant writer
  b.u32(0);                                                 // sequence number, high
  b.u32(sequence);                                          // sequence number, low
  b.u8(0x00);                                               // PL_CDR_LE encapsulation
  b.u8(0x03);
  b.u16(0);
  b.u16(kPidProtocolVersion);
  b.u16(4);
  for (std::uint8_t v : {2, 3, 0, 0}) b.u8(v);
  b.u16(kPidVendorId);
  b.u16(4);
  b.bytes(vendor, 2);
  b.u16(0);
  b.u16(kPidParticipantGuid);
  b.u16(16);
  b.bytes(p.prefix, 12);
  for (std::uint8_t v : {0x00, 0x00, 0x01, 0xc1}) b.u8(v);
  b.u16(kPidDomainId);
  b.u16(4);
  b.u32(static_cast<std::uint32_t>(domain));
  locator(b, kPidMetatrafficUnicastLocator, own_port, own_address);
  locator(b, kPidDefaultUnicastLocator, own_port, own_address);
  b.u16(kPidLeaseDuration);
  b.u16(8);
  const auto lease_sec = static_cast<std::uint32_t>(lease_s);
  b.u32(lease_sec);
  b.u32(static_cast<std::uint32_t>((lease_s - lease_sec) * 4294967296.0));
  b.u16(kPidBuiltinEndpointSet);
  b.u16(4);
  b.u32(kBuiltinEndpoints);
  b.u16(kPidEntityName);
  const std::size_t name_length_at = b.size();
  b.u16(0);
  const std::size_t name_start = b.size();
  cdr_string(b, p.name);
  b.put_u16_at(name_length_at, static_cast<std::uint16_t>(b.size() - name_start));
  if (identity_token) {
    b.u16(kPidIdentityToken);
    const std::size_t token_length_at = b.size();
    b.u16(0);
    const std::size_t token_start = b.size();
    cdr_string(b, "DDS:Auth:PKI-DH:1.0");  // class id
    b.u32(0);                              // properties
    b.u32(0);                              // binary properties
    b.put_u16_at(token_length_at, static_cast<std::uint16_t>(b.size() - token_start));
  }
  b.u16(kPidSentinel);
  b.u16(0);
  b.put_u16_at(length_at, static_cast<std::uint16_t>(b.size() - body_start));
  return b.data();
}

int run(const odonav::Options& o) {
  const int domain = static_cast<int>(o.get_int("domain"));
  const auto count = static_cast<std::size_t>(o.get_int("participants"));
  const int ports_of = static_cast<int>(o.get_int("ports-of"));
  const double period_s = o.get_double("period-s");
  const double lease_s = o.get_double("lease-s");
  const std::string prefix = o.get_string("name-prefix");
  const auto vendor_id = static_cast<std::uint16_t>(o.get_int("vendor-id"));
  const bool identity_token = o.get_bool("identity-token");
  const std::uint8_t vendor[2] = {static_cast<std::uint8_t>(vendor_id >> 8), static_cast<std::uint8_t>(vendor_id)};

  in_addr address{};
  if (inet_pton(AF_INET, o.get_string("address").c_str(), &address) != 1 || (ntohl(address.s_addr) >> 24) != 127) {
    throw odonav::ConfigError("--address: '" + o.get_string("address") +
                              "' is not an IPv4 loopback address (127.x.y.z)");
  }
  if (kPortBase + kDomainGain * domain + kMetatrafficUnicastOffset + kParticipantGain * (ports_of - 1) > 65535) {
    throw odonav::ConfigError("--domain " + std::to_string(domain) + " with --ports-of " + std::to_string(ports_of) +
                              " leaves the UDP port range");
  }

  const int fd = ::socket(AF_INET, SOCK_DGRAM, 0);
  if (fd < 0) throw std::runtime_error(std::string("socket: ") + std::strerror(errno));
  sockaddr_in own{};
  own.sin_family = AF_INET;
  own.sin_addr = address;
  own.sin_port = 0;
  if (::bind(fd, reinterpret_cast<sockaddr*>(&own), sizeof own) != 0) {
    throw std::runtime_error(std::string("bind to the loopback: ") + std::strerror(errno));
  }
  socklen_t own_len = sizeof own;
  ::getsockname(fd, reinterpret_cast<sockaddr*>(&own), &own_len);
  const int buffer = 4 << 20;
  ::setsockopt(fd, SOL_SOCKET, SO_SNDBUF, &buffer, sizeof buffer);
  ::setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &buffer, sizeof buffer);

  std::vector<FakeParticipant> fakes(count);
  const auto pid = static_cast<std::uint32_t>(::getpid());
  for (std::size_t i = 0; i < count; ++i) {
    auto& f = fakes[i];
    f.prefix[0] = vendor[0];
    f.prefix[1] = vendor[1];
    for (int k = 0; k < 4; ++k) f.prefix[2 + k] = static_cast<std::uint8_t>(pid >> (8 * k));
    for (int k = 0; k < 4; ++k) f.prefix[6 + k] = static_cast<std::uint8_t>(i >> (8 * k));
    f.prefix[10] = 0xf1;
    f.prefix[11] = 0x0d;
    f.name = prefix + std::to_string(i);
  }

  // Whoever discovered a fake participant announces itself to its locator: count them.
  std::atomic<std::uint64_t> received{0};
  std::mutex responders_mutex;
  std::set<std::string> responders;
  std::thread receiver([&] {
    std::vector<std::uint8_t> in(65536);
    while (!g_stop.load()) {
      pollfd p{fd, POLLIN, 0};
      if (::poll(&p, 1, 100) <= 0) continue;
      const ssize_t n = ::recv(fd, in.data(), in.size(), 0);
      if (n < 20 || std::memcmp(in.data(), "RTPS", 4) != 0) continue;
      ++received;
      std::lock_guard<std::mutex> lock(responders_mutex);
      responders.insert(std::string(reinterpret_cast<const char*>(in.data() + 8), 12));
    }
  });

  std::uint64_t sent = 0, errors = 0, rounds = 0;
  const auto t0 = std::chrono::steady_clock::now();
  const auto end = t0 + std::chrono::microseconds(static_cast<std::int64_t>(o.get_double("duration-s") * 1e6));
  // Each participant announces itself once a period, the N spread over the period (as N
  // participants with their own timers do): a burst of all of them at once would overflow the
  // receivers' socket buffers and hide the same tail of the flood every round.
  const auto gap = std::chrono::microseconds(static_cast<std::int64_t>(period_s * 1e6 / static_cast<double>(count)));
  auto next = t0;
  while (!g_stop.load() && std::chrono::steady_clock::now() < end) {
    ++rounds;
    for (const auto& f : fakes) {
      if (g_stop.load()) break;
      const auto message = announcement(f, vendor, domain, ntohs(own.sin_port), address, lease_s,
                                        static_cast<std::uint32_t>(rounds), identity_token);
      for (int id = 0; id < ports_of; ++id) {
        sockaddr_in to{};
        to.sin_family = AF_INET;
        to.sin_addr = address;
        to.sin_port = htons(static_cast<std::uint16_t>(kPortBase + kDomainGain * domain + kMetatrafficUnicastOffset +
                                                       kParticipantGain * id));
        if (::sendto(fd, message.data(), message.size(), 0, reinterpret_cast<sockaddr*>(&to), sizeof to) ==
            static_cast<ssize_t>(message.size())) {
          ++sent;
        } else {
          ++errors;  // ECONNREFUSED from a port nobody listens on is reported on a later send
        }
      }
      next += gap;
      std::this_thread::sleep_until(next);
    }
  }
  g_stop.store(true);
  receiver.join();
  ::close(fd);
  nlohmann::json j{{"participants", count},
                   {"rounds", rounds},
                   {"datagrams_sent", sent},
                   {"send_errors", errors},
                   {"datagrams_received", received.load()},
                   {"responders", responders.size()}};
  std::cout << j.dump() << std::endl;
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  odonav::Options o("odonav-spdp-flood",
                    "Announces many DDS participants without DDS Security credentials on the loopback (a "
                    "discovery flood for tests/integration/flood).");
  o.add_int("domain", 0, "DDS domain id", 0, 232);
  o.add_int("participants", 200, "participants announced", 1, 100000);
  o.add_int("ports-of", 32, "announce to the discovery ports of participant ids 0..N-1", 1, 120);
  o.add_double("period-s", 1.0, "announcement period of every participant, s", 0.01, 3600.0);
  o.add_double("lease-s", 10.0, "lease duration the participants announce, s", 1.0, 3600.0);
  o.add_double("duration-s", 10.0, "how long to run, s", 0.1, 3600.0);
  o.add_string("address", "127.0.0.1", "loopback address written to and announced (127.0.0.0/8 only)");
  o.add_string("name-prefix", "odonav-flood-", "participant names: prefix + index");
  o.add_int("vendor-id", 0x0110, "RTPS vendor id announced (default 0x0110, Eclipse Cyclone DDS)", 0, 0xffff);
  o.add_bool("identity-token", false,
             "announce a PKI-DH identity token (credentials that never answer the handshake) instead of none");
  odonav::test::stop_on_signals();
  try {
    if (o.parse(argc, argv) == odonav::ParseResult::kHelp) return 0;
    return run(o);
  } catch (const odonav::ConfigError& e) {
    std::cerr << "odonav-spdp-flood: bad configuration: " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "odonav-spdp-flood: " << e.what() << "\n";
    return 3;
  }
}
