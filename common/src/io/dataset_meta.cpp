// meta.json of a dataset directory (docs/DATASET.md): read with type checks, written with the
// unknown keys carried through.
#include <spdlog/spdlog.h>

#include <cmath>
#include <nlohmann/json.hpp>

#include "dataset_internal.hpp"
#include "odonav/dataset.hpp"

namespace odonav::dataset_detail {

namespace {

// Reads a JSON value at a dotted key path into `out` when present and not null.
void read_meta_string(const nlohmann::json& object, const char* key, const std::string& path, std::string& out) {
  const auto it = object.find(key);
  if (it == object.end() || it->is_null()) return;
  if (!it->is_string()) throw DatasetError(path + ": key '" + key + "' must be a string");
  out = it->get<std::string>();
}

std::optional<double> read_meta_number(const nlohmann::json& root, const char* section, const char* key,
                                       const std::string& path) {
  const auto sec = root.find(section);
  if (sec == root.end() || sec->is_null()) return std::nullopt;
  if (!sec->is_object()) throw DatasetError(path + ": key '" + section + "' must be an object");
  const auto it = sec->find(key);
  if (it == sec->end() || it->is_null()) return std::nullopt;
  if (!it->is_number()) {
    throw DatasetError(path + ": key '" + section + "." + key + "' must be a number");
  }
  const double value = it->get<double>();
  if (!std::isfinite(value)) throw DatasetError(path + ": key '" + section + "." + key + "' is not finite");
  return value;
}

}  // namespace

DatasetMeta read_meta(const std::string& path) {
  DatasetMeta meta;
  meta.raw_json = read_whole_file(path);
  nlohmann::json root;
  try {
    root = nlohmann::json::parse(meta.raw_json);
  } catch (const nlohmann::json::parse_error& e) {
    // e.what() carries the parser's position ("at line 3, column 5"); byte is the offset.
    throw DatasetError(path + ": malformed JSON (byte " + std::to_string(e.byte) + "): " + e.what());
  }
  if (!root.is_object()) throw DatasetError(path + ": the top level must be a JSON object");
  read_meta_string(root, "format", path, meta.format);
  read_meta_string(root, "vehicle_id", path, meta.vehicle_id);
  read_meta_string(root, "description", path, meta.description);
  meta.k_nominal_m_per_pulse = read_meta_number(root, "odometer", "k_nominal_m_per_pulse", path);
  if (meta.k_nominal_m_per_pulse && !(*meta.k_nominal_m_per_pulse > 0.0 && *meta.k_nominal_m_per_pulse <= 10.0))
    throw DatasetError(path + ": key 'odometer.k_nominal_m_per_pulse' = " +
                       std::to_string(*meta.k_nominal_m_per_pulse) + ": the nominal K must be in (0, 10] m/pulse");
  meta.k_nominal_sigma_percent = read_meta_number(root, "odometer", "k_nominal_sigma_percent", path);
  if (meta.k_nominal_sigma_percent && !(*meta.k_nominal_sigma_percent > 0.0 && *meta.k_nominal_sigma_percent <= 100.0))
    throw DatasetError(path + ": key 'odometer.k_nominal_sigma_percent' = " +
                       std::to_string(*meta.k_nominal_sigma_percent) + ": must be in (0, 100] %");
  meta.truth_misalignment_heading_deg = read_meta_number(root, "truth", "misalignment_heading_deg", path);
  meta.truth_misalignment_pitch_deg = read_meta_number(root, "truth", "misalignment_pitch_deg", path);
  if (root.contains("gnss") && root["gnss"].is_object() && root["gnss"].contains("lever_arm_m")) {
    const nlohmann::json& arm = root["gnss"]["lever_arm_m"];
    if (!arm.is_array() || arm.size() != 3 || !arm[0].is_number() || !arm[1].is_number() || !arm[2].is_number())
      throw DatasetError(path + ": key 'gnss.lever_arm_m' must be an array of three numbers [x, y, z] in metres");
    meta.gnss_lever_arm_m = Eigen::Vector3d(arm[0].get<double>(), arm[1].get<double>(), arm[2].get<double>());
    if (!meta.gnss_lever_arm_m->allFinite()) throw DatasetError(path + ": key 'gnss.lever_arm_m' is not finite");
    if (meta.gnss_lever_arm_m->cwiseAbs().maxCoeff() > kMaxLeverArmComponent_m)
      throw DatasetError(path + ": key 'gnss.lever_arm_m' has a component beyond +-" +
                         std::to_string(static_cast<int>(kMaxLeverArmComponent_m)) +
                         " m: an antenna on a land vehicle is within that of the INS");
  }
  if (meta.format != "odonav-dataset/1") {
    spdlog::warn("{}: format '{}' is not 'odonav-dataset/1'; reading it as format v1", path, meta.format);
  }
  return meta;
}

namespace {

// Sets section.key to value, or removes it (and an emptied section) when value is nullopt.
void set_meta_number(nlohmann::json& root, const char* section, const char* key, const std::optional<double>& value) {
  if (value) {
    if (!root.contains(section) || !root[section].is_object()) root[section] = nlohmann::json::object();
    root[section][key] = *value;
    return;
  }
  if (root.contains(section) && root[section].is_object()) {
    root[section].erase(key);
    if (root[section].empty()) root.erase(section);
  }
}

}  // namespace

std::string meta_json(const std::string& path, const DatasetMeta& meta) {
  nlohmann::json root = nlohmann::json::object();
  if (!meta.raw_json.empty()) {
    try {
      root = nlohmann::json::parse(meta.raw_json);
    } catch (const nlohmann::json::parse_error& e) {
      throw DatasetError(path + ": cannot carry meta.raw_json, it is malformed JSON: " + e.what());
    }
    if (!root.is_object()) throw DatasetError(path + ": cannot carry meta.raw_json, it is not a JSON object");
  }
  root["format"] = meta.format;
  const auto set_string = [&](const char* key, const std::string& value) {
    if (value.empty())
      root.erase(key);
    else
      root[key] = value;
  };
  set_string("vehicle_id", meta.vehicle_id);
  set_string("description", meta.description);
  set_meta_number(root, "odometer", "k_nominal_m_per_pulse", meta.k_nominal_m_per_pulse);
  set_meta_number(root, "odometer", "k_nominal_sigma_percent", meta.k_nominal_sigma_percent);
  set_meta_number(root, "truth", "misalignment_heading_deg", meta.truth_misalignment_heading_deg);
  set_meta_number(root, "truth", "misalignment_pitch_deg", meta.truth_misalignment_pitch_deg);
  if (meta.gnss_lever_arm_m) {
    if (!meta.gnss_lever_arm_m->allFinite()) throw DatasetError(path + ": cannot write a non-finite lever arm");
    root["gnss"]["lever_arm_m"] = {meta.gnss_lever_arm_m->x(), meta.gnss_lever_arm_m->y(), meta.gnss_lever_arm_m->z()};
  }
  for (const auto* value : {&meta.k_nominal_m_per_pulse, &meta.k_nominal_sigma_percent,
                            &meta.truth_misalignment_heading_deg, &meta.truth_misalignment_pitch_deg}) {
    if (*value && !std::isfinite(**value)) throw DatasetError(path + ": cannot write a non-finite number");
  }
  return root.dump(2) + "\n";
}

}  // namespace odonav::dataset_detail
