#include "odonav/lever_arm_option.hpp"

#include <cmath>
#include <cstdlib>
#include <sstream>
#include <string>

#include "odonav/dataset.hpp"

namespace odonav {

void add_lever_arm_option(Options& o) {
  o.add_string("lever-arm", "", "GNSS antenna position in the INS body frame, forward,left,up (m); empty = none");
}

std::optional<Eigen::Vector3d> lever_arm_from(const Options& o) {
  const std::string text = o.get_string("lever-arm");
  if (text.empty()) return std::nullopt;
  Eigen::Vector3d v;
  std::istringstream in(text);
  std::string part;
  int i = 0;
  while (std::getline(in, part, ',')) {
    char* end = nullptr;
    const double x = std::strtod(part.c_str(), &end);
    if (i >= 3 || part.empty() || *end != '\0' || !std::isfinite(x))
      throw ConfigError("--lever-arm=" + text + ": expected three numbers x,y,z in metres");
    v[i++] = x;
  }
  if (i != 3) throw ConfigError("--lever-arm=" + text + ": expected three numbers x,y,z in metres");
  if (v.cwiseAbs().maxCoeff() > kMaxLeverArmComponent_m)
    throw ConfigError("--lever-arm=" + text +
                      ": a component beyond +-20 m (an antenna on a land vehicle is within "
                      "that of the INS)");
  return v;
}

}  // namespace odonav
