#include "odonav/ground/fleet_history.hpp"

#include <cmath>
#include <stdexcept>

#include "odonav/geodesy.hpp"

namespace odonav::ground {

namespace {
constexpr double kDegToRad = 3.14159265358979323846 / 180.0;
}

FleetHistory::FleetHistory(FleetHistoryConfig config) : config_(config) {
  if (!(config_.k_window_s > 0.0)) throw std::invalid_argument("FleetHistory: k_window_s must be > 0");
  if (config_.max_track_points < 16) throw std::invalid_argument("FleetHistory: max_track_points must be >= 16");
}

FleetHistory::~FleetHistory() = default;

void FleetHistory::add_track_point(std::vector<Point>& series, double east_m, double north_m) {
  if (!std::isfinite(east_m) || !std::isfinite(north_m)) return;
  if (!series.empty() && std::hypot(east_m - series.back().a, north_m - series.back().b) < config_.track_min_step_m)
    return;
  series.push_back({east_m, north_m, 0.0});
  if (series.size() > config_.max_track_points) {
    std::vector<Point> kept;
    kept.reserve(series.size() / 2 + 1);
    for (std::size_t i = 0; i < series.size(); i += 2) kept.push_back(series[i]);
    if (kept.back().a != series.back().a || kept.back().b != series.back().b) kept.push_back(series.back());
    series.swap(kept);
  }
}

void FleetHistory::on_dead_reckoning(const DeadReckoningView& d) {
  std::lock_guard<std::mutex> lock(mutex_);
  Vehicle& v = vehicles_[d.vehicle_id];
  const std::pair<double, double> origin{d.origin_latitude_deg, d.origin_longitude_deg};
  if (!v.origin_deg || *v.origin_deg != origin) {
    // A new origin (first sample, or DR restarted elsewhere): the old track is in another frame.
    v.origin_deg = origin;
    v.frame = std::make_shared<LocalEnuFrame>(
        Geodetic{d.origin_latitude_deg * kDegToRad, d.origin_longitude_deg * kDegToRad, d.origin_height_m});
    v.dr.clear();
    v.gnss.clear();
  }
  add_track_point(v.dr, d.row.east_m, d.row.north_m);
}

void FleetHistory::on_gnss(const GnssView& g) {
  if (!g.valid || !std::isfinite(g.latitude_deg) || !std::isfinite(g.longitude_deg)) return;
  std::lock_guard<std::mutex> lock(mutex_);
  auto it = vehicles_.find(g.vehicle_id);
  if (it == vehicles_.end() || !it->second.frame) return;
  const auto enu =
      it->second.frame->to_enu(Geodetic{g.latitude_deg * kDegToRad, g.longitude_deg * kDegToRad, g.height_m});
  add_track_point(it->second.gnss, enu.x(), enu.y());
}

void FleetHistory::on_scale_factor(const ScaleFactorView& view) {
  const results::ScaleFactorRow& k = view.row;
  // No K yet (0 on the topic): not a value to plot.
  if (!std::isfinite(k.t_s) || !k.k_m_per_pulse || !std::isfinite(*k.k_m_per_pulse)) return;
  const double sigma_m_per_pulse = k.sigma_m_per_pulse.value_or(-1.0);  // -1: unknown, as the plot takes it
  std::lock_guard<std::mutex> lock(mutex_);
  auto& series = vehicles_[view.vehicle_id].k;
  if (!series.empty() && k.t_s < series.back().a) series.clear();  // time went back: a new run
  series.push_back({k.t_s, *k.k_m_per_pulse, sigma_m_per_pulse});
  std::size_t drop = 0;
  while (drop < series.size() && series[drop].a < k.t_s - config_.k_window_s) ++drop;
  if (drop > 0) series.erase(series.begin(), series.begin() + static_cast<std::ptrdiff_t>(drop));
}

nlohmann::json FleetHistory::json(std::size_t max_points) const {
  if (max_points < 2) max_points = 2;
  auto thin = [max_points](const std::vector<Point>& s, bool three) {
    nlohmann::json out = nlohmann::json::array();
    const std::size_t n = s.size();
    const std::size_t m = std::min(n, max_points);
    for (std::size_t k = 0; k < m; ++k) {
      // Evenly spaced indices from the first to the last point.
      const std::size_t i =
          m == 1 ? 0 : static_cast<std::size_t>(std::llround(k * static_cast<double>(n - 1) / (m - 1)));
      const Point& p = s[i];
      if (three) {
        out.push_back({p.a, p.b, std::isfinite(p.c) && p.c >= 0.0 ? nlohmann::json(p.c) : nlohmann::json()});
      } else {
        out.push_back({std::round(p.a * 100.0) / 100.0, std::round(p.b * 100.0) / 100.0});
      }
    }
    return out;
  };
  std::lock_guard<std::mutex> lock(mutex_);
  nlohmann::json all = nlohmann::json::object();
  for (const auto& [id, v] : vehicles_) {
    nlohmann::json j;
    j["origin"] = v.origin_deg
                      ? nlohmann::json{{"latitude_deg", v.origin_deg->first}, {"longitude_deg", v.origin_deg->second}}
                      : nlohmann::json();
    j["dr"] = thin(v.dr, false);
    j["gnss"] = thin(v.gnss, false);
    j["k"] = thin(v.k, true);
    all[id] = std::move(j);
  }
  return all;
}

}  // namespace odonav::ground
