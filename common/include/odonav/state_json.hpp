#pragma once
// StateJson, the type of a checkpoint state (checkpoint_state.hpp), declared without the whole of
// nlohmann/json.hpp for the headers that only pass states around.
#include <nlohmann/json_fwd.hpp>

namespace odonav {
using StateJson = nlohmann::json;
/// Reaches a class's private checkpoint fields (checkpoint_state.hpp); a class befriends it.
struct StateAccess;
}  // namespace odonav
