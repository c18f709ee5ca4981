#pragma once
// The message type of every topic of the contract (idl/include/odonav/topics.hpp), at compile time:
// MessageOf<TopicId> is defined for each TopicId and for nothing else, and with_message_type_of()
// instantiates its callback for every TopicId of kAllTopicIds, so a topic added to the contract
// without its message type here does not compile ("incomplete type MessageOf<...>").
#include <cstddef>
#include <stdexcept>
#include <string>
#include <utility>

#include "odonav/msg/Command.h"
#include "odonav/msg/DeadReckoning.h"
#include "odonav/msg/GnssFix.h"
#include "odonav/msg/Health.h"
#include "odonav/msg/InsAttitude.h"
#include "odonav/msg/Misalignment.h"
#include "odonav/msg/NavigationPosition.h"
#include "odonav/msg/Odometer.h"
#include "odonav/msg/ScaleFactor.h"
#include "odonav/topics.hpp"

namespace odonav::ground {

template <topics::TopicId Id>
struct MessageOf;  // Only the specializations below exist.
template <>
struct MessageOf<topics::TopicId::kOdometer> {
  using type = odonav::msg::Odometer;
};
template <>
struct MessageOf<topics::TopicId::kInsAttitude> {
  using type = odonav::msg::InsAttitude;
};
template <>
struct MessageOf<topics::TopicId::kGnssFix> {
  using type = odonav::msg::GnssFix;
};
template <>
struct MessageOf<topics::TopicId::kMisalignment> {
  using type = odonav::msg::Misalignment;
};
template <>
struct MessageOf<topics::TopicId::kScaleFactor> {
  using type = odonav::msg::ScaleFactor;
};
template <>
struct MessageOf<topics::TopicId::kDeadReckoning> {
  using type = odonav::msg::DeadReckoning;
};
template <>
struct MessageOf<topics::TopicId::kHealth> {
  using type = odonav::msg::Health;
};
template <>
struct MessageOf<topics::TopicId::kCommand> {
  using type = odonav::msg::Command;
};
template <>
struct MessageOf<topics::TopicId::kNavigationPosition> {
  using type = odonav::msg::NavigationPosition;
};

namespace detail {
template <class F, std::size_t... I>
void with_message_type_of(topics::TopicId id, F& f, std::index_sequence<I...>) {
  // One branch per TopicId of the contract, each instantiated: f(prototype, TopicId constant).
  ((id == topics::kAllTopicIds[I] ? (f(typename MessageOf<topics::kAllTopicIds[I]>::type{},
                                       std::integral_constant<topics::TopicId, topics::kAllTopicIds[I]>{}),
                                     true)
                                  : false) ||
   ...);
}
}  // namespace detail

/// Calls f(prototype, std::integral_constant<TopicId, id>) with a default-constructed message of
/// topic `id`'s type (f is instantiated for every topic of the contract).
template <class F>
void with_message_type_of(topics::TopicId id, F&& f) {
  detail::with_message_type_of(id, f, std::make_index_sequence<topics::kAllTopicIds.size()>{});
}

/// The TopicId of a topic of the contract, found by its DDS name. Throws std::invalid_argument for a
/// spec that is not in the contract.
inline topics::TopicId topic_id_of(const topics::TopicSpec& spec) {
  for (const topics::TopicId id : topics::kAllTopicIds)
    if (std::string(topics::spec_of(id).name) == spec.name) return id;
  throw std::invalid_argument("odonav-ground: topic '" + std::string(spec.name) + "' is not in the contract");
}

}  // namespace odonav::ground
