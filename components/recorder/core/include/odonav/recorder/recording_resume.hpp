#pragma once
// Resuming an unfinished recording (README.md, "Restart: the recording resumes"), without DDS.
//
// odonav-recorder writes its files through CsvWriter: rows go to `<file>.tmp-<pid>` and take the
// real name at a clean exit. While it records, the directory holds the marker kRecordingMarker
// (its pid and vehicle), removed as the very last step of a clean exit. So at start:
// - no marker: the last recording in the directory was finished (or there was none): a new one
//   starts and replaces its files at its clean exit, as every odonav run does;
// - a marker of a recorder still running: refused (two recorders would replace each other's files);
// - a marker of another vehicle: refused, its rows are left as they are;
// - a marker of a dead recorder of the same vehicle: its recording is adopted. For each data file
//   its orphan `<file>.tmp-<pid>`, or, when the process was killed while closing, the committed
//   `<file>` (if written after the marker): the header must be this recorder's, the complete rows
//   are taken, a torn last line (no newline: the process died while writing it) is dropped and
//   counted. The new process writes them first into its own files, syncs them, takes the marker
//   over, and only then removes the orphans (ResumePlan::remove): a kill at any point leaves the
//   rows on disk under a name the next start adopts.
// Rows received after the restart that are stamped at or before the last adopted one are repeats
// (RowStamps), so the producers' history handed to the new readers fills the downtime only.
#include <cstdint>
#include <functional>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace odonav::recorder {

/// File name of the marker of a recording in progress.
inline constexpr const char* kRecordingMarker = ".odonav-recording";

/// A recording that cannot be resumed (nor replaced without losing rows); what() says which file and why.
class ResumeError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct RecordingMarker {
  long pid = 0;
  std::string vehicle_id;
};
/// "pid <pid>\nvehicle_id <id>\n".
std::string marker_text(const RecordingMarker& m);
/// Throws ResumeError naming `path` when the text is not marker_text's.
RecordingMarker parse_marker(const std::string& text, const std::string& path);

/// The complete rows of one file of an unfinished recording.
struct AdoptedRows {
  std::string text;            ///< the rows, each ending in '\n', without the header
  std::vector<double> t_s;     ///< each row's stamp (first column), in file order
  std::size_t torn_lines = 0;  ///< an incomplete last line dropped (0 or 1)
  std::size_t rows() const { return t_s.size(); }
  std::optional<double> last_t_s() const { return t_s.empty() ? std::nullopt : std::optional<double>(t_s.back()); }
};

/// The rows of `text`, a CSV file as CsvWriter writes it with `columns`: the first line must be the
/// header; each complete row must have the header's field count and a number first; a last line
/// without '\n' is torn: dropped and counted. An empty file or a torn header has no rows. Throws
/// ResumeError naming `path` and the line otherwise.
AdoptedRows adopt_rows(const std::string& text, const std::vector<std::string>& columns, const std::string& path);

/// A data file of the recording and its header.
struct RecordingFile {
  std::string name;
  std::vector<std::string> columns;
};

struct AdoptedFile {
  std::string name;  ///< e.g. "dead_reckoning.csv"
  std::string from;  ///< the file the rows were read from
  AdoptedRows rows;
};

struct ResumePlan {
  std::optional<RecordingMarker> previous;  ///< the unfinished recording's marker, when one is adopted
  std::vector<AdoptedFile> files;           ///< the data files with something adopted
  std::vector<std::string> remove;          ///< its files, removed once the rows are safely in the new ones
  std::vector<std::string> ignored;         ///< orphans of no recording adopted: left as they are
  bool resumed() const { return previous.has_value(); }
};

/// What of `dir` to adopt (the file comment's rules). `files`: the data files (rows adopted);
/// `recomputed`: files of the recording rebuilt at the end (gaps.csv), removed with the orphans.
/// pid_alive(pid): whether the recorder of that pid still runs. An orphan named with `own_pid`
/// (a pid reused after a reboot or in a container) is renamed `<file>.adopt-<pid>` first, as this
/// process's own writer would replace it. Throws ResumeError (the rows stay where they are).
ResumePlan plan_resume(const std::string& dir, const std::string& vehicle_id, const std::vector<RecordingFile>& files,
                       const std::vector<std::string>& recomputed, long own_pid,
                       const std::function<bool(long)>& pid_alive);

/// One file's last stamp recorded and the rows not written: a row stamped at or before the last one
/// is a repeat (an estimate heartbeat, a producer's history handed again to a restarted recorder, a
/// restarted producer's catch-up), counted and not written.
struct RowStamps {
  std::optional<double> last_t_s;
  std::uint64_t repeats = 0;
  /// True (and the stamp becomes the last) for a new row; false, counted, for a repeat.
  bool admit(double t_s) {
    if (last_t_s && t_s <= *last_t_s) {
      ++repeats;
      return false;
    }
    last_t_s = t_s;
    return true;
  }
};

}  // namespace odonav::recorder
