#include "recorder_node.hpp"

#include <spdlog/spdlog.h>

#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <set>
#include <stdexcept>

#include "odonav/dds/output_messages.hpp"
#include "odonav/dds/time.hpp"
#include "odonav/frames.hpp"
#include "odonav/run_provenance.hpp"
#include "odonav/topics.hpp"

namespace odonav::recorder {

namespace {

const char* health_state_name(odonav::msg::HealthState s) {
  switch (s) {
    case odonav::msg::HEALTH_STATE_STARTING: return "starting";
    case odonav::msg::HEALTH_STATE_RUNNING: return "running";
    case odonav::msg::HEALTH_STATE_DEGRADED: return "degraded";
    case odonav::msg::HEALTH_STATE_ERROR: return "error";
    case odonav::msg::HEALTH_STATE_STOPPING: return "stopping";
  }
  return "?";
}

const char* health_level_name(odonav::msg::HealthLevel l) {
  switch (l) {
    case odonav::msg::HEALTH_LEVEL_OK: return "ok";
    case odonav::msg::HEALTH_LEVEL_WARN: return "warn";
    case odonav::msg::HEALTH_LEVEL_ERROR: return "error";
    case odonav::msg::HEALTH_LEVEL_STALE: return "stale";
  }
  return "?";
}

}  // namespace

std::vector<GapRow> recording_gaps(const std::vector<double>& gnss_epochs_s, const std::vector<double>& misalignment_s,
                                   const std::vector<double>& scale_factor_s,
                                   const std::vector<OutputGap>& dead_reckoning_gaps,
                                   const std::vector<OutputGap>& navigation_gaps) {
  std::vector<GapRow> rows;
  auto add = [&rows](const char* topic, const std::vector<OutputGap>& gaps, const std::string& reason) {
    for (const OutputGap& g : gaps) rows.push_back({topic, g.first_missing_t_s, g.last_missing_t_s, g.missed, reason});
  };
  add(topics::kMisalignment.name, missing_epochs(gnss_epochs_s, misalignment_s),
      "no misalignment for these GNSS epochs: the calibration did not publish them or they were lost");
  add(topics::kScaleFactor.name, missing_epochs(gnss_epochs_s, scale_factor_s),
      "no scale factor for these GNSS epochs: the identification did not publish them or they were lost");
  add(topics::kDeadReckoning.name, dead_reckoning_gaps,
      "no dead-reckoning outputs between the rows around: the producer or the link lost them");
  add(topics::kNavigationPosition.name, navigation_gaps,
      "no navigation positions between the rows around: the producer or the link lost them");
  return rows;
}

GapsCsv::GapsCsv(const std::string& path)
    : csv_(path, {"topic", "first_missing_t_s", "last_missing_t_s", "count", "reason"}) {}

void GapsCsv::write(const GapRow& r) {
  csv_.field(r.topic).field(r.first_missing_t_s).field(r.last_missing_t_s).field(r.count).field(r.reason);
  csv_.end_row();
}

void add_recorder_options(Options& o) {
  o.add_string("out", "",
               "folder for misalignment.csv, scale_factor.csv, dead_reckoning.csv, navigation_position.csv "
               "(created if missing); required");
  o.add_bool("force", false, "write into an existing non-empty directory that is not an odonav output directory");
  o.add_double("progress-every-s", 10.0, "a progress line every this much simulated (event) time, s", 0.1, 1e6);
  o.add_double("dead-reckoning-period-s", 0.0,
               "period of the dead-reckoning outputs (the odometer's), s, for the gap count; 0 = the smallest "
               "interval seen",
               0.0, 3600.0);
}

RecorderSettings recorder_settings_from(const Options& o) {
  RecorderSettings s;
  s.out_dir = o.get_string("out");
  if (s.out_dir.empty()) throw ConfigError("--out: the output folder is required");
  s.progress_every_s = o.get_double("progress-every-s");
  s.force = o.get_bool("force");
  s.dead_reckoning_period_s = o.get_double("dead-reckoning-period-s");
  return s;
}

namespace {
OutputPolicy output_policy(const RecorderSettings& s) {
  OutputPolicy p;
  p.force = s.force;
  return p;
}

constexpr const char* kMisalignmentFile = "misalignment.csv";
constexpr const char* kScaleFactorFile = "scale_factor.csv";
constexpr const char* kDeadReckoningFile = "dead_reckoning.csv";
constexpr const char* kNavigationPositionFile = "navigation_position.csv";
constexpr const char* kGapsFile = "gaps.csv";

/// Whether an odonav-recorder runs with this pid (a reused pid of another program, or a killed
/// recorder not yet reaped by its parent, does not count).
bool recorder_alive(long pid) {
  const std::string proc = "/proc/" + std::to_string(pid);
  std::ifstream comm(proc + "/comm");
  if (!comm) return ::kill(static_cast<pid_t>(pid), 0) == 0 || errno == EPERM;
  std::string name;
  std::getline(comm, name);
  if (name.rfind("odonav-recorder", 0) != 0) return false;
  // /proc/<pid>/stat: "pid (comm) state ...": Z = a zombie, X = dead.
  std::ifstream stat(proc + "/stat");
  std::string text;
  std::getline(stat, text);
  const std::size_t paren = text.rfind(')');
  return paren == std::string::npos || paren + 2 >= text.size() || (text[paren + 2] != 'Z' && text[paren + 2] != 'X');
}

/// Decides what of an unfinished recording in `out` to adopt (recording_resume.hpp); a new
/// recording writes its marker now, before any of its files exists.
ResumePlan begin_recording(const OutputDirectory& out, const std::string& vehicle) {
  const std::vector<RecordingFile> files{{kMisalignmentFile, results::misalignment_columns()},
                                         {kScaleFactorFile, results::scale_factor_columns()},
                                         {kDeadReckoningFile, results::dead_reckoning_columns()},
                                         {kNavigationPositionFile, results::navigation_position_columns()}};
  ResumePlan plan = plan_resume(out.path(), vehicle, files, {kGapsFile}, ::getpid(), recorder_alive);
  for (const std::string& f : plan.ignored)
    spdlog::warn("{}: a temporary file of another run, not of a recording to resume: left as it is", f);
  if (!plan.resumed()) write_file_atomically(out.file(kRecordingMarker), marker_text({::getpid(), vehicle}));
  return plan;
}
}  // namespace

RecorderNode::RecorderNode(dds::ComponentRuntime& runtime, const RecorderSettings& settings)
    : runtime_(runtime),
      settings_(settings),
      out_(settings.out_dir, output_policy(settings)),
      resume_(begin_recording(out_, runtime.settings().vehicle_id)),
      misalignment_csv_(out_.file(kMisalignmentFile)),
      scale_factor_csv_(out_.file(kScaleFactorFile)),
      dead_reckoning_csv_(out_.file(kDeadReckoningFile)),
      navigation_position_csv_(out_.file(kNavigationPositionFile)),
      gaps_csv_(out_.file(kGapsFile)) {
  // An error (an exception, a failed write) leaves the rows in the temporaries, as a kill does:
  // the next start resumes them; the real names are never touched before a clean close.
  for (CsvWriter* csv : {&misalignment_csv_.csv(), &scale_factor_csv_.csv(), &dead_reckoning_csv_.csv(),
                         &navigation_position_csv_.csv()})
    csv->keep_on_failure();
  if (resume_.resumed()) adopt_resumed_rows();
  const std::string vehicle = runtime.settings().vehicle_id;
  auto& p = runtime.participant();
  // Callbacks copy and queue; conversion and file I/O happen on the worker thread.
  misalignment_reader_ = std::make_unique<dds::Reader<odonav::msg::Misalignment>>(
      p, topics::kMisalignment.name, kMisalignmentRecorderReaderProfile,
      [this, vehicle](const odonav::msg::Misalignment& m) {
        if (m.vehicle_id() == vehicle) runtime_.post([this, m] { on_misalignment(m); });
      });
  scale_factor_reader_ = std::make_unique<dds::Reader<odonav::msg::ScaleFactor>>(
      p, topics::kScaleFactor.name, kScaleFactorRecorderReaderProfile,
      [this, vehicle](const odonav::msg::ScaleFactor& m) {
        if (m.vehicle_id() == vehicle) runtime_.post([this, m] { on_scale_factor(m); });
      });
  // Dead reckoning, navigation and GNSS with the transient-local readers: a restarted recorder gets
  // the producers' history (30 s of outputs, the GNSS epochs for gaps.csv) for its downtime.
  dead_reckoning_reader_ = std::make_unique<dds::Reader<odonav::msg::DeadReckoning>>(
      p, topics::kDeadReckoning.name, topics::kDeadReckoningRecorderReaderProfile,
      [this, vehicle](const odonav::msg::DeadReckoning& m) {
        if (m.vehicle_id() == vehicle) runtime_.post([this, m] { on_dead_reckoning(m); });
      });
  navigation_reader_ = std::make_unique<dds::Reader<odonav::msg::NavigationPosition>>(
      p, topics::kNavigationPosition.name, topics::kDeadReckoningRecorderReaderProfile,
      [this, vehicle](const odonav::msg::NavigationPosition& m) {
        if (m.vehicle_id() == vehicle) runtime_.post([this, m] { on_navigation_position(m); });
      });
  // The GNSS epochs: each should have one misalignment and one scale-factor row (gaps.csv). A
  // resumed recording also takes the gateway's history (the epochs of its downtime); a new one
  // counts from its start, as before.
  gnss_reader_ = std::make_unique<dds::Reader<odonav::msg::GnssFix>>(
      p, topics::kGnssFix.name,
      resume_.resumed() ? topics::kSensorReplayReaderProfile : topics::kGnssFix.reader_profile,
      [this, vehicle](const odonav::msg::GnssFix& m) {
        if (m.vehicle_id() == vehicle) runtime_.post([this, m] { on_gnss(m); });
      });
  health_reader_ = std::make_unique<dds::Reader<odonav::msg::Health>>(
      p, topics::kHealth.name, topics::kHealth.reader_profile, [this, vehicle](const odonav::msg::Health& h) {
        if (h.vehicle_id() == vehicle) runtime_.post([this, h] { on_health(h); });
      });
}

RecorderNode::~RecorderNode() { close_readers(); }

void RecorderNode::close_readers() {
  misalignment_reader_.reset();
  scale_factor_reader_.reset();
  dead_reckoning_reader_.reset();
  navigation_reader_.reset();
  health_reader_.reset();
  gnss_reader_.reset();
}

void RecorderNode::adopt_resumed_rows() {
  spdlog::info(
      "resuming the unfinished recording of odonav-recorder pid {} in {} (it did not finish: killed or "
      "crashed)",
      resume_.previous->pid, settings_.out_dir);
  std::string adopted;
  for (const AdoptedFile& f : resume_.files) {
    if (!f.rows.t_s.empty())
      resumed_from_s_ = std::min(resumed_from_s_.value_or(f.rows.t_s.front()), f.rows.t_s.front());
    CsvWriter& csv = f.name == kMisalignmentFile    ? misalignment_csv_.csv()
                     : f.name == kScaleFactorFile   ? scale_factor_csv_.csv()
                     : f.name == kDeadReckoningFile ? dead_reckoning_csv_.csv()
                                                    : navigation_position_csv_.csv();
    csv.append_rows(f.rows.text, f.rows.rows());
    adopted_rows_ += f.rows.rows();
    adopted_torn_lines_ += f.rows.torn_lines;
    const std::string last = f.rows.last_t_s() ? fmt::format("{:.3f} s", *f.rows.last_t_s()) : "-";
    spdlog::info("adopted {} rows of {} from {}, last t={}{}", f.rows.rows(), f.name, f.from, last,
                 f.rows.torn_lines ? "; its torn last line (cut by the kill) dropped" : "");
    adopted += (adopted.empty() ? "" : ", ") + f.name + " " + std::to_string(f.rows.rows()) + " rows to t=" + last;
    // Each file goes on after its last row: what the producers hand again is a repeat, and the
    // gap counts see the adopted rows.
    RowStamps& stamps = f.name == kMisalignmentFile    ? misalignment_stamps_
                        : f.name == kScaleFactorFile   ? scale_factor_stamps_
                        : f.name == kDeadReckoningFile ? dead_reckoning_stamps_
                                                       : navigation_stamps_;
    for (const double t : f.rows.t_s) stamps.admit(t);
    if (f.name == kMisalignmentFile)
      misalignment_s_.insert(misalignment_s_.end(), f.rows.t_s.begin(), f.rows.t_s.end());
    if (f.name == kScaleFactorFile) scale_factor_s_.insert(scale_factor_s_.end(), f.rows.t_s.begin(), f.rows.t_s.end());
    if (f.name == kDeadReckoningFile)
      for (const double t : f.rows.t_s) note_dead_reckoning_gap(t);
    if (f.name == kNavigationPositionFile)
      for (const double t : f.rows.t_s) note_navigation_gap(t);
  }
  // The orphans go only once their rows are on disk under this process's names and the marker
  // names this process: a kill at any point leaves every row where the next start adopts it.
  for (CsvWriter* csv : {&misalignment_csv_.csv(), &scale_factor_csv_.csv(), &dead_reckoning_csv_.csv(),
                         &navigation_position_csv_.csv()})
    csv->flush(true);
  write_file_atomically(out_.file(kRecordingMarker), marker_text({::getpid(), runtime_.settings().vehicle_id}));
  for (const std::string& f : resume_.remove) {
    std::error_code ec;
    if (!std::filesystem::remove(f, ec) && ec)
      spdlog::warn("{}: not removed ({}); its rows are in this recording", f, ec.message());
  }
  resumed_text_ = "resumed the recording of pid " + std::to_string(resume_.previous->pid) + ": " + adopted;
  if (adopted_torn_lines_ > 0) resumed_text_ += "; " + std::to_string(adopted_torn_lines_) + " torn lines dropped";
  resumed_wall_s_ = dds::steady_now_s();
}

void RecorderNode::flush_files() {
  if (!unflushed_) return;
  misalignment_csv_.csv().flush();
  scale_factor_csv_.csv().flush();
  dead_reckoning_csv_.csv().flush();
  navigation_position_csv_.csv().flush();
  unflushed_ = false;
}

void RecorderNode::note_dead_reckoning_gap(double t_s) {
  if (const auto gap = dr_gaps_.offer(t_s)) {
    dr_gap_list_.push_back(*gap);
    last_gap_wall_s_ = dds::steady_now_s();
    spdlog::warn(
        "{} (no such rows were received: the producer or the link lost them, or the recorder was down "
        "longer than their history)",
        describe_gap(*gap, "dead-reckoning"));
  }
}

void RecorderNode::note_navigation_gap(double t_s) {
  if (const auto gap = navigation_gaps_.offer(t_s)) {
    navigation_gap_list_.push_back(*gap);
    spdlog::warn(
        "{} (no such rows were received: the producer or the link lost them, or the recorder was down "
        "longer than their history)",
        describe_gap(*gap, "navigation-position"));
  }
}

void RecorderNode::on_misalignment(const odonav::msg::Misalignment& m) {
  const results::MisalignmentRow r = dds::row_of(m);
  // A calibration restarted from its checkpoint publishes again the epochs after it, which the
  // killed process had published already (the same values): each epoch is recorded once, as the
  // scale factor's arbiter does for a restarted identification.
  const std::optional<double> last = misalignment_stamps_.last_t_s;
  if (!misalignment_stamps_.admit(r.t_s)) {
    if (r.t_s < *last && !misalignment_replay_logged_) {
      misalignment_replay_logged_ = true;
      spdlog::info(
          "misalignment: t={} s is before the last recorded {} s: a restarted calibration's catch-up "
          "or the history handed to a restarted recorder, recorded once (counted in the repeats)",
          r.t_s, *last);
    }
    return;
  }
  unflushed_ = true;
  misalignment_csv_.write(r);
  misalignment_s_.push_back(r.t_s);
  ++rows_[0];
}

void RecorderNode::on_scale_factor(const odonav::msg::ScaleFactor& m) {
  double t_s = 0.0;
  try {
    t_s = dds::to_seconds(m.header().stamp());
  } catch (const std::invalid_argument& e) {
    spdlog::warn("scale factor of '{}': {}: not recorded", m.source(), e.what());
    return;
  }
  const std::uint64_t switches = k_arbiter_.counters().switches;
  const std::vector<odonav::msg::ScaleFactor> released = k_arbiter_.offer(m.source(), m.source_priority(), t_s, m);
  if (k_arbiter_.counters().switches != switches && !k_arbiter_.switches().empty()) {
    const SourceSwitch& sw = k_arbiter_.switches().back();
    spdlog::info("scale factor: recording '{}' from t={:.3f} s ({})", sw.to, sw.at_stamp_s, sw.reason);
  }
  for (const auto& k : released) write_scale_factor(k);
}

void RecorderNode::write_scale_factor(const odonav::msg::ScaleFactor& m) {
  const results::ScaleFactorRow r = dds::row_of(m);
  if (!scale_factor_stamps_.admit(r.t_s)) return;
  unflushed_ = true;
  scale_factor_csv_.write(r);
  scale_factor_s_.push_back(r.t_s);
  ++rows_[1];
  last_k_ = m;
}

void RecorderNode::on_dead_reckoning(const odonav::msg::DeadReckoning& m) {
  const results::DeadReckoningRow r = dds::row_of(m);
  if (!dead_reckoning_stamps_.admit(r.t_s)) return;
  unflushed_ = true;
  dead_reckoning_csv_.write(r);
  ++rows_[2];
  note_dead_reckoning_gap(r.t_s);
  last_distance_m_ = r.distance_m;
  if (!next_progress_t_s_) next_progress_t_s_ = r.t_s + settings_.progress_every_s;
  if (r.t_s >= *next_progress_t_s_) {
    progress(r.t_s, r.distance_m);
    while (*next_progress_t_s_ <= r.t_s) *next_progress_t_s_ += settings_.progress_every_s;
  }
}

void RecorderNode::on_navigation_position(const odonav::msg::NavigationPosition& m) {
  const results::NavigationPositionRow r = dds::row_of(m);
  if (!navigation_stamps_.admit(r.t_s)) return;
  unflushed_ = true;
  navigation_position_csv_.write(r);
  ++navigation_rows_;
  note_navigation_gap(r.t_s);
}

void RecorderNode::on_gnss(const odonav::msg::GnssFix& m) {
  try {
    const double t_s = dds::to_seconds(m.header().stamp());
    // History older than the resumed recording's first row: before that recording started.
    if (resumed_from_s_ && t_s < *resumed_from_s_) return;
    gnss_epochs_s_.push_back(t_s);
  } catch (const std::invalid_argument& e) {
    spdlog::warn("gnss fix: {}: not counted as an epoch", e.what());
  }
}

std::string RecorderNode::write_gaps() {
  const std::vector<GapRow> gaps =
      recording_gaps(gnss_epochs_s_, misalignment_s_, scale_factor_s_, dr_gap_list_, navigation_gap_list_);
  for (const GapRow& g : gaps) gaps_csv_.write(g);
  gaps_csv_.close();
  const std::size_t epochs = std::set<double>(gnss_epochs_s_.begin(), gnss_epochs_s_.end()).size();
  if (gaps.empty())
    return "gaps.csv: nothing missing (" + std::to_string(epochs) + " GNSS epochs, each with its estimates)";
  std::map<std::string, std::uint64_t> missing;
  for (const GapRow& g : gaps) missing[g.topic] += g.count;
  std::string what;
  for (const auto& [topic, n] : missing) what += (what.empty() ? "" : ", ") + topic + " " + std::to_string(n);
  for (const GapRow& g : gaps)
    spdlog::warn("missing {} t={:.3f}-{:.3f} s ({}): {}", g.topic, g.first_missing_t_s, g.last_missing_t_s, g.count,
                 g.reason);
  return "gaps.csv: " + std::to_string(gaps.size()) + " spans missing: " + what + " (of " + std::to_string(epochs) +
         " GNSS epochs for the estimates, outputs for the others)";
}

void RecorderNode::progress(double t_s, double distance_m) {
  if (!last_k_ || !(last_k_->k_m_per_pulse() > 0.0)) {
    spdlog::info("progress: t={:.1f} s distance {:.0f} m K=- (no identified K yet)", t_s, distance_m);
    return;
  }
  spdlog::info("progress: t={:.1f} s distance {:.0f} m K={:.7g} ({}, {})", t_s, distance_m, last_k_->k_m_per_pulse(),
               last_k_->estimator(), last_k_->converged() ? "converged" : "not converged");
}

void RecorderNode::on_health(const odonav::msg::Health& h) {
  std::string text = std::string(health_state_name(h.state())) + " " + health_level_name(h.level());
  if (!h.reason().empty()) text += ": " + h.reason();
  auto& last = component_health_[h.component()];
  if (last == text) return;
  last = text;
  if (h.level() == odonav::msg::HEALTH_LEVEL_OK)
    spdlog::info("health {}: {}", h.component(), text);
  else
    spdlog::warn("health {}: {}", h.component(), text);
}

void RecorderNode::tick() {
  // After each batch of samples: a killed recorder leaves on disk all it wrote but the last batch,
  // which the producers' history (30 s) gives back to the restarted one.
  flush_files();
  if (!producers_matched_logged_ && misalignment_reader_->matched_writers() > 0 &&
      scale_factor_reader_->matched_writers() > 0 && dead_reckoning_reader_->matched_writers() > 0) {
    producers_matched_logged_ = true;
    spdlog::info("every producer matched (misalignment, scale factor, dead reckoning)");
  }
  dds::HealthCounters c{{"misalignment_rows", static_cast<double>(rows_[0])},
                        {"scale_factor_rows", static_cast<double>(rows_[1])},
                        {"dead_reckoning_rows", static_cast<double>(rows_[2])},
                        {"navigation_position_rows", static_cast<double>(navigation_rows_)},
                        {"queue_depth", static_cast<double>(runtime_.queue_depth())},
                        {"scale_factor_source_switches", static_cast<double>(k_arbiter_.counters().switches)},
                        {"scale_factor_other_source", static_cast<double>(k_arbiter_.counters().superseded)},
                        {"scale_factor_filled", static_cast<double>(k_arbiter_.counters().filled)},
                        {"dead_reckoning_missed", static_cast<double>(dr_gaps_.missed())},
                        {"dead_reckoning_gaps", static_cast<double>(dr_gaps_.gaps())},
                        {"resumed_rows", static_cast<double>(adopted_rows_)},
                        {"resumed_torn_lines", static_cast<double>(adopted_torn_lines_)}};
  // A hole in the dead-reckoning rows stays in the reason for a while after it is found (the
  // counters keep it for good), so a monitor polling at 1 Hz sees it.
  std::string reason = producers_matched_logged_ ? "" : "waiting for producers";
  auto level = odonav::msg::HEALTH_LEVEL_OK;
  if (!resumed_text_.empty() && dds::steady_now_s() - resumed_wall_s_ < kGapReasonHold_s) reason = resumed_text_;
  if (dr_gaps_.last_gap() && dds::steady_now_s() - last_gap_wall_s_ < kGapReasonHold_s) {
    level = odonav::msg::HEALTH_LEVEL_WARN;
    reason = describe_gap(*dr_gaps_.last_gap(), "dead-reckoning");
    if (dr_gaps_.gaps() > 1)
      reason +=
          " (" + std::to_string(dr_gaps_.gaps()) + " gaps, " + std::to_string(dr_gaps_.missed()) + " outputs in all)";
  }
  runtime_.publish_health(odonav::msg::HEALTH_STATE_RUNNING, level, reason, c);
}

int RecorderNode::run() {
  spdlog::info("recording vehicle '{}' into {}", runtime_.settings().vehicle_id, settings_.out_dir);
  runtime_.run([this] { tick(); });
  spdlog::info("stop requested: writing what is queued");
  runtime_.publish_health(odonav::msg::HEALTH_STATE_STOPPING, odonav::msg::HEALTH_LEVEL_OK, "stopping: draining", {},
                          true);
  close_readers();         // no callback after this
  runtime_.run_pending();  // everything received is written
  misalignment_csv_.close();
  scale_factor_csv_.close();
  dead_reckoning_csv_.close();
  navigation_position_csv_.close();
  const std::string gaps = write_gaps();
  // Which vehicle these rows are of: odonav-evaluate and odonav-report check it against the dataset.
  RunProvenance provenance;
  provenance.tool = "odonav-recorder";
  provenance.dds_vehicle_id = runtime_.settings().vehicle_id;
  write_file_atomically(out_.file(kProvenanceFile), provenance_json(provenance));
  if (rows_[2] > 0) progress(*dead_reckoning_stamps_.last_t_s, last_distance_m_);
  spdlog::info(
      "wrote {} misalignment, {} scale-factor, {} dead-reckoning, {} navigation-position rows into {} "
      "(repeats skipped: {}, {}, {}, {}{}); {}",
      rows_[0], rows_[1], rows_[2], navigation_rows_, settings_.out_dir, misalignment_stamps_.repeats,
      scale_factor_stamps_.repeats + k_arbiter_.counters().repeated, dead_reckoning_stamps_.repeats,
      navigation_stamps_.repeats,
      resume_.resumed() ? "; after " + std::to_string(adopted_rows_) +
                              " rows adopted from the unfinished "
                              "recording of pid " +
                              std::to_string(resume_.previous->pid)
                        : "",
      gaps);
  if (dr_gaps_.gaps() > 0)
    spdlog::warn("dead_reckoning.csv has {} gaps, {} outputs missing in all; the last: {}", dr_gaps_.gaps(),
                 dr_gaps_.missed(), describe_gap(*dr_gaps_.last_gap(), "dead-reckoning"));
  if (k_arbiter_.counters().switches > 1 || k_arbiter_.counters().superseded > 0)
    spdlog::info(
        "scale factor sources: {} switches, {} rows of a source not followed skipped (epochs written by "
        "another), {} epochs filled from another source",
        k_arbiter_.counters().switches, k_arbiter_.counters().superseded, k_arbiter_.counters().filled);
  // Last: the recording is finished (the next recorder into this folder starts a new one).
  std::error_code ec;
  std::filesystem::remove(out_.file(kRecordingMarker), ec);
  if (ec)
    spdlog::warn("{}: not removed ({}): the next recorder into this folder would resume this recording",
                 out_.file(kRecordingMarker), ec.message());
  runtime_.publish_health(odonav::msg::HEALTH_STATE_STOPPING, odonav::msg::HEALTH_LEVEL_OK, "stopped: files closed", {},
                          true);
  dds::wait_for_acknowledgments_logged(runtime_.health().writer(), std::chrono::seconds(1));
  return 0;
}

}  // namespace odonav::recorder
