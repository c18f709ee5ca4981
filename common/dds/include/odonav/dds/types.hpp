#pragma once
// Maps each generated message type to its generated TopicDataType (fastddsgen: <Type>PubSubType),
// so endpoints are written Writer<odonav::msg::Odometer>. A type missing here does not compile:
// "incomplete type DdsType<...>" names it.
#include "odonav/msg/Command.h"
#include "odonav/msg/CommandPubSubTypes.h"
#include "odonav/msg/DeadReckoning.h"
#include "odonav/msg/DeadReckoningPubSubTypes.h"
#include "odonav/msg/NavigationPosition.h"
#include "odonav/msg/NavigationPositionPubSubTypes.h"
#include "odonav/msg/GnssFix.h"
#include "odonav/msg/GnssFixPubSubTypes.h"
#include "odonav/msg/Health.h"
#include "odonav/msg/HealthPubSubTypes.h"
#include "odonav/msg/InsAttitude.h"
#include "odonav/msg/InsAttitudePubSubTypes.h"
#include "odonav/msg/Misalignment.h"
#include "odonav/msg/MisalignmentPubSubTypes.h"
#include "odonav/msg/Odometer.h"
#include "odonav/msg/OdometerPubSubTypes.h"
#include "odonav/msg/ScaleFactor.h"
#include "odonav/msg/ScaleFactorPubSubTypes.h"

namespace odonav::dds {

template <class Message>
struct DdsType;  // Only the specializations below exist.

template <>
struct DdsType<odonav::msg::Odometer> {
  using PubSubType = odonav::msg::OdometerPubSubType;
};
template <>
struct DdsType<odonav::msg::InsAttitude> {
  using PubSubType = odonav::msg::InsAttitudePubSubType;
};
template <>
struct DdsType<odonav::msg::GnssFix> {
  using PubSubType = odonav::msg::GnssFixPubSubType;
};
template <>
struct DdsType<odonav::msg::Misalignment> {
  using PubSubType = odonav::msg::MisalignmentPubSubType;
};
template <>
struct DdsType<odonav::msg::ScaleFactor> {
  using PubSubType = odonav::msg::ScaleFactorPubSubType;
};
template <>
struct DdsType<odonav::msg::DeadReckoning> {
  using PubSubType = odonav::msg::DeadReckoningPubSubType;
};
template <>
struct DdsType<odonav::msg::NavigationPosition> {
  using PubSubType = odonav::msg::NavigationPositionPubSubType;
};
template <>
struct DdsType<odonav::msg::Health> {
  using PubSubType = odonav::msg::HealthPubSubType;
};
template <>
struct DdsType<odonav::msg::Command> {
  using PubSubType = odonav::msg::CommandPubSubType;
};

}  // namespace odonav::dds
