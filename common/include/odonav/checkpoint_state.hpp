#pragma once
// The one serialisation of a component's checkpoint state (odonav-identification, -calibration,
// -dead-reckoning), on nlohmann::json, middleware-free. The file around it (envelope, checksum,
// atomic write, moving a bad file aside) is checkpoint_file.hpp.
//
// A state is listed ONCE, as a function template over an archive that both saves and restores:
//
//   template <class Archive, class Self>        // Self: T when restoring, const T when saving
//   void state_fields(Archive& a, Self& s) { a("t_s", s.t_s)("position", s.position); }
//
// StateOut writes each named member into a JSON object; StateIn reads them back, and every failure
// is a CheckpointError naming the field by its path ("dead_reckoner.gnss[3].fix is missing").
// A plain struct is described by a free state_fields found by argument-dependent lookup
// (ODONAV_STATE_FIELDS(Type) { a("x", s.x); } declares one), a private nested struct by a static
// member template T::state_fields(a, s), a class by a private static member template that its
// save_state() / restore_state() reach through save_fields() / restored_copy() (the class declares
// `friend struct StateAccess;`): restore_state restores into a copy and commits it only when every
// field was read and checked. Members reached only through accessors go through via(): an object
// that saves itself (StateJson save_state() / restore_state(const StateJson&)), one with
// State state() / restore_state(State), or a getter and a setter. check() tests a restored value.
//
// Values: bool, integers (range-checked when read), enums (as their underlying integer; the owner
// checks the value), std::string, double, StateJson (a nested state its owner saved),
// std::optional and std::shared_ptr<const T> (null when empty), std::vector,
// std::deque, std::array (exact length), std::pair (two-element array), fixed-size Eigen
// matrices of double (column-major array), structs (objects).
// Doubles: a finite double is a JSON number; nlohmann writes the shortest text that reads back to
// the same bits (-0.0 and subnormals included), so a restored state is bit-exact. JSON has no NaN
// or infinity (nlohmann would write null): they are the strings "nan", "-nan", "inf", "-inf".
#include <array>
#include <cstdint>
#include <deque>
#include <limits>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "odonav/state_json.hpp"

namespace odonav {

/// A checkpoint or state that cannot be used; what() says why (truncated, checksum, version, field...).
class CheckpointError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Restores `state` into `target` (target.restore_state(state)); whatever that throws becomes a
/// CheckpointError "<what> state refused: <why>", so a component's checkpoint load names the part
/// of it that was refused. target is unchanged when it throws (restore_state's own rule).
template <class Target, class State>
void restore_or_refuse(const std::string& what, Target& target, const State& state) {
  try {
    target.restore_state(state);
  } catch (const std::exception& e) {
    throw CheckpointError(what + " state refused: " + e.what());
  }
}

/// A double as checkpoint JSON: a number when finite, else "nan", "-nan", "inf" or "-inf".
StateJson state_double(double v);
/// Reads state_double's value (or any JSON number). Throws CheckpointError naming `field`.
double state_double_of(const StateJson& j, const std::string& field);

template <class T>
StateJson to_state(const T& value);
template <class T>
void from_state(const StateJson& j, T& value, const std::string& field);

namespace state_detail {
/// Whether T saves itself: StateJson save_state() const / restore_state(const StateJson&).
template <class T, class = void>
struct saves_itself : std::false_type {};
template <class T>
struct saves_itself<T, std::void_t<decltype(std::declval<const T&>().save_state())>> : std::true_type {};
}  // namespace state_detail

/// Saves: each (key, member) into a JSON object.
class StateOut {
 public:
  static constexpr bool kSaving = true;
  template <class T>
  StateOut& operator()(const char* key, const T& value) {
    j_[key] = to_state(value);
    return *this;
  }
  /// An object that saves itself (StateJson save_state(), restore_state(const StateJson&)), or
  /// whose state is obj.state() (restored with obj.restore_state(State)).
  template <class Obj>
  StateOut& via(const char* key, const Obj& obj) {
    if constexpr (state_detail::saves_itself<Obj>::value)
      j_[key] = obj.save_state();
    else
      (*this)(key, obj.state());
    return *this;
  }
  /// A value read with get() (restored with set(value)).
  template <class Get, class Set>
  StateOut& via(const char* key, Get get, Set) {
    return (*this)(key, get());
  }
  /// A check of restored values (nothing when saving).
  StateOut& check(const char*, bool, const char*) { return *this; }
  StateJson take() { return std::move(j_); }

 private:
  StateJson j_ = StateJson::object();
};

/// Restores: each (key, member) from a JSON object; throws CheckpointError naming the field.
class StateIn {
 public:
  static constexpr bool kSaving = false;
  /// where: the path of this object in error messages ("" for the top).
  StateIn(const StateJson& j, std::string where);
  StateIn(StateJson&&, std::string) = delete;  // it keeps a reference to j
  template <class T>
  StateIn& operator()(const char* key, T& value) {
    from_state(at(key), value, path(key));
    return *this;
  }
  template <class Obj>
  StateIn& via(const char* key, Obj& obj) {
    if constexpr (state_detail::saves_itself<Obj>::value) {
      obj.restore_state(at(key));
    } else {
      typename Obj::State s{};
      (*this)(key, s);
      obj.restore_state(std::move(s));
    }
    return *this;
  }
  template <class Get, class Set>
  StateIn& via(const char* key, Get get, Set set) {
    std::decay_t<decltype(get())> v{};
    (*this)(key, v);
    set(std::move(v));
    return *this;
  }
  /// Throws CheckpointError "field '<path of key>' <what>" unless ok (a restored value out of range).
  StateIn& check(const char* key, bool ok, const char* what);
  /// "<where>.<key>", for messages.
  std::string path(const char* key) const { return where_.empty() ? std::string(key) : where_ + "." + key; }

 private:
  const StateJson& at(const char* key) const;
  const StateJson& j_;
  std::string where_;
};

namespace state_detail {
template <class T>
struct is_optional : std::false_type {};
template <class T>
struct is_optional<std::optional<T>> : std::true_type {};
template <class T>
struct is_shared_const : std::false_type {};
template <class T>
struct is_shared_const<std::shared_ptr<const T>> : std::true_type {};
template <class T>
struct is_list : std::false_type {};
template <class T, class A>
struct is_list<std::vector<T, A>> : std::true_type {};
template <class T, class A>
struct is_list<std::deque<T, A>> : std::true_type {};
template <class T>
struct is_array : std::false_type {};
template <class T, std::size_t N>
struct is_array<std::array<T, N>> : std::true_type {};
template <class T>
struct is_pair : std::false_type {};
template <class A, class B>
struct is_pair<std::pair<A, B>> : std::true_type {};
template <class T>
struct is_matrix : std::false_type {};
template <int R, int C, int O, int MR, int MC>
struct is_matrix<Eigen::Matrix<double, R, C, O, MR, MC>> : std::bool_constant<(R > 0 && C > 0)> {};
template <class T, class = void>
struct has_member_fields : std::false_type {};
template <class T>
struct has_member_fields<T, std::void_t<decltype(T::state_fields(std::declval<StateOut&>(), std::declval<const T&>()))>>
    : std::true_type {};

[[noreturn]] void fail(const std::string& field, const std::string& what);
int64_t integer_of(const StateJson& j, const std::string& field, int64_t lo, uint64_t hi);

template <class Archive, class T>
void fields_of(Archive& a, T& value) {
  if constexpr (has_member_fields<std::remove_const_t<T>>::value)
    std::remove_const_t<T>::state_fields(a, value);
  else
    state_fields(a, value);  // found by argument-dependent lookup
}
}  // namespace state_detail

template <class T>
StateJson to_state(const T& v) {
  using namespace state_detail;
  if constexpr (std::is_same_v<T, double>) {
    return state_double(v);
  } else if constexpr (std::is_same_v<T, StateJson>) {
    return v;
  } else if constexpr (is_shared_const<T>::value) {
    return v ? to_state(*v) : StateJson(nullptr);
  } else if constexpr (std::is_same_v<T, bool> || std::is_integral_v<T> || std::is_same_v<T, std::string>) {
    return StateJson(v);
  } else if constexpr (std::is_enum_v<T>) {
    return StateJson(static_cast<std::underlying_type_t<T>>(v));
  } else if constexpr (is_optional<T>::value) {
    return v ? to_state(*v) : StateJson(nullptr);
  } else if constexpr (is_list<T>::value || is_array<T>::value) {
    StateJson out = StateJson::array();
    for (const auto& e : v) out.push_back(to_state(e));
    return out;
  } else if constexpr (is_pair<T>::value) {
    return StateJson::array({to_state(v.first), to_state(v.second)});
  } else if constexpr (is_matrix<T>::value) {
    StateJson out = StateJson::array();
    for (Eigen::Index i = 0; i < v.size(); ++i) out.push_back(state_double(v.data()[i]));
    return out;
  } else {
    StateOut out;
    fields_of(out, v);
    return out.take();
  }
}

template <class T>
void from_state(const StateJson& j, T& v, const std::string& field) {
  using namespace state_detail;
  if constexpr (std::is_same_v<T, double>) {
    v = state_double_of(j, field);
  } else if constexpr (std::is_same_v<T, StateJson>) {
    v = j;
  } else if constexpr (is_shared_const<T>::value) {
    if (j.is_null()) {
      v.reset();
    } else {
      std::remove_const_t<typename T::element_type> x{};
      from_state(j, x, field);
      v = std::make_shared<const std::remove_const_t<typename T::element_type>>(std::move(x));
    }
  } else if constexpr (std::is_same_v<T, bool>) {
    if (!j.is_boolean()) fail(field, "is not true or false");
    v = j.get<bool>();
  } else if constexpr (std::is_integral_v<T>) {
    v = static_cast<T>(integer_of(j, field, static_cast<int64_t>(std::numeric_limits<T>::min()),
                                  static_cast<uint64_t>(std::numeric_limits<T>::max())));
  } else if constexpr (std::is_enum_v<T>) {
    std::underlying_type_t<T> u{};
    from_state(j, u, field);
    v = static_cast<T>(u);
  } else if constexpr (std::is_same_v<T, std::string>) {
    if (!j.is_string()) fail(field, "is not a text");
    v = j.get<std::string>();
  } else if constexpr (is_optional<T>::value) {
    if (j.is_null()) {
      v.reset();
    } else {
      typename T::value_type x{};
      from_state(j, x, field);
      v = std::move(x);
    }
  } else if constexpr (is_list<T>::value) {
    if (!j.is_array()) fail(field, "is not a list");
    v.clear();
    for (std::size_t i = 0; i < j.size(); ++i) {
      typename T::value_type x{};
      from_state(j[i], x, field + "[" + std::to_string(i) + "]");
      v.push_back(std::move(x));
    }
  } else if constexpr (is_array<T>::value || is_matrix<T>::value) {
    const std::size_t n = static_cast<std::size_t>(v.size());
    if (!j.is_array() || j.size() != n) fail(field, "does not hold " + std::to_string(n) + " values");
    for (std::size_t i = 0; i < n; ++i) {
      if constexpr (is_matrix<T>::value)
        v.data()[i] = state_double_of(j[i], field + "[" + std::to_string(i) + "]");
      else
        from_state(j[i], v[i], field + "[" + std::to_string(i) + "]");
    }
  } else if constexpr (is_pair<T>::value) {
    if (!j.is_array() || j.size() != 2) fail(field, "does not hold 2 values");
    from_state(j[0], v.first, field + "[0]");
    from_state(j[1], v.second, field + "[1]");
  } else {
    if (!j.is_object()) fail(field, "is not an object");
    StateIn in(j, field);
    fields_of(in, v);
  }
}

/// The door to a class's private static state_fields for save_fields() and restored_copy(): a class
/// that lists its checkpoint fields privately declares `friend struct StateAccess;`.
struct StateAccess {
  template <class Archive, class T>
  static void fields(Archive& a, T& obj) {
    std::remove_const_t<T>::state_fields(a, obj);
  }
};

/// The checkpoint fields of obj (its state_fields) as one JSON object: a save_state().
template <class T>
StateJson save_fields(const T& obj) {
  StateOut out;
  StateAccess::fields(out, obj);
  return out.take();
}

/// `copy` with its checkpoint fields read from state (its state_fields), for a restore_state() that
/// commits the result only when everything was read and checked. copy: the object before the
/// restore, or one made afresh from the same parameters. Throws CheckpointError naming the field
/// under `where` ("dead_reckoner.gnss[3].fix is missing").
template <class T>
T restored_copy(T copy, const StateJson& state, const std::string& where) {
  StateIn in(state, where);
  StateAccess::fields(in, copy);
  return copy;
}

/// Declares the state_fields of a plain struct `Type` (members reached as `s.<member>`, the
/// archive as `a`), for saving and restoring alike.
#define ODONAV_STATE_FIELDS(Type)                                                                                  \
  template <class Archive, class Self, std::enable_if_t<std::is_same_v<std::remove_const_t<Self>, Type>, int> = 0> \
  void state_fields(Archive& a, Self& s)

}  // namespace odonav
