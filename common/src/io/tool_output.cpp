#include "odonav/tool_output.hpp"

#include <iostream>

namespace odonav {

std::ostream& tool_output() { return std::cout; }

}  // namespace odonav
