#include "run_diagnosis.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <utility>

namespace odonav::offline {

namespace {

std::string num(double v, int precision = 4) {
  std::ostringstream s;
  s.precision(precision);
  s << v;
  return s.str();
}

template <class Samples>
std::vector<double> times_of(const Samples& samples) {
  std::vector<double> t;
  t.reserve(samples.size());
  for (const auto& s : samples) t.push_back(s.t_s);
  return t;
}

// The identification's rejections: which gate took most GNSS epochs, in words with its threshold,
// the observed value and the flag that sets it.
std::string dominant_gate(const Dataset& d, const OfflineParams& p, const SampleBuilderCounters& c) {
  const SampleBuilderParams& b = p.identification.builder;
  const double gnss_period_s = median_period_s(times_of(d.gnss));
  std::vector<std::pair<uint64_t, std::string>> gates = {
      {c.gap, "as gaps > " + num(effective_max_interval_s(b, gnss_period_s)) +
                  " s (--max-interval-s" + (b.max_interval_s > 0.0 ? "" : ", derived from the GNSS period") +
                  "); the GNSS period is " + num(gnss_period_s) + " s"},
      {c.min_speed, "below the minimum speed " + num(b.min_speed_mps) + " m/s (--min-speed) or the minimum of " +
                        num(b.min_pulses) + " pulses per sample (--min-pulses)"},
      {c.yaw_rate, "in turns above " + num(rad_to_deg(b.max_yaw_rate_rad_s)) + " deg/s (--max-yaw-rate-deg-s)"},
      {c.invalid_fix, "with an invalid fix (fix 0, 6, 7 or 8)"},
      {c.speed_jump, "as speed jumps above " + num(b.max_acceleration_mps2) + " m/s^2 x dt + " +
                         num(b.speed_jump_margin_mps) + " m/s"},
      {c.no_odometer, "with no odometer sample around the epoch (no time overlap?)"},
      {c.no_attitude, "with no INS attitude around the epoch"},
      {c.reversing, b.reversing_samples ? "in which the odometer's direction changes" : "while reversing"},
      {c.negative_speed, "with a negative forward speed (GNSS velocity negated or INS heading off by 180 deg?)"},
      {c.no_pulses, "with no odometer pulses over the interval (constant counter?)"},
      {c.innovation, "by the innovation gate"},
      {c.cross_track, "with GNSS velocity across the odometer axis above " + num(b.cross_track_n_sigma) +
                          " sigma + tan(" + num(rad_to_deg(b.cross_track_angle_rad)) + " deg) x speed (cross-track gate)"},
      {c.low_fix_quality, "below the minimum fix quality"},
  };
  std::stable_sort(gates.begin(), gates.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
  if (gates.front().first == 0) return "";
  return num(static_cast<double>(gates.front().first), 12) + " of " + num(static_cast<double>(c.epochs), 12) +
         " GNSS epochs rejected " + gates.front().second;
}

}  // namespace

double median_period_s(const std::vector<double>& t) {
  if (t.size() < 2) return std::nan("");
  std::vector<double> dt;
  dt.reserve(t.size() - 1);
  for (std::size_t i = 1; i < t.size(); ++i) dt.push_back(t[i] - t[i - 1]);
  std::nth_element(dt.begin(), dt.begin() + static_cast<std::ptrdiff_t>(dt.size() / 2), dt.end());
  return dt[dt.size() / 2];
}

RunDiagnosis diagnose_run(const Dataset& d, const OfflineParams& p, const OfflineResult& r) {
  RunDiagnosis out;
  auto warn = [&](std::string code, std::string message) { out.warnings.push_back({std::move(code), std::move(message)}); };

  // Time overlap of the two streams every result needs.
  if (!d.odometer.empty() && !d.gnss.empty()) {
    const double o0 = d.odometer.front().t_s, o1 = d.odometer.back().t_s;
    const double g0 = d.gnss.front().t_s, g1 = d.gnss.back().t_s;
    if (std::min(o1, g1) <= std::max(o0, g0))
      warn("no_time_overlap", "GNSS (t = " + num(g0, 10) + " .. " + num(g1, 10) + " s) and odometer (t = " +
                                  num(o0, 10) + " .. " + num(o1, 10) +
                                  " s) do not overlap in time: both must use one time base in seconds");
  }

  // K.
  const SampleBuilderCounters& c = r.builder_counters;
  if (c.accepted == 0) {
    out.usable = false;
    const std::string gate = dominant_gate(d, p, c);
    warn("no_k", "no K identified: 0 of " + num(static_cast<double>(c.epochs), 12) + " GNSS epochs accepted" +
                     (gate.empty() ? std::string() : "; " + gate) + "; dead reckoning used the nominal K " +
                     num(p.dead_reckoning.nominal_k_m_per_pulse, 6) + " m/pulse");
  } else if (!r.identification.empty()) {
    const ScaleFactorEstimate& k = r.identification.back().main;
    const double nominal = p.dead_reckoning.nominal_k_m_per_pulse;
    if (k.valid && std::isfinite(k.k_m_per_pulse) && nominal > 0.0) {
      const double ratio = k.k_m_per_pulse / nominal;
      if (ratio < 0.5 || ratio > 2.0)
        warn("implausible_k", "identified K " + num(k.k_m_per_pulse, 6) + " m/pulse is " + num(ratio, 3) +
                                  " x the nominal K " + num(nominal, 6) +
                                  " m/pulse (plausible: 0.5 .. 2 x): check the nominal K, the pulse counter and "
                                  "the GNSS velocity units");
    }
  }

  // Misalignment (only with an INS: without one, degraded mode is announced when reading).
  if (d.has_ins()) {
    const MisalignmentCounters& m = r.calibration_counters;
    if (m.used == 0) {
      std::vector<std::pair<uint64_t, std::string>> why = {
          {m.low_speed, "below the minimum speed " + num(p.calibration.min_speed_mps) + " m/s (--cal-min-speed)"},
          {m.turning, "in turns above " + num(rad_to_deg(p.calibration.max_yaw_rate_rad_s)) +
                          " deg/s (--cal-max-yaw-rate-deg-s)"},
          {m.invalid_fix, "with an invalid fix"},
          {m.reversing, "reversing"},
          {m.no_attitude, "with no INS attitude around the epoch"},
          {m.outlier, "as GNSS velocity outliers"},
      };
      std::stable_sort(why.begin(), why.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
      warn("no_misalignment", "no misalignment calibrated: 0 of " + num(static_cast<double>(m.epochs), 12) +
                                  " GNSS epochs used" +
                                  (why.front().first > 0 ? "; " + num(static_cast<double>(why.front().first), 12) +
                                                               " " + why.front().second
                                                         : std::string()) +
                                  "; zero misalignment applied");
    }
  }

  // Dead reckoning: present, and covering the odometer record.
  if (r.dr_online.empty()) {
    out.usable = false;
    warn("no_dead_reckoning", "no dead-reckoning output: DR starts at the first valid GNSS fix inside the odometer "
                              "record, and none was found");
  } else if (!d.odometer.empty()) {
    const double span = d.odometer.back().t_s - d.odometer.front().t_s;
    const double dr_end = r.dr_online.back().t_s;
    const double missing = d.odometer.back().t_s - dr_end;
    if (span > 0.0 && missing > 0.1 * span && missing > 1.0) {
      std::string cause;
      if (r.dr_counters.pulse_jumps_rejected > 0)
        cause = "; " + num(static_cast<double>(r.dr_counters.pulse_jumps_rejected), 12) +
                " odometer samples rejected by the pulse-jump gate (max " +
                num(p.dead_reckoning.max_speed_mps) + " m/s at the nominal K " +
                num(p.dead_reckoning.nominal_k_m_per_pulse, 6) + " m/pulse): check --nominal-k";
      out.usable = false;  // most of the drive has no position
      warn("dead_reckoning_truncated", "dead reckoning ends at t = " + num(dr_end, 10) + " s, " + num(missing, 6) +
                                           " s before the odometer record" + cause);
    }
  }
  return out;
}

}  // namespace odonav::offline
