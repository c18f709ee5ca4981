#include "odonav/offline/summary.hpp"

#include <algorithm>
#include <deque>
#include <limits>
#include <cmath>
#include <iomanip>
#include <iterator>
#include <ostream>
#include <sstream>

#include "odonav/frames.hpp"
#include "odonav/geodesy.hpp"

namespace odonav::offline {
namespace {

using nlohmann::json;

json number_or_null(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }

// meta.json's "simulation" object, with the keys the evaluation reads checked: a malformed one is a
// DatasetError naming meta.json and the key, not a JSON library message.
nlohmann::json simulation_meta(const DatasetMeta& m) {
  if (m.raw_json.empty()) return json::object();
  const json meta = json::parse(m.raw_json, nullptr, /*allow_exceptions=*/false);
  if (meta.is_discarded() || !meta.is_object() || !meta.contains("simulation")) return json::object();
  const json& sim = meta["simulation"];
  const auto bad = [](const std::string& key, const std::string& expected) {
    throw DatasetError("meta.json: key 'simulation." + key + "' must be " + expected);
  };
  if (!sim.is_object()) bad("", "an object");
  if (sim.contains("k_true_initial_m_per_pulse") && !sim["k_true_initial_m_per_pulse"].is_number())
    bad("k_true_initial_m_per_pulse", "a number (m/pulse)");
  if (sim.contains("k_steps")) {
    if (!sim["k_steps"].is_array()) bad("k_steps", "a list of {t_s, k_before, k_after}");
    for (const json& step : sim["k_steps"])
      if (!step.is_object() || !step.contains("t_s") || !step["t_s"].is_number() || !step.contains("k_before") ||
          !step["k_before"].is_number() || !step.contains("k_after") || !step["k_after"].is_number())
        bad("k_steps", "a list of {t_s, k_before, k_after} with numbers");
  }
  if (sim.contains("ins_heading_bias_deg") && !sim["ins_heading_bias_deg"].is_number())
    bad("ins_heading_bias_deg", "a number (deg)");
  if (sim.contains("gnss_outages")) {
    if (!sim["gnss_outages"].is_array()) bad("gnss_outages", "a list of [start_s, end_s]");
    for (const json& o : sim["gnss_outages"])
      if (!o.is_array() || o.size() != 2 || !o[0].is_number() || !o[1].is_number())
        bad("gnss_outages", "a list of [start_s, end_s] with numbers");
  }
  return sim;
}

// The DR reference: truth.csv's positions, or the valid GNSS fixes without truth.
SourceFactory<TimedPosition> truth_positions(const SourceFactory<TruthSample>& truth) {
  return [truth]() -> Source<TimedPosition> {
    return [src = truth()]() -> std::optional<TimedPosition> {
      const std::optional<TruthSample> t = src();
      if (!t) return std::nullopt;
      return TimedPosition{t->t_s, t->position};
    };
  };
}
SourceFactory<TimedPosition> valid_fixes(const SourceFactory<GnssSample>& gnss) {
  return [gnss]() -> Source<TimedPosition> {
    return [src = gnss ? gnss() : Source<GnssSample>()]() -> std::optional<TimedPosition> {
      if (!src) return std::nullopt;
      for (std::optional<GnssSample> g = src(); g; g = src())
        if (g->valid()) return TimedPosition{g->t_s, g->position};
      return std::nullopt;
    };
  };
}

// A source that is empty when the factory is.
template <class T>
Source<T> open(const SourceFactory<T>& factory) {
  if (factory) return factory();
  return [] { return std::optional<T>(); };
}

// The outages: meta.json's simulation.gnss_outages, else spans of >= 5 s with no valid fix.
OutageList outages_of(const json& sim, const SourceFactory<GnssSample>& gnss) {
  if (sim.contains("gnss_outages")) {
    std::vector<Outage> out;
    for (const json& o : sim["gnss_outages"]) out.push_back({o[0].get<double>(), o[1].get<double>()});
    return OutageList(out);
  }
  return OutageList(open(gnss));
}

// Two samples around a time on a cursor over a source: `prev` the last before t_s, `next` the
// first at or after it. Queried in time order; a query before the last one reopens the source.
template <class T>
class Bracket {
 public:
  explicit Bracket(SourceFactory<T> factory) : factory_(std::move(factory)) {}
  void seek(double t_s) {
    if (!started_ || t_s < last_query_s_) {
      src_ = open(factory_);
      prev_.reset();
      next_ = src_();
      started_ = true;
    }
    last_query_s_ = t_s;
    while (next_ && next_->t_s < t_s) {
      prev_ = std::move(next_);
      next_ = src_();
    }
  }
  const std::optional<T>& prev() const { return prev_; }
  const std::optional<T>& next() const { return next_; }

 private:
  SourceFactory<T> factory_;
  Source<T> src_;
  std::optional<T> prev_, next_;
  bool started_ = false;
  double last_query_s_ = 0.0;
};

double rms_of(double sum_sq, std::size_t n) {
  return n > 0 ? std::sqrt(sum_sq / static_cast<double>(n)) : std::nan("");
}

// The anchored navigation position against GNSS while it is valid (the reference point from each
// valid fix: antenna minus the lever arm turned by the INS attitude), beside the pure DR; and against
// truth when there is one: while GNSS is valid (with the fixes' own error) and across each outage.
// The navigation and DR rows are kept from the last one before the earliest time still to be
// evaluated (each navigation row, each valid fix, each outage's ends) until both streams pass it.
class NavigationEvaluator {
 public:
  NavigationEvaluator(const SummaryInputs& in, bool truth_positions, OutageList outages)
      : lever_(in.meta.gnss_lever_arm_m),
        truth_positions_(truth_positions),
        gnss_(open(in.gnss)),
        ins_(in.ins),
        truth_rows_(in.truth),
        truth_fixes_(in.truth),
        truth_outages_(in.truth),
        outages_(std::move(outages)) {}

  void add_dead_reckoning(const results::DeadReckoningRow& r) {
    dr_.push_back({r.t_s, Geodetic{r.lat_rad, r.lon_rad, r.height_m}});
    process(false);
  }
  void add(const results::NavigationPositionRow& r) {
    if (!frame_) frame_.emplace(Geodetic{r.lat_rad, r.lon_rad, r.height_m});
    const bool anchored = r.status == "anchored";
    if (anchored) ++anchored_;
    if (r.status == "dead_reckoning") ++bridging_;
    nav_.push_back({r.t_s, Geodetic{r.lat_rad, r.lon_rad, r.height_m}, anchored, r.distance_since_fix_m, nav_count_++});
    process(false);
  }
  std::size_t nav_buffered() const { return nav_.size(); }
  std::size_t dr_buffered() const { return dr_.size(); }
  std::size_t outages() const { return outages_.outages().size(); }

  json finish() {
    process(true);
    if (nav_count_ == 0) return nullptr;
    json j;
    j["vs_gnss"] = {{"epochs", n_},
                    {"horizontal_rms_m", number_or_null(rms_of(nav_sq_, n_))},
                    {"pure_dr_horizontal_rms_m", number_or_null(rms_of(dr_sq_, n_dr_))}};
    j["rows_anchored"] = anchored_;
    j["rows_dead_reckoning"] = bridging_;
    if (truth_positions_) {
      json o = json::array();
      for (const OutageState& st : outage_states_)
        if (st.entry) o.push_back(*st.entry);
      j["vs_truth"] = {{"rows", na_},
                       {"horizontal_rms_m", number_or_null(rms_of(a_sq_, na_))},
                       {"pure_dr_horizontal_rms_m", number_or_null(rms_of(b_sq_, na_))},
                       {"gnss_horizontal_rms_m", number_or_null(rms_of(g_sq_, ng_))},
                       {"outages", o}};
    }
    return j;
  }

 private:
  struct NavPoint {
    double t_s;
    Geodetic position;
    bool anchored;
    double distance_since_fix_m;
    std::size_t index;
  };
  struct DrPoint {
    double t_s;
    Geodetic position;
  };
  struct OutageState {
    bool start_known = false, end_known = false, done = false;
    std::optional<NavPoint> start, end;  // the last navigation row before the start, before the end
    std::optional<json> entry;
  };

  // A track's ENU position at t_s, interpolated between the rows bracketing it (at most 1 s apart).
  template <class Row>
  std::optional<Eigen::Vector3d> track_at(const std::deque<Row>& rows, double t_s) const {
    const auto it = std::lower_bound(rows.begin(), rows.end(), t_s, [](const Row& r, double t) { return r.t_s < t; });
    if (it == rows.end()) return std::nullopt;
    const Eigen::Vector3d b = frame_->to_enu(it->position);
    if (it->t_s == t_s) return b;
    if (it == rows.begin() || it->t_s - std::prev(it)->t_s > 1.0) return std::nullopt;
    const auto& p = *std::prev(it);
    const Eigen::Vector3d a = frame_->to_enu(p.position);
    return Eigen::Vector3d(a + (t_s - p.t_s) / (it->t_s - p.t_s) * (b - a));
  }

  // Whether the last navigation row at or before t_s is anchored.
  bool anchored_at(double t_s) const {
    const auto it =
        std::upper_bound(nav_.begin(), nav_.end(), t_s, [](double t, const NavPoint& r) { return t < r.t_s; });
    return it != nav_.begin() && std::prev(it)->anchored;
  }

  // The last navigation row before t_s.
  std::optional<NavPoint> row_before(double t_s) const {
    const auto it =
        std::lower_bound(nav_.begin(), nav_.end(), t_s, [](const NavPoint& r, double x) { return r.t_s < x; });
    if (it == nav_.begin()) return std::nullopt;
    return *std::prev(it);
  }

  // The truth (INS reference point) at t_s in ENU, and the attitude of the nearer sample.
  std::optional<std::pair<Eigen::Vector3d, Attitude>> truth_at(Bracket<TruthSample>& cursor, double t_s) const {
    cursor.seek(t_s);
    const std::optional<TruthSample>& next = cursor.next();
    const std::optional<TruthSample>& prev = cursor.prev();
    if (!next || (!prev && next->t_s != t_s)) return std::nullopt;
    const Eigen::Vector3d b = frame_->to_enu(next->position);
    if (next->t_s == t_s) return std::make_pair(b, next->attitude);
    const TruthSample& p = *prev;
    const double f = (t_s - p.t_s) / (next->t_s - p.t_s);
    const Eigen::Vector3d a = frame_->to_enu(p.position);
    return std::make_pair(Eigen::Vector3d(a + f * (b - a)), f < 0.5 ? p.attitude : next->attitude);
  }

  // The INS attitude nearest to t_s (for the lever arm of a GNSS fix), if within 0.1 s.
  std::optional<Attitude> ins_attitude_at(double t_s) {
    ins_.seek(t_s);
    const std::optional<InsSample>* it = &ins_.next();
    if (ins_.prev() && (!ins_.next() || t_s - ins_.prev()->t_s < ins_.next()->t_s - t_s)) it = &ins_.prev();
    if (!*it || std::abs((*it)->t_s - t_s) > 0.1) return std::nullopt;
    return (*it)->attitude;
  }

  void evaluate_row(const NavPoint& r) {
    if (!truth_positions_ || !r.anchored) return;
    const auto tr = truth_at(truth_rows_, r.t_s);
    const auto q = track_at(dr_, r.t_s);
    if (!tr || !q) return;
    a_sq_ += (frame_->to_enu(r.position) - tr->first).head<2>().squaredNorm();
    b_sq_ += (*q - tr->first).head<2>().squaredNorm();
    ++na_;
  }

  void evaluate_fix(const GnssSample& g) {
    if (!anchored_at(g.t_s)) return;
    [&] {
      Eigen::Vector3d ref = frame_->to_enu(g.position);
      if (lever_) {
        const std::optional<Attitude> att = ins_attitude_at(g.t_s);
        if (!att) return;
        ref -= body_to_enu(*att) * *lever_;
      }
      const auto p = track_at(nav_, g.t_s);
      if (!p) return;
      nav_sq_ += ((*p - ref).head<2>()).squaredNorm();
      ++n_;
      if (const auto q = track_at(dr_, g.t_s)) {
        dr_sq_ += ((*q - ref).head<2>()).squaredNorm();
        ++n_dr_;
      }
    }();
    if (!truth_positions_) return;
    const auto tr = truth_at(truth_fixes_, g.t_s);
    if (!tr) return;
    Eigen::Vector3d antenna = tr->first;
    if (lever_ && std::isfinite(tr->second.heading_rad)) antenna += body_to_enu(tr->second) * *lever_;
    g_sq_ += (frame_->to_enu(g.position) - antenna).head<2>().squaredNorm();
    ++ng_;
  }

  // The outage's error at its start and end: at the last row before the outage, and the last
  // before GNSS returns.
  void evaluate_outage(const Outage& out, OutageState& st) {
    st.done = true;
    const auto& a = st.start;
    const auto& b = st.end;
    if (!a || !b || a->index == b->index) return;
    const auto ta = truth_at(truth_outages_, a->t_s), tb = truth_at(truth_outages_, b->t_s);
    if (!ta || !tb) return;
    const double ea = (frame_->to_enu(a->position) - ta->first).head<2>().norm();
    const double eb = (frame_->to_enu(b->position) - tb->first).head<2>().norm();
    st.entry = json{{"start_s", out.start_s},
                    {"end_s", out.end_s},
                    {"error_at_start_m", ea},
                    {"error_at_end_m", eb},
                    {"distance_m", number_or_null(b->distance_since_fix_m - a->distance_since_fix_m)}};
  }

  // Evaluates what both streams have passed (everything when final), then drops the rows no later
  // evaluation needs.
  void process(bool final) {
    double frontier = std::numeric_limits<double>::infinity();
    if (!final) {
      if (nav_.empty() || dr_.empty()) return;  // nothing to match yet
      frontier = std::min(nav_.back().t_s, dr_.back().t_s);
    }
    // Each navigation row.
    while (next_row_ < nav_count_) {
      const NavPoint& r = nav_[next_row_ - nav_.front().index];
      if (!(r.t_s < frontier)) break;
      evaluate_row(r);
      ++next_row_;
    }
    // Each valid GNSS fix.
    while (true) {
      if (!fix_) {
        for (std::optional<GnssSample> g = gnss_(); g; g = gnss_())
          if (g->valid()) {
            fix_ = g;
            break;
          }
        if (!fix_) break;
      }
      if (!(fix_->t_s < frontier)) break;
      evaluate_fix(*fix_);
      fix_.reset();
    }
    // Each outage, once the navigation rows have passed its ends.
    double keep_nav_from = frontier, keep_dr_from = frontier;
    if (truth_positions_) {
      if (final)
        outages_.discover_all();
      else
        outages_.discover_through(frontier);
      outage_states_.resize(outages_.outages().size());
      for (std::size_t i = 0; i < outage_states_.size(); ++i) {
        OutageState& st = outage_states_[i];
        const Outage& o = outages_.outages()[i];
        if (st.done) continue;
        if (!st.start_known && (final || (!nav_.empty() && nav_.back().t_s >= o.start_s))) {
          st.start = row_before(o.start_s);
          st.start_known = true;
        }
        if (!st.end_known && (final || (!nav_.empty() && nav_.back().t_s >= o.end_s))) {
          st.end = row_before(o.end_s);
          st.end_known = true;
        }
        if (st.start_known && st.end_known)
          evaluate_outage(o, st);
        else
          keep_nav_from = std::min(keep_nav_from, st.start_known ? o.end_s : std::min(o.start_s, o.end_s));
      }
    }
    if (final) return;
    // Rows still needed: from the last one before the earliest time still to be evaluated.
    if (next_row_ < nav_count_) {
      const double t = nav_[next_row_ - nav_.front().index].t_s;
      keep_nav_from = std::min(keep_nav_from, t);
      keep_dr_from = std::min(keep_dr_from, t);
    }
    if (fix_) {
      keep_nav_from = std::min(keep_nav_from, fix_->t_s);
      keep_dr_from = std::min(keep_dr_from, fix_->t_s);
    }
    while (nav_.size() >= 2 && nav_[1].t_s < keep_nav_from && nav_[1].index <= next_row_) nav_.pop_front();
    while (dr_.size() >= 2 && dr_[1].t_s < keep_dr_from) dr_.pop_front();
  }

  std::optional<Eigen::Vector3d> lever_;
  bool truth_positions_;
  Source<GnssSample> gnss_;
  std::optional<GnssSample> fix_;  ///< the next valid fix to evaluate
  Bracket<InsSample> ins_;
  Bracket<TruthSample> truth_rows_, truth_fixes_, truth_outages_;
  OutageList outages_;
  std::vector<OutageState> outage_states_;
  std::optional<LocalEnuFrame> frame_;
  std::deque<NavPoint> nav_;
  std::deque<DrPoint> dr_;
  std::size_t nav_count_ = 0, next_row_ = 0;
  std::size_t anchored_ = 0, bridging_ = 0;
  double nav_sq_ = 0.0, dr_sq_ = 0.0, a_sq_ = 0.0, b_sq_ = 0.0, g_sq_ = 0.0;
  std::size_t n_ = 0, n_dr_ = 0, na_ = 0, ng_ = 0;
};

// One DR run (online or coarse K) against the reference.
struct DrStream {
  explicit DrStream(DeadReckoningEvaluator e) : evaluator(std::move(e)) {}
  DeadReckoningEvaluator evaluator;
  bool any = false;
  double final_k_m_per_pulse = 0.0;
  std::string final_k_source;

  void add(const results::DeadReckoningRow& r) {
    evaluator.add(r.t_s, Geodetic{r.lat_rad, r.lon_rad, r.height_m}, r.distance_m);
    any = true;
    final_k_m_per_pulse = r.k_m_per_pulse;
    final_k_source = r.k_source;
  }

  json finish() {
    DrEvaluation e = evaluator.finish();
    if (!any) return nullptr;
    const std::vector<Outage>& outages = evaluator.outages();
    json j;
    j["epochs_compared"] = e.epochs;
    j["distance_m"] = e.distance_m;
    j["final_error_m"] = number_or_null(e.final_error_m);
    j["final_error_percent"] = number_or_null(e.final_error_percent);
    j["max_error_m"] = number_or_null(e.max_error_m);
    j["max_error_percent"] = number_or_null(e.max_error_percent);
    j["final_k_m_per_pulse"] = final_k_m_per_pulse;
    j["final_k_source"] = final_k_source;
    json o = json::array();
    for (std::size_t i = 0; i < outages.size(); ++i)
      o.push_back({{"start_s", outages[i].start_s},
                   {"end_s", outages[i].end_s},
                   {"error_m", number_or_null(e.outage_error_m[i])},
                   {"error_percent_of_outage_distance", number_or_null(e.outage_error_percent[i])}});
    j["outages"] = o;
    return j;
  }
};

// One estimator's column of scale_factor.csv.
struct EstimatorStream {
  EstimatorStream(std::string n, ScaleFactorEvaluator e) : name(std::move(n)), evaluator(std::move(e)) {}
  std::string name;
  ScaleFactorEvaluator evaluator;
  bool any = false;
  double final_k_m_per_pulse = 0.0;
};

}  // namespace

struct SummaryAccumulator::Impl {
  SummaryInputs in;
  json sim;
  bool has_ins = false, has_truth = false, truth_positions = false;

  std::size_t odometer_count = 0;
  double odometer_first_s = 0.0, odometer_last_s = 0.0;

  std::optional<results::MisalignmentRow> misalignment;
  std::optional<double> converged_at_s;

  // The true K: the simulator's base K and its steps (those the odometer has reached are
  // confirmed; scale-factor rows past an unconfirmed step wait for it), else truth.csv's k_true.
  enum class KReference { kNone, kSteps, kTruth } k_reference = KReference::kNone;
  double k_initial = 0.0;
  std::vector<KStep> steps;
  std::size_t steps_confirmed = 0;
  bool finishing = false;
  Source<TruthSample> k_truth;
  std::optional<TimedValue> k_prev, k_next;
  std::deque<results::ScaleFactorRow> waiting;
  double first_motion = std::numeric_limits<double>::quiet_NaN();
  std::vector<EstimatorStream> estimators;
  bool estimators_known = false;
  std::optional<results::ScaleFactorRow> last_k_row;

  std::optional<DrStream> dr_online, dr_coarse;
  std::optional<NavigationEvaluator> navigation;

  // The next finite k_true of the truth source.
  std::optional<TimedValue> next_k_true() {
    for (std::optional<TruthSample> t = k_truth(); t; t = k_truth())
      if (std::isfinite(t->k_true_m_per_pulse)) return TimedValue{t->t_s, t->k_true_m_per_pulse};
    return std::nullopt;
  }

  // The true K in force at t_s (the latest value at or before it; the first when t_s precedes all).
  double reference_k_at(double t_s) {
    if (k_reference == KReference::kSteps) {
      double k = k_initial;
      for (std::size_t i = 0; i < steps_confirmed && steps[i].t_s <= t_s; ++i) k = steps[i].k_after_m_per_pulse;
      return k;
    }
    while (k_next && k_next->t_s <= t_s) {
      k_prev = k_next;
      k_next = next_k_true();
    }
    return k_prev ? k_prev->value : k_next->value;
  }

  bool k_row_may_wait(double t_s) const {
    return k_reference == KReference::kSteps && !finishing && steps_confirmed < steps.size() &&
           t_s >= steps[steps_confirmed].t_s;
  }

  void process_k_row(const results::ScaleFactorRow& r) {
    if (!estimators_known) {
      estimators_known = true;
      for (const auto& [name, value] : r.k_by_estimator)
        estimators.emplace_back(name, ScaleFactorEvaluator(steps, in.options.k_evaluation));
    }
    if (std::isnan(first_motion) && r.samples_accepted > 0) {
      first_motion = r.t_s;
      for (EstimatorStream& e : estimators) e.evaluator.set_first_motion(first_motion);
    }
    std::optional<double> k_ref;
    for (std::size_t i = 0; i < r.k_by_estimator.size(); ++i) {
      const auto& [name, value] = r.k_by_estimator[i];
      if (!value) continue;
      EstimatorStream* e = i < estimators.size() && estimators[i].name == name ? &estimators[i] : nullptr;
      for (std::size_t j = 0; !e && j < estimators.size(); ++j)
        if (estimators[j].name == name) e = &estimators[j];
      if (!e) continue;
      e->any = true;
      e->final_k_m_per_pulse = *value;
      if (k_reference == KReference::kNone) continue;
      if (!k_ref) k_ref = reference_k_at(r.t_s);
      e->evaluator.add(r.t_s, *value, *k_ref);
    }
    last_k_row = r;
  }

  void release_waiting() {
    while (!waiting.empty() && !k_row_may_wait(waiting.front().t_s)) {
      process_k_row(waiting.front());
      waiting.pop_front();
    }
  }
};

SummaryAccumulator::SummaryAccumulator(SummaryInputs inputs) : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.in = std::move(inputs);
  m.sim = simulation_meta(m.in.meta);
  std::optional<TruthSample> first_truth;
  if (m.in.truth) first_truth = m.in.truth()();
  m.has_truth = first_truth.has_value();
  m.truth_positions = m.has_truth && std::isfinite(first_truth->position.lat_rad);
  m.has_ins = m.in.ins && m.in.ins()().has_value();
  if (m.sim.contains("k_true_initial_m_per_pulse") && m.sim.contains("k_steps")) {
    m.k_reference = Impl::KReference::kSteps;
    m.k_initial = m.sim["k_true_initial_m_per_pulse"].get<double>();
    for (const json& s : m.sim["k_steps"])
      m.steps.push_back({s["t_s"].get<double>(), s["k_before"].get<double>(), s["k_after"].get<double>()});
  } else if (m.has_truth) {
    m.k_truth = open(m.in.truth);
    m.k_next = m.next_k_true();
    if (m.k_next) m.k_reference = Impl::KReference::kTruth;
  }
  const SourceFactory<TimedPosition> reference =
      m.truth_positions ? truth_positions(m.in.truth) : valid_fixes(m.in.gnss);
  const double min_distance_m = m.in.options.dr_min_distance_m;
  m.dr_online.emplace(DeadReckoningEvaluator(reference, outages_of(m.sim, m.in.gnss), min_distance_m));
  m.dr_coarse.emplace(DeadReckoningEvaluator(reference, outages_of(m.sim, m.in.gnss), min_distance_m));
  m.navigation.emplace(m.in, m.truth_positions, outages_of(m.sim, m.in.gnss));
}

SummaryAccumulator::~SummaryAccumulator() = default;

SummaryOptions& SummaryAccumulator::options() { return impl_->in.options; }

void SummaryAccumulator::add_odometer(double t_s) {
  Impl& m = *impl_;
  if (m.odometer_count++ == 0) m.odometer_first_s = t_s;
  m.odometer_last_s = t_s;
  // A step the drive reaches (a drive cut short, --duration-s, never reaches the later ones).
  while (m.steps_confirmed < m.steps.size() && m.steps[m.steps_confirmed].t_s <= t_s) ++m.steps_confirmed;
  m.release_waiting();
}

void SummaryAccumulator::add(const results::MisalignmentRow& r) {
  Impl& m = *impl_;
  if (r.converged && !m.converged_at_s) m.converged_at_s = r.t_s;
  m.misalignment = r;
}

void SummaryAccumulator::add(const results::ScaleFactorRow& r) {
  Impl& m = *impl_;
  if (!m.waiting.empty() || m.k_row_may_wait(r.t_s))
    m.waiting.push_back(r);
  else
    m.process_k_row(r);
}

void SummaryAccumulator::add_dead_reckoning(const results::DeadReckoningRow& r) {
  impl_->dr_online->add(r);
  impl_->navigation->add_dead_reckoning(r);
}

void SummaryAccumulator::add_dead_reckoning_coarse(const results::DeadReckoningRow& r) { impl_->dr_coarse->add(r); }

void SummaryAccumulator::add(const results::NavigationPositionRow& r) { impl_->navigation->add(r); }

SummaryAccumulator::Footprint SummaryAccumulator::footprint() const {
  Footprint f;
  f.scale_factor_rows_waiting = impl_->waiting.size();
  f.navigation_rows_buffered = impl_->navigation->nav_buffered();
  f.dead_reckoning_rows_buffered = impl_->navigation->dr_buffered();
  f.outages = impl_->navigation->outages();
  return f;
}

json SummaryAccumulator::finish() {
  Impl& m = *impl_;
  const SummaryOptions& options = m.in.options;
  // The steps the drive never reached are dropped; the rows that waited for them are evaluated.
  m.finishing = true;
  if (m.odometer_count == 0)
    while (m.steps_confirmed < m.steps.size() && m.steps[m.steps_confirmed].t_s <= 0.0) ++m.steps_confirmed;
  m.steps.resize(m.steps_confirmed);
  for (EstimatorStream& e : m.estimators) e.evaluator.drop_steps_from(m.steps_confirmed);
  m.release_waiting();

  json s;
  s["dataset"] = {{"name", options.dataset_name},
                  {"vehicle_id", m.in.meta.vehicle_id},
                  {"duration_s", m.odometer_count == 0 ? 0.0 : m.odometer_last_s - m.odometer_first_s},
                  {"has_ins", m.has_ins},
                  {"has_truth", m.has_truth}};
  if (options.elapsed_s) {
    s["processing"] = {{"elapsed_s", *options.elapsed_s},
                       {"odometer_epochs_per_s", m.odometer_count / std::max(*options.elapsed_s, 1e-9)}};
  }

  // Misalignment: the final estimate, and its error when the truth is known.
  if (m.misalignment) {
    const results::MisalignmentRow& r = *m.misalignment;
    const DatasetMeta& meta = m.in.meta;
    json j = {{"heading_deg", rad_to_deg(r.heading_rad)},
              {"pitch_deg", rad_to_deg(r.pitch_rad)},
              {"heading_std_deg", number_or_null(rad_to_deg(r.heading_std_rad))},
              {"pitch_std_deg", number_or_null(rad_to_deg(r.pitch_std_rad))},
              {"converged", r.converged},
              {"state", r.state},
              {"samples_used", r.samples_used}};
    if (m.converged_at_s) j["converged_at_s"] = *m.converged_at_s;
    if (meta.truth_misalignment_heading_deg && meta.truth_misalignment_pitch_deg) {
      j["truth_heading_deg"] = *meta.truth_misalignment_heading_deg;
      j["truth_pitch_deg"] = *meta.truth_misalignment_pitch_deg;
      j["heading_error_deg"] = rad_to_deg(r.heading_rad) - *meta.truth_misalignment_heading_deg;
      j["pitch_error_deg"] = rad_to_deg(r.pitch_rad) - *meta.truth_misalignment_pitch_deg;
      // A constant INS heading error cannot be told from a heading misalignment (docs/ALGORITHM.md,
      // caveat of §1): the calibration estimates their sum, which is what dead reckoning with this
      // INS needs. Against the mechanical angle alone a right estimate would look wrong by the bias.
      if (m.sim.contains("ins_heading_bias_deg")) {
        const double bias_deg = m.sim["ins_heading_bias_deg"].get<double>();
        j["ins_heading_bias_deg"] = bias_deg;
        j["dr_heading_error_deg"] = rad_to_deg(r.heading_rad) - (*meta.truth_misalignment_heading_deg + bias_deg);
      }
    }
    s["misalignment"] = j;
  }

  // Scale factor: every estimator that has a column, evaluated against the true K when known.
  json estimators = json::object();
  for (const EstimatorStream& e : m.estimators) {
    if (!e.any) continue;
    json j = {{"final_k_m_per_pulse", e.final_k_m_per_pulse}};
    if (m.k_reference != Impl::KReference::kNone && std::isfinite(m.first_motion)) {
      const KEvaluation k = e.evaluator.result();
      j["rms_rel_error_percent"] = number_or_null(100.0 * k.rms_rel_error);
      j["max_rel_error_percent"] = number_or_null(100.0 * k.max_rel_error);
      j["final_rel_error_percent"] = number_or_null(100.0 * k.final_rel_error);
      j["time_to_converge_s"] = number_or_null(k.time_to_converge_s);
      json settle = json::array();
      for (double t : k.settle_times_s) settle.push_back(number_or_null(t));
      j["settle_times_s"] = settle;
    }
    estimators[e.name] = j;
  }
  json sf = {{"estimators", estimators}};
  if (m.last_k_row) {
    const results::ScaleFactorRow& last = *m.last_k_row;
    sf["main_estimator"] = last.estimator;
    sf["converged"] = last.converged;
    sf["samples_accepted"] = last.samples_accepted;
    sf["samples_rejected"] = last.samples_rejected;
    sf["first_motion_t_s"] = number_or_null(m.first_motion);
    sf["gnss_latency_s"] = number_or_null(last.gnss_latency_s);
    sf["gnss_latency_sigma_s"] = last.gnss_latency_sigma_s ? number_or_null(*last.gnss_latency_sigma_s) : json();
    if (m.sim.is_object() && m.sim.contains("gnss_latency_s") && m.sim["gnss_latency_s"].is_number())
      sf["gnss_latency_error_s"] = number_or_null(last.gnss_latency_s - m.sim["gnss_latency_s"].get<double>());
    sf["turn_slip_s_per_rad"] = number_or_null(last.turn_slip_s_per_rad);
    sf["turn_slip_sigma_s_per_rad"] =
        last.turn_slip_sigma_s_per_rad ? number_or_null(*last.turn_slip_sigma_s_per_rad) : json();
    sf["turn_slip_applies"] = last.turn_slip_applies;
  }
  if (m.k_reference != Impl::KReference::kNone) {
    double k_final = m.k_initial;
    if (m.k_reference == Impl::KReference::kSteps) {
      if (!m.steps.empty()) k_final = m.steps.back().k_after_m_per_pulse;
    } else {
      for (std::optional<TimedValue> k = m.k_next ? m.k_next : m.k_prev; k; k = m.next_k_true()) k_final = k->value;
    }
    sf["true_k_final_m_per_pulse"] = k_final;
    json st = json::array();
    for (const KStep& k : m.steps)
      st.push_back({{"t_s", k.t_s}, {"k_before", k.k_before_m_per_pulse}, {"k_after", k.k_after_m_per_pulse}});
    sf["k_steps"] = st;
  }
  s["scale_factor"] = sf;

  // Dead reckoning against truth positions, or valid GNSS fixes without truth.
  s["dead_reckoning"] = {{"reference", m.truth_positions ? "truth" : "gnss"},
                         {"online_k", m.dr_online->finish()},
                         {"coarse_k", m.dr_coarse->finish()},
                         {"coarse_k_origin", options.coarse_k_origin}};
  s["navigation_position"] = m.navigation->finish();
  return s;
}

SummaryInputs summary_inputs(const Dataset& d, const SummaryOptions& options) {
  SummaryInputs in;
  in.meta = d.meta;
  if (!d.truth.empty()) in.truth = vector_source(d.truth);
  in.gnss = vector_source(d.gnss);
  if (!d.ins.empty()) in.ins = vector_source(d.ins);
  in.options = options;
  return in;
}

json make_summary(const Dataset& d, const results::OutputRows& rows, const SummaryOptions& options) {
  SummaryAccumulator acc(summary_inputs(d, options));
  for (const OdometerSample& o : d.odometer) acc.add_odometer(o.t_s);
  for (const results::MisalignmentRow& r : rows.misalignment) acc.add(r);
  for (const results::ScaleFactorRow& r : rows.scale_factor) acc.add(r);
  // The dead-reckoning and navigation rows in time order, as a streaming run produces them.
  std::size_t i = 0, j = 0;
  const auto& dr = rows.dead_reckoning;
  const auto& nav = rows.navigation_position;
  while (i < dr.size() || j < nav.size()) {
    if (j >= nav.size() || (i < dr.size() && dr[i].t_s <= nav[j].t_s))
      acc.add_dead_reckoning(dr[i++]);
    else
      acc.add(nav[j++]);
  }
  for (const results::DeadReckoningRow& r : rows.dead_reckoning_coarse) acc.add_dead_reckoning_coarse(r);
  return acc.finish();
}

namespace {
std::string fmt(const json& v, int precision, const char* unit = "") {
  if (v.is_null() || !v.is_number()) return "-";
  std::ostringstream o;
  o << std::fixed << std::setprecision(precision) << v.get<double>() << unit;
  return o.str();
}
}  // namespace

void add_consistency(json& s, const std::vector<dead_reckoning::ConsistencyState>& checks) {
  json c = json::object();
  std::string misalignment_withdrawn, k_withdrawn;
  for (std::size_t i = 0; i < checks.size(); ++i) {
    const dead_reckoning::ConsistencyState& st = checks[i];
    const auto check = static_cast<dead_reckoning::ConsistencyCheck>(i);
    c[to_string(check)] = {{"raised", st.raised},
                           {"times_raised", st.times_raised},
                           {"finding", st.times_raised ? json(st.text) : json()},
                           {"last_value", number_or_null(st.last_value)}};
    if (!st.raised) continue;
    // A heading that contradicts the GNSS course spoils the misalignment; a distance that does, K;
    // a drifting track, either.
    if (check != dead_reckoning::ConsistencyCheck::kOdometerSpeed && misalignment_withdrawn.empty())
      misalignment_withdrawn = st.text;
    if (check != dead_reckoning::ConsistencyCheck::kHeadingRate && k_withdrawn.empty()) k_withdrawn = st.text;
  }
  s["consistency"] = c;
  if (!misalignment_withdrawn.empty() && s.contains("misalignment") && s["misalignment"].is_object()) {
    s["misalignment"]["converged"] = false;
    s["misalignment"]["converged_withdrawn"] = misalignment_withdrawn;
  }
  if (!k_withdrawn.empty() && s.contains("scale_factor") && s["scale_factor"].contains("converged")) {
    s["scale_factor"]["converged"] = false;
    s["scale_factor"]["converged_withdrawn"] = k_withdrawn;
  }
}

void print_summary(const json& s, std::ostream& out) {
  out << "odonav summary: " << s["dataset"]["name"].get<std::string>() << " (" << fmt(s["dataset"]["duration_s"], 1)
      << " s";
  if (s.contains("processing")) out << ", processed in " << fmt(s["processing"]["elapsed_s"], 3) << " s";
  out << ")\n";
  if (s.contains("misalignment")) {
    const json& m = s["misalignment"];
    out << "  misalignment   heading " << fmt(m["heading_deg"], 3) << " deg +- " << fmt(m["heading_std_deg"], 3)
        << ", pitch " << fmt(m["pitch_deg"], 3) << " deg +- " << fmt(m["pitch_std_deg"], 3) << "  ("
        << m["state"].get<std::string>() << (m.contains("converged_withdrawn") ? ", converged withdrawn" : "") << ")";
    if (m.contains("heading_error_deg"))
      out << "\n                 error vs truth: heading " << fmt(m["heading_error_deg"], 4) << " deg, pitch "
          << fmt(m["pitch_error_deg"], 4) << " deg";
    if (m.contains("dr_heading_error_deg"))
      out << "\n                 heading vs truth plus the INS heading bias (" << fmt(m["ins_heading_bias_deg"], 3)
          << " deg; the angle dead reckoning needs): " << fmt(m["dr_heading_error_deg"], 4) << " deg";
    out << "\n";
  }
  if (s.contains("consistency"))
    for (const auto& [name, c] : s["consistency"].items())
      if (c.value("raised", false)) out << "  INCONSISTENT   " << c["finding"].get<std::string>() << "\n";
  const json& sf = s["scale_factor"];
  out << "  scale factor   (main: " << sf.value("main_estimator", std::string("-")) << ", accepted "
      << sf.value("samples_accepted", 0) << ", rejected " << sf.value("samples_rejected", 0) << ")\n";
  out << "    estimator     final K [m/pulse]   RMS err %   converge s   settle s after each step\n";
  for (const auto& [name, e] : sf["estimators"].items()) {
    out << "    " << std::left << std::setw(12) << name << std::right << std::setw(14)
        << fmt(e["final_k_m_per_pulse"], 7);
    out << std::setw(14) << fmt(e.value("rms_rel_error_percent", json()), 3) << std::setw(13)
        << fmt(e.value("time_to_converge_s", json()), 1) << "   ";
    if (e.contains("settle_times_s"))
      for (const json& t : e["settle_times_s"]) out << fmt(t, 1) << " ";
    out << "\n";
  }
  if (sf.contains("true_k_final_m_per_pulse"))
    out << "    true K (final) " << fmt(sf["true_k_final_m_per_pulse"], 7) << "\n";
  if (sf.contains("gnss_latency_s")) {
    out << "    GNSS latency  " << fmt(sf["gnss_latency_s"], 4, " s") << " +- "
        << fmt(sf.value("gnss_latency_sigma_s", json()), 4, " s");
    if (sf.contains("gnss_latency_error_s"))
      out << "  (error vs simulation " << fmt(sf["gnss_latency_error_s"], 4, " s") << ")";
    out << "\n";
  }
  if (sf.contains("turn_slip_s_per_rad")) {
    out << "    turn slip     " << fmt(sf["turn_slip_s_per_rad"], 4, " s/rad") << " +- "
        << fmt(sf.value("turn_slip_sigma_s_per_rad", json()), 4, " s/rad")
        << (sf.value("turn_slip_applies", false) ? "  (applied by dead reckoning" : "  (not applied");
    if (sf.contains("turn_slip_samples")) out << "; " << sf["turn_slip_samples"].get<uint64_t>() << " turn samples";
    const std::string why = sf.value("turn_slip_reason", std::string());
    if (!why.empty()) out << ": " << why;
    out << ")\n";
  }
  const json& dr = s["dead_reckoning"];
  out << "  dead reckoning (vs " << dr["reference"].get<std::string>() << ")\n";
  out << "    K             final err m   final %D   max %D   outage err m (% of outage distance)\n";
  for (const char* which : {"online_k", "coarse_k"}) {
    const json& j = dr[which];
    if (j.is_null()) continue;
    out << "    " << std::left << std::setw(12) << which << std::right << std::setw(12) << fmt(j["final_error_m"], 2)
        << std::setw(11) << fmt(j["final_error_percent"], 3) << std::setw(9) << fmt(j["max_error_percent"], 3) << "   ";
    for (const json& o : j["outages"])
      out << fmt(o["error_m"], 2) << " (" << fmt(o["error_percent_of_outage_distance"], 3) << " %) ";
    out << "\n";
  }
  if (!dr["coarse_k"].is_null()) out << "    coarse K from: " << dr["coarse_k_origin"].get<std::string>() << "\n";
  if (s.contains("navigation_position") && !s["navigation_position"].is_null()) {
    const json& nav = s["navigation_position"];
    out << "  navigation position (anchored on GNSS)   horizontal RMS: anchored / pure DR / GNSS fixes\n";
    out << "    vs GNSS while valid   " << fmt(nav["vs_gnss"]["horizontal_rms_m"], 2, " m") << " / "
        << fmt(nav["vs_gnss"]["pure_dr_horizontal_rms_m"], 2, " m") << " / -\n";
    if (nav.contains("vs_truth")) {
      const json& t = nav["vs_truth"];
      out << "    vs truth while valid  " << fmt(t["horizontal_rms_m"], 2, " m") << " / "
          << fmt(t["pure_dr_horizontal_rms_m"], 2, " m") << " / " << fmt(t["gnss_horizontal_rms_m"], 2, " m") << "\n";
      for (const json& o : t["outages"])
        out << "    outage " << fmt(o["start_s"], 0) << "-" << fmt(o["end_s"], 0) << " s: error "
            << fmt(o["error_at_start_m"], 2) << " -> " << fmt(o["error_at_end_m"], 2, " m") << " over "
            << fmt(o["distance_m"], 0, " m") << "\n";
    }
  }
  if (s.contains("warnings") && s["warnings"].is_array() && !s["warnings"].empty()) {
    out << "  warnings\n";
    for (const json& w : s["warnings"])
      if (w.is_object() && w.contains("message") && w["message"].is_string())
        out << "    " << w.value("code", std::string("-")) << ": " << w["message"].get<std::string>() << "\n";
  }
}

}  // namespace odonav::offline
