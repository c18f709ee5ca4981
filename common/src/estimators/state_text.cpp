// The text format of save_state() / restore_state() (see estimator_internal.hpp).
#include <cerrno>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "estimator_internal.hpp"

namespace odonav::estimators_internal {

namespace {

constexpr const char* kMagic = "odonav-scale-factor-state";
constexpr const char* kVersion = "1";

uint64_t fnv1a64(const std::string& text) {
  uint64_t hash = 1469598103934665603ull;
  for (unsigned char c : text) {
    hash ^= c;
    hash *= 1099511628211ull;
  }
  return hash;
}

std::string hex_double(double value) {
  char buffer[64];
  std::snprintf(buffer, sizeof buffer, "%a", value);
  return buffer;
}

// Every parameter as (name, value); integers are exact in a double over their valid ranges.
std::vector<std::pair<std::string, double>> param_fields(const ScaleFactorEstimatorParams& p) {
  return {{"k_prior_m_per_pulse", p.k_prior_m_per_pulse},
          {"prior_weight_pulses2", p.prior_weight_pulses2},
          {"sigma_y_floor_m", p.sigma_y_floor_m},
          {"sigma_y_ewma_alpha", p.sigma_y_ewma_alpha},
          {"converged_rel_sigma", p.converged_rel_sigma},
          {"min_samples", static_cast<double>(p.min_samples)},
          {"forgetting_factor", p.forgetting_factor},
          {"window_length", static_cast<double>(p.window_length)},
          {"resum_interval", static_cast<double>(p.resum_interval)},
          {"lambda_min", p.lambda_min},
          {"vff_c_m2", p.vff_c_m2},
          {"vff_kappa", p.vff_kappa},
          {"vff_change_threshold", p.vff_change_threshold},
          {"vff_change_drift", p.vff_change_drift},
          {"sigma_v_mps", p.sigma_v_mps},
          {"sample_interval_s", p.sample_interval_s},
          {"coarse_min_length_m", p.coarse_min_length_m},
          {"coarse_position_sigma_m", p.coarse_position_sigma_m},
          {"kf_rel_process_noise_per_sqrt_s", p.kf_rel_process_noise_per_sqrt_s},
          {"kf_change_threshold", p.kf_change_threshold},
          {"kf_change_drift", p.kf_change_drift},
          {"kf_change_rel_sigma", p.kf_change_rel_sigma}};
}

double parse_double(const std::string& token, const std::string& key) {
  errno = 0;
  char* end = nullptr;
  const double value = std::strtod(token.c_str(), &end);
  if (token.empty() || end != token.c_str() + token.size() || errno == ERANGE)
    throw std::runtime_error("estimator state: field '" + key + "' has a bad number '" + token + "'");
  return value;
}

}  // namespace

StateWriter::StateWriter(const std::string& estimator_name) {
  text_ = std::string(kMagic) + " " + kVersion + "\nestimator " + estimator_name + "\n";
}

void StateWriter::put(const std::string& key, double value) { text_ += key + " " + hex_double(value) + "\n"; }

void StateWriter::put_u64(const std::string& key, uint64_t value) { text_ += key + " " + std::to_string(value) + "\n"; }

void StateWriter::put_row(const std::string& key, const std::vector<double>& values) {
  text_ += key;
  for (double v : values) text_ += " " + hex_double(v);
  text_ += "\n";
}

void StateWriter::put_params(const ScaleFactorEstimatorParams& params) {
  for (const auto& [name, value] : param_fields(params)) put("param." + name, value);
}

std::string StateWriter::finish() {
  char buffer[40];
  std::snprintf(buffer, sizeof buffer, "%016" PRIx64, fnv1a64(text_));
  return text_ + "checksum " + buffer + "\n";
}

StateReader::StateReader(const std::string& text, const std::string& estimator_name) : estimator_(estimator_name) {
  const std::string where = "estimator state for '" + estimator_name + "': ";
  const std::size_t checksum_at = text.rfind("checksum ");
  if (checksum_at == std::string::npos || (checksum_at > 0 && text[checksum_at - 1] != '\n'))
    throw std::runtime_error(where + "no checksum line (truncated or not a state text)");
  std::string stated = text.substr(checksum_at + 9);
  while (!stated.empty() && (stated.back() == '\n' || stated.back() == '\r')) stated.pop_back();
  char computed[40];
  std::snprintf(computed, sizeof computed, "%016" PRIx64, fnv1a64(text.substr(0, checksum_at)));
  if (stated != computed)
    throw std::runtime_error(where + "checksum mismatch (stated " + stated + ", computed " + computed +
                             "): the text is corrupt");

  std::istringstream lines(text.substr(0, checksum_at));
  std::string line;
  std::size_t line_number = 0;
  while (std::getline(lines, line)) {
    ++line_number;
    std::istringstream tokens(line);
    std::vector<std::string> fields;
    for (std::string token; tokens >> token;) fields.push_back(token);
    if (fields.empty()) continue;
    if (line_number == 1) {
      if (fields.size() != 2 || fields[0] != kMagic)
        throw std::runtime_error(where + "not an odonav estimator state (first line '" + line + "')");
      if (fields[1] != kVersion)
        throw std::runtime_error(where + "unsupported state version " + fields[1] + " (this build reads " + kVersion +
                                 ")");
      continue;
    }
    if (line_number == 2) {
      if (fields.size() != 2 || fields[0] != "estimator")
        throw std::runtime_error(where + "second line must name the estimator, got '" + line + "'");
      if (fields[1] != estimator_name)
        throw std::runtime_error(where + "the state was saved by estimator '" + fields[1] + "'");
      continue;
    }
    const std::string key = fields[0];
    fields.erase(fields.begin());
    if (key == "row")
      rows_[key].push_back(fields);
    else if (!single_.emplace(key, fields).second)
      throw std::runtime_error(where + "field '" + key + "' appears twice");
  }
  if (line_number < 2) throw std::runtime_error(where + "the text has no header");
}

const std::vector<std::string>& StateReader::values(const std::string& key) const {
  const auto it = single_.find(key);
  if (it == single_.end())
    throw std::runtime_error("estimator state for '" + estimator_ + "': missing field '" + key + "'");
  if (it->second.size() != 1)
    throw std::runtime_error("estimator state for '" + estimator_ + "': field '" + key + "' must have one value");
  return it->second;
}

double StateReader::get(const std::string& key) const { return parse_double(values(key)[0], key); }

uint64_t StateReader::get_u64(const std::string& key) const {
  const std::string& token = values(key)[0];
  errno = 0;
  char* end = nullptr;
  const unsigned long long value = std::strtoull(token.c_str(), &end, 10);
  if (token.empty() || token[0] == '-' || end != token.c_str() + token.size() || errno == ERANGE)
    throw std::runtime_error("estimator state for '" + estimator_ + "': field '" + key + "' has a bad count '" + token +
                             "'");
  return value;
}

std::vector<std::vector<double>> StateReader::rows(const std::string& key, std::size_t width) const {
  std::vector<std::vector<double>> out;
  const auto it = rows_.find(key);
  if (it == rows_.end()) return out;
  for (const auto& fields : it->second) {
    if (fields.size() != width)
      throw std::runtime_error("estimator state for '" + estimator_ + "': a '" + key + "' line has " +
                               std::to_string(fields.size()) + " values, expected " + std::to_string(width));
    std::vector<double> row;
    for (const std::string& f : fields) row.push_back(parse_double(f, key));
    out.push_back(std::move(row));
  }
  return out;
}

void put_change_detector(StateWriter& out, const CusumChangeDetector& detector) {
  const CusumChangeDetector::State s = detector.state();
  out.put("cusum_high", s.high);
  out.put("cusum_low", s.low);
  out.put_u64("cusum_high_start", s.high_start);
  out.put_u64("cusum_low_start", s.low_start);
  out.put_u64("changes_detected", s.changes);
}

CusumChangeDetector::State get_change_detector(const StateReader& in) {
  CusumChangeDetector::State s;
  s.high = in.get("cusum_high");
  s.low = in.get("cusum_low");
  s.high_start = in.get_u64("cusum_high_start");
  s.low_start = in.get_u64("cusum_low_start");
  s.changes = in.get_u64("changes_detected");
  if (!(s.high >= 0.0) || !(s.low >= 0.0) || !std::isfinite(s.high) || !std::isfinite(s.low))
    throw std::runtime_error("estimator state: change detector sums (cusum_high, cusum_low) out of range");
  return s;
}

void StateReader::check_params(const ScaleFactorEstimatorParams& params) const {
  for (const auto& [name, value] : param_fields(params)) {
    const double saved = get("param." + name);
    // Bitwise equality on purpose: a different parameter would not continue identically.
    if (!(saved == value))
      throw std::runtime_error("estimator state for '" + estimator_ + "': saved with " + name + " = " +
                               hex_double(saved) + " but this estimator has " + hex_double(value));
  }
}

}  // namespace odonav::estimators_internal
