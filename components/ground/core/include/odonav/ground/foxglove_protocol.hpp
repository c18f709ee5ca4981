#pragma once
// The server side of the Foxglove WebSocket protocol (foxglove/ws-protocol, docs/spec.md), without
// any network code: subprotocol choice, the server's JSON messages (serverInfo, advertise,
// unadvertise, status), the binary message-data frame, one client's subscriptions, and the set of
// channels (ids, expiry). The WebSocket transport (Boost.Beast) is in web/.
#include <cstdint>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace odonav::ground {

/// The subprotocol names a Foxglove client may ask for (Foxglove Studio / Lichtblick / the
/// @foxglove/ws-protocol client ask for the first, the Foxglove SDK's clients for the second).
inline constexpr const char* kFoxgloveSubprotocols[] = {"foxglove.websocket.v1", "foxglove.sdk.v1"};

/// The subprotocol the server answers with, from the client's Sec-WebSocket-Protocol header
/// (comma-separated, in the client's order of preference): the first one offered that is in
/// kFoxgloveSubprotocols; nullopt when none is (the handshake is then refused).
std::optional<std::string> choose_subprotocol(const std::string& offered);

/// One advertised channel.
struct ChannelInfo {
  std::uint32_t id = 0;
  std::string topic;            ///< "/odonav/vehicle-01/scale_factor"
  std::string encoding;         ///< "cdr" or "json"
  std::string schema_name;      ///< "odonav/msg/ScaleFactor"
  std::string schema;           ///< ros2msg text or JSON schema
  std::string schema_encoding;  ///< "ros2msg" or "jsonschema"
};

nlohmann::json server_info_json(const std::string& name, const std::string& session_id,
                                const std::map<std::string, std::string>& metadata);
nlohmann::json advertise_json(const std::vector<ChannelInfo>& channels);
nlohmann::json unadvertise_json(const std::vector<std::uint32_t>& channel_ids);
/// level: 0 info, 1 warning, 2 error.
nlohmann::json status_json(int level, const std::string& message);

/// The binary MESSAGE_DATA frame: opcode 0x01, uint32 subscription id, uint64 timestamp (ns),
/// payload; integers little endian.
std::string message_frame(std::uint32_t subscription_id, std::uint64_t timestamp_ns, const std::uint8_t* data,
                          std::size_t size);

/// Event time in ns for a frame: seconds (a message stamp) to ns; 0 for a negative or non-finite stamp.
std::uint64_t stamp_ns(double stamp_s);

/// One client's subscriptions and what it asked for. Not thread-safe (the server locks around it).
class ClientSubscriptions {
 public:
  /// Handles one text message of the client. channel_exists says whether a channel id is
  /// advertised now. Returns the status messages to send back (empty when all was fine): bad
  /// JSON, an unknown op, an unknown channel, a subscription id in use, and an unsubscribe of an
  /// unknown id each give one error/warning status naming what was wrong; ops of capabilities the
  /// server does not advertise (clientPublish, parameters, services, ...) a warning.
  template <class ChannelExists>
  std::vector<nlohmann::json> handle_text(const std::string& text, ChannelExists channel_exists);

  /// The subscription ids of a channel (empty when the client did not subscribe to it).
  std::vector<std::uint32_t> subscriptions_of(std::uint32_t channel_id) const;
  /// Drops every subscription of a channel (it was unadvertised).
  void remove_channel(std::uint32_t channel_id);
  std::size_t size() const { return by_subscription_.size(); }
  /// The channels subscribed at least once.
  std::set<std::uint32_t> channels() const;

 private:
  std::vector<nlohmann::json> handle(const nlohmann::json& message, const std::set<std::uint32_t>& unknown_channels);
  std::map<std::uint32_t, std::uint32_t> by_subscription_;       // subscription id -> channel id
  std::map<std::uint32_t, std::set<std::uint32_t>> by_channel_;  // channel id -> its subscription ids
};

template <class ChannelExists>
std::vector<nlohmann::json> ClientSubscriptions::handle_text(const std::string& text, ChannelExists channel_exists) {
  nlohmann::json message;
  try {
    message = nlohmann::json::parse(text);
  } catch (const nlohmann::json::exception& e) {
    return {status_json(2, std::string("not JSON: ") + e.what())};
  }
  // Which of the channels named by a subscribe exist: asked here, so handle() stays non-template.
  std::set<std::uint32_t> unknown;
  if (message.is_object() && message.value("op", "") == "subscribe" && message.contains("subscriptions") &&
      message["subscriptions"].is_array()) {
    for (const auto& s : message["subscriptions"])
      if (s.is_object() && s.contains("channelId") && s["channelId"].is_number_unsigned() &&
          !channel_exists(s["channelId"].get<std::uint32_t>()))
        unknown.insert(s["channelId"].get<std::uint32_t>());
  }
  return handle(message, unknown);
}

/// The channels of a server: ids from 1 up (never reused), found by a key the caller chooses
/// (e.g. "vehicle-01 rt/odonav/scale_factor"), with the last time each was fed. Thread-safe.
class ChannelSet {
 public:
  /// The channel of `key`, created with `info` (its id filled in) when absent; `added` says which.
  /// `now_s` (steady clock) refreshes its last-seen time.
  ChannelInfo get_or_add(const std::string& key, const ChannelInfo& info, double now_s, bool& added);
  /// The id of a key's channel, refreshing its last-seen time; nullopt when absent.
  std::optional<std::uint32_t> touch(const std::string& key, double now_s);
  /// The id of a key's channel without refreshing it; nullopt when absent.
  std::optional<std::uint32_t> find(const std::string& key) const;
  bool contains(std::uint32_t id) const;
  std::vector<ChannelInfo> all() const;
  /// Removes and returns the channels not fed for more than `after_s` (they went away).
  std::vector<ChannelInfo> expire(double now_s, double after_s);
  std::size_t size() const;

 private:
  struct Entry {
    ChannelInfo info;
    double last_seen_s = 0.0;
  };
  mutable std::mutex mutex_;
  std::map<std::string, Entry> by_key_;
  std::map<std::uint32_t, std::string> key_of_;
  std::uint32_t next_id_ = 1;
};

}  // namespace odonav::ground
