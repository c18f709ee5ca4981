// setup_logging: level from the argument, else ODONAV_LOG_LEVEL, else info; invalid names are a
// ConfigError listing the valid ones; output on stderr carries time, component and level.
#include <gtest/gtest.h>

#include <cstdlib>
#include <optional>
#include <regex>

#include "odonav/logging.hpp"

using namespace odonav;

namespace {
// Sets or clears ODONAV_LOG_LEVEL for one test and restores it after.
class LogLevelEnv {
 public:
  explicit LogLevelEnv(const char* value) {
    if (const char* old = std::getenv("ODONAV_LOG_LEVEL")) saved_ = old;
    if (value)
      setenv("ODONAV_LOG_LEVEL", value, 1);
    else
      unsetenv("ODONAV_LOG_LEVEL");
  }
  ~LogLevelEnv() {
    if (saved_)
      setenv("ODONAV_LOG_LEVEL", saved_->c_str(), 1);
    else
      unsetenv("ODONAV_LOG_LEVEL");
  }

 private:
  std::optional<std::string> saved_;
};
}  // namespace

TEST(Logging, LevelFromArgumentThenEnvironmentThenInfo) {
  {
    LogLevelEnv env(nullptr);
    EXPECT_EQ(setup_logging("odonav-test")->level(), spdlog::level::info);
  }
  {
    LogLevelEnv env("debug");
    EXPECT_EQ(setup_logging("odonav-test")->level(), spdlog::level::debug);
    EXPECT_EQ(setup_logging("odonav-test", "error")->level(), spdlog::level::err);  // the argument wins
  }
  {
    LogLevelEnv env("");
    EXPECT_EQ(setup_logging("odonav-test")->level(), spdlog::level::info);
  }
  EXPECT_EQ(setup_logging("odonav-test", "warning")->level(), spdlog::level::warn);
  EXPECT_EQ(setup_logging("odonav-test", "off")->level(), spdlog::level::off);
}

TEST(Logging, InvalidLevelNamesTheValidOnes) {
  try {
    setup_logging("odonav-test", "verbose");
    FAIL() << "no error";
  } catch (const ConfigError& e) {
    EXPECT_EQ(std::string(e.what()),
              "log level 'verbose' is not valid: use one of trace, debug, info, warn, error, critical, off");
  }
  LogLevelEnv env("INFO");
  try {
    setup_logging("odonav-test");
    FAIL() << "no error";
  } catch (const ConfigError& e) {
    EXPECT_EQ(std::string(e.what()),
              "log level (from ODONAV_LOG_LEVEL) 'INFO' is not valid: use one of trace, "
              "debug, info, warn, error, critical, off");
  }
}

TEST(Logging, DefaultLoggerWritesComponentAndLevelToStderr) {
  LogLevelEnv env(nullptr);
  auto logger = setup_logging("odonav-gateway", "info");
  EXPECT_EQ(logger->name(), "odonav-gateway");
  EXPECT_EQ(spdlog::default_logger(), logger);
  EXPECT_EQ(spdlog::get("odonav-gateway"), logger);
  // Set up twice for the same component: the second replaces the first, no registry clash.
  auto again = setup_logging("odonav-gateway", "warn");
  EXPECT_EQ(spdlog::default_logger(), again);

  testing::internal::CaptureStderr();
  spdlog::info("hidden below warn");
  spdlog::warn("replay at {} x", 2);
  again->flush();
  const std::string text = testing::internal::GetCapturedStderr();
  EXPECT_EQ(text.find("hidden"), std::string::npos);
  const std::regex line(R"(\d{4}-\d\d-\d\d \d\d:\d\d:\d\d\.\d{3} \[odonav-gateway\] \[warning\] replay at 2 x\n)");
  EXPECT_TRUE(std::regex_match(text, line)) << text;
}
