#include "odonav/dds/endpoints.hpp"

#include <fastdds/dds/core/status/StatusMask.hpp>
#include <fastdds/dds/publisher/qos/DataWriterQos.hpp>
#include <fastdds/dds/subscriber/qos/DataReaderQos.hpp>
#include <spdlog/spdlog.h>

#include <cstring>
#include <stdexcept>

#include "odonav/dds/component.hpp"
#include "odonav/topics.hpp"

namespace odonav::dds::detail {

using eprosima::fastdds::dds::DataReader;
using eprosima::fastdds::dds::DataReaderQos;
using eprosima::fastdds::dds::DataWriter;
using eprosima::fastdds::dds::DataWriterQos;
using eprosima::fastdds::dds::StatusMask;
using eprosima::fastrtps::types::ReturnCode_t;

namespace {
eprosima::fastrtps::Duration_t to_duration(std::chrono::milliseconds timeout) {
  const auto ms = timeout.count() < 0 ? 0 : timeout.count();
  return eprosima::fastrtps::Duration_t(static_cast<int32_t>(ms / 1000), static_cast<uint32_t>((ms % 1000) * 1000000));
}
}  // namespace

// ---- MatchCounter ----

void MatchCounter::set(int current_count) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    count_ = current_count < 0 ? 0 : static_cast<std::size_t>(current_count);
  }
  changed_.notify_all();
}

std::size_t MatchCounter::count() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return count_;
}

bool MatchCounter::wait_for(std::size_t n, std::chrono::milliseconds timeout) const {
  std::unique_lock<std::mutex> lock(mutex_);
  return changed_.wait_for(lock, timeout, [&] { return count_ >= n; });
}

// ---- WriterBase ----

WriterBase::WriterBase(const Participant& participant, const std::string& topic_name, const std::string& qos_profile,
                       eprosima::fastdds::dds::TypeSupport type, const WriterSettings& settings)
    : core_(participant.core()), topic_name_(topic_name) {
  auto& publisher = core_->publisher();
  DataWriterQos qos;
  bool has_profile = false;
  {
    const std::lock_guard<std::mutex> profiles_lock(xml_profiles_mutex());
    has_profile = publisher.get_datawriter_qos_from_profile(qos_profile, qos) == ReturnCode_t::RETCODE_OK;
  }
  if (!has_profile) {
    throw std::runtime_error("odonav::dds::Writer: no data_writer QoS profile named '" + qos_profile + "' for topic '" +
                             topic_name + "' (" + core_->description() + ")");
  }
  auto& topic = core_->topic(topic_name, type);
  if (settings.empty()) {
    writer_ = publisher.create_datawriter_with_profile(&topic, qos_profile, this, StatusMask::publication_matched());
  } else {
    if (settings.ownership_strength) qos.ownership_strength().value = *settings.ownership_strength;
    if (settings.transient) qos.durability().kind = eprosima::fastdds::dds::TRANSIENT_DURABILITY_QOS;
    for (const auto& [name, value] : settings.properties)
      qos.properties().properties().emplace_back(eprosima::fastrtps::rtps::Property(name, value, false));
    writer_ = publisher.create_datawriter(&topic, qos, this, StatusMask::publication_matched());
  }
  if (writer_ == nullptr) {
    if (const auto& security = core_->security()) {
      // Access control returns nullptr for a topic the permissions do not grant (docs/DDS.md §6).
      throw std::runtime_error("odonav::dds::Writer: cannot create the writer of topic '" + topic_name +
                               "': the DDS Security permissions of identity '" + security->identity + "' (" +
                               security->permissions_file + ") do not allow publishing it, or profile '" + qos_profile +
                               "' is inconsistent (see the Fast DDS log; " + core_->description() + ")");
    }
    throw std::runtime_error("odonav::dds::Writer: cannot create the writer of topic '" + topic_name +
                             "' with profile '" + qos_profile + "' (inconsistent QoS? see the Fast DDS log; " +
                             core_->description() + ")");
  }
}

WriterBase::~WriterBase() {
  if (core_->publisher().delete_datawriter(writer_) != ReturnCode_t::RETCODE_OK) {
    spdlog::error("odonav::dds: cannot delete the writer of topic '{}'", topic_name_);
  }
}

bool WriterBase::write_untyped(void* sample) { return writer_->write(sample); }

bool WriterBase::wait_for_acknowledgments(std::chrono::milliseconds timeout) {
  return writer_->wait_for_acknowledgments(to_duration(timeout)) == ReturnCode_t::RETCODE_OK;
}

void WriterBase::on_publication_matched(DataWriter* /*writer*/,
                                        const eprosima::fastdds::dds::PublicationMatchedStatus& status) {
  {
    std::lock_guard<std::mutex> lock(readers_mutex_);
    const auto& handle = status.last_subscription_handle;
    const auto guid = eprosima::fastrtps::rtps::iHandle2GUID(handle);
    if (status.current_count_change > 0) {
      const auto* log = core_->event_log();
      reader_names_[handle] = {core_->participant_name(guid), log == nullptr || log->reader_is_reliable(guid)};
    } else if (status.current_count_change < 0) {
      const auto it = reader_names_.find(handle);
      if (it == reader_names_.end()) {
        lost_.push_back({core_->participant_name(guid), steady_now_s()});
      } else {
        if (it->second.reliable) lost_.push_back({it->second.name, steady_now_s()});
        reader_names_.erase(it);
      }
    }
  }
  matched_.set(status.current_count);
}

std::vector<WriterBase::LostReader> WriterBase::lost_readers() const {
  std::lock_guard<std::mutex> lock(readers_mutex_);
  return lost_;
}

std::string endpoint_key(const eprosima::fastdds::dds::InstanceHandle_t& handle) {
  const eprosima::fastrtps::rtps::octet* bytes = handle.value;  // the GUID: prefix, entity id
  return std::string(reinterpret_cast<const char*>(bytes), 16);
}

// ---- ReaderBase ----

ReaderBase::ReaderBase(const Participant& participant, const std::string& topic_name, const std::string& qos_profile,
                       eprosima::fastdds::dds::TypeSupport type)
    : core_(participant.core()), topic_name_(topic_name), qos_profile_(qos_profile) {
  DataReaderQos qos;
  bool has_profile = false;
  {
    const std::lock_guard<std::mutex> profiles_lock(xml_profiles_mutex());
    has_profile = core_->subscriber().get_datareader_qos_from_profile(qos_profile, qos) == ReturnCode_t::RETCODE_OK;
  }
  if (!has_profile) {
    throw std::runtime_error("odonav::dds::Reader: no data_reader QoS profile named '" + qos_profile + "' for topic '" +
                             topic_name + "' (" + core_->description() + ")");
  }
  topic_ = &core_->topic(topic_name, type);
  track_peers_ = topic_name != odonav::topics::kHealth.name && topic_name != odonav::topics::kCommand.name;
}

void ReaderBase::open(bool listen_for_data, bool listen_for_deadline) {
  StatusMask mask = StatusMask::subscription_matched();
  // Without a data callback the listener must not consume samples: take() does.
  if (listen_for_data) mask << StatusMask::data_available();
  if (listen_for_deadline) mask << StatusMask::requested_deadline_missed();
  reader_ = core_->subscriber().create_datareader_with_profile(topic_, qos_profile_, this, mask);
  if (reader_ == nullptr) {
    if (const auto& security = core_->security()) {
      throw std::runtime_error("odonav::dds::Reader: cannot create the reader of topic '" + topic_name_ +
                               "': the DDS Security permissions of identity '" + security->identity + "' (" +
                               security->permissions_file + ") do not allow subscribing to it, or profile '" +
                               qos_profile_ + "' is inconsistent (see the Fast DDS log; " + core_->description() + ")");
    }
    throw std::runtime_error("odonav::dds::Reader: cannot create the reader of topic '" + topic_name_ +
                             "' with profile '" + qos_profile_ + "' (inconsistent QoS? see the Fast DDS log; " +
                             core_->description() + ")");
  }
}

void ReaderBase::close() {
  {
    std::lock_guard<std::recursive_mutex> lock(state_mutex_);
    if (closed_) return;
    closed_ = true;
  }
  if (reader_ == nullptr) return;
  // Deleting waits for a callback in progress (it holds the reader's mutex); later ones are
  // refused by closed_.
  reader_->set_listener(nullptr);
  if (core_->subscriber().delete_datareader(reader_) != ReturnCode_t::RETCODE_OK) {
    spdlog::error("odonav::dds: cannot delete the reader of topic '{}'", topic_name_);
  }
  reader_ = nullptr;
  // No unmatch callback follows: this reader's writers are no longer anyone's peers.
  std::lock_guard<std::mutex> lock(tracked_mutex_);
  for (const std::string& key : tracked_) core_->peers().unmatched(key);
  tracked_.clear();
}

ReaderBase::~ReaderBase() { close(); }

bool ReaderBase::wait_for_data(std::chrono::milliseconds timeout) {
  return reader_->wait_for_unread_message(to_duration(timeout));
}

void ReaderBase::on_subscription_matched(DataReader* /*reader*/,
                                         const eprosima::fastdds::dds::SubscriptionMatchedStatus& status) {
  if (track_peers_) {
    const auto& handle = status.last_publication_handle;
    const std::string key = endpoint_key(handle);
    std::lock_guard<std::mutex> lock(tracked_mutex_);
    if (status.current_count_change > 0) {
      core_->peers().matched(odonav::stream_name_of_topic(topic_name_), key,
                             core_->participant_name(eprosima::fastrtps::rtps::iHandle2GUID(handle)), steady_now_s());
      tracked_.insert(key);
    } else if (status.current_count_change < 0) {
      core_->peers().unmatched(key);
      tracked_.erase(key);
    }
  }
  matched_.set(status.current_count);
}

void ReaderBase::heard_from(const eprosima::fastdds::dds::InstanceHandle_t& publication) {
  if (track_peers_) core_->peers().heard(endpoint_key(publication), steady_now_s());
}

void ReaderBase::on_data_available(DataReader* reader) {
  {
    std::lock_guard<std::recursive_mutex> lock(state_mutex_);
    if (closed_) return;
  }
  if (reader != nullptr) handle_data_available(*reader);
}

void ReaderBase::on_requested_deadline_missed(DataReader* /*reader*/,
                                              const eprosima::fastdds::dds::RequestedDeadlineMissedStatus& status) {
  std::lock_guard<std::recursive_mutex> lock(state_mutex_);
  if (closed_) return;
  // Fires every period for a silent instance: report the first one only.
  if (silence_.on_deadline_missed(status.last_instance_handle)) instance_went_silent(status.last_instance_handle);
}

}  // namespace odonav::dds::detail
