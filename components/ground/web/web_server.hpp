#pragma once
// HTTP and the Foxglove WebSocket protocol on one port, with Boost.Beast (Debian's libboost-dev):
// the fleet page and its JSON API over HTTP, Foxglove/Lichtblick clients over WebSocket (both
// subprotocol names). One I/O thread runs every connection; DDS listener threads only queue frames
// (publish() never blocks on a client): each WebSocket client has a bounded queue, and data frames
// beyond it are dropped and counted, so a client that does not read loses frames while the others
// and the DDS side go on. Control messages (advertise, unadvertise, status) are never dropped.
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "odonav/ground/foxglove_protocol.hpp"

namespace odonav::ground {

struct WebServerOptions {
  std::string bind_address = "127.0.0.1";
  int port = 8765;  ///< 0: any free port (port() tells which)
  std::string name = "odonav-ground";
  std::map<std::string, std::string> metadata;         ///< serverInfo metadata
  std::size_t max_queued_bytes_per_client = 4u << 20;  ///< data frames past this are dropped
};

/// An HTTP reply the handlers build.
struct HttpReply {
  int status = 200;
  std::string content_type = "application/json";
  std::string body;
};

struct WebHandlers {
  /// GET requests: target (path and query) -> reply; called on the I/O thread, must be quick.
  std::function<HttpReply(const std::string& target)> get;
  /// POST /api/command: (authorization header, body) -> reply. Called on the server's command
  /// thread (it may wait seconds for an acknowledgement), one at a time.
  std::function<HttpReply(const std::string& authorization, const std::string& body)> command;
};

class WebServer {
 public:
  /// Binds and listens at once (throws std::runtime_error naming the address and port when it
  /// cannot); serves from start() on. channels: the set whose channels a new client is advertised.
  WebServer(WebServerOptions options, WebHandlers handlers, const ChannelSet& channels);
  ~WebServer();
  WebServer(const WebServer&) = delete;
  WebServer& operator=(const WebServer&) = delete;

  void start();
  /// Closes the listener and every connection, joins the threads (idempotent).
  void stop();
  int port() const { return port_; }

  /// Tells every client about new channels / channels gone (their subscriptions are dropped).
  void advertise(const std::vector<ChannelInfo>& channels);
  void unadvertise(const std::vector<std::uint32_t>& channel_ids);
  /// Whether some client subscribed to the channel (so the caller serializes only then).
  bool subscribed(std::uint32_t channel_id) const;
  /// Queues one message of a channel to every client subscribed to it. Never blocks on a client.
  void publish(std::uint32_t channel_id, std::uint64_t timestamp_ns, const std::uint8_t* data, std::size_t size);

  struct Stats {
    std::size_t clients = 0;
    std::uint64_t frames_sent = 0, frames_dropped = 0;
  };
  Stats stats() const;

  class Impl;  // Beast sessions; public for them, defined in web_server.cpp

 private:
  std::unique_ptr<Impl> impl_;
  int port_ = 0;
};

}  // namespace odonav::ground
