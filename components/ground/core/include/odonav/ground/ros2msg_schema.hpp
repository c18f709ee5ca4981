#pragma once
// ros2msg schemas for MCAP, built from the .msg twins of idl/ the way ROS 2 (rosbag2) writes them:
// the type's own .msg text, then each type it depends on, once, depth first in order of first use:
//
//   <text of pkg/msg/Type.msg>
//   ================================================================================
//   MSG: std_msgs/Header
//   <text of std_msgs/msg/Header.msg>
//   ================================================================================
//   MSG: builtin_interfaces/Time
//   ...
//
// Foxglove, PlotJuggler and ros2 bag parse this to decode the CDR payloads.
#include <map>
#include <string>
#include <vector>

namespace odonav::ground {

/// .msg texts by ROS interface name "pkg/msg/Type".
using MsgLibrary = std::map<std::string, std::string>;

/// The .msg files of the odonav contract (idl/**/msg/*.msg), embedded at build time so the program
/// needs no source tree at run time.
const MsgLibrary& embedded_msg_library();

/// Reads every <dir>/<pkg>/msg/<Type>.msg under `idl_dir`. Throws std::runtime_error naming the
/// folder when it does not exist or holds no .msg file.
MsgLibrary load_msg_library(const std::string& idl_dir);

/// The types a .msg text refers to, as "pkg/msg/Type", in order of first appearance. Relative names
/// ("Counter") resolve to `package`; builtin types (bool, int8..uint64, float32/64, string,
/// wstring, byte, char, time, duration) are skipped; array and bound suffixes are removed.
/// Throws std::runtime_error naming the line for a field line it cannot read.
std::vector<std::string> msg_dependencies(const std::string& msg_text, const std::string& package);

/// The complete ros2msg schema of `type_name` ("pkg/msg/Type"). Throws std::runtime_error naming
/// the missing type (and who needs it) when a dependency is not in `library`.
std::string ros2msg_schema(const MsgLibrary& library, const std::string& type_name);

}  // namespace odonav::ground
