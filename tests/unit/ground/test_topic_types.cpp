// odonav-ground's compile-time topic -> message type map (node/topic_types.hpp) against the topic
// contract (topics.hpp): every topic's mapped type registers the DDS type name the contract gives,
// ids and specs correspond both ways, and a topic outside the contract is refused by name.
#include <gtest/gtest.h>

#include <set>
#include <stdexcept>
#include <string>

#include "node/topic_types.hpp"
#include "odonav/dds/types.hpp"

using namespace odonav;
using odonav::ground::topic_id_of;
using odonav::ground::with_message_type_of;

TEST(GroundTopicTypes, EveryContractTopicMapsToTheTypeItsSpecNames) {
  std::set<std::string> seen_types;
  for (const topics::TopicId id : topics::kAllTopicIds) {
    std::string registered;
    int calls = 0;
    with_message_type_of(id, [&](auto prototype, auto id_constant) {
      using T = decltype(prototype);
      typename dds::DdsType<T>::PubSubType type;
      registered = type.getName();
      EXPECT_EQ(decltype(id_constant)::value, id);
      ++calls;
    });
    EXPECT_EQ(calls, 1);
    EXPECT_EQ(registered, topics::spec_of(id).dds_type_name) << topics::spec_of(id).name;
    seen_types.insert(registered);
  }
  EXPECT_EQ(seen_types.size(), topics::kAllTopics.size());  // one distinct type per topic
}

TEST(GroundTopicTypes, IdsAndSpecsCorrespondAndUnknownTopicsAreNamed) {
  ASSERT_EQ(topics::kAllTopicIds.size(), 9u);
  for (std::size_t i = 0; i < topics::kAllTopics.size(); ++i) {
    EXPECT_EQ(topic_id_of(topics::kAllTopics[i]), topics::kAllTopicIds[i]);
    EXPECT_STREQ(topics::spec_of(topics::kAllTopicIds[i]).name, topics::kAllTopics[i].name);
  }
  EXPECT_EQ(topic_id_of(topics::kScaleFactor), topics::TopicId::kScaleFactor);
  EXPECT_STREQ(topics::spec_of(topics::TopicId::kGnssFix).name, "rt/odonav/gnss/fix");
  topics::TopicSpec stranger = topics::kOdometer;
  stranger.name = "rt/odonav/not_a_topic";
  try {
    topic_id_of(stranger);
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(), "odonav-ground: topic 'rt/odonav/not_a_topic' is not in the contract");
  }
}
