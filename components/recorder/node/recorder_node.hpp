#pragma once
// odonav-recorder's DDS node: subscribes to one vehicle's misalignment, scale factor and dead
// reckoning (and health, for the log; GNSS, for the epochs) and writes misalignment.csv,
// scale_factor.csv, dead_reckoning.csv and navigation_position.csv, the same files and columns as odonav-offline (odonav/results/output_files.hpp),
// so a user can run either and compare them directly, and gaps.csv: what the recording lacks.
//
// Threads: reader callbacks only copy the message into the runtime's queue; the worker thread
// (ComponentRuntime::run) converts and writes, so the readers keep up with a replay at full speed.
// On SIGINT/SIGTERM: readers closed, every queued message written, files flushed and closed.
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>

#include "odonav/recorder/recording_resume.hpp"
#include "odonav/csv_writer.hpp"
#include "odonav/dds/component.hpp"
#include "odonav/gap_detector.hpp"
#include "odonav/topics.hpp"
#include "odonav/msg/DeadReckoning.h"
#include "odonav/msg/GnssFix.h"
#include "odonav/msg/NavigationPosition.h"
#include "odonav/msg/Health.h"
#include "odonav/msg/Misalignment.h"
#include "odonav/msg/ScaleFactor.h"
#include "odonav/results/output_files.hpp"
#include "odonav/safe_output.hpp"
#include "odonav/source_arbiter.hpp"

namespace odonav::recorder {

// Each estimate message becomes its file's row by the topic's field table (dds::row_of,
// odonav/dds/output_messages.hpp): the rows odonav-offline writes from the cores' output_row.

/// One row of gaps.csv: what the recording lacks on one topic, over one span (event time, s).
struct GapRow {
  std::string topic;  ///< the DDS topic name
  double first_missing_t_s = 0.0;
  double last_missing_t_s = 0.0;
  std::uint64_t count = 0;  ///< GNSS epochs (estimates) or outputs (dead reckoning, navigation) missing
  std::string reason;       ///< no ',' (a CSV field)
};

/// What the recording lacks: the misalignment and scale-factor rows missing against the GNSS
/// epochs received (missing_epochs: one estimate per epoch), then the holes in the dead-reckoning and
/// navigation-position rows (GapDetector), each topic's spans in time order.
std::vector<GapRow> recording_gaps(const std::vector<double>& gnss_epochs_s, const std::vector<double>& misalignment_s,
                                   const std::vector<double>& scale_factor_s,
                                   const std::vector<OutputGap>& dead_reckoning_gaps,
                                   const std::vector<OutputGap>& navigation_gaps);

/// gaps.csv (topic, first_missing_t_s, last_missing_t_s, count, reason): written through CsvWriter
/// (safe_output.hpp rules); a lossless recording has the header only.
class GapsCsv {
 public:
  explicit GapsCsv(const std::string& path);
  void write(const GapRow& row);
  void close() { csv_.close(); }

 private:
  CsvWriter csv_;
};

/// Estimates are read with topics::kMisalignmentRecorderReaderProfile and
/// kScaleFactorRecorderReaderProfile (KEEP_LAST 1000 per vehicle: a replay at maximum speed loses
/// no estimate; the vehicle's consumers keep the latest one only). The scale factor of several
/// identification instances (hot standby) goes through a SourceArbiter, as dead reckoning's does:
/// scale_factor.csv holds one row per epoch, of the highest-priority live instance, and after a
/// switch continues with the new instance's row of the epoch after the last one written.
using topics::kMisalignmentRecorderReaderProfile;
using topics::kScaleFactorRecorderReaderProfile;

/// The recorder's own flags.
struct RecorderSettings {
  std::string out_dir;             ///< created if missing; see OutputDirectory (odonav/safe_output.hpp).
  bool force = false;              ///< use a non-empty directory that is not an odonav output directory.
  double progress_every_s = 10.0;  ///< progress line every this much event (simulated) time, s.
  /// Period of the dead-reckoning outputs for the gap count (GapDetector), s; 0 = learned.
  double dead_reckoning_period_s = 0.0;
};

/// Declares --out (required), --force, --progress-every-s and --dead-reckoning-period-s.
void add_recorder_options(Options& options);
/// Reads them. Throws ConfigError naming the flag (e.g. --out missing).
RecorderSettings recorder_settings_from(const Options& options);

class RecorderNode {
 public:
  /// Creates the output directory and files (std::runtime_error naming the path on failure) and the
  /// readers of runtime's participant (only samples of runtime's vehicle are recorded).
  RecorderNode(dds::ComponentRuntime& runtime, const RecorderSettings& settings);
  ~RecorderNode();

  /// Records until SIGINT/SIGTERM, then drains and closes the files. Returns the exit code (0).
  int run();

 private:
  /// Writes the adopted rows into the new files, syncs them, takes the marker over, removes the
  /// orphans, and starts each file's repeat check and gap count after its last adopted row.
  void adopt_resumed_rows();
  /// Every row written so far to the files' temporaries (a killed recorder leaves them on disk).
  void flush_files();
  /// Offers a row's stamp to the gap count (a hole is logged and goes to gaps.csv).
  void note_dead_reckoning_gap(double t_s);
  void note_navigation_gap(double t_s);
  void on_misalignment(const odonav::msg::Misalignment& m);
  void on_scale_factor(const odonav::msg::ScaleFactor& m);
  void write_scale_factor(const odonav::msg::ScaleFactor& m);
  void on_dead_reckoning(const odonav::msg::DeadReckoning& m);
  void on_navigation_position(const odonav::msg::NavigationPosition& m);
  void on_health(const odonav::msg::Health& h);
  void on_gnss(const odonav::msg::GnssFix& m);
  /// Writes gaps.csv; returns its summary for the final log line.
  std::string write_gaps();
  void tick();
  void progress(double t_s, double distance_m);
  void close_readers();

  dds::ComponentRuntime& runtime_;
  RecorderSettings settings_;
  OutputDirectory out_;  // checked (and created) before any file is opened
  ResumePlan resume_;    // decided (and the marker written) before any file is opened
  results::MisalignmentCsv misalignment_csv_;
  results::ScaleFactorCsv scale_factor_csv_;
  results::DeadReckoningCsv dead_reckoning_csv_;
  results::NavigationPositionCsv navigation_position_csv_;
  GapsCsv gaps_csv_;
  // Worker thread only:
  // Per file, a row at or before the last one written is a repeat (heartbeats, a restarted
  // producer's catch-up, the producers' history handed again to a restarted recorder).
  RowStamps misalignment_stamps_, scale_factor_stamps_, dead_reckoning_stamps_, navigation_stamps_;
  std::uint64_t navigation_rows_ = 0;
  std::uint64_t rows_[3] = {0, 0, 0};        // misalignment, scale factor, dead reckoning (this process)
  bool misalignment_replay_logged_ = false;  // a restarted calibration's catch-up was told once
  std::uint64_t adopted_rows_ = 0, adopted_torn_lines_ = 0;  // of the unfinished recording resumed
  std::string resumed_text_;                                 // what was adopted, for health
  double resumed_wall_s_ = 0.0;                              // steady clock, when it was adopted
  std::optional<double> resumed_from_s_;                     // its first row (s), any file
  bool unflushed_ = false;                                   // rows written since the last flush
  std::optional<odonav::msg::ScaleFactor> last_k_;
  SourceArbiter<odonav::msg::ScaleFactor> k_arbiter_;
  GapDetector dr_gaps_{settings_.dead_reckoning_period_s};          // holes in the dead-reckoning rows
  GapDetector navigation_gaps_{settings_.dead_reckoning_period_s};  // and in the navigation positions
  std::vector<OutputGap> dr_gap_list_, navigation_gap_list_;
  // Stamps for gaps.csv (s): the GNSS epochs received and the estimate rows written.
  std::vector<double> gnss_epochs_s_, misalignment_s_, scale_factor_s_;
  double last_gap_wall_s_ = 0.0;  // steady clock, when the last was found
  static constexpr double kGapReasonHold_s = 30.0;
  std::optional<double> next_progress_t_s_;
  double last_distance_m_ = 0.0;
  bool producers_matched_logged_ = false;
  std::map<std::string, std::string> component_health_;  // component -> last "state level reason"
  // Last members: destroyed first, so no callback reaches a half-destroyed node.
  std::unique_ptr<dds::Reader<odonav::msg::Misalignment>> misalignment_reader_;
  std::unique_ptr<dds::Reader<odonav::msg::ScaleFactor>> scale_factor_reader_;
  std::unique_ptr<dds::Reader<odonav::msg::DeadReckoning>> dead_reckoning_reader_;
  std::unique_ptr<dds::Reader<odonav::msg::NavigationPosition>> navigation_reader_;
  std::unique_ptr<dds::Reader<odonav::msg::Health>> health_reader_;
  std::unique_ptr<dds::Reader<odonav::msg::GnssFix>> gnss_reader_;
};

}  // namespace odonav::recorder
