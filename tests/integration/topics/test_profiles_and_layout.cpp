// The contract's static side: qos.xml and loopback.xml say what idl/README.md says, and every ROS
// .msg twin describes exactly the bytes the generated type puts on the wire.
#include <fastdds/dds/domain/DomainParticipantFactory.hpp>
#include <fastdds/dds/publisher/qos/DataWriterQos.hpp>
#include <fastdds/dds/subscriber/qos/DataReaderQos.hpp>
#include <fastdds/rtps/transport/UDPv4TransportDescriptor.h>
#include <fastdds/rtps/transport/shared_mem/SharedMemTransportDescriptor.h>
#include <fastrtps/utils/IPLocator.h>
#include <gtest/gtest.h>

#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "message_fields.hpp"
#include "odonav/dds/participant.hpp"
#include "odonav/topics.hpp"

using namespace eprosima::fastdds::dds;
namespace topics = odonav::topics;

namespace {

const std::string kProfilesDir = std::string(ODONAV_SOURCE_DIR) + "/deploy/profiles";

odonav::dds::ParticipantOptions loopback_options() {
  odonav::dds::ParticipantOptions options;
  options.profiles_file = kProfilesDir + "/loopback.xml";
  options.domain_id = 10;
  options.participant_name = "odonav-test-profiles";
  return options;
}

constexpr double kNoDeadline = std::numeric_limits<double>::infinity();

// What idl/README.md promises for each profile.
struct ExpectedQos {
  ReliabilityQosPolicyKind reliability;
  DurabilityQosPolicyKind durability;
  int depth;
  double deadline_s;
  OwnershipQosPolicyKind ownership = SHARED_OWNERSHIP_QOS;
};

const std::map<std::string, ExpectedQos>& expected_qos() {
  static const std::map<std::string, ExpectedQos> table{
      // Sensor writers keep 30 s for a restarted reader that asks for it (the replay reader); the
      // vehicle's other readers are VOLATILE, as a default-QoS reader of another vendor.
      {topics::kSensorWriterProfile, {RELIABLE_RELIABILITY_QOS, TRANSIENT_LOCAL_DURABILITY_QOS, 3000, kNoDeadline}},
      {topics::kSensorReaderProfile, {RELIABLE_RELIABILITY_QOS, VOLATILE_DURABILITY_QOS, 3000, kNoDeadline}},
      {topics::kSensorReplayReaderProfile,
       {RELIABLE_RELIABILITY_QOS, TRANSIENT_LOCAL_DURABILITY_QOS, 3000, kNoDeadline}},
      // Estimates: SHARED like everything (hot standby arbitrated by the consumers); the writer offers
      // 300 ms, no longer than any reader requests.
      {topics::kEstimateWriterProfile, {RELIABLE_RELIABILITY_QOS, TRANSIENT_LOCAL_DURABILITY_QOS, 300, 0.3}},
      {topics::kEstimateReaderProfile, {RELIABLE_RELIABILITY_QOS, TRANSIENT_LOCAL_DURABILITY_QOS, 300, 1.0}},
      {topics::kGroundEstimateReaderProfile, {RELIABLE_RELIABILITY_QOS, TRANSIENT_LOCAL_DURABILITY_QOS, 1, 1.0}},
      {topics::kMisalignmentRecorderReaderProfile,
       {RELIABLE_RELIABILITY_QOS, TRANSIENT_LOCAL_DURABILITY_QOS, 1000, kNoDeadline}},
      {topics::kScaleFactorRecorderReaderProfile,
       {RELIABLE_RELIABILITY_QOS, TRANSIENT_LOCAL_DURABILITY_QOS, 1000, kNoDeadline}},
      // Dead-reckoning writers keep 30 s for a restarted recorder (its reader asks for them); the
      // other readers are VOLATILE.
      {topics::kDeadReckoningWriterProfile,
       {RELIABLE_RELIABILITY_QOS, TRANSIENT_LOCAL_DURABILITY_QOS, 3000, kNoDeadline}},
      {topics::kDeadReckoningReaderProfile, {RELIABLE_RELIABILITY_QOS, VOLATILE_DURABILITY_QOS, 3000, kNoDeadline}},
      {topics::kDeadReckoningRecorderReaderProfile,
       {RELIABLE_RELIABILITY_QOS, TRANSIENT_LOCAL_DURABILITY_QOS, 3000, kNoDeadline}},
      {topics::kHealthWriterProfile, {RELIABLE_RELIABILITY_QOS, TRANSIENT_LOCAL_DURABILITY_QOS, 1, 3.0}},
      {topics::kHealthReaderProfile, {RELIABLE_RELIABILITY_QOS, TRANSIENT_LOCAL_DURABILITY_QOS, 1, 3.0}},
      {topics::kCommandWriterProfile, {RELIABLE_RELIABILITY_QOS, VOLATILE_DURABILITY_QOS, 10, kNoDeadline}},
      {topics::kCommandReaderProfile, {RELIABLE_RELIABILITY_QOS, VOLATILE_DURABILITY_QOS, 10, kNoDeadline}},
      {topics::kGroundBestEffortReaderProfile,
       {BEST_EFFORT_RELIABILITY_QOS, VOLATILE_DURABILITY_QOS, 100, kNoDeadline}},
  };
  return table;
}

double seconds_of(const eprosima::fastrtps::Duration_t& d) {
  return d == eprosima::fastrtps::c_TimeInfinite ? kNoDeadline : d.to_ns() * 1e-9;
}

template <class Qos>
void expect_qos(const std::string& profile, const Qos& qos) {
  const ExpectedQos& e = expected_qos().at(profile);
  EXPECT_EQ(qos.reliability().kind, e.reliability) << profile;
  EXPECT_EQ(qos.durability().kind, e.durability) << profile;
  EXPECT_EQ(qos.history().kind, KEEP_LAST_HISTORY_QOS) << profile;
  EXPECT_EQ(qos.history().depth, e.depth) << profile;
  // Fast DDS caps the depth at max_samples_per_instance (400 by default) without an error.
  EXPECT_GE(qos.resource_limits().max_samples_per_instance, e.depth) << profile;
  EXPECT_GE(qos.resource_limits().max_samples, e.depth) << profile;
  EXPECT_DOUBLE_EQ(seconds_of(qos.deadline().period), e.deadline_s) << profile;  // 300000000 ns != 0.3 exactly
  EXPECT_EQ(qos.ownership().kind, e.ownership) << profile;
}

bool is_estimate_topic(const topics::TopicSpec& spec) {
  return std::string(spec.writer_profile) == topics::kEstimateWriterProfile;
}

}  // namespace

TEST(QosProfiles, EveryProfileHasTheDocumentedQosAndTopicsMatchTheirReaders) {
  odonav::dds::Participant participant(loopback_options());
  auto& publisher = participant.core()->publisher();
  auto& subscriber = participant.core()->subscriber();
  for (const auto& spec : topics::kAllTopics) {
    SCOPED_TRACE(spec.name);
    DataWriterQos w;
    DataReaderQos r, ground;
    ASSERT_EQ(publisher.get_datawriter_qos_from_profile(spec.writer_profile, w), ReturnCode_t::RETCODE_OK);
    ASSERT_EQ(subscriber.get_datareader_qos_from_profile(spec.reader_profile, r), ReturnCode_t::RETCODE_OK);
    const char* ground_profile = topics::kGroundBestEffortReaderProfile;
    ASSERT_EQ(subscriber.get_datareader_qos_from_profile(ground_profile, ground), ReturnCode_t::RETCODE_OK);
    expect_qos(spec.writer_profile, w);
    expect_qos(spec.reader_profile, r);
    expect_qos(ground_profile, ground);
    std::vector<const DataReaderQos*> readers{&r, &ground};
    // The estimate topics' other readers: the recorders.
    std::vector<DataReaderQos> extra;
    if (is_estimate_topic(spec)) {
      for (const char* profile : {topics::kMisalignmentRecorderReaderProfile, topics::kScaleFactorRecorderReaderProfile,
                                  topics::kGroundEstimateReaderProfile}) {
        extra.emplace_back();
        ASSERT_EQ(subscriber.get_datareader_qos_from_profile(profile, extra.back()), ReturnCode_t::RETCODE_OK);
        expect_qos(profile, extra.back());
      }
    }
    // The sensor topics' other reader: a restarted identification's, which asks for the history.
    if (std::string(spec.writer_profile) == topics::kSensorWriterProfile) {
      extra.emplace_back();
      ASSERT_EQ(subscriber.get_datareader_qos_from_profile(topics::kSensorReplayReaderProfile, extra.back()),
                ReturnCode_t::RETCODE_OK);
      expect_qos(topics::kSensorReplayReaderProfile, extra.back());
    }
    // The dead-reckoning topics' other reader: odonav-recorder's, which asks for the history.
    if (std::string(spec.writer_profile) == topics::kDeadReckoningWriterProfile) {
      extra.emplace_back();
      ASSERT_EQ(subscriber.get_datareader_qos_from_profile(topics::kDeadReckoningRecorderReaderProfile, extra.back()),
                ReturnCode_t::RETCODE_OK);
      expect_qos(topics::kDeadReckoningRecorderReaderProfile, extra.back());
    }
    for (const DataReaderQos& q : extra) readers.push_back(&q);
    // DDS request/offer rules, so every reader of the topic matches its writer.
    for (const DataReaderQos* reader : readers) {
      EXPECT_GE(w.reliability().kind, reader->reliability().kind);
      EXPECT_GE(w.durability().kind, reader->durability().kind);
      EXPECT_LE(seconds_of(w.deadline().period), seconds_of(reader->deadline().period));
      EXPECT_EQ(w.ownership().kind, reader->ownership().kind);
    }
  }
}

// The ground station's readers keep one instance per vehicle (health: per vehicle x component).
// Fast DDS keeps 10 instances per reader unless told otherwise, and the samples of any further
// vehicle are refused without an error: a fleet of 200 was seen as 103 vehicles (docs/DESIGN_DECISIONS.md).
TEST(QosProfiles, GroundStationReadersHoldAFleetOf1024Vehicles) {
  odonav::dds::Participant participant(loopback_options());
  auto& subscriber = participant.core()->subscriber();
  const std::map<std::string, int> min_instances{{topics::kGroundEstimateReaderProfile, 1024},
                                                 {topics::kGroundBestEffortReaderProfile, 1024},
                                                 {topics::kMisalignmentRecorderReaderProfile, 1024},
                                                 {topics::kScaleFactorRecorderReaderProfile, 1024},
                                                 {topics::kHealthReaderProfile, 8192}};
  for (const auto& [profile, instances] : min_instances) {
    DataReaderQos r;
    ASSERT_EQ(subscriber.get_datareader_qos_from_profile(profile, r), ReturnCode_t::RETCODE_OK) << profile;
    EXPECT_GE(r.resource_limits().max_instances, instances) << profile;
    // Every instance can hold its full history.
    EXPECT_GE(r.resource_limits().max_samples, r.resource_limits().max_instances * r.history().depth) << profile;
    EXPECT_GE(r.resource_limits().max_samples_per_instance, r.history().depth) << profile;
  }
}

// Every profile is SHARED, which is what a ROS 2 reader (its QoS has no ownership field) and another
// vendor's default-QoS reader ask for: ownership kinds must be equal to match, so one EXCLUSIVE
// writer would hide its topic from them (tests/integration/interop reads every topic with Cyclone
// DDS). No profile file sets an ownership kind at all.
TEST(QosProfiles, EveryProfileIsSharedSoDefaultQosReadersOfAnyVendorMatch) {
  odonav::dds::Participant participant(loopback_options());
  auto& publisher = participant.core()->publisher();
  auto& subscriber = participant.core()->subscriber();
  for (const auto& [profile, expected] : expected_qos()) {
    DataWriterQos w;
    DataReaderQos r;
    if (publisher.get_datawriter_qos_from_profile(profile, w) == ReturnCode_t::RETCODE_OK) {
      EXPECT_EQ(w.ownership().kind, SHARED_OWNERSHIP_QOS) << profile;
    } else {
      ASSERT_EQ(subscriber.get_datareader_qos_from_profile(profile, r), ReturnCode_t::RETCODE_OK) << profile;
      EXPECT_EQ(r.ownership().kind, SHARED_OWNERSHIP_QOS) << profile;
    }
  }
  for (const char* file : {"qos.xml", "loopback.xml", "vehicle.xml", "discovery-server.xml", "secure.xml"}) {
    std::ifstream in(kProfilesDir + "/" + file);
    ASSERT_TRUE(in) << file;
    std::ostringstream text;
    text << in.rdbuf();
    EXPECT_EQ(text.str().find("EXCLUSIVE"), std::string::npos) << file;
    EXPECT_EQ(text.str().find("<ownership>"), std::string::npos) << file;
  }
}

// The DDS Security grants (deploy/security/grants, from which make-pki signs every identity's
// permissions) cover every topic of the contract: some identity publishes it and the ground station
// reads it. A topic missing there works on the plain profiles and stops the secure pipeline at start
// (a reader the permissions refuse cannot be created).
TEST(SecurityGrants, EveryTopicHasAPublisherAndTheGroundStationReadsIt) {
  std::ifstream in(std::string(ODONAV_SOURCE_DIR) + "/deploy/security/grants");
  ASSERT_TRUE(in) << "deploy/security/grants";
  std::map<std::string, std::set<std::string>> publishers_of, subscribers_of;
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream fields(line);
    std::string identity, publish, subscribe;
    ASSERT_TRUE(fields >> identity >> publish >> subscribe) << "grants line: " << line;
    auto add = [&](const std::string& list, std::map<std::string, std::set<std::string>>& to) {
      std::istringstream items(list);
      for (std::string topic; std::getline(items, topic, ',');)
        if (topic != "-") to["rt/odonav/" + topic].insert(identity);
    };
    add(publish, publishers_of);
    add(subscribe, subscribers_of);
  }
  for (const auto& spec : topics::kAllTopics) {
    const std::string name = spec.name;
    EXPECT_FALSE(publishers_of[name].empty()) << name << ": no identity may publish it";
    if (name != topics::kCommand.name) {  // the ground station writes commands, it does not read them
      EXPECT_TRUE(subscribers_of[name].count("odonav-ground")) << name << ": the ground station may not read it";
    }
  }
}

TEST(QosProfiles, LoopbackParticipantKeepsEverythingOnLoopback) {
  DomainParticipantQos qos;
  odonav::dds::Participant participant(loopback_options());  // loads the file
  ASSERT_EQ(DomainParticipantFactory::get_instance()->get_participant_qos_from_profile(
                topics::kLoopbackParticipantProfile, qos),
            ReturnCode_t::RETCODE_OK);
  EXPECT_FALSE(qos.transport().use_builtin_transports);
  // UDPv4 only: a SIGKILL leaves a shared-memory port behind that cuts the restarted process off.
  ASSERT_EQ(qos.transport().user_transports.size(), 1u);
  int udp = 0, shm = 0;
  for (const auto& transport : qos.transport().user_transports) {
    if (auto* u = dynamic_cast<eprosima::fastdds::rtps::UDPv4TransportDescriptor*>(transport.get())) {
      ++udp;
      EXPECT_EQ(u->interfaceWhiteList, std::vector<std::string>{"127.0.0.1"});
      EXPECT_GE(u->maxInitialPeersRange, 10u) << "room for ~10 participants on one host";
    } else if (dynamic_cast<eprosima::fastdds::rtps::SharedMemTransportDescriptor*>(transport.get())) {
      ++shm;
    }
  }
  EXPECT_EQ(udp, 1);
  EXPECT_EQ(shm, 0);
  const auto& peers = qos.wire_protocol().builtin.initialPeersList;
  ASSERT_EQ(peers.size(), 1u);
  for (const auto& locator : peers) {
    EXPECT_EQ(eprosima::fastrtps::rtps::IPLocator::toIPv4string(locator), "127.0.0.1");
  }
  EXPECT_EQ(qos.wire_protocol().builtin.discovery_config.leaseDuration.seconds, 15);
}

// The gateway's flow-control writers ("speed max"): named in topics.hpp, defined in qos.xml, the
// sensor writer's QoS contract with only the heartbeat period shortened (100 ms -> 5 ms).
TEST(QosProfiles, GatewayFastAckWriterIsTheSensorWriterWithA5msHeartbeat) {
  odonav::dds::Participant participant(loopback_options());
  auto& publisher = participant.core()->publisher();
  auto& subscriber = participant.core()->subscriber();
  DataWriterQos sensor, fast;
  DataReaderQos reader;
  ASSERT_EQ(publisher.get_datawriter_qos_from_profile(topics::kSensorWriterProfile, sensor), ReturnCode_t::RETCODE_OK);
  ASSERT_EQ(publisher.get_datawriter_qos_from_profile(topics::kGatewayFastAckSensorWriterProfile, fast),
            ReturnCode_t::RETCODE_OK)
      << "qos.xml has no data_writer profile " << topics::kGatewayFastAckSensorWriterProfile;
  ASSERT_EQ(subscriber.get_datareader_qos_from_profile(topics::kSensorReaderProfile, reader), ReturnCode_t::RETCODE_OK);
  EXPECT_EQ(fast.reliability().kind, RELIABLE_RELIABILITY_QOS);
  EXPECT_EQ(fast.durability().kind, TRANSIENT_LOCAL_DURABILITY_QOS);
  EXPECT_EQ(fast.history().kind, KEEP_LAST_HISTORY_QOS);
  EXPECT_EQ(fast.history().depth, 3000);
  EXPECT_EQ(seconds_of(fast.deadline().period), kNoDeadline);
  EXPECT_EQ(fast.ownership().kind, SHARED_OWNERSHIP_QOS);
  // Everything of the contract as odonav_sensor_writer, so it matches the same readers.
  EXPECT_EQ(fast.reliability().kind, sensor.reliability().kind);
  EXPECT_EQ(fast.durability().kind, sensor.durability().kind);
  EXPECT_EQ(fast.history().depth, sensor.history().depth);
  EXPECT_EQ(fast.ownership().kind, sensor.ownership().kind);
  EXPECT_GE(fast.reliability().kind, reader.reliability().kind);
  EXPECT_GE(fast.durability().kind, reader.durability().kind);
  EXPECT_EQ(fast.reliable_writer_qos().times.heartbeatPeriod.to_ns(), 5000000);
  EXPECT_EQ(sensor.reliable_writer_qos().times.heartbeatPeriod.to_ns(), 100000000LL) << "repairs within 0.1 s";
}

// ---- .msg twins against the wire ----

namespace {

struct MsgField {
  std::string type;  // e.g. "float64", "std_msgs/Header", "Counter"
  std::string name;
  bool is_sequence = false;
};

// Replaces a .msg file's fields ("pkg/Type" -> fields) to show the check catches wrong twins.
std::map<std::string, std::vector<MsgField>> g_mutated_msg;

// Fields of idl/<package>/msg/<type>.msg in order; constants (NAME=value) and comments skipped.
std::vector<MsgField> read_msg(const std::string& package, const std::string& type) {
  const auto mutated = g_mutated_msg.find(package + "/" + type);
  if (mutated != g_mutated_msg.end()) return mutated->second;
  const std::string path = std::string(ODONAV_SOURCE_DIR) + "/idl/" + package + "/msg/" + type + ".msg";
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot read " + path);
  std::vector<MsgField> fields;
  std::string line;
  while (std::getline(in, line)) {
    line = line.substr(0, line.find('#'));
    std::istringstream words(line);
    MsgField f;
    if (!(words >> f.type >> f.name)) continue;
    if (f.name.find('=') != std::string::npos) continue;  // a constant: not serialized
    if (f.type.size() > 2 && f.type.compare(f.type.size() - 2, 2, "[]") == 0) {
      f.is_sequence = true;
      f.type.resize(f.type.size() - 2);
    }
    fields.push_back(f);
  }
  return fields;
}

// Reads XCDR1 little endian (what Fast DDS 2.9 writes), alignment relative to the body start.
class CdrReader {
 public:
  CdrReader(const unsigned char* data, std::size_t size) : data_(data), size_(size) {}
  template <class V>
  V read() {
    pos_ = (pos_ + sizeof(V) - 1) / sizeof(V) * sizeof(V);
    if (pos_ + sizeof(V) > size_) throw std::runtime_error("read past the end at byte " + std::to_string(pos_));
    V v;
    std::memcpy(&v, data_ + pos_, sizeof(V));
    pos_ += sizeof(V);
    return v;
  }
  std::string read_string() {
    const auto length = read<std::uint32_t>();  // including the terminating NUL
    if (length == 0 || pos_ + length > size_)
      throw std::runtime_error("bad string length at byte " + std::to_string(pos_));
    if (data_[pos_ + length - 1] != 0)
      throw std::runtime_error("string not NUL terminated at byte " + std::to_string(pos_));
    std::string s(reinterpret_cast<const char*>(data_ + pos_), length - 1);
    pos_ += length;
    return s;
  }
  std::size_t position() const { return pos_; }

 private:
  const unsigned char* data_;
  std::size_t size_;
  std::size_t pos_ = 0;
};

void decode(const std::string& package, const std::string& type, CdrReader& in, const std::string& prefix,
            odonav::test::Fields& out);

void decode_value(const std::string& package, const std::string& type, CdrReader& in, const std::string& path,
                  odonav::test::Fields& out) {
  using odonav::test::text;
  if (type == "bool") {
    const auto b = in.read<std::uint8_t>();
    if (b > 1) throw std::runtime_error(path + ": bool byte " + std::to_string(b));
    out.emplace_back(path, text(b == 1));
  } else if (type == "int8") {
    out.emplace_back(path, text(in.read<std::int8_t>()));
  } else if (type == "uint8" || type == "byte") {
    out.emplace_back(path, text(in.read<std::uint8_t>()));
  } else if (type == "int32") {
    out.emplace_back(path, text(in.read<std::int32_t>()));
  } else if (type == "uint32") {
    out.emplace_back(path, text(in.read<std::uint32_t>()));
  } else if (type == "float64") {
    out.emplace_back(path, text(in.read<double>()));
  } else if (type == "string") {
    out.emplace_back(path, text(in.read_string()));
  } else if (type.find('/') != std::string::npos) {  // "pkg/Type"
    decode(type.substr(0, type.find('/')), type.substr(type.find('/') + 1), in, path + ".", out);
  } else if (!type.empty() && std::isupper(static_cast<unsigned char>(type[0]))) {  // same package
    decode(package, type, in, path + ".", out);
  } else {
    throw std::runtime_error(path + ": type '" + type + "' not handled by this test decoder");
  }
}

void decode(const std::string& package, const std::string& type, CdrReader& in, const std::string& prefix,
            odonav::test::Fields& out) {
  for (const MsgField& f : read_msg(package, type)) {
    if (f.is_sequence) {
      const auto n = in.read<std::uint32_t>();
      for (std::uint32_t i = 0; i < n; ++i) {
        decode_value(package, f.type, in, prefix + f.name + "[" + std::to_string(i) + "]", out);
      }
    } else {
      decode_value(package, f.type, in, prefix + f.name, out);
    }
  }
}

struct Decoded {
  odonav::test::Fields fields;
  std::size_t bytes_read = 0;
  std::size_t bytes_total = 0;
};

/// Serializes `sample` with its generated type and decodes the bytes with the .msg twin.
template <class T>
Decoded serialize_and_decode(const topics::TopicSpec& spec, const T& sample) {
  typename odonav::dds::DdsType<T>::PubSubType type;
  EXPECT_EQ(type.getName(), std::string(spec.dds_type_name));
  eprosima::fastrtps::rtps::SerializedPayload_t payload(type.getSerializedSizeProvider(const_cast<T*>(&sample))());
  if (!type.serialize(const_cast<T*>(&sample), &payload) || payload.length < 4) {
    throw std::runtime_error("serialization failed");
  }
  if (payload.data[0] != 0x00 || payload.data[1] != 0x01) {  // encapsulation CDR_LE (XCDR1)
    throw std::runtime_error("unexpected encapsulation");
  }
  const std::string ros_type = spec.ros_type_name;  // "odonav/msg/Type"
  CdrReader in(payload.data + 4, payload.length - 4);
  Decoded d;
  decode("odonav", ros_type.substr(ros_type.rfind('/') + 1), in, "", d.fields);
  d.bytes_read = in.position();
  d.bytes_total = payload.length - 4;
  return d;
}

template <class T>
void expect_msg_twin_matches_wire(const topics::TopicSpec& spec, const T& sample) {
  SCOPED_TRACE(spec.ros_type_name);
  const Decoded d = serialize_and_decode(spec, sample);
  EXPECT_EQ(d.bytes_read, d.bytes_total) << "the .msg twin does not cover every byte";
  EXPECT_EQ(d.fields, odonav::test::fields(sample));
}

}  // namespace

TEST(MsgTwins, EveryMsgFileDescribesTheCdrLayoutOfItsIdlType) {
  expect_msg_twin_matches_wire(topics::kOdometer, odonav::test::make_odometer());
  expect_msg_twin_matches_wire(topics::kInsAttitude, odonav::test::make_ins_attitude());
  expect_msg_twin_matches_wire(topics::kGnssFix, odonav::test::make_gnss_fix());
  expect_msg_twin_matches_wire(topics::kMisalignment, odonav::test::make_misalignment());
  expect_msg_twin_matches_wire(topics::kScaleFactor, odonav::test::make_scale_factor());
  expect_msg_twin_matches_wire(topics::kDeadReckoning, odonav::test::make_dead_reckoning());
  expect_msg_twin_matches_wire(topics::kNavigationPosition, odonav::test::make_navigation_position());
  expect_msg_twin_matches_wire(topics::kHealth, odonav::test::make_health_sample());
  expect_msg_twin_matches_wire(topics::kCommand, odonav::test::make_command());
}

// CommandKind's wire values: 0-3 kept from the former names, 4 added; the .msg twin's constants say
// the same numbers.
TEST(MsgTwins, CommandKindConstantsAreTheWireValues) {
  namespace msg = odonav::msg;
  EXPECT_EQ(static_cast<uint32_t>(msg::COMMAND_RESET_ESTIMATION), 0u);  // was COMMAND_RESET_CALIBRATION
  EXPECT_EQ(static_cast<uint32_t>(msg::COMMAND_SET_K), 1u);
  EXPECT_EQ(static_cast<uint32_t>(msg::COMMAND_FREEZE_ESTIMATION), 2u);    // was COMMAND_FREEZE_IDENTIFICATION
  EXPECT_EQ(static_cast<uint32_t>(msg::COMMAND_UNFREEZE_ESTIMATION), 3u);  // was COMMAND_UNFREEZE_IDENTIFICATION
  EXPECT_EQ(static_cast<uint32_t>(msg::COMMAND_RELEASE_K), 4u);
  std::ifstream in(std::string(ODONAV_SOURCE_DIR) + "/idl/odonav/msg/Command.msg");
  ASSERT_TRUE(in);
  std::map<std::string, uint32_t> constants;
  std::string line;
  while (std::getline(in, line)) {
    line = line.substr(0, line.find('#'));
    std::istringstream words(line);
    std::string type, assignment;
    if (!(words >> type >> assignment) || assignment.find('=') == std::string::npos) continue;
    EXPECT_EQ(type, "uint32") << assignment;
    constants[assignment.substr(0, assignment.find('='))] =
        static_cast<uint32_t>(std::stoul(assignment.substr(assignment.find('=') + 1)));
  }
  const std::map<std::string, uint32_t> expected{{"COMMAND_RESET_ESTIMATION", msg::COMMAND_RESET_ESTIMATION},
                                                 {"COMMAND_SET_K", msg::COMMAND_SET_K},
                                                 {"COMMAND_FREEZE_ESTIMATION", msg::COMMAND_FREEZE_ESTIMATION},
                                                 {"COMMAND_UNFREEZE_ESTIMATION", msg::COMMAND_UNFREEZE_ESTIMATION},
                                                 {"COMMAND_RELEASE_K", msg::COMMAND_RELEASE_K}};
  EXPECT_EQ(constants, expected);
}

TEST(MsgTwins, TheCheckCatchesSwappedMissingAndMistypedFields) {
  // The same bytes read with a wrong twin must not pass.
  const auto sample = odonav::test::make_ins_attitude();
  const std::vector<MsgField> twin = read_msg("odonav", "InsAttitude");
  ASSERT_EQ(twin[3].name, "pitch_rad");
  ASSERT_EQ(twin[4].name, "roll_rad");
  ASSERT_EQ(twin[5].name, "velocity_east_mps");
  ASSERT_EQ(twin.back().name, "gnss_last_stamp_s");

  // Two float64 fields swapped: every byte read, values land in the wrong fields.
  std::vector<MsgField> swapped = twin;
  std::swap(swapped[3], swapped[4]);
  g_mutated_msg["odonav/InsAttitude"] = swapped;
  const Decoded d_swapped = serialize_and_decode(topics::kInsAttitude, sample);
  EXPECT_EQ(d_swapped.bytes_read, d_swapped.bytes_total);
  EXPECT_NE(d_swapped.fields, odonav::test::fields(sample));

  // The last field (a float64) forgotten: its eight bytes left unread.
  std::vector<MsgField> missing = twin;
  missing.pop_back();
  g_mutated_msg["odonav/InsAttitude"] = missing;
  const Decoded d_missing = serialize_and_decode(topics::kInsAttitude, sample);
  EXPECT_EQ(d_missing.bytes_read + 8, d_missing.bytes_total);

  // A float64 declared uint32: its value and the alignment of what follows go wrong.
  std::vector<MsgField> mistyped = twin;
  mistyped[5].type = "uint32";
  g_mutated_msg["odonav/InsAttitude"] = mistyped;
  const Decoded d_mistyped = serialize_and_decode(topics::kInsAttitude, sample);
  EXPECT_NE(d_mistyped.fields, odonav::test::fields(sample));

  g_mutated_msg.clear();
}
