#include "odonav/offline/run_diagnosis.hpp"

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

// The identification's rejections: which gate took most GNSS epochs, in words with its threshold,
// the observed value and the flag that sets it.
std::string dominant_gate(double gnss_period_s, const OfflineParams& p, const SampleBuilderCounters& c) {
  const SampleBuilderParams& b = p.identification.builder;
  std::vector<std::pair<uint64_t, std::string>> gates = {
      {c.gap, "as gaps > " + num(effective_max_interval_s(b, gnss_period_s)) + " s (--max-interval-s" +
                  (b.max_interval_s > 0.0 ? "" : ", derived from the GNSS period") + "); the GNSS period is " +
                  num(gnss_period_s) + " s"},
      {c.min_speed, "below the minimum speed " + num(b.min_speed_mps) + " m/s (--id-min-speed) or the minimum of " +
                        num(b.min_pulses) + " pulses per sample (--min-pulses)"},
      {c.yaw_rate, "in turns above " + num(rad_to_deg(b.max_yaw_rate_rad_s)) + " deg/s (--id-max-yaw-rate-deg-s)"},
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
                          " sigma + tan(" + num(rad_to_deg(b.cross_track_angle_rad)) +
                          " deg) x speed (cross-track gate)"},
      {c.low_fix_quality, "below the minimum fix quality"},
  };
  std::stable_sort(gates.begin(), gates.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
  if (gates.front().first == 0) return "";
  return num(static_cast<double>(gates.front().first), 12) + " of " + num(static_cast<double>(c.epochs), 12) +
         " GNSS epochs rejected " + gates.front().second;
}

}  // namespace

void MedianPeriod::add(double t_s) {
  if (last_s_) {
    double dt = t_s - *last_s_;
    if (rounded_) dt = std::round(dt * 1e6) / 1e6;
    ++count_by_interval_[dt];
    ++intervals_;
    if (!rounded_ && count_by_interval_.size() > kMaxDistinct) {
      std::map<double, std::size_t> rounded;
      for (const auto& [interval, n] : count_by_interval_) rounded[std::round(interval * 1e6) / 1e6] += n;
      count_by_interval_.swap(rounded);
      rounded_ = true;
    }
  }
  last_s_ = t_s;
}

double MedianPeriod::median_s() const {
  if (intervals_ == 0) return std::nan("");
  const std::size_t k = intervals_ / 2;  // the k-th smallest, from 0
  std::size_t below = 0;
  for (const auto& [interval, n] : count_by_interval_) {
    below += n;
    if (below > k) return interval;
  }
  return std::nan("");
}

double median_period_s(const std::vector<double>& t) {
  MedianPeriod m;
  for (double x : t) m.add(x);
  return m.median_s();
}

void RunDiagnosisAccumulator::Span::add(double t_s) {
  if (n++ == 0) first_s = t_s;
  last_s = t_s;
}

void RunDiagnosisAccumulator::add_odometer(double t_s) { odometer_.add(t_s); }
void RunDiagnosisAccumulator::add_gnss(double t_s) {
  gnss_.add(t_s);
  gnss_period_.add(t_s);
}
void RunDiagnosisAccumulator::add_ins(double) { has_ins_ = true; }
void RunDiagnosisAccumulator::add_identification(const ScaleFactorEstimate& main, const GnssLatencyEstimate& latency,
                                                 bool latency_decided) {
  last_main_ = main;
  last_latency_ = latency;
  last_latency_decided_ = latency_decided;
  latency_ever_decided_ = latency_ever_decided_ || latency_decided;
}
void RunDiagnosisAccumulator::add_dead_reckoning(double t_s, const Geodetic& position) {
  dead_reckoning_.add(t_s);
  const std::optional<double> pole_m = dead_reckoning::polar_heading_distance_m(position);
  if (!pole_m) return;
  if (near_pole_.n++ == 0 || *pole_m < near_pole_.closest_m) {
    if (near_pole_.n == 1) near_pole_.first_s = t_s;
    near_pole_.closest_m = *pole_m;
    near_pole_.north = position.lat_rad >= 0.0;
  }
}

RunDiagnosis diagnose_run(const Dataset& d, const OfflineParams& p, const OfflineResult& r) {
  RunDiagnosisAccumulator acc;
  for (const OdometerSample& o : d.odometer) acc.add_odometer(o.t_s);
  for (const GnssSample& g : d.gnss) acc.add_gnss(g.t_s);
  for (const InsSample& i : d.ins) acc.add_ins(i.t_s);
  for (const identification::IdentificationOutput& k : r.identification)
    acc.add_identification(k.main, k.latency, k.latency_decided);
  for (const calibration::MisalignmentOutput& m : r.misalignment) acc.add_misalignment(m);
  for (const dead_reckoning::DeadReckoningOutput& o : r.dr_online) acc.add_dead_reckoning(o.t_s, o.position);
  return acc.finish(p, r.builder_counters, r.calibration_counters, r.dr_counters, r.consistency, r.gnss_jumps);
}

void RunDiagnosisAccumulator::add_misalignment(const calibration::MisalignmentOutput& output) {
  last_misalignment_ = output;
}

RunDiagnosis RunDiagnosisAccumulator::finish(const OfflineParams& p, const SampleBuilderCounters& c,
                                             const calibration::MisalignmentCounters& m,
                                             const dead_reckoning::DeadReckonerCounters& dr_counters,
                                             const std::vector<dead_reckoning::ConsistencyState>& consistency,
                                             const dead_reckoning::GnssJumpCounters& gnss_jumps) const {
  RunDiagnosis out;
  auto warn = [&](std::string code, std::string message) {
    out.warnings.push_back({std::move(code), std::move(message)});
  };

  if (gnss_jumps.jumps > 0)
    warn("gnss_position_jumps",
         std::to_string(gnss_jumps.jumps) + " GNSS fix" + (gnss_jumps.jumps == 1 ? "" : "es") +
             " jumped away from the track (first at t = " + num(gnss_jumps.first_t_s, 10) + " s, the largest " +
             num(gnss_jumps.largest_m / 1000.0, 4) +
             " km): outliers, kept out of the anchored position by its gate; the estimators use the GNSS velocity");
  // The results contradicted independent evidence: a wrong input, named with its numbers.
  for (std::size_t i = 0; i < consistency.size(); ++i) {
    const dead_reckoning::ConsistencyState& s = consistency[i];
    if (s.times_raised == 0) continue;
    warn(std::string("inconsistent_") + to_string(static_cast<dead_reckoning::ConsistencyCheck>(i)),
         s.text + " (from t = " + num(s.raised_at_s, 10) + " s" +
             (s.raised ? ", to the end: converged withdrawn)" : ", later cleared)"));
  }

  // Dead reckoning near a pole, where the INS heading is ill-defined (dead_reckoner.hpp).
  if (near_pole_.n > 0)
    warn("near_pole", "dead reckoning " + dead_reckoning::polar_heading_text(near_pole_.closest_m, near_pole_.north) +
                          " (" + num(static_cast<double>(near_pole_.n), 12) +
                          " outputs from t = " + num(near_pole_.first_s, 10) + " s)");

  // Time overlap of the two streams every result needs.
  if (odometer_.n > 0 && gnss_.n > 0) {
    const double o0 = odometer_.first_s, o1 = odometer_.last_s;
    const double g0 = gnss_.first_s, g1 = gnss_.last_s;
    if (std::min(o1, g1) <= std::max(o0, g0))
      warn("no_time_overlap", "GNSS (t = " + num(g0, 10) + " .. " + num(g1, 10) +
                                  " s) and odometer (t = " + num(o0, 10) + " .. " + num(o1, 10) +
                                  " s) do not overlap in time: both must use one time base in seconds");
  }

  // K.
  if (c.accepted == 0) {
    out.usable = false;
    const std::string gate = dominant_gate(gnss_period_.median_s(), p, c);
    warn("no_k", "no K identified: 0 of " + num(static_cast<double>(c.epochs), 12) + " GNSS epochs accepted" +
                     (gate.empty() ? std::string() : "; " + gate) + "; dead reckoning used the nominal K " +
                     num(p.dead_reckoning.nominal_k_m_per_pulse, 6) + " m/pulse");
  } else if (last_main_) {
    const ScaleFactorEstimate& k = *last_main_;
    const double nominal = p.dead_reckoning.nominal_k_m_per_pulse;
    // Accepted samples, but not enough for the convergence rule: say what is missing.
    if (k.valid && !k.converged && std::isfinite(k.k_m_per_pulse) && k.k_m_per_pulse != 0.0) {
      const ScaleFactorEstimatorParams& e = p.identification.estimator;
      std::string missing;
      if (c.accepted < e.min_samples)
        missing = num(static_cast<double>(c.accepted), 12) + " samples accepted while moving, " +
                  num(static_cast<double>(e.min_samples), 12) + " needed";
      const double rel_percent = 100.0 * k.sigma_m_per_pulse / std::abs(k.k_m_per_pulse);
      if (!(rel_percent < 100.0 * e.converged_rel_sigma))
        missing += (missing.empty() ? "" : "; ") + std::string("sigma ") + num(rel_percent, 3) + " % of K, " +
                   num(100.0 * e.converged_rel_sigma, 3) + " % needed (--converged-rel-sigma)";
      if (last_latency_ && !last_latency_decided_)
        missing += (missing.empty() ? "" : "; ") + std::string("the GNSS latency not decided");
      warn("k_not_converged",
           "K did not converge: " + (missing.empty() ? std::string("estimator not converged") : missing) + " (" +
               num(static_cast<double>(c.accepted), 12) + " of " + num(static_cast<double>(c.epochs), 12) +
               " GNSS epochs accepted); the last K " + num(k.k_m_per_pulse, 6) + " m/pulse is provisional");
    }
    if (k.valid && std::isfinite(k.k_m_per_pulse) && nominal > 0.0) {
      const double ratio = k.k_m_per_pulse / nominal;
      if (ratio < 0.5 || ratio > 2.0)
        warn("implausible_k", "identified K " + num(k.k_m_per_pulse, 6) + " m/pulse is " + num(ratio, 3) +
                                  " x the nominal K " + num(nominal, 6) +
                                  " m/pulse (plausible: 0.5 .. 2 x): check the nominal K, the pulse counter and "
                                  "the GNSS velocity units");
    }
  }

  // GNSS latency estimated online but never decided: K was never published as converged, and its
  // sigma carries the latency's uncertainty to the end (docs/ALGORITHM.md "Honest sigma of K").
  const SampleBuilderParams& builder_params = p.identification.builder;
  if (last_latency_ && !latency_ever_decided_ && builder_params.latency_estimation_enabled &&
      !builder_params.gnss_latency_fixed_s) {
    const GnssLatencyEstimate& l = *last_latency_;
    std::string missing;
    if (l.sigma_s >= 0.0)
      missing = "its estimate " + num(1000.0 * l.estimate_s) + " +- " + num(1000.0 * l.sigma_s) + " ms (" +
                num(static_cast<double>(l.samples), 12) + " samples) neither met the apply rule nor confirmed the " +
                num(1000.0 * l.applied_s) + " ms in force (sigma at most " +
                num(1000.0 * builder_params.latency_apply_coarse_sigma_s) + " ms and within 3 sigma)";
    else
      missing = "no estimate: " + (l.reason.empty() ? std::string("no accepted sample") : l.reason);
    warn("latency_not_decided",
         "the GNSS latency was never decided: " + missing + "; K was never published as converged and its sigma " +
             "includes the latency's uncertainty (give --gnss-latency-s when the receiver's latency is known)");
  }

  // Misalignment (only with an INS: without one, degraded mode is announced when reading).
  if (has_ins_) {
    if (m.used == 0) {
      std::vector<std::pair<uint64_t, std::string>> why = {
          {m.low_speed, "below the minimum speed " + num(p.calibration.min_speed_mps) + " m/s (--cal-min-speed)"},
          {m.turning,
           "in turns above " + num(rad_to_deg(p.calibration.max_yaw_rate_rad_s)) + " deg/s (--cal-max-yaw-rate-deg-s)"},
          {m.invalid_fix, "with an invalid fix"},
          {m.reversing, "reversing"},
          {m.no_attitude, "with no INS attitude around the epoch"},
          {m.outlier, "as GNSS velocity outliers"},
      };
      std::stable_sort(why.begin(), why.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
      warn(
          "no_misalignment",
          "no misalignment calibrated: 0 of " + num(static_cast<double>(m.epochs), 12) + " GNSS epochs used" +
              (why.front().first > 0 ? "; " + num(static_cast<double>(why.front().first), 12) + " " + why.front().second
                                     : std::string()) +
              "; zero misalignment applied");
    } else if (last_misalignment_ && !last_misalignment_->converged) {
      // Used, but not enough: say what is missing, epochs or precision.
      const calibration::MisalignmentOutput& o = *last_misalignment_;
      std::string missing;
      if (o.samples_used < p.calibration.min_samples)
        missing = num(static_cast<double>(o.samples_used), 12) + " GNSS epochs used while moving (straight, above " +
                  num(p.calibration.min_speed_mps) + " m/s) of the " +
                  num(static_cast<double>(p.calibration.min_samples), 12) + " required (--cal-min-samples)";
      const double limit_deg = rad_to_deg(p.calibration.converged_sigma_rad);
      const double worst_deg = rad_to_deg(std::max(o.sigma_heading_rad, o.sigma_pitch_rad));
      if (!(worst_deg < limit_deg))
        missing += (missing.empty() ? "" : "; ") + std::string("sigma ") + num(worst_deg, 3) + " deg above the " +
                   num(limit_deg, 3) + " deg required (--cal-converged-sigma-deg)";
      warn("misalignment_not_converged",
           "the misalignment did not converge: " +
               (missing.empty() ? std::string("state ") + to_string(o.state) : missing) +
               "; the estimate is provisional (a longer drive with straight segments above " +
               num(p.calibration.min_speed_mps) + " m/s gives more epochs)");
    }
  }

  // Dead reckoning: present, and covering the odometer record.
  if (dead_reckoning_.n == 0) {
    out.usable = false;
    warn("no_dead_reckoning",
         "no dead-reckoning output: DR starts at the first valid GNSS fix inside the odometer "
         "record, and none was found");
  } else if (odometer_.n > 0) {
    const double span = odometer_.last_s - odometer_.first_s;
    const double dr_end = dead_reckoning_.last_s;
    const double missing = odometer_.last_s - dr_end;
    if (span > 0.0 && missing > 0.1 * span && missing > 1.0) {
      std::string cause;
      if (dr_counters.pulse_jumps_rejected > 0)
        cause = "; " + num(static_cast<double>(dr_counters.pulse_jumps_rejected), 12) +
                " odometer samples rejected by the pulse-jump gate (max " + num(p.dead_reckoning.max_speed_mps) +
                " m/s at the nominal K " + num(p.dead_reckoning.nominal_k_m_per_pulse, 6) +
                " m/pulse): check --nominal-k";
      out.usable = false;  // most of the drive has no position
      warn("dead_reckoning_truncated", "dead reckoning ends at t = " + num(dr_end, 10) + " s, " + num(missing, 6) +
                                           " s before the odometer record" + cause);
    }
  }
  return out;
}

}  // namespace odonav::offline
