#pragma once
// What the fleet page draws besides the table: each vehicle's track in local metres (east, north
// of its dead-reckoning origin; the DR solution and the valid GNSS fixes) and K against time over
// the last minutes. Fed with the views of fleet_state.hpp from any thread; no DDS.
//
// Time: K history is kept by message stamp (event time): the points whose stamp is within
// k_window_s of the newest. Tracks keep at most max_track_points per vehicle and series: past
// that, every second point is dropped (the whole drive stays, coarser).
#include <cstddef>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "odonav/ground/fleet_state.hpp"

namespace odonav {
class LocalEnuFrame;
}

namespace odonav::ground {

struct FleetHistoryConfig {
  double k_window_s = 600.0;            ///< K kept for this long by stamp (s, > 0)
  std::size_t max_track_points = 4000;  ///< per vehicle and series (>= 16)
  double track_min_step_m = 0.5;        ///< a track point is kept when it moved this far from the last (m)
};

class FleetHistory {
 public:
  explicit FleetHistory(FleetHistoryConfig config = FleetHistoryConfig());
  ~FleetHistory();

  void on_dead_reckoning(const DeadReckoningView& dr);
  /// Valid fixes only, once the vehicle's DR origin is known (they are drawn in its frame).
  void on_gnss(const GnssView& gnss);
  /// Estimates with K > 0 only (0: the identification has none yet).
  void on_scale_factor(const ScaleFactorView& k);

  /// {"<vehicle>": {"origin": {"latitude_deg", "longitude_deg"} or null, "dr": [[east_m, north_m],
  /// ...], "gnss": [[east_m, north_m], ...], "k": [[stamp_s, k, sigma or null], ...]}}, each series
  /// thinned evenly to at most max_points (the last point always kept).
  nlohmann::json json(std::size_t max_points) const;

 private:
  struct Point {
    double a, b, c;
  };
  struct Vehicle {
    std::optional<std::pair<double, double>> origin_deg;
    std::shared_ptr<LocalEnuFrame> frame;
    std::vector<Point> dr, gnss, k;
  };
  void add_track_point(std::vector<Point>& series, double east_m, double north_m);

  FleetHistoryConfig config_;
  mutable std::mutex mutex_;
  std::map<std::string, Vehicle> vehicles_;
};

}  // namespace odonav::ground
