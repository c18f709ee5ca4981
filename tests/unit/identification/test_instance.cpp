// Hot-standby instance names: validation, the state files they name, and the fixed persistence
// GUID (deterministic, distinct per vehicle and instance, in Fast DDS's text form).
#include <gtest/gtest.h>

#include <regex>
#include <set>

#include "odonav/identification/instance.hpp"

namespace {

using namespace odonav;
using namespace odonav::identification;

TEST(Instance, NamesAreValidatedWithTheReason) {
  EXPECT_NO_THROW(validate_identification_instance("identification"));
  EXPECT_NO_THROW(validate_identification_instance("identification/standby"));
  for (const char* bad : {"", "/x", "x/", "a//b", "a/../b", "a b", "command", "x;rm"}) {
    try {
      validate_identification_instance(bad);
      ADD_FAILURE() << "accepted '" << bad << "'";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(std::string("identification instance '") + bad + "'"), std::string::npos)
          << e.what();
    }
  }
  EXPECT_THROW(validate_identification_instance(std::string(65, 'a')), std::invalid_argument);
}

TEST(Instance, StateFilesKeepTheDefaultNameAndSeparateAStandby) {
  EXPECT_EQ(instance_checkpoint_path("/var/lib/odonav", "vehicle-01", "identification"),
            "/var/lib/odonav/identification-vehicle-01.ckpt");
  EXPECT_EQ(instance_checkpoint_path("/var/lib/odonav", "vehicle-01", "identification/standby"),
            "/var/lib/odonav/identification_standby-vehicle-01.ckpt");
  EXPECT_EQ(persistence_db_path("/var/lib/odonav", "vehicle-01", "identification/standby"),
            "/var/lib/odonav/vehicle-01-identification_standby.db");
  EXPECT_THROW(persistence_db_path("/tmp", "../x", "identification"), std::invalid_argument);
  EXPECT_THROW(instance_checkpoint_path("/tmp", "vehicle-01", "a//b"), std::invalid_argument);
}

TEST(Instance, PersistenceGuidIsFixedDistinctAndWellFormed) {
  const std::string g = persistence_guid("vehicle-01", "identification");
  // 12 prefix bytes | 4 entity-id bytes, lower-case hex; 'o','d' first; a keyed user writer.
  EXPECT_TRUE(std::regex_match(g, std::regex("^6f\\.64(\\.[0-9a-f]{2}){10}\\|00\\.00\\.01\\.02$"))) << g;
  EXPECT_EQ(g, persistence_guid("vehicle-01", "identification")) << "stable across calls";
  std::set<std::string> all;
  for (const char* v : {"vehicle-01", "vehicle-02", "vehicle-1"})
    for (const char* i : {"identification", "identification/standby", "identification/b"})
      all.insert(persistence_guid(v, i));
  EXPECT_EQ(all.size(), 9u);
  // The derivation, recomputed independently for one name: FNV-1a 64 of the documented text.
  uint64_t h = 1469598103934665603ULL;
  for (unsigned char c : std::string("odonav-persistence\nvehicle-01\nidentification")) {
    h ^= c;
    h *= 1099511628211ULL;
  }
  char third[3];
  std::snprintf(third, sizeof third, "%02x", static_cast<unsigned>(h >> 56));
  EXPECT_EQ(g.substr(6, 2), third);
  EXPECT_THROW(persistence_guid("", "identification"), std::invalid_argument);
}

}  // namespace
