// The non-template part of the checkpoint state serialisation (checkpoint_state.hpp).
#include "odonav/checkpoint_state.hpp"

#include <cmath>

namespace odonav {

StateJson state_double(double v) {
  if (std::isnan(v)) return std::signbit(v) ? "-nan" : "nan";
  if (std::isinf(v)) return v > 0.0 ? "inf" : "-inf";
  return v;
}

double state_double_of(const StateJson& j, const std::string& field) {
  if (j.is_number()) return j.get<double>();
  if (j.is_string()) {
    const std::string& s = j.get_ref<const std::string&>();
    if (s == "nan") return std::numeric_limits<double>::quiet_NaN();
    if (s == "-nan") return -std::numeric_limits<double>::quiet_NaN();
    if (s == "inf") return std::numeric_limits<double>::infinity();
    if (s == "-inf") return -std::numeric_limits<double>::infinity();
  }
  state_detail::fail(field, "is not a number");
}

StateIn::StateIn(const StateJson& j, std::string where) : j_(j), where_(std::move(where)) {
  if (!j_.is_object()) state_detail::fail(where_.empty() ? "state" : where_, "is not an object");
}

const StateJson& StateIn::at(const char* key) const {
  const auto it = j_.find(key);
  if (it == j_.end()) state_detail::fail(path(key), "is missing");
  return *it;
}

StateIn& StateIn::check(const char* key, bool ok, const char* what) {
  if (!ok) state_detail::fail(path(key), what);
  return *this;
}

namespace state_detail {

void fail(const std::string& field, const std::string& what) { throw CheckpointError("field '" + field + "' " + what); }

int64_t integer_of(const StateJson& j, const std::string& field, int64_t lo, uint64_t hi) {
  if (j.is_number_unsigned()) {
    const uint64_t u = j.get<uint64_t>();
    if (u > hi) fail(field, "is out of range (" + std::to_string(u) + ")");
    return static_cast<int64_t>(u);
  }
  if (j.is_number_integer()) {
    const int64_t i = j.get<int64_t>();
    if (i < lo || (i >= 0 && static_cast<uint64_t>(i) > hi)) fail(field, "is out of range (" + std::to_string(i) + ")");
    return i;
  }
  fail(field, "is not a whole number");
}

}  // namespace state_detail

}  // namespace odonav
