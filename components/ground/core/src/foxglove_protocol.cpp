#include "odonav/ground/foxglove_protocol.hpp"

#include <cmath>
#include <cstring>
#include <sstream>

namespace odonav::ground {

namespace {
std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t");
  if (b == std::string::npos) return "";
  return s.substr(b, s.find_last_not_of(" \t") - b + 1);
}
void put_le(std::string& out, std::uint64_t v, int bytes) {
  for (int i = 0; i < bytes; ++i) out.push_back(static_cast<char>((v >> (8 * i)) & 0xff));
}
}  // namespace

std::optional<std::string> choose_subprotocol(const std::string& offered) {
  std::istringstream in(offered);
  std::string item;
  while (std::getline(in, item, ',')) {
    const std::string name = trim(item);
    for (const char* p : kFoxgloveSubprotocols)
      if (name == p) return name;
  }
  return std::nullopt;
}

nlohmann::json server_info_json(const std::string& name, const std::string& session_id,
                                const std::map<std::string, std::string>& metadata) {
  return {{"op", "serverInfo"},
          {"name", name},
          {"capabilities", nlohmann::json::array()},
          {"supportedEncodings", nlohmann::json::array()},
          {"metadata", metadata},
          {"sessionId", session_id}};
}

nlohmann::json advertise_json(const std::vector<ChannelInfo>& channels) {
  nlohmann::json list = nlohmann::json::array();
  for (const ChannelInfo& c : channels) {
    list.push_back({{"id", c.id},
                    {"topic", c.topic},
                    {"encoding", c.encoding},
                    {"schemaName", c.schema_name},
                    {"schema", c.schema},
                    {"schemaEncoding", c.schema_encoding}});
  }
  return {{"op", "advertise"}, {"channels", list}};
}

nlohmann::json unadvertise_json(const std::vector<std::uint32_t>& channel_ids) {
  return {{"op", "unadvertise"}, {"channelIds", channel_ids}};
}

nlohmann::json status_json(int level, const std::string& message) {
  return {{"op", "status"}, {"level", level}, {"message", message}};
}

std::string message_frame(std::uint32_t subscription_id, std::uint64_t timestamp_ns, const std::uint8_t* data,
                          std::size_t size) {
  std::string frame;
  frame.reserve(13 + size);
  frame.push_back(0x01);
  put_le(frame, subscription_id, 4);
  put_le(frame, timestamp_ns, 8);
  frame.append(reinterpret_cast<const char*>(data), size);
  return frame;
}

std::uint64_t stamp_ns(double stamp_s) {
  if (!std::isfinite(stamp_s) || stamp_s < 0.0 || stamp_s > 1.8e10) return 0;
  return static_cast<std::uint64_t>(std::llround(stamp_s * 1e9));
}

std::vector<nlohmann::json> ClientSubscriptions::handle(const nlohmann::json& message,
                                                        const std::set<std::uint32_t>& unknown_channels) {
  std::vector<nlohmann::json> replies;
  if (!message.is_object() || !message.contains("op") || !message["op"].is_string()) {
    replies.push_back(status_json(2, "a client message must be a JSON object with a string \"op\""));
    return replies;
  }
  const std::string op = message["op"];
  if (op == "subscribe") {
    if (!message.contains("subscriptions") || !message["subscriptions"].is_array()) {
      replies.push_back(status_json(2, "subscribe: \"subscriptions\" must be an array"));
      return replies;
    }
    for (const auto& s : message["subscriptions"]) {
      if (!s.is_object() || !s.contains("id") || !s["id"].is_number_unsigned() || !s.contains("channelId") ||
          !s["channelId"].is_number_unsigned()) {
        replies.push_back(
            status_json(2, "subscribe: each subscription needs unsigned \"id\" and \"channelId\": " + s.dump()));
        continue;
      }
      const auto id = s["id"].get<std::uint32_t>();
      const auto channel = s["channelId"].get<std::uint32_t>();
      if (unknown_channels.count(channel)) {
        replies.push_back(status_json(2, "subscribe: channel " + std::to_string(channel) + " is not advertised"));
        continue;
      }
      if (by_subscription_.count(id)) {
        replies.push_back(status_json(2, "subscribe: subscription id " + std::to_string(id) + " is already in use"));
        continue;
      }
      by_subscription_[id] = channel;
      by_channel_[channel].insert(id);
    }
  } else if (op == "unsubscribe") {
    if (!message.contains("subscriptionIds") || !message["subscriptionIds"].is_array()) {
      replies.push_back(status_json(2, "unsubscribe: \"subscriptionIds\" must be an array"));
      return replies;
    }
    for (const auto& id : message["subscriptionIds"]) {
      const auto it = id.is_number_unsigned() ? by_subscription_.find(id.get<std::uint32_t>()) : by_subscription_.end();
      if (it == by_subscription_.end()) {
        replies.push_back(status_json(1, "unsubscribe: no subscription " + id.dump()));
        continue;
      }
      auto& subs = by_channel_[it->second];
      subs.erase(it->first);
      if (subs.empty()) by_channel_.erase(it->second);
      by_subscription_.erase(it);
    }
  } else if (op == "advertise" || op == "unadvertise" || op == "getParameters" || op == "setParameters" ||
             op == "subscribeParameterUpdates" || op == "unsubscribeParameterUpdates" ||
             op == "subscribeConnectionGraph" || op == "unsubscribeConnectionGraph" || op == "fetchAsset") {
    replies.push_back(status_json(1, "'" + op + "' is not supported by this server (no such capability advertised)"));
  } else {
    replies.push_back(status_json(2, "unknown op '" + op + "'"));
  }
  return replies;
}

std::vector<std::uint32_t> ClientSubscriptions::subscriptions_of(std::uint32_t channel_id) const {
  // Called for every frame of every channel: a lookup by channel, not a walk over all subscriptions
  // (a client subscribed to a fleet's thousand channels made that walk the server's main cost).
  const auto it = by_channel_.find(channel_id);
  if (it == by_channel_.end()) return {};
  return {it->second.begin(), it->second.end()};
}

void ClientSubscriptions::remove_channel(std::uint32_t channel_id) {
  const auto it = by_channel_.find(channel_id);
  if (it == by_channel_.end()) return;
  for (std::uint32_t sub : it->second) by_subscription_.erase(sub);
  by_channel_.erase(it);
}

std::set<std::uint32_t> ClientSubscriptions::channels() const {
  std::set<std::uint32_t> c;
  for (const auto& [channel, subs] : by_channel_) c.insert(channel);
  return c;
}

ChannelInfo ChannelSet::get_or_add(const std::string& key, const ChannelInfo& info, double now_s, bool& added) {
  std::lock_guard<std::mutex> lock(mutex_);
  auto it = by_key_.find(key);
  added = it == by_key_.end();
  if (added) {
    Entry e{info, now_s};
    e.info.id = next_id_++;
    key_of_[e.info.id] = key;
    it = by_key_.emplace(key, std::move(e)).first;
  }
  it->second.last_seen_s = now_s;
  return it->second.info;
}

std::optional<std::uint32_t> ChannelSet::touch(const std::string& key, double now_s) {
  std::lock_guard<std::mutex> lock(mutex_);
  auto it = by_key_.find(key);
  if (it == by_key_.end()) return std::nullopt;
  it->second.last_seen_s = now_s;
  return it->second.info.id;
}

std::optional<std::uint32_t> ChannelSet::find(const std::string& key) const {
  std::lock_guard<std::mutex> lock(mutex_);
  auto it = by_key_.find(key);
  if (it == by_key_.end()) return std::nullopt;
  return it->second.info.id;
}

bool ChannelSet::contains(std::uint32_t id) const {
  std::lock_guard<std::mutex> lock(mutex_);
  return key_of_.count(id) > 0;
}

std::vector<ChannelInfo> ChannelSet::all() const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<ChannelInfo> list;
  for (const auto& [id, key] : key_of_) list.push_back(by_key_.at(key).info);
  return list;
}

std::vector<ChannelInfo> ChannelSet::expire(double now_s, double after_s) {
  std::lock_guard<std::mutex> lock(mutex_);
  std::vector<ChannelInfo> gone;
  for (auto it = by_key_.begin(); it != by_key_.end();) {
    if (now_s - it->second.last_seen_s > after_s) {
      gone.push_back(it->second.info);
      key_of_.erase(it->second.info.id);
      it = by_key_.erase(it);
    } else {
      ++it;
    }
  }
  return gone;
}

std::size_t ChannelSet::size() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return by_key_.size();
}

}  // namespace odonav::ground
