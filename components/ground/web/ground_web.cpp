#include "web/ground_web.hpp"

#include <fastdds/rtps/common/SerializedPayload.h>
#include <spdlog/spdlog.h>

#include <cmath>
#include <stdexcept>
#include <type_traits>

#include "odonav/ground/recording.hpp"
#include "odonav/ground/ros2msg_schema.hpp"
#include "odonav/ground/standard_channels.hpp"
#include "odonav/ground/web_api.hpp"
#include "odonav/dds/time.hpp"
#include "odonav/dds/types.hpp"

namespace odonav::ground {

const std::string& fleet_page_html();  // web/assets/index.html, embedded at build time

namespace {

double steady_now_s() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

ChannelInfo derived_info(const std::string& vehicle, DerivedChannel kind) {
  ChannelInfo c;
  c.topic = derived_topic(vehicle, kind);
  c.encoding = derived_encoding(kind);
  c.schema_name = derived_schema_name(kind);
  c.schema = derived_schema(kind);
  c.schema_encoding = derived_schema_encoding(kind);
  return c;
}

std::string derived_key(DerivedChannel kind) { return "derived/" + std::to_string(static_cast<int>(kind)); }

HttpReply json_reply(int status, const nlohmann::json& j) { return {status, "application/json", j.dump()}; }

}  // namespace

GroundWeb::GroundWeb(const dds::Participant& participant, ServeOptions options, WebServerOptions web)
    : participant_(participant), options_(std::move(options)) {
  for (const auto& spec : topics::kAllTopics)
    schemas_[spec.ros_type_name] = ros2msg_schema(embedded_msg_library(), spec.ros_type_name);
  WebHandlers handlers;
  handlers.get = [this](const std::string& target) { return get(target); };
  handlers.command = [this](const std::string& authorization, const std::string& body) {
    return command(authorization, body);
  };
  server_ = std::make_unique<WebServer>(std::move(web), std::move(handlers), channels_);
  monitor_ = std::make_unique<FleetMonitor>(participant, state_, steady_now_s,
                                            [this](topics::TopicId topic, AnySample s) { on_sample(topic, s); });
}

GroundWeb::~GroundWeb() { stop(); }

void GroundWeb::stop() {
  if (server_) server_->stop();  // no handler runs afterwards
  monitor_.reset();              // no sample arrives afterwards
}

std::uint32_t GroundWeb::channel(const std::string& vehicle, const std::string& key,
                                 const std::function<ChannelInfo()>& make) {
  const std::string full_key = vehicle + "\n" + key;
  if (auto id = channels_.touch(full_key, steady_now_s())) return *id;
  bool added = false;
  const ChannelInfo c = channels_.get_or_add(full_key, make(), steady_now_s(), added);
  if (added) {
    spdlog::debug("web: channel {} {}", c.id, c.topic);
    server_->advertise({c});
  }
  return c.id;
}

void GroundWeb::publish_json(std::uint32_t id, double stamp_s, const std::string& text) {
  server_->publish(id, stamp_ns(stamp_s), reinterpret_cast<const std::uint8_t*>(text.data()), text.size());
}

void GroundWeb::on_sample(topics::TopicId topic, AnySample sample) {
  std::visit(
      [&](auto* m) {
        using T = std::remove_cv_t<std::remove_pointer_t<decltype(m)>>;
        const std::string vehicle = m->vehicle_id();
        if (vehicle.empty()) return;  // no vehicle to file it under
        const topics::TopicSpec& spec = topics::spec_of(topic);
        const double stamp_s = stamp_of(m->header());
        const std::uint32_t id = channel(vehicle, spec.name, [&] {
          ChannelInfo info;
          info.topic = vehicle_topic(vehicle, topic_short_name(spec));
          info.encoding = "cdr";
          info.schema_name = spec.ros_type_name;
          info.schema = schemas_.at(spec.ros_type_name);
          info.schema_encoding = "ros2msg";
          return info;
        });
        if (server_->subscribed(id)) {
          // Serialized again with the generated type support: the CDR bytes Fast DDS carries.
          typename dds::DdsType<T>::PubSubType type;
          T* data = const_cast<T*>(m);  // serialize() takes void* but only reads
          eprosima::fastrtps::rtps::SerializedPayload_t payload(type.getSerializedSizeProvider(data)());
          if (type.serialize(data, &payload)) server_->publish(id, stamp_ns(stamp_s), payload.data, payload.length);
        }
        // A derived channel of this vehicle (advertised on first use).
        auto derived = [&](DerivedChannel kind) {
          return channel(vehicle, derived_key(kind), [&] { return derived_info(vehicle, kind); });
        };
        // The NavSatFix fix() makes, CDR-encoded, to the clients of the derived channel `kind`.
        auto publish_navsat = [&](DerivedChannel kind, const auto& fix) {
          const std::uint32_t c = derived(kind);
          if (!server_->subscribed(c)) return;
          const auto bytes = encode_cdr(fix());
          server_->publish(c, stamp_ns(stamp_s), bytes.data(), bytes.size());
        };
        if constexpr (std::is_same_v<T, odonav::msg::DeadReckoning>) {
          const DeadReckoningView v = view_of(*m);
          history_.on_dead_reckoning(v);
          publish_navsat(DerivedChannel::kNavSatDeadReckoning, [&] { return navsat_from_dead_reckoning(v); });
        } else if constexpr (std::is_same_v<T, odonav::msg::NavigationPosition>) {
          // The "navigation" NavSatFix: the GNSS-anchored position, not the pure DR.
          const NavigationPositionView v = view_of(*m);
          publish_navsat(DerivedChannel::kNavSatNavigation, [&] { return navsat_from_navigation(v); });
        } else if constexpr (std::is_same_v<T, odonav::msg::GnssFix>) {
          const GnssView v = view_of(*m);
          history_.on_gnss(v);
          publish_navsat(DerivedChannel::kNavSatGnss, [&] { return navsat_from_gnss(v); });
        } else if constexpr (std::is_same_v<T, odonav::msg::ScaleFactor>) {
          const ScaleFactorView v = view_of(*m);
          history_.on_scale_factor(v);
          const std::uint32_t c = derived(DerivedChannel::kScaleFactorPlot);
          if (server_->subscribed(c)) publish_json(c, stamp_s, scale_factor_plot(v).dump());
        } else if constexpr (std::is_same_v<T, odonav::msg::Health>) {
          // The diagnostics channel lives while some component of the vehicle speaks; tick() fills it.
          derived(DerivedChannel::kDiagnostics);
        }
      },
      sample);
}

void GroundWeb::tick(double now_s) {
  if (now_s - last_diagnostics_s_ >= options_.diagnostics_period_s) {
    last_diagnostics_s_ = now_s;
    const FleetSnapshot snap = state_.snapshot(now_s);
    for (const VehicleSnapshot& v : snap.vehicles) {
      const auto id = channels_.find(v.vehicle_id + "\n" + derived_key(DerivedChannel::kDiagnostics));
      if (!id || !server_->subscribed(*id) || v.components.empty()) continue;
      const DiagnosticArrayMsg d = diagnostics_from(v);
      const auto bytes = encode_cdr(d);
      server_->publish(*id, stamp_ns(d.stamp_s), bytes.data(), bytes.size());
    }
  }
  if (now_s - last_expiry_s_ >= 1.0) {
    last_expiry_s_ = now_s;
    const auto gone = channels_.expire(now_s, options_.forget_after_s);
    if (!gone.empty()) {
      std::vector<std::uint32_t> ids;
      for (const auto& c : gone) {
        ids.push_back(c.id);
        spdlog::info("web: {} silent for {} s: unadvertised", c.topic, options_.forget_after_s);
      }
      server_->unadvertise(ids);
    }
  }
}

HttpReply GroundWeb::get(const std::string& target) {
  const std::string path = target_path(target);
  if (path == "/" || path == "/index.html") return {200, "text/html; charset=utf-8", fleet_page_html()};
  if (path == "/api/fleet") {
    const FleetSnapshot snap = state_.snapshot(steady_now_s());
    nlohmann::json j;
    j["domain"] = options_.domain;
    j["commands_enabled"] = !options_.token.empty();
    const auto st = server_->stats();
    j["server"] = {{"foxglove_clients", st.clients},
                   {"frames_sent", st.frames_sent},
                   {"frames_dropped", st.frames_dropped},
                   {"channels", channels_.size()}};
    j["snapshot"] = snapshot_json(snap);
    const std::string wanted = query_parameter(target, "history");
    j["history"] = nlohmann::json::object();
    if (!wanted.empty()) {
      const nlohmann::json all = history_.json(options_.history_points);
      if (all.contains(wanted)) j["history"][wanted] = all[wanted];
    }
    return json_reply(200, j);
  }
  if (path == "/api/channels") {
    nlohmann::json list = nlohmann::json::array();
    for (const auto& c : channels_.all())
      list.push_back({{"id", c.id}, {"topic", c.topic}, {"encoding", c.encoding}, {"schemaName", c.schema_name}});
    return json_reply(200, list);
  }
  return {404, "text/plain", "not found: " + path + " (the page is /, its data /api/fleet)\n"};
}

HttpReply GroundWeb::command(const std::string& authorization, const std::string& body) {
  if (const auto why = authorization_error(options_.token, authorization)) {
    spdlog::warn("web: command refused: {}", *why);
    return json_reply(options_.token.empty() ? 403 : 401, {{"error", *why}});
  }
  CommandRequest request;
  WebCommand c;
  try {
    c = parse_web_command(body);
    request.kind = parse_command_kind(c.command);
  } catch (const std::invalid_argument& e) {
    return json_reply(400, {{"error", e.what()}});
  }
  request.vehicle_id = c.vehicle;
  request.component = c.component;
  request.value = c.value;
  request.timeout_s = options_.command_timeout_s;
  const CommandReply reply = send_command(participant_, request);
  const char* outcome = reply.outcome == CommandOutcome::kAccepted   ? "ACCEPTED"
                        : reply.outcome == CommandOutcome::kRejected ? "REJECTED"
                                                                     : "TIMEOUT";
  spdlog::info("web: command {} {} {}{} (id {}): {} {}", c.vehicle, c.component, c.command,
               c.command == "set-k" ? " " + std::to_string(c.value) : std::string(), reply.command_id, outcome,
               reply.detail);
  return json_reply(200, {{"vehicle", c.vehicle},
                          {"component", c.component},
                          {"command", c.command},
                          {"value", c.value},
                          {"command_id", reply.command_id},
                          {"outcome", outcome},
                          {"detail", reply.detail}});
}

}  // namespace odonav::ground
