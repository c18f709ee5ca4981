#include "odonav/recorder/recording_resume.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <system_error>

namespace odonav::recorder {

namespace fs = std::filesystem;

namespace {

std::string read_all(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw ResumeError("cannot read '" + path.string() + "' of the unfinished recording");
  std::ostringstream text;
  text << in.rdbuf();
  if (in.bad()) throw ResumeError("cannot read '" + path.string() + "' of the unfinished recording");
  return text.str();
}

std::string header_line(const std::vector<std::string>& columns) {
  std::string h;
  for (std::size_t i = 0; i < columns.size(); ++i) h += (i ? "," : "") + columns[i];
  return h;
}

/// `<name>.tmp-<pid>` -> pid, or nullopt for another name.
std::optional<long> orphan_pid(const std::string& file, const std::string& name) {
  const std::string prefix = name + ".tmp-";
  if (file.size() <= prefix.size() || file.compare(0, prefix.size(), prefix) != 0) return std::nullopt;
  long pid = 0;
  const char* first = file.data() + prefix.size();
  const char* last = file.data() + file.size();
  const auto [end, ec] = std::from_chars(first, last, pid);
  if (ec != std::errc() || end != last || pid <= 0) return std::nullopt;
  return pid;
}

}  // namespace

std::string marker_text(const RecordingMarker& m) {
  return "pid " + std::to_string(m.pid) + "\nvehicle_id " + m.vehicle_id + "\n";
}

RecordingMarker parse_marker(const std::string& text, const std::string& path) {
  std::istringstream in(text);
  std::string key_pid, key_vehicle;
  RecordingMarker m;
  if (!(in >> key_pid >> m.pid) || key_pid != "pid" || m.pid <= 0 || !(in >> key_vehicle) ||
      key_vehicle != "vehicle_id")
    throw ResumeError("'" + path + "' is not a recording marker (expected \"pid N\", then \"vehicle_id ID\")");
  in.get();  // the space after the key; the id is the rest of the line (it may be empty)
  std::getline(in, m.vehicle_id);
  return m;
}

AdoptedRows adopt_rows(const std::string& text, const std::vector<std::string>& columns, const std::string& path) {
  AdoptedRows out;
  const std::string header = header_line(columns);
  const std::size_t header_end = text.find('\n');
  if (header_end == std::string::npos) {
    // Nothing, or a header cut short: no row was written yet.
    if (header.compare(0, text.size(), text) != 0)
      throw ResumeError("'" + path + "' line 1: not the header of this file (expected \"" + header + "\")");
    if (!text.empty()) out.torn_lines = 1;
    return out;
  }
  if (text.compare(0, header_end, header) != 0 || header_end != header.size())
    throw ResumeError("'" + path + "' line 1: header \"" + text.substr(0, std::min<std::size_t>(header_end, 200)) +
                      "\" is not this recorder's \"" + header + "\" (another version or another file): not adopted");
  std::size_t begin = header_end + 1;
  std::size_t complete_end = begin;  // end of the last complete row
  std::size_t line_no = 1;
  while (begin < text.size()) {
    ++line_no;
    const std::size_t end = text.find('\n', begin);
    if (end == std::string::npos) {
      out.torn_lines = 1;  // the process died while writing this line
      break;
    }
    const std::size_t fields = 1 + static_cast<std::size_t>(std::count(text.begin() + begin, text.begin() + end, ','));
    if (fields != columns.size())
      throw ResumeError("'" + path + "' line " + std::to_string(line_no) + ": " + std::to_string(fields) +
                        " fields, the header has " + std::to_string(columns.size()));
    const std::size_t comma = text.find(',', begin);
    double t = 0.0;
    const auto [p, ec] = std::from_chars(text.data() + begin, text.data() + comma, t);
    if (ec != std::errc() || p != text.data() + comma || !std::isfinite(t))
      throw ResumeError("'" + path + "' line " + std::to_string(line_no) + ": t \"" +
                        text.substr(begin, comma - begin) + "\" is not a number");
    out.t_s.push_back(t);
    begin = end + 1;
    complete_end = begin;
  }
  out.text = text.substr(header_end + 1, complete_end - (header_end + 1));
  return out;
}

ResumePlan plan_resume(const std::string& dir, const std::string& vehicle_id, const std::vector<RecordingFile>& files,
                       const std::vector<std::string>& recomputed, long own_pid,
                       const std::function<bool(long)>& pid_alive) {
  ResumePlan plan;
  const fs::path root(dir);
  const fs::path marker_path = root / kRecordingMarker;
  std::error_code ec;
  std::vector<std::string> names;
  for (const auto& f : files) names.push_back(f.name);
  names.insert(names.end(), recomputed.begin(), recomputed.end());
  // Every orphan of the recording's files, by pid.
  std::vector<std::pair<std::string, long>> orphans;
  for (const auto& entry : fs::directory_iterator(root, ec)) {
    const std::string file = entry.path().filename().string();
    for (const auto& name : names)
      if (const auto pid = orphan_pid(file, name)) orphans.emplace_back(file, *pid);
  }
  if (ec) throw ResumeError("cannot list '" + dir + "': " + ec.message());

  if (!fs::exists(marker_path, ec)) {
    // No recording in progress: orphans are another tool's or of a recorder without the marker;
    // nothing says which vehicle they hold, so they are left as they are.
    for (const auto& [file, pid] : orphans) plan.ignored.push_back((root / file).string());
    return plan;
  }
  const RecordingMarker previous = parse_marker(read_all(marker_path), marker_path.string());
  if (previous.pid != own_pid && pid_alive(previous.pid))
    throw ResumeError("'" + dir + "' is being recorded by a running odonav-recorder (pid " +
                      std::to_string(previous.pid) + ", " + marker_path.string() + "): use another --out");
  if (previous.vehicle_id != vehicle_id)
    throw ResumeError("'" + dir + "' holds an unfinished recording of vehicle '" + previous.vehicle_id +
                      "' (odonav-recorder pid " + std::to_string(previous.pid) + " did not finish), not of '" +
                      vehicle_id + "': its rows are left as they are; use another --out, or move them away");
  for (const auto& [file, pid] : orphans)
    if (pid != previous.pid) plan.ignored.push_back((root / file).string());

  plan.previous = previous;
  const auto marker_time = fs::last_write_time(marker_path, ec);
  const std::string suffix = ".tmp-" + std::to_string(previous.pid);
  const std::string aside = ".adopt-" + std::to_string(previous.pid);
  auto take_over = [&](const std::string& name) -> std::optional<fs::path> {
    const fs::path orphan = root / (name + suffix);
    const fs::path moved = root / (name + aside);
    if (fs::exists(orphan, ec)) {
      if (previous.pid != own_pid) return orphan;
      // This process's writer would replace the orphan of its own (reused) pid: moved aside first.
      fs::rename(orphan, moved, ec);
      if (ec) throw ResumeError("cannot move '" + orphan.string() + "' aside: " + ec.message());
      return moved;
    }
    if (fs::exists(moved, ec)) return moved;  // moved aside by a start killed before it took over
    // Committed by the recording while it closed (and not by an earlier one): adopted, not removed.
    const fs::path committed = root / name;
    if (fs::is_regular_file(committed, ec) && fs::last_write_time(committed, ec) >= marker_time) return committed;
    return std::nullopt;
  };
  for (const auto& f : files) {
    const auto from = take_over(f.name);
    if (!from) continue;
    AdoptedFile a;
    a.name = f.name;
    a.from = from->string();
    a.rows = adopt_rows(read_all(*from), f.columns, a.from);
    if (from->filename().string() != f.name) plan.remove.push_back(a.from);
    plan.files.push_back(std::move(a));
  }
  for (const auto& name : recomputed)
    if (const auto from = take_over(name); from && from->filename().string() != name)
      plan.remove.push_back(from->string());
  return plan;
}

}  // namespace odonav::recorder
