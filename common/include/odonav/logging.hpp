#pragma once
// Logging setup shared by every odonav tool and component: one spdlog logger per component,
// writing to standard error, made the default logger so library code can call spdlog::info(...).
#include <spdlog/spdlog.h>

#include <memory>
#include <string>

#include "odonav/config.hpp"

namespace odonav {

/// The level names setup_logging accepts, in increasing severity.
inline constexpr const char* kLogLevelNames = "trace, debug, info, warn, error, critical, off";

/// Parses a level name (one of kLogLevelNames; "warning" is accepted for warn). Throws ConfigError
/// naming the bad value and listing the valid ones; `source` says where it came from (for the message).
spdlog::level::level_enum parse_log_level(const std::string& name, const std::string& source = "log level");

/// Creates (or re-creates) the logger named `component`, writing to stderr with the pattern
/// "<date> <time.ms> [<component>] [<level>] <message>", and sets it as the spdlog default logger.
/// Level: `level` when not empty, else the environment variable ODONAV_LOG_LEVEL when set and not
/// empty, else info. An invalid level name is a ConfigError listing the valid ones.
std::shared_ptr<spdlog::logger> setup_logging(const std::string& component, const std::string& level = "");

}  // namespace odonav
