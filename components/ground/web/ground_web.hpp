#pragma once
// odonav-ground serve: the fleet as Foxglove WebSocket channels and as the fleet page, from one
// DDS participant. The FleetMonitor's readers (the monitor's QoS) feed the FleetState, the page's
// history, and, through its tap, the channels: every odonav topic per vehicle (CDR as received,
// ros2msg schema) and the standard ones of core/standard_channels.hpp.
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <string>

#include "odonav/ground/fleet_history.hpp"
#include "odonav/ground/fleet_state.hpp"
#include "odonav/ground/foxglove_protocol.hpp"
#include "node/ground_node.hpp"
#include "web/web_server.hpp"

namespace odonav::ground {

struct ServeOptions {
  std::string token;                  ///< commands need it; empty: commands disabled
  double diagnostics_period_s = 0.5;  ///< DiagnosticArray per vehicle this often (s)
  double forget_after_s = 60.0;       ///< a channel fed by nothing this long is unadvertised (s)
  std::size_t history_points = 400;   ///< track and K points per series on the page
  double command_timeout_s = 5.0;     ///< a command's whole exchange (s)
  int domain = 0;                     ///< shown on the page
};

class GroundWeb {
 public:
  /// Binds the server (throws std::runtime_error when it cannot) and creates the readers.
  GroundWeb(const dds::Participant& participant, ServeOptions options, WebServerOptions web);
  ~GroundWeb();
  GroundWeb(const GroundWeb&) = delete;
  GroundWeb& operator=(const GroundWeb&) = delete;

  void start() { server_->start(); }
  int port() const { return server_->port(); }
  /// Periodic work (call every ~0.1 s with the steady clock): DiagnosticArray of every vehicle
  /// each diagnostics period, channels gone unadvertised.
  void tick(double now_s);
  /// Stops serving and closes the readers (idempotent).
  void stop();
  WebServer::Stats stats() const { return server_->stats(); }

 private:
  void on_sample(topics::TopicId topic, AnySample sample);
  /// The channel of (vehicle, key), advertised when new.
  std::uint32_t channel(const std::string& vehicle, const std::string& key, const std::function<ChannelInfo()>& make);
  void publish_json(std::uint32_t channel, double stamp_s, const std::string& text);
  HttpReply get(const std::string& target);
  HttpReply command(const std::string& authorization, const std::string& body);

  const dds::Participant& participant_;
  ServeOptions options_;
  FleetState state_;
  FleetHistory history_;
  ChannelSet channels_;
  std::map<std::string, std::string> schemas_;  // ros type -> ros2msg schema
  std::unique_ptr<WebServer> server_;
  std::unique_ptr<FleetMonitor> monitor_;
  double last_diagnostics_s_ = -1e300;
  double last_expiry_s_ = -1e300;
};

}  // namespace odonav::ground
