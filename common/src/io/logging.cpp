// Logging setup (see odonav/logging.hpp).
#include "odonav/logging.hpp"

#include <spdlog/sinks/stdout_sinks.h>

#include <cstdlib>

namespace odonav {

spdlog::level::level_enum parse_log_level(const std::string& name, const std::string& source) {
  using spdlog::level::level_enum;
  // spdlog::level::from_str maps any unknown name to "off", which would silence a typo: check here.
  static const std::pair<const char*, level_enum> kLevels[] = {
      {"trace", level_enum::trace},       {"debug", level_enum::debug},  {"info", level_enum::info},
      {"warn", level_enum::warn},         {"warning", level_enum::warn}, {"error", level_enum::err},
      {"critical", level_enum::critical}, {"off", level_enum::off}};
  for (const auto& [text, level] : kLevels) {
    if (name == text) return level;
  }
  throw ConfigError(source + " '" + name + "' is not valid: use one of " + kLogLevelNames);
}

std::shared_ptr<spdlog::logger> setup_logging(const std::string& component, const std::string& level) {
  spdlog::level::level_enum chosen = spdlog::level::info;
  if (!level.empty()) {
    chosen = parse_log_level(level, "log level");
  } else if (const char* env = std::getenv("ODONAV_LOG_LEVEL"); env && *env) {
    chosen = parse_log_level(env, "log level (from ODONAV_LOG_LEVEL)");
  }
  // Plain (uncoloured) stderr: logs are often redirected to files and read by tools.
  auto logger = std::make_shared<spdlog::logger>(component, std::make_shared<spdlog::sinks::stderr_sink_mt>());
  logger->set_pattern("%Y-%m-%d %H:%M:%S.%e [%n] [%l] %v");
  logger->set_level(chosen);
  logger->flush_on(spdlog::level::warn);
  spdlog::drop(component);  // a second call for the same component replaces the first logger
  spdlog::register_logger(logger);
  spdlog::set_default_logger(logger);
  return logger;
}

}  // namespace odonav
