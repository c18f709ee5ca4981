#pragma once
// Typed DDS endpoints: Writer<T> and Reader<T> on a topic, with the QoS of a named profile of
// qos.xml. T is a generated message type listed in odonav/dds/types.hpp.
//
// Threads: Reader callbacks run on Fast DDS listener threads, never concurrently with each other
// for one Reader, with the reader's mutex held; keep them short and never block in them
// (ComponentRuntime::post decides where the work runs).
// Endpoints are neither copyable nor movable (the middleware holds pointers to their listeners):
// hold them by value as members or in a std::unique_ptr.
#include <fastdds/dds/publisher/DataWriter.hpp>
#include <fastdds/dds/publisher/DataWriterListener.hpp>
#include <fastdds/dds/subscriber/DataReader.hpp>
#include <fastdds/dds/subscriber/DataReaderListener.hpp>
#include <fastdds/dds/subscriber/SampleInfo.hpp>

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "odonav/dds/participant.hpp"
#include "odonav/dds/silence_tracker.hpp"
#include "odonav/dds/types.hpp"

namespace odonav::dds {

/// Settings of one writer that depend on the process (its command line), so they cannot live in a
/// shared XML profile: applied on top of the profile's QoS when the writer is created.
struct WriterSettings {
  /// OWNERSHIP_STRENGTH value (Fast DDS holds it unsigned; higher wins). Only meaningful with EXCLUSIVE
  /// ownership, which no odonav profile uses (docs/DDS.md section 4); nothing = the profile's.
  std::optional<uint32_t> ownership_strength;
  /// TRANSIENT durability instead of the profile's: the writer's history outlives the process in
  /// the persistence service named by `properties` (dds.persistence.plugin, ...sqlite3.filename,
  /// dds.persistence.guid; docs/DDS.md §5). Readers stay TRANSIENT_LOCAL: they match.
  bool transient = false;
  /// Extra DDS properties (name, value), not propagated to remote participants.
  std::vector<std::pair<std::string, std::string>> properties;

  bool empty() const { return !ownership_strength && !transient && properties.empty(); }
};

namespace detail {

/// T's generated type support with a key hash that depends on the key alone, safe to compute on
/// several threads at once. fastddsgen 2.x's getKey() serialises the key into a buffer of the type
/// support and hashes it with an MD5 member of it, and:
///  - it does not clear the buffer, so the alignment padding between two key members (Health's
///    vehicle_id and component) keeps the bytes of the previous key serialised there: the same key
///    hashed to another instance handle after another key had been computed;
///  - a participant keeps one registered type support per type for all its writers and readers of
///    that type: a writer computes its sample's key on the writing thread while a reader computes a
///    received sample's on a receive thread (the recorder and the ground station publish Health and
///    read it), one over the other's bytes.
/// Here the buffer is zeroed before each key (its padding then reads 0 whatever came before) and
/// one mutex per type support serialises getKey() (the other members are stateless).
template <class PubSubType>
class ThreadSafeKeyType : public PubSubType {
 public:
  bool getKey(void* data, eprosima::fastrtps::rtps::InstanceHandle_t* handle, bool force_md5 = false) override {
    const std::lock_guard<std::mutex> lock(key_mutex_);
    if (this->m_keyBuffer != nullptr)  // allocated with this length by the generated constructor
      std::memset(this->m_keyBuffer, 0, std::max<std::size_t>(PubSubType::type::getKeyMaxCdrSerializedSize(), 16));
    return PubSubType::getKey(data, handle, force_md5);
  }

 private:
  std::mutex key_mutex_;
};

/// Counts matched remote endpoints, from the listener thread, and lets callers wait for them.
class MatchCounter {
 public:
  void set(int current_count);
  std::size_t count() const;
  bool wait_for(std::size_t n, std::chrono::milliseconds timeout) const;

 private:
  mutable std::mutex mutex_;
  mutable std::condition_variable changed_;
  std::size_t count_ = 0;
};

/// The untyped part of Writer<T>: profile lookup, creation, matching, acknowledgments.
class WriterBase : public eprosima::fastdds::dds::DataWriterListener {
 public:
  WriterBase(const Participant& participant, const std::string& topic_name, const std::string& qos_profile,
             eprosima::fastdds::dds::TypeSupport type, const WriterSettings& settings = {});
  ~WriterBase() override;
  WriterBase(const WriterBase&) = delete;
  WriterBase& operator=(const WriterBase&) = delete;

  std::size_t matched_readers() const { return matched_.count(); }
  bool wait_for_matched(std::size_t readers, std::chrono::milliseconds timeout) const {
    return matched_.wait_for(readers, timeout);
  }
  bool wait_for_acknowledgments(std::chrono::milliseconds timeout);
  const std::string& topic_name() const { return topic_name_; }
  eprosima::fastdds::dds::DataWriter& native() const { return *writer_; }

  /// A matched reader that went away (it left, its lease expired, or it was closed): whatever it
  /// had not acknowledged by then it never gets.
  struct LostReader {
    std::string reader;  ///< the owning participant, as ParticipantCore::participant_name gives it
    double at_s;         ///< steady clock (steady_now_s)
  };
  /// Every RELIABLE reader unmatched since this writer was created, in order (a best-effort reader
  /// is never owed anything).
  std::vector<LostReader> lost_readers() const;

  void on_publication_matched(eprosima::fastdds::dds::DataWriter* writer,
                              const eprosima::fastdds::dds::PublicationMatchedStatus& status) override;

 protected:
  bool write_untyped(void* sample);

 private:
  std::shared_ptr<ParticipantCore> core_;
  std::string topic_name_;
  eprosima::fastdds::dds::DataWriter* writer_ = nullptr;
  MatchCounter matched_;
  mutable std::mutex readers_mutex_;
  struct MatchedReader {
    std::string name;
    bool reliable = true;
  };
  std::map<eprosima::fastdds::dds::InstanceHandle_t, MatchedReader> reader_names_;  // matched readers
  std::vector<LostReader> lost_;
};

/// The untyped part of Reader<T>: profile lookup, creation, matching, deadline edge detection.
/// Locking: Fast DDS calls the listener with its reader mutex held, so state_mutex_ is never held
/// while calling into Fast DDS (that order would deadlock against the listener threads).
class ReaderBase : public eprosima::fastdds::dds::DataReaderListener {
 public:
  ~ReaderBase() override;
  ReaderBase(const ReaderBase&) = delete;
  ReaderBase& operator=(const ReaderBase&) = delete;

  std::size_t matched_writers() const { return matched_.count(); }
  bool wait_for_matched(std::size_t writers, std::chrono::milliseconds timeout) const {
    return matched_.wait_for(writers, timeout);
  }
  bool wait_for_data(std::chrono::milliseconds timeout);
  const std::string& topic_name() const { return topic_name_; }
  eprosima::fastdds::dds::DataReader& native() const { return *reader_; }

  void on_subscription_matched(eprosima::fastdds::dds::DataReader* reader,
                               const eprosima::fastdds::dds::SubscriptionMatchedStatus& status) override;
  void on_data_available(eprosima::fastdds::dds::DataReader* reader) override;
  void on_requested_deadline_missed(eprosima::fastdds::dds::DataReader* reader,
                                    const eprosima::fastdds::dds::RequestedDeadlineMissedStatus& status) override;

 protected:
  /// Checks the profile and the topic; the DDS reader itself is created by open().
  ReaderBase(const Participant& participant, const std::string& topic_name, const std::string& qos_profile,
             eprosima::fastdds::dds::TypeSupport type);
  /// Creates the DDS reader. Called by the derived constructor, once its members exist, so no
  /// callback can reach a half-constructed object.
  void open(bool listen_for_data, bool listen_for_deadline);
  /// Deletes the DDS reader; after it returns no callback runs. The derived destructor calls it
  /// first, so no callback can reach a half-destroyed object.
  void close();

  /// Listener thread: samples are available in `reader` (only when open() asked to listen for
  /// data). Use `reader`, not native(): the first samples can arrive while create_datareader has
  /// not returned yet, before reader_ is set (a restarted process joining a running stream).
  virtual void handle_data_available(eprosima::fastdds::dds::DataReader& reader) = 0;
  /// Called under state_mutex_, once per silence edge of an instance.
  virtual void instance_went_silent(const eprosima::fastdds::dds::InstanceHandle_t& instance) = 0;
  /// A sample of the remote writer `publication` (SampleInfo::publication_handle) arrived: the
  /// participant's peer tracker hears from it (data topics only).
  void heard_from(const eprosima::fastdds::dds::InstanceHandle_t& publication);

  SilenceTracker<eprosima::fastdds::dds::InstanceHandle_t> silence_;
  std::recursive_mutex state_mutex_;  // user callbacks and last samples; see the class comment
  bool closed_ = false;               // guarded by state_mutex_

 private:
  std::shared_ptr<ParticipantCore> core_;
  std::string topic_name_;
  std::string qos_profile_;
  eprosima::fastdds::dds::Topic* topic_ = nullptr;
  eprosima::fastdds::dds::DataReader* reader_ = nullptr;
  MatchCounter matched_;
  bool track_peers_ = false;  // a data topic: its writers are reported to core_->peers()
  std::mutex tracked_mutex_;
  std::set<std::string> tracked_;  // writer keys reported matched to core_->peers()
};

/// The peer tracker's key of a remote endpoint: its GUID (the handle's 16 bytes).
std::string endpoint_key(const eprosima::fastdds::dds::InstanceHandle_t& handle);

}  // namespace detail

/// Writes samples of T on one topic.
template <class T>
class Writer : public detail::WriterBase {
 public:
  /// Creates the writer on `topic_name` (registering T and creating the topic on first use) with
  /// the data_writer profile `qos_profile` of the participant's QoS file.
  /// Throws std::runtime_error naming the profile, topic and participant files when the profile
  /// does not exist or the writer cannot be created.
  Writer(const Participant& participant, const std::string& topic_name, const std::string& qos_profile)
      : WriterBase(
            participant, topic_name, qos_profile,
            eprosima::fastdds::dds::TypeSupport(new detail::ThreadSafeKeyType<typename DdsType<T>::PubSubType>())) {}
  /// The same, with per-writer settings on top of the profile (ownership strength, persistence).
  /// Also throws std::runtime_error when the settings make the QoS inconsistent.
  Writer(const Participant& participant, const std::string& topic_name, const std::string& qos_profile,
         const WriterSettings& settings)
      : WriterBase(
            participant, topic_name, qos_profile,
            eprosima::fastdds::dds::TypeSupport(new detail::ThreadSafeKeyType<typename DdsType<T>::PubSubType>()),
            settings) {}

  /// Publishes one sample. Returns false if the middleware refused it (for a RELIABLE writer whose
  /// history is full of unacknowledged samples, after the profile's max_blocking_time).
  bool write(const T& sample) {
    // Fast DDS 2.9 takes a non-const pointer but only serializes the sample.
    return write_untyped(const_cast<T*>(&sample));
  }

  // Inherited: matched_readers(), wait_for_matched(n, timeout),
  // wait_for_acknowledgments(timeout) (true when every matched reliable reader has acknowledged
  // everything written so far: flow control when replaying as fast as possible), topic_name().
};

/// Reads samples of T from one topic, by callback or by polling.
template <class T>
class Reader : public detail::ReaderBase {
 public:
  /// Called on a listener thread for each sample received.
  using DataCallback = std::function<void(const T& sample)>;
  /// Called edge-detected per instance (per key): once with silent = true when an instance misses
  /// its QoS deadline (the profile must set one), once with silent = false when its data returns;
  /// never once per deadline period. `last_sample` is the last sample received for that instance
  /// (its key fields say which vehicle/component). Runs on a listener thread, or, for the return
  /// edge in polling mode, on the thread calling take().
  using SilenceCallback = std::function<void(const T& last_sample, bool silent)>;

  /// Creates the reader on `topic_name` with the data_reader profile `qos_profile`.
  /// With on_data, every sample goes to the callback (and take() returns nothing); without it,
  /// samples wait in the reader history (the profile's depth) for take().
  /// Throws std::runtime_error naming the profile, topic and participant files when the profile
  /// does not exist or the reader cannot be created.
  Reader(const Participant& participant, const std::string& topic_name, const std::string& qos_profile,
         DataCallback on_data = nullptr, SilenceCallback on_silence = nullptr)
      : ReaderBase(
            participant, topic_name, qos_profile,
            eprosima::fastdds::dds::TypeSupport(new detail::ThreadSafeKeyType<typename DdsType<T>::PubSubType>())),
        on_data_(std::move(on_data)),
        on_silence_(std::move(on_silence)) {
    open(static_cast<bool>(on_data_), static_cast<bool>(on_silence_));
  }

  ~Reader() override { close(); }

  /// Takes every sample available now, oldest first. Always empty when a data callback is set.
  std::vector<T> take() {
    std::vector<T> samples;
    if (on_data_) return samples;
    T sample;
    eprosima::fastdds::dds::SampleInfo info;
    while (native().take_next_sample(&sample, &info) == eprosima::fastrtps::types::ReturnCode_t::RETCODE_OK) {
      if (!info.valid_data) continue;  // disposal or unregistration notices carry no data
      heard_from(info.publication_handle);
      note_arrival(info.instance_handle, sample);
      samples.push_back(sample);
    }
    return samples;
  }

  // Inherited: matched_writers(), wait_for_matched(n, timeout), wait_for_data(timeout) (true when
  // an unread sample is available), topic_name(), native().

 protected:
  void handle_data_available(eprosima::fastdds::dds::DataReader& reader) override {
    T sample;
    eprosima::fastdds::dds::SampleInfo info;
    while (reader.take_next_sample(&sample, &info) == eprosima::fastrtps::types::ReturnCode_t::RETCODE_OK) {
      if (!info.valid_data) continue;
      heard_from(info.publication_handle);
      note_arrival(info.instance_handle, sample);
      std::lock_guard<std::recursive_mutex> lock(state_mutex_);
      if (!closed_) on_data_(sample);
    }
  }

  void instance_went_silent(const eprosima::fastdds::dds::InstanceHandle_t& instance) override {
    if (!on_silence_) return;
    const auto it = last_sample_.find(instance);
    on_silence_(it != last_sample_.end() ? it->second : T{}, true);
  }

 private:
  void note_arrival(const eprosima::fastdds::dds::InstanceHandle_t& instance, const T& sample) {
    if (!on_silence_) return;
    std::lock_guard<std::recursive_mutex> lock(state_mutex_);
    if (closed_) return;
    last_sample_[instance] = sample;
    if (silence_.on_data(instance)) on_silence_(sample, false);
  }

  DataCallback on_data_;
  SilenceCallback on_silence_;
  std::map<eprosima::fastdds::dds::InstanceHandle_t, T> last_sample_;  // guarded by state_mutex_
};

}  // namespace odonav::dds
