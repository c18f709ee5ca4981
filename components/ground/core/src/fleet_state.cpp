#include "odonav/ground/fleet_state.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "odonav/frames.hpp"
#include "odonav/printf_text.hpp"

namespace odonav::ground {

namespace {
int index(Stream s) { return static_cast<int>(s); }
}  // namespace

const char* stream_name(Stream s) {
  switch (s) {
    case Stream::kOdometer: return "odometer";
    case Stream::kInsAttitude: return "ins";
    case Stream::kGnssFix: return "gnss";
    case Stream::kMisalignment: return "misalignment";
    case Stream::kScaleFactor: return "scale_factor";
    case Stream::kDeadReckoning: return "dead_reckoning";
    case Stream::kHealth: return "health";
  }
  return "?";
}

std::string health_state_name(std::uint32_t state) {
  static const char* names[] = {"STARTING", "RUNNING", "DEGRADED", "ERROR", "STOPPING"};
  return state < 5 ? names[state] : "STATE" + std::to_string(state);
}
std::string health_level_name(std::uint32_t level) {
  static const char* names[] = {"OK", "WARN", "ERROR", "STALE"};
  return level < 4 ? names[level] : "LEVEL" + std::to_string(level);
}
std::string command_result_name(std::uint32_t result) {
  static const char* names[] = {"none", "accepted", "rejected"};
  return result < 3 ? names[result] : "result" + std::to_string(result);
}
std::string fix_quality_name(std::uint8_t q) {
  switch (q) {
    case 0: return "invalid";
    case 1: return "single";
    case 2: return "dgps";
    case 4: return "rtk-fixed";
    case 5: return "rtk-float";
    case 6: return "dead-reckoning";
  }
  return "fix" + std::to_string(q);
}
FleetState::FleetState(FleetStateConfig config) : config_(config) {
  if (!(config_.rate_window_s > 0.0)) throw std::invalid_argument("FleetState: rate_window_s must be > 0");
  for (double s : config_.stale_after_s)
    if (!(s > 0.0)) throw std::invalid_argument("FleetState: every stale_after_s must be > 0");
}

FleetState::Vehicle& FleetState::vehicle(const std::string& id) { return vehicles_[id]; }

void FleetState::count(Vehicle& v, Stream s, double now_s) {
  auto& q = v.arrivals[index(s)];
  q.push_back(now_s);
  while (!q.empty() && q.front() < now_s - config_.rate_window_s) q.pop_front();
}

bool FleetState::is_stale(const Timed& t, Stream s, double now_s) const {
  return t.silent || now_s - t.last_arrival_s > config_.stale_after_s[index(s)];
}

void FleetState::on_health(const HealthView& h, double now_s) {
  std::lock_guard<std::mutex> lock(mutex_);
  Vehicle& v = vehicle(h.vehicle_id);
  auto& slot = v.components[h.component];
  slot.first = h;
  slot.second.last_arrival_s = now_s;
  slot.second.silent = false;
  count(v, Stream::kHealth, now_s);
}

template <class View>
FleetState::Vehicle& FleetState::keep_latest(std::optional<std::pair<View, Timed>> Vehicle::*slot, const View& view,
                                             double now_s) {
  Vehicle& v = vehicle(view.vehicle_id);
  v.*slot = std::make_pair(view, Timed{now_s, false});
  return v;
}

void FleetState::on_scale_factor(const ScaleFactorView& sf, double now_s) {
  std::lock_guard<std::mutex> lock(mutex_);
  count(keep_latest(&Vehicle::scale_factor, sf, now_s), Stream::kScaleFactor, now_s);
}

void FleetState::on_misalignment(const MisalignmentView& m, double now_s) {
  std::lock_guard<std::mutex> lock(mutex_);
  count(keep_latest(&Vehicle::misalignment, m, now_s), Stream::kMisalignment, now_s);
}

void FleetState::on_dead_reckoning(const DeadReckoningView& d, double now_s) {
  std::lock_guard<std::mutex> lock(mutex_);
  Vehicle& v = keep_latest(&Vehicle::dead_reckoning, d, now_s);
  count(v, Stream::kDeadReckoning, now_s);
  v.dead_reckoning_gaps.offer(d.row.t_s);
}

void FleetState::on_navigation(const NavigationPositionView& n, double now_s) {
  std::lock_guard<std::mutex> lock(mutex_);
  keep_latest(&Vehicle::navigation, n, now_s);
}

void FleetState::on_gnss(const GnssView& g, double now_s) {
  std::lock_guard<std::mutex> lock(mutex_);
  count(keep_latest(&Vehicle::gnss, g, now_s), Stream::kGnssFix, now_s);
}

void FleetState::on_arrival(const std::string& vehicle_id, Stream stream, double now_s) {
  std::lock_guard<std::mutex> lock(mutex_);
  count(vehicle(vehicle_id), stream, now_s);
}

void FleetState::on_silence(const std::string& vehicle_id, Stream stream, const std::string& component, bool silent) {
  std::lock_guard<std::mutex> lock(mutex_);
  const auto it = vehicles_.find(vehicle_id);
  if (it == vehicles_.end()) return;  // nothing known yet: nothing to mark
  Vehicle& v = it->second;
  // The latest view of the stream, when there is one, is marked.
  const auto mark = [silent](auto& latest) {
    if (latest) latest->second.silent = silent;
  };
  switch (stream) {
    case Stream::kHealth: {
      const auto c = v.components.find(component);
      if (c != v.components.end()) c->second.second.silent = silent;
      break;
    }
    case Stream::kScaleFactor: mark(v.scale_factor); break;
    case Stream::kMisalignment: mark(v.misalignment); break;
    case Stream::kDeadReckoning: mark(v.dead_reckoning); break;
    case Stream::kGnssFix: mark(v.gnss); break;
    default: break;
  }
}

FleetSnapshot FleetState::snapshot(double now_s, const std::vector<std::string>& only) const {
  std::lock_guard<std::mutex> lock(mutex_);
  FleetSnapshot snap;
  snap.now_s = now_s;
  for (const auto& [id, v] : vehicles_) {
    if (!only.empty() && std::find(only.begin(), only.end(), id) == only.end()) continue;
    VehicleSnapshot vs;
    vs.vehicle_id = id;
    for (const auto& [name, entry] : v.components) {
      ComponentSnapshot c{entry.first, now_s - entry.second.last_arrival_s,
                          is_stale(entry.second, Stream::kHealth, now_s)};
      vs.stale = vs.stale || c.stale;
      vs.components.push_back(std::move(c));
    }
    auto fill = [&](const auto& source, auto& target, Stream s) {
      if (!source) return;
      target.emplace();
      target->view = source->first;
      target->age_s = now_s - source->second.last_arrival_s;
      target->stale = is_stale(source->second, s, now_s);
      vs.stale = vs.stale || target->stale;
    };
    fill(v.scale_factor, vs.scale_factor, Stream::kScaleFactor);
    fill(v.misalignment, vs.misalignment, Stream::kMisalignment);
    fill(v.dead_reckoning, vs.dead_reckoning, Stream::kDeadReckoning);
    fill(v.navigation, vs.navigation, Stream::kDeadReckoning);
    fill(v.gnss, vs.gnss, Stream::kGnssFix);
    vs.dead_reckoning_missed = v.dead_reckoning_gaps.missed();
    vs.dead_reckoning_gaps = v.dead_reckoning_gaps.gaps();
    vs.dead_reckoning_last_gap = v.dead_reckoning_gaps.last_gap();
    for (int s = 0; s < kStreamCount; ++s) {
      const auto& q = v.arrivals[s];
      const auto n = std::count_if(q.begin(), q.end(), [&](double t) { return t >= now_s - config_.rate_window_s; });
      vs.rate_hz[s] = static_cast<double>(n) / config_.rate_window_s;
    }
    snap.vehicles.push_back(std::move(vs));
  }
  return snap;
}

nlohmann::json snapshot_json(const FleetSnapshot& snap) {
  nlohmann::json vehicles = nlohmann::json::array();
  for (const VehicleSnapshot& v : snap.vehicles) {
    nlohmann::json jv;
    jv["vehicle_id"] = v.vehicle_id;
    jv["stale"] = v.stale;
    nlohmann::json components = nlohmann::json::array();
    for (const ComponentSnapshot& c : v.components) {
      nlohmann::json counters = nlohmann::json::object();
      for (const auto& [name, value] : c.health.counters) counters[name] = value;
      components.push_back({{"component", c.health.component},
                            {"state", health_state_name(c.health.state)},
                            {"level", health_level_name(c.health.level)},
                            {"reason", c.health.reason},
                            {"stale", c.stale},
                            {"age_s", c.age_s},
                            {"stamp_s", c.health.stamp_s},
                            {"last_command",
                             {{"id", c.health.last_command_id},
                              {"result", command_result_name(c.health.last_command_result)},
                              {"detail", c.health.last_command_detail}}},
                            {"counters", counters}});
    }
    jv["components"] = components;
    // The estimates: the output file's row (its column names and units) plus what only the topic has
    // (`extra` adds it), its age and staleness; null while the vehicle has none.
    const auto item = [](const auto& snapshot, auto extra) {
      if (!snapshot) return nlohmann::json();
      nlohmann::json j = results::row_json(snapshot->view.row);
      extra(j, snapshot->view);
      j["age_s"] = snapshot->age_s;
      j["stale"] = snapshot->stale;
      return j;
    };
    jv["scale_factor"] = item(v.scale_factor, [](nlohmann::json& j, const ScaleFactorView& k) {
      j["frozen"] = k.frozen;
      j["source"] = k.source;
    });
    jv["misalignment"] = item(v.misalignment, [](nlohmann::json&, const MisalignmentView&) {});
    jv["dead_reckoning"] = item(v.dead_reckoning, [](nlohmann::json& j, const DeadReckoningView& d) {
      j["origin_lat_deg"] = d.origin_latitude_deg;
      j["origin_lon_deg"] = d.origin_longitude_deg;
      j["origin_height_m"] = d.origin_height_m;
      j["gnss_valid"] = d.gnss_valid;
    });
    jv["navigation"] = item(v.navigation, [](nlohmann::json& j, const NavigationPositionView& view) {
      const results::NavigationPositionRow& n = view.row;
      const double horizontal_var_m2 = n.var_east_m2 + n.var_north_m2;  // NaN when either is unknown
      j["horizontal_sigma_m"] = std::isfinite(horizontal_var_m2) && horizontal_var_m2 >= 0.0
                                    ? nlohmann::json(std::sqrt(horizontal_var_m2))
                                    : nlohmann::json();
    });
    if (v.gnss) {
      const auto& g = v.gnss->view;
      jv["gnss"] = {
          {"valid", g.valid},         {"fix_quality", g.fix_quality}, {"fix", fix_quality_name(g.fix_quality)},
          {"speed_mps", g.speed_mps}, {"stamp_s", g.stamp_s},         {"age_s", v.gnss->age_s},
          {"stale", v.gnss->stale}};
    } else {
      jv["gnss"] = nullptr;
    }
    nlohmann::json rates = nlohmann::json::object();
    for (int s = 0; s < kStreamCount; ++s) rates[stream_name(static_cast<Stream>(s))] = v.rate_hz[s];
    jv["rates_hz"] = rates;
    nlohmann::json dr_gaps = {{"missed", v.dead_reckoning_missed}, {"gaps", v.dead_reckoning_gaps}};
    if (v.dead_reckoning_last_gap) {
      dr_gaps["last"] = describe_gap(*v.dead_reckoning_last_gap, "dead-reckoning");
      dr_gaps["last_first_missing_t_s"] = v.dead_reckoning_last_gap->first_missing_t_s;
      dr_gaps["last_last_missing_t_s"] = v.dead_reckoning_last_gap->last_missing_t_s;
    } else {
      dr_gaps["last"] = nullptr;
      dr_gaps["last_first_missing_t_s"] = nullptr;
      dr_gaps["last_last_missing_t_s"] = nullptr;
    }
    jv["gaps"] = {{"dead_reckoning", dr_gaps}};
    vehicles.push_back(std::move(jv));
  }
  return {{"vehicles", vehicles}};
}

namespace {

/// A line of the dashboard: text plus optional highlight, cut to the width.
struct Line {
  std::string text;
  bool alert = false;  // stale or error: reverse video with ansi
};

std::string fit(const std::string& s, int width) {
  return static_cast<int>(s.size()) <= width ? s : s.substr(0, static_cast<std::size_t>(width));
}

std::string pad(const std::string& s, std::size_t n) { return s.size() >= n ? s : s + std::string(n - s.size(), ' '); }

// The line of one estimate of a vehicle: `text` writes the estimate's row when the vehicle has one
// (the line marked when it is stale), else the line is `absent`.
template <class View, class Text>
Line item_line(const std::optional<ItemSnapshot<View>>& item, const char* absent, Text text) {
  if (!item) return {absent, false};
  std::ostringstream line;
  text(line, item->view.row);
  return {line.str(), item->stale};
}

std::vector<Line> vehicle_block(const VehicleSnapshot& v) {
  std::vector<Line> lines;
  std::ostringstream head;
  head << "== " << v.vehicle_id << (v.stale ? " [STALE]" : "") << " ";
  if (v.gnss) {
    head << " GNSS " << (v.gnss->view.valid ? "valid" : "INVALID") << " fix "
         << fix_quality_name(v.gnss->view.fix_quality) << printf_text(" %.1f m/s", v.gnss->view.speed_mps)
         << (v.gnss->stale ? " STALE" : "");
  } else {
    head << " GNSS -";
  }
  lines.push_back({head.str(), v.stale});

  lines.push_back(item_line(v.scale_factor, " K -", [&](std::ostringstream& k, const results::ScaleFactorRow& s) {
    k << " K " << printf_text("%.7f", s.k_m_per_pulse.value_or(0.0));
    if (s.sigma_m_per_pulse) k << " +-" << printf_text("%.7f", *s.sigma_m_per_pulse);
    k << " m/p " << s.estimator << (s.converged ? " conv" : " -") << (v.scale_factor->view.frozen ? " FROZEN" : "")
      << printf_text(" lambda %.4f", s.forgetting_factor) << printf_text(" fill %.0f%%", 100.0 * s.window_fill)
      << (v.scale_factor->stale ? " STALE" : "");
  }));

  lines.push_back(
      item_line(v.misalignment, " misalign -", [&](std::ostringstream& m, const results::MisalignmentRow& a) {
        m << " misalign hdg " << printf_text("%+.3f", rad_to_deg(a.heading_rad));
        if (std::isfinite(a.heading_std_rad)) m << " +-" << printf_text("%.3f", rad_to_deg(a.heading_std_rad));
        m << " pitch " << printf_text("%+.3f", rad_to_deg(a.pitch_rad));
        if (std::isfinite(a.pitch_std_rad)) m << " +-" << printf_text("%.3f", rad_to_deg(a.pitch_std_rad));
        m << " deg " << a.state << (v.misalignment->stale ? " STALE" : "");
      }));

  lines.push_back(item_line(v.dead_reckoning, " DR -", [&](std::ostringstream& d, const results::DeadReckoningRow& r) {
    d << " DR err ";
    d << (std::isfinite(r.horizontal_error_m) ? printf_text("%.1f m", r.horizontal_error_m) : std::string("- m"));
    d << " " << (std::isfinite(r.error_percent) ? printf_text("%.2f %%D", r.error_percent) : std::string("- %D"));
    d << printf_text(" dist %.0f m", r.distance_m) << " K " << r.k_source;
    // Which identification instance the K comes from (a hot standby publishes under its own name).
    if (v.scale_factor && !v.scale_factor->view.source.empty()) d << " from " << v.scale_factor->view.source;
    d << (v.dead_reckoning->stale ? " STALE" : "");
    // What never reached the ground (a fault on the vehicle or the link), from the stamps.
    if (v.dead_reckoning_missed > 0)
      d << " missed " << v.dead_reckoning_missed << " in " << v.dead_reckoning_gaps << " gap(s), last "
        << printf_text("t=%.2f", v.dead_reckoning_last_gap->first_missing_t_s)
        << printf_text("-%.2f s", v.dead_reckoning_last_gap->last_missing_t_s);
  }));

  std::ostringstream r;
  static const char* short_names[] = {"odo", "ins", "gnss", "mis", "k", "dr", "hlth"};
  r << " Hz";
  for (int s = 0; s < kStreamCount; ++s) r << " " << short_names[s] << " " << printf_text("%.0f", v.rate_hz[s]);
  lines.push_back({r.str(), false});

  for (const ComponentSnapshot& c : v.components) {
    std::ostringstream l;
    l << "  " << pad(c.health.component, 22) << " ";
    if (c.stale) {
      l << pad("STALE", 9) << printf_text("silent %.1f s", c.age_s) << " (last " << health_state_name(c.health.state)
        << ")";
    } else {
      l << pad(health_state_name(c.health.state), 9) << pad(health_level_name(c.health.level), 6) << c.health.reason;
    }
    lines.push_back({l.str(), c.stale || c.health.level >= 2});
  }
  return lines;
}

}  // namespace

std::string render_dashboard(const FleetSnapshot& snap, int width, int height, bool ansi, const std::string& title) {
  width = std::max(width, 40);
  height = std::max(height, 8);
  std::vector<Line> out;
  out.push_back({title + "  vehicles " + std::to_string(snap.vehicles.size()), false});
  if (snap.vehicles.empty()) out.push_back({"  (no vehicle heard yet)", false});
  std::size_t shown = 0;
  for (const VehicleSnapshot& v : snap.vehicles) {
    std::vector<Line> block = vehicle_block(v);
    const bool last = shown + 1 == snap.vehicles.size();
    // Keep one line for "N more vehicles" unless this is the last vehicle.
    const long room = static_cast<long>(height) - static_cast<long>(out.size()) - (last ? 0 : 1);
    if (static_cast<long>(block.size()) > room) {
      if (shown == 0 && room > 0) {  // at least part of the first vehicle
        block.resize(static_cast<std::size_t>(room));
        out.insert(out.end(), block.begin(), block.end());
        ++shown;
      }
      break;
    }
    out.insert(out.end(), block.begin(), block.end());
    ++shown;
  }
  if (shown < snap.vehicles.size()) {
    std::ostringstream more;
    more << "... " << snap.vehicles.size() - shown << " more vehicle(s); --vehicle ID to pick";
    out.push_back({more.str(), false});
  }
  std::string text;
  for (const Line& l : out) {
    const std::string t = fit(l.text, width);
    if (ansi && l.alert)
      text += "\x1b[7m" + t + "\x1b[0m";
    else
      text += t;
    text += '\n';
  }
  return text;
}

}  // namespace odonav::ground
