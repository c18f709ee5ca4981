#include "odonav/run_provenance.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include <nlohmann/json.hpp>

namespace odonav {

namespace {

// FNV-1a, 64 bit: a content digest, not a security measure (a user who wants to fool the check can).
struct Fnv64 {
  uint64_t h = 14695981039346656037ull;
  void bytes(const void* p, std::size_t n) {
    const auto* b = static_cast<const unsigned char*>(p);
    for (std::size_t i = 0; i < n; ++i) {
      h ^= b[i];
      h *= 1099511628211ull;
    }
  }
  void number(double v) { bytes(&v, sizeof v); }
  void number(int64_t v) { bytes(&v, sizeof v); }
};

double time_span_start(const Dataset& d) {
  double t = std::numeric_limits<double>::infinity();
  if (!d.odometer.empty()) t = std::min(t, d.odometer.front().t_s);
  if (!d.gnss.empty()) t = std::min(t, d.gnss.front().t_s);
  if (!d.ins.empty()) t = std::min(t, d.ins.front().t_s);
  return t;
}

double time_span_end(const Dataset& d) {
  double t = -std::numeric_limits<double>::infinity();
  if (!d.odometer.empty()) t = std::max(t, d.odometer.back().t_s);
  if (!d.gnss.empty()) t = std::max(t, d.gnss.back().t_s);
  if (!d.ins.empty()) t = std::max(t, d.ins.back().t_s);
  return t;
}

std::string number_text(double v) {
  std::ostringstream s;
  s.precision(10);
  s << v;
  return s.str();
}

}  // namespace

DatasetFingerprint::DatasetFingerprint(const std::string& vehicle_id) {
  Fnv64 f;
  f.bytes(vehicle_id.data(), vehicle_id.size());
  h_ = f.h;
}

void DatasetFingerprint::add(const GnssSample& g) {
  if (odometer_started_) throw std::logic_error("DatasetFingerprint: a GNSS sample after an odometer sample");
  Fnv64 f{h_};
  f.number(g.t_s);
  f.number(g.position.lat_rad);
  f.number(g.position.lon_rad);
  h_ = f.h;
}

void DatasetFingerprint::add(const OdometerSample& o) {
  odometer_started_ = true;
  Fnv64 f{h_};
  f.number(o.t_s);
  f.number(static_cast<int64_t>(o.pulses));
  h_ = f.h;
}

std::string DatasetFingerprint::text() const {
  char text[17];
  std::snprintf(text, sizeof text, "%016llx", static_cast<unsigned long long>(h_));
  return text;
}

std::string dataset_fingerprint(const Dataset& d) {
  DatasetFingerprint f(d.meta.vehicle_id);
  for (const GnssSample& g : d.gnss) f.add(g);
  for (const OdometerSample& o : d.odometer) f.add(o);
  return f.text();
}

RunProvenance provenance_of(const Dataset& d, const std::string& tool) {
  RunProvenance p;
  p.tool = tool;
  p.vehicle_id = d.meta.vehicle_id;
  p.dataset_fingerprint = dataset_fingerprint(d);
  const double t0 = time_span_start(d), t1 = time_span_end(d);
  if (std::isfinite(t0)) p.t_first_s = t0;
  if (std::isfinite(t1)) p.t_last_s = t1;
  return p;
}

std::string provenance_json(const RunProvenance& p) {
  nlohmann::json j;
  j["tool"] = p.tool;
  j["vehicle_id"] = p.vehicle_id;
  if (!p.dds_vehicle_id.empty()) j["dds_vehicle_id"] = p.dds_vehicle_id;
  j["dataset_fingerprint"] = p.dataset_fingerprint;
  j["t_first_s"] = std::isfinite(p.t_first_s) ? nlohmann::json(p.t_first_s) : nlohmann::json(nullptr);
  j["t_last_s"] = std::isfinite(p.t_last_s) ? nlohmann::json(p.t_last_s) : nlohmann::json(nullptr);
  return j.dump(2) + "\n";
}

std::optional<RunProvenance> read_provenance(const std::string& folder) {
  const std::string path = folder + "/" + kProvenanceFile;
  std::ifstream in(path, std::ios::binary);
  if (!in) return std::nullopt;
  std::stringstream text;
  text << in.rdbuf();
  try {
    const nlohmann::json j = nlohmann::json::parse(text.str());
    RunProvenance p;
    p.tool = j.at("tool").get<std::string>();
    p.vehicle_id = j.at("vehicle_id").get<std::string>();
    p.dds_vehicle_id = j.value("dds_vehicle_id", std::string());
    p.dataset_fingerprint = j.value("dataset_fingerprint", std::string());
    if (j.contains("t_first_s") && j["t_first_s"].is_number()) p.t_first_s = j["t_first_s"].get<double>();
    if (j.contains("t_last_s") && j["t_last_s"].is_number()) p.t_last_s = j["t_last_s"].get<double>();
    return p;
  } catch (const nlohmann::json::exception&) {
    throw std::runtime_error(path + ": not an odonav provenance record (expected JSON with tool, vehicle_id)");
  }
}

std::vector<std::string> provenance_mismatches(const std::optional<RunProvenance>& r, double rows_t_first_s,
                                               double rows_t_last_s, const Dataset& d, double tolerance_s) {
  std::vector<std::string> out;
  if (r) {
    if (!r->vehicle_id.empty() && !d.meta.vehicle_id.empty() && r->vehicle_id != d.meta.vehicle_id)
      out.push_back("the results are of vehicle '" + r->vehicle_id + "', the dataset of '" + d.meta.vehicle_id + "'");
    if (!r->dataset_fingerprint.empty()) {
      const std::string fp = dataset_fingerprint(d);
      if (fp != r->dataset_fingerprint)
        out.push_back("the results were computed from another recording (dataset fingerprint " +
                      r->dataset_fingerprint + ", this dataset's is " + fp + ")");
    }
  }
  const double t0 = time_span_start(d), t1 = time_span_end(d);
  if (std::isfinite(t0) && std::isfinite(t1) && std::isfinite(rows_t_first_s) && std::isfinite(rows_t_last_s) &&
      (rows_t_first_s < t0 - tolerance_s || rows_t_last_s > t1 + tolerance_s))
    out.push_back("the results span t = " + number_text(rows_t_first_s) + " .. " + number_text(rows_t_last_s) +
                  " s, outside the dataset's " + number_text(t0) + " .. " + number_text(t1) + " s");
  return out;
}

}  // namespace odonav
