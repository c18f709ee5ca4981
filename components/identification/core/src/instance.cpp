#include "odonav/identification/instance.hpp"

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <stdexcept>

#include "odonav/identification/checkpoint.hpp"

namespace odonav::identification {

namespace {
uint64_t fnv1a64(const std::string& text) {
  uint64_t h = 1469598103934665603ULL;
  for (unsigned char c : text) {
    h ^= c;
    h *= 1099511628211ULL;
  }
  return h;
}

void check_vehicle(const std::string& vehicle_id) {
  // checkpoint_path's check: letters, digits, '.', '_', '-' (it becomes a file name).
  (void)checkpoint_path(".", vehicle_id);
}
}  // namespace

void validate_identification_instance(const std::string& instance) {
  auto bad = [&](const std::string& why) {
    throw std::invalid_argument("identification instance '" + instance + "': " + why);
  };
  if (instance.empty()) bad("is empty");
  if (instance.size() > 64) bad("is longer than 64 characters");
  for (char c : instance) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '.' ||
                    c == '_' || c == '-' || c == '/';
    if (!ok) bad("only letters, digits, '.', '_', '-' and '/' are allowed");
  }
  if (instance.front() == '/' || instance.back() == '/') bad("must not start or end with '/'");
  if (instance.find("//") != std::string::npos) bad("must not hold '//'");
  if (instance.find("..") != std::string::npos) bad("must not hold '..'");
  if (instance == "command") bad("'command' is reserved (a commanded K is not an identification's estimate)");
}

std::string instance_file_part(const std::string& instance) {
  validate_identification_instance(instance);
  std::string part = instance;
  for (char& c : part)
    if (c == '/') c = '_';
  return part;
}

std::string instance_checkpoint_path(const std::string& state_dir, const std::string& vehicle_id,
                                     const std::string& instance) {
  const std::string part = instance_file_part(instance);
  const std::string default_path = checkpoint_path(state_dir, vehicle_id);  // checks the vehicle id
  if (instance == kDefaultIdentificationInstance) return default_path;
  return (std::filesystem::path(state_dir) / (part + "-" + vehicle_id + ".ckpt")).string();
}

std::string persistence_db_path(const std::string& state_dir, const std::string& vehicle_id,
                                const std::string& instance) {
  const std::string part = instance_file_part(instance);
  check_vehicle(vehicle_id);
  return (std::filesystem::path(state_dir) / (vehicle_id + "-" + part + ".db")).string();
}

std::string persistence_guid(const std::string& vehicle_id, const std::string& instance) {
  validate_identification_instance(instance);
  if (vehicle_id.empty()) throw std::invalid_argument("persistence_guid: the vehicle id is empty");
  const uint64_t h1 = fnv1a64("odonav-persistence\n" + vehicle_id + "\n" + instance);
  const uint64_t h2 = fnv1a64(instance + "\n" + vehicle_id);
  unsigned char prefix[12];
  prefix[0] = 0x6f;  // 'o'
  prefix[1] = 0x64;  // 'd'
  for (int i = 0; i < 8; ++i) prefix[2 + i] = static_cast<unsigned char>(h1 >> (56 - 8 * i));
  prefix[10] = static_cast<unsigned char>(h2 >> 56);
  prefix[11] = static_cast<unsigned char>(h2 >> 48);
  std::string text;
  char byte[4];
  for (int i = 0; i < 12; ++i) {
    std::snprintf(byte, sizeof byte, "%02x", prefix[i]);
    text += byte;
    text += i < 11 ? "." : "|";
  }
  text += "00.00.01.02";
  return text;
}

}  // namespace odonav::identification
