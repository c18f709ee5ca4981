#include "odonav/gateway/gpsd_source.hpp"

#include <arpa/inet.h>
#include <gps.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <thread>

#include "odonav/config.hpp"
#include "odonav/frames.hpp"
#include "odonav/geodesy.hpp"

namespace odonav::gateway {

namespace {

constexpr const char* kGpsdForms = "gpsd:, gpsd:<port> or gpsd:<host>:<port>";

bool known(double v) { return std::isfinite(v); }

/// GGA fix quality of a gpsd STATUS_* value (mode >= 2 already checked).
int fix_quality_of(int status) {
  switch (status) {
    case STATUS_DGPS_FIX: return 2;
    case STATUS_RTK_FIX: return 4;
    case STATUS_RTK_FLT: return 5;
    case STATUS_DR: return 6;  // dead reckoning only: published, but not a reference (docs/DATASET.md)
    default: return 1;
  }
}

bool is_loopback_host(const std::string& host) {
  if (host == "localhost" || host == "::1") return true;
  in_addr a{};
  return ::inet_pton(AF_INET, host.c_str(), &a) == 1 && (ntohl(a.s_addr) >> 24) == 127;
}

double seconds_of(const timespec_t& t) {
  if (t.tv_sec == 0 && t.tv_nsec == 0) return GpsdReport::kUnknown;  // libgps: time not reported
  return static_cast<double>(t.tv_sec) + static_cast<double>(t.tv_nsec) * 1e-9;
}

}  // namespace

bool is_gpsd_source(const std::string& text) { return text.rfind("gpsd:", 0) == 0; }

GpsdSourceSpec parse_gpsd_source(const std::string& text, bool allow_non_loopback, const std::string& flag) {
  GpsdSourceSpec spec;
  auto bad = [&](const std::string& why) {
    return ConfigError(flag + " '" + text + "': " + why + " (accepted: " + kGpsdForms + ")");
  };
  if (!is_gpsd_source(text)) throw bad("not a gpsd source");
  const std::string rest = text.substr(5);
  if (!rest.empty()) {
    const std::size_t colon = rest.rfind(':');
    const std::string port = colon == std::string::npos ? rest : rest.substr(colon + 1);
    if (colon != std::string::npos) spec.host = rest.substr(0, colon);
    if (spec.host.empty()) throw bad("empty host");
    if (port.empty() || port.size() > 5 || port.find_first_not_of("0123456789") != std::string::npos ||
        std::stoul(port) == 0 || std::stoul(port) > 65535)
      throw bad("port '" + port + "' is not in 1..65535");
    spec.port = static_cast<std::uint16_t>(std::stoul(port));
  }
  // Why refuse: a position from another machine steers the calibration; reading one must be a decision.
  if (!is_loopback_host(spec.host) && !allow_non_loopback)
    throw ConfigError(flag + " '" + text + "': host " + spec.host +
                      " is not a loopback address; give --allow-non-loopback to read from it");
  return spec;
}

std::string to_string(const GpsdSourceSpec& spec) { return "gpsd:" + spec.host + ":" + std::to_string(spec.port); }

std::optional<GnssSample> gnss_sample_from(const GpsdReport& r, double utc_origin_s) {
  if (!known(r.time_utc_s)) return std::nullopt;
  constexpr double nan = GpsdReport::kUnknown;
  GnssSample s;
  s.t_s = r.time_utc_s - utc_origin_s;
  // gpsd's JSON leaves "status" out for a plain fix (libgps then reads 0, "unknown"): the mode
  // says whether there is a fix, the status only what kind.
  const bool has_fix = r.mode >= MODE_2D && known(r.lat_deg) && known(r.lon_deg);
  if (!has_fix) {
    s.fix = 0;
    s.position = Geodetic{nan, nan, nan};
    s.vel_enu_mps = Eigen::Vector3d::Constant(nan);
    return s;
  }
  s.fix = fix_quality_of(r.status);
  s.position.lat_rad = deg_to_rad(r.lat_deg);
  s.position.lon_rad = deg_to_rad(normalize_lon_deg(r.lon_deg));  // 180 as -180: positions in [-180, 180)
  s.position.height_m = nan;
  if (r.mode >= MODE_3D) {
    if (known(r.alt_hae_m))
      s.position.height_m = r.alt_hae_m;
    else if (known(r.alt_msl_m) && known(r.geoid_sep_m))
      s.position.height_m = r.alt_msl_m + r.geoid_sep_m;
  }

  std::optional<double> vel_std_mps;
  if (known(r.eps_mps)) vel_std_mps = r.eps_mps / 2.0;
  if (known(r.ecef_vx_mps) && known(r.ecef_vy_mps) && known(r.ecef_vz_mps)) {
    // ECEF -> ENU at the fix: rows are the east, north and up unit vectors in ECEF.
    const double sl = std::sin(s.position.lat_rad), cl = std::cos(s.position.lat_rad);
    const double so = std::sin(s.position.lon_rad), co = std::cos(s.position.lon_rad);
    const Eigen::Vector3d v(r.ecef_vx_mps, r.ecef_vy_mps, r.ecef_vz_mps);
    s.vel_enu_mps = Eigen::Vector3d(-so * v.x() + co * v.y(), -sl * co * v.x() - sl * so * v.y() + cl * v.z(),
                                    cl * co * v.x() + cl * so * v.y() + sl * v.z());
  } else {
    const double up = known(r.climb_mps) ? r.climb_mps : 0.0;
    if (known(r.speed_mps) && known(r.track_deg)) {
      const double track_rad = deg_to_rad(r.track_deg);
      s.vel_enu_mps = Eigen::Vector3d(r.speed_mps * std::sin(track_rad), r.speed_mps * std::cos(track_rad), up);
    } else if (known(r.speed_mps) && r.speed_mps < kCourseMissingStandingSpeedMps) {
      // Standing or creeping: the receiver dropped the course; the speed bounds what is unknown.
      s.vel_enu_mps = Eigen::Vector3d(0.0, 0.0, up);
      vel_std_mps = std::max(vel_std_mps.value_or(0.0), r.speed_mps);
    } else {
      s.vel_enu_mps = Eigen::Vector3d(nan, nan, up);
    }
  }
  if (known(r.gst_lat_std_m) && known(r.gst_lon_std_m))
    s.pos_std_m = std::hypot(r.gst_lat_std_m, r.gst_lon_std_m);
  else if (known(r.eph_m))
    s.pos_std_m = r.eph_m / 2.0;
  s.vel_std_mps = vel_std_mps;
  return s;
}

GnssTimeGate::Verdict GnssTimeGate::admit(double t_s) {
  if (last_t_s_ && t_s < *last_t_s_) return Verdict::kBackwards;
  if (last_t_s_ && t_s == *last_t_s_) return Verdict::kRepeated;
  last_t_s_ = t_s;
  return Verdict::kAccept;
}

double gpsd_reconnect_backoff_s(int consecutive_failures) {
  const int n = std::clamp(consecutive_failures, 1, 6);
  return std::min(30.0, static_cast<double>(1 << (n - 1)));
}

namespace {

/// One libgps session; closes on scope exit.
class GpsdSession {
 public:
  explicit GpsdSession(const GpsdSourceSpec& spec) : where_(to_string(spec)) {
    std::memset(&data_, 0, sizeof(data_));
    const std::string port = std::to_string(spec.port);
    if (::gps_open(spec.host.c_str(), port.c_str(), &data_) != 0)
      throw std::runtime_error(where_ + ": connect failed: " + ::gps_errstr(errno));
    open_ = true;
    if (::gps_stream(&data_, WATCH_ENABLE | WATCH_JSON, nullptr) != 0)
      throw std::runtime_error(where_ + ": watch request failed: " + ::gps_errstr(errno));
  }
  ~GpsdSession() {
    if (open_) {
      ::gps_stream(&data_, WATCH_DISABLE, nullptr);
      ::gps_close(&data_);
    }
  }
  GpsdSession(const GpsdSession&) = delete;
  GpsdSession& operator=(const GpsdSession&) = delete;

  /// Waits at most timeout_ms for a report; returns its JSON text (empty on timeout). Throws when
  /// the daemon went away.
  std::string read(int timeout_ms) {
    // gps_waiting returns false both on a timeout and on an error, and sets errno only on an error:
    // without clearing it, a stale errno of any earlier call in this thread (EDOM from a maths
    // function) read as a lost connection and dropped the session.
    errno = 0;
    if (!::gps_waiting(&data_, timeout_ms * 1000)) {
      if (errno != 0 && errno != EINTR && errno != EAGAIN && errno != ETIMEDOUT)
        throw std::runtime_error(where_ + ": connection lost: " + std::strerror(errno));
      return {};
    }
    char message[4096];
    message[0] = '\0';
    const int n = ::gps_read(&data_, message, sizeof(message) - 1);
    if (n < 0) throw std::runtime_error(where_ + ": connection lost (gpsd closed the socket or sent garbage)");
    return message;
  }
  const gps_data_t& data() const { return data_; }

 private:
  std::string where_;
  gps_data_t data_;
  bool open_ = false;
};

GpsdReport report_of(const gps_data_t& d) {
  GpsdReport r;
  const gps_fix_t& f = d.fix;
  r.time_utc_s = seconds_of(f.time);
  r.mode = f.mode;
  r.status = f.status;
  r.lat_deg = f.latitude;
  r.lon_deg = f.longitude;
  r.alt_hae_m = f.altHAE;
  r.alt_msl_m = f.altMSL;
  r.geoid_sep_m = f.geoid_sep;
  r.speed_mps = f.speed;
  r.track_deg = f.track;
  r.climb_mps = f.climb;
  r.ecef_vx_mps = f.ecef.vx;
  r.ecef_vy_mps = f.ecef.vy;
  r.ecef_vz_mps = f.ecef.vz;
  r.eph_m = f.eph;
  r.eps_mps = f.eps;
  return r;
}

/// The GST of the last epoch and the TPV waiting for it. Why hold a TPV: gpsd reports the GST of
/// an epoch after its TPV (receivers send GST last, and gpsd writes it when that sentence arrives).
/// A TPV waits for the GST of its epoch or the next TPV, at most 200 ms while the receiver sends
/// GST; once an epoch went without one, at most 20 ms (a receiver without GST costs 20 ms of
/// latency) until a GST shows up again.
class GstPairing {
 public:
  /// How long the next read may wait, ms: 100 with nothing held, else 200 or 20 (see above).
  int read_timeout_ms() const { return !pending_ ? 100 : expect_gst_ ? 200 : 20; }
  /// A GST report (UTC of its epoch, s; one-sigma latitude and longitude errors, m). True when it
  /// completes the held TPV (to be released now).
  bool on_gst(double time_s, double lat_std_m, double lon_std_m) {
    expect_gst_ = true;
    gst_time_s_ = time_s;
    gst_lat_m_ = lat_std_m;
    gst_lon_m_ = lon_std_m;
    return pending_ && matches(pending_->time_utc_s);
  }
  /// A TPV report: held (nullopt) until its GST or the next report, or, when the GST of its
  /// epoch is already here, returned at once with the GST's sigmas.
  std::optional<GpsdReport> on_tpv(const GpsdReport& r) {
    if (!matches(r.time_utc_s)) {
      pending_ = r;
      return std::nullopt;
    }
    return with_gst(r);
  }
  /// Releases the held TPV, if any (with the GST's sigmas when they match); an epoch released
  /// without its GST makes the next TPV wait only 20 ms.
  std::optional<GpsdReport> release() {
    std::optional<GpsdReport> r;
    if (pending_) {
      if (!matches(pending_->time_utc_s)) expect_gst_ = false;
      r = with_gst(*pending_);
    }
    pending_.reset();
    return r;
  }

 private:
  // A GST before the receiver's date is known (GGA and GST come before the first RMC) carries the
  // time of day only: it matches the TPV of that time of day.
  bool matches(double tpv_time_s) const {
    return known(gst_time_s_) && known(tpv_time_s) &&
           (gst_time_s_ == tpv_time_s || (gst_time_s_ < 86400.0 && gst_time_s_ == std::fmod(tpv_time_s, 86400.0)));
  }
  GpsdReport with_gst(GpsdReport r) const {
    if (matches(r.time_utc_s)) {
      r.gst_lat_std_m = gst_lat_m_;
      r.gst_lon_std_m = gst_lon_m_;
    }
    return r;
  }

  double gst_time_s_ = GpsdReport::kUnknown, gst_lat_m_ = GpsdReport::kUnknown, gst_lon_m_ = GpsdReport::kUnknown;
  bool expect_gst_ = true;
  std::optional<GpsdReport> pending_;
};

/// The libgps loop of run_gpsd_input, step by step: connection with back-off, GST pairing, the
/// time gate and the counters.
class GpsdInput {
 public:
  GpsdInput(const GpsdSourceSpec& spec, double utc_origin_s, const std::function<void(const GnssSample&)>& publish_gnss,
            GpsdCounters& counters, std::mutex& counters_mutex)
      : spec_(spec),
        utc_origin_s_(utc_origin_s),
        publish_gnss_(publish_gnss),
        counters_(counters),
        counters_mutex_(counters_mutex) {}

  void run(const std::function<bool()>& stop, const std::function<void()>& periodic) {
    while (!stop()) {
      periodic();
      if (!session_) {
        connect();
        continue;
      }
      std::string json;
      try {
        json = session_->read(pairing_.read_timeout_ms());
      } catch (const std::exception& e) {
        release();
        fail(e.what());
        continue;
      }
      if (json.empty())
        release();
      else
        on_report(json, session_->data());
    }
    release();
  }

 private:
  using Clock = std::chrono::steady_clock;

  // Connects once the back-off after the last failure is over (sleeps 50 ms before that).
  void connect() {
    if (Clock::now() < retry_at_) {
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
      return;
    }
    try {
      session_.emplace(spec_);
    } catch (const std::exception& e) {
      fail(e.what());
      return;
    }
    consecutive_failures_ = 0;
    spdlog::info("connected to {}", to_string(spec_));
    const std::lock_guard<std::mutex> lock(counters_mutex_);
    counters_.connected = true;
  }

  // A failed connect or a lost connection: counted, logged, retried after the back-off.
  void fail(const std::string& why) {
    session_.reset();
    ++consecutive_failures_;
    const double backoff_s = gpsd_reconnect_backoff_s(consecutive_failures_);
    retry_at_ = Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(backoff_s));
    spdlog::warn("{}; retrying in {} s", why, backoff_s);
    const std::lock_guard<std::mutex> lock(counters_mutex_);
    ++counters_.connection_failures;
    counters_.connected = false;
    counters_.last_failure = why;
  }

  // One JSON report libgps decoded into `d`: GST and TPV are used, every other class ignored.
  void on_report(const std::string& json, const gps_data_t& d) {
    if (json.find("\"class\":\"GST\"") != std::string::npos && (d.set & GST_SET)) {
      const double gst_time_s =
          static_cast<double>(d.gst.utctime.tv_sec) + static_cast<double>(d.gst.utctime.tv_nsec) * 1e-9;
      if (pairing_.on_gst(gst_time_s, d.gst.lat_err_deviation, d.gst.lon_err_deviation)) release();
      return;
    }
    if (json.find("\"class\":\"TPV\"") == std::string::npos) return;
    release();
    if (const auto r = pairing_.on_tpv(report_of(d))) emit(*r);
  }

  void release() {
    if (const auto r = pairing_.release()) emit(*r);
  }

  // Converts, gates, counts and publishes one TPV.
  void emit(const GpsdReport& r) {
    const std::optional<GnssSample> s = gnss_sample_from(r, utc_origin_s_);
    GnssTimeGate::Verdict verdict = GnssTimeGate::Verdict::kAccept;
    if (s) verdict = gate_.admit(s->t_s);
    {
      const std::lock_guard<std::mutex> lock(counters_mutex_);
      ++counters_.reports;
      if (!s) {
        ++counters_.no_time;
        return;
      }
      if (verdict == GnssTimeGate::Verdict::kBackwards) {
        if (++counters_.time_backwards <= 20)
          spdlog::warn("{}: fix at UTC {:.3f} s is earlier than the last published one: dropped", to_string(spec_),
                       r.time_utc_s);
        return;
      }
      if (verdict == GnssTimeGate::Verdict::kRepeated) {
        ++counters_.repeated;
        return;
      }
      if (s->fix == 0) ++counters_.no_fix;
    }
    publish_gnss_(*s);
  }

  const GpsdSourceSpec& spec_;
  const double utc_origin_s_;
  const std::function<void(const GnssSample&)>& publish_gnss_;
  GpsdCounters& counters_;
  std::mutex& counters_mutex_;
  GnssTimeGate gate_;
  GstPairing pairing_;
  std::optional<GpsdSession> session_;
  int consecutive_failures_ = 0;
  Clock::time_point retry_at_{};
};

}  // namespace

void run_gpsd_input(const GpsdSourceSpec& spec, double utc_origin_s,
                    const std::function<void(const GnssSample&)>& publish_gnss, const std::function<bool()>& stop,
                    const std::function<void()>& periodic, GpsdCounters& counters, std::mutex& counters_mutex) {
  GpsdInput(spec, utc_origin_s, publish_gnss, counters, counters_mutex).run(stop, periodic);
}

}  // namespace odonav::gateway
