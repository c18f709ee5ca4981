#pragma once
// A small MCAP writer (https://mcap.dev/spec, format version 0), unchunked, for odonav-ground record.
// No MCAP package exists in Debian, so this implements the subset of the spec a recorder needs:
//
//   magic, Header, then in the data section Schema, Channel and Message records in arrival order,
//   then DataEnd (data-section CRC32), the summary section (Schema, Channel, Statistics records),
//   Summary Offset records, Footer (summary CRC32) and the closing magic.
//
// Crash safety: records are buffered in memory and written to the file only whole, by flush()
// (the recorder calls it every second) or when the buffer grows past a limit. A process killed at
// any moment therefore leaves a file that ends on a record boundary (the last unflushed second
// lost): a streaming reader (e.g. @mcap/core's McapStreamReader) recovers every message up to the
// last flush; only the summary and footer, written by close(), are missing.
//
// Thread safety: every public member locks an internal mutex, so DDS listener threads may call
// write_message() while another thread calls flush().
#include <cstddef>
#include <cstdint>
#include <map>
#include <mutex>
#include <string>
#include <vector>

namespace odonav::ground {

/// CRC-32 (ISO-HDLC / zlib polynomial 0xEDB88320) of `size` bytes, continued from `crc` (0 to start),
/// as MCAP uses for its data-section and summary CRCs.
std::uint32_t crc32_update(std::uint32_t crc, const std::uint8_t* data, std::size_t size);

/// Writes one MCAP file.
class McapWriter {
 public:
  struct Options {
    std::string profile = "ros2";                 ///< Header.profile ("ros2": ROS 2 CDR messages)
    std::string library = "odonav-ground 0.1.0";  ///< Header.library
    /// Buffered bytes above which write_message() flushes by itself (bounds memory).
    std::size_t max_buffer_bytes = 4u << 20;
  };

  /// Creates (or truncates) `path` and writes the magic and the Header record to it at once.
  /// Throws std::runtime_error naming the path when the file cannot be created or written.
  explicit McapWriter(const std::string& path, Options options);
  explicit McapWriter(const std::string& path) : McapWriter(path, Options()) {}
  /// Closes the file (close()) if still open; errors are swallowed (call close() to see them).
  ~McapWriter();
  McapWriter(const McapWriter&) = delete;
  McapWriter& operator=(const McapWriter&) = delete;

  /// Adds a Schema record (ids from 1 up). encoding e.g. "ros2msg"; data the schema text.
  /// Throws std::logic_error after close(), std::length_error past 65535 schemas.
  std::uint16_t add_schema(const std::string& name, const std::string& encoding, const std::string& data);
  /// Adds a Channel record (ids from 0 up) on an existing schema (0 = no schema).
  /// Throws std::invalid_argument for an unknown schema id, std::logic_error after close().
  std::uint16_t add_channel(std::uint16_t schema_id, const std::string& topic, const std::string& message_encoding,
                            const std::map<std::string, std::string>& metadata);
  /// Appends a Message record on `channel_id` with the next sequence number of that channel
  /// (from 1). log_time_ns / publish_time_ns: nanoseconds since the UNIX epoch.
  /// Throws std::invalid_argument for an unknown channel, std::logic_error after close(),
  /// std::runtime_error (naming the file) when an automatic flush fails.
  void write_message(std::uint16_t channel_id, std::uint64_t log_time_ns, std::uint64_t publish_time_ns,
                     const std::uint8_t* data, std::size_t size);

  /// Writes every buffered record to the file (whole records only). Throws std::runtime_error
  /// naming the file on an I/O error. No-op after close().
  void flush();
  /// Writes DataEnd, the summary section, the Footer and the closing magic, and closes the file.
  /// Idempotent. Throws std::runtime_error naming the file on an I/O error.
  void close();

  const std::string& path() const { return path_; }
  std::uint64_t message_count() const;
  /// Messages written so far on one channel (0 for an unknown one).
  std::uint64_t channel_message_count(std::uint16_t channel_id) const;

 private:
  struct Schema {
    std::uint16_t id;
    std::string name, encoding, data;
  };
  struct Channel {
    std::uint16_t id;
    std::uint16_t schema_id;
    std::string topic, message_encoding;
    std::map<std::string, std::string> metadata;
    std::uint32_t next_sequence = 1;
    std::uint64_t message_count = 0;
  };

  void flush_locked();
  void write_to_file(const std::string& bytes);
  static void append_schema(std::string& out, const Schema& s);
  static void append_channel(std::string& out, const Channel& c);

  std::string path_;
  int fd_ = -1;
  Options options_;
  mutable std::mutex mutex_;
  std::string buffer_;             // whole records not yet in the file
  std::uint32_t data_crc_ = 0;     // CRC32 of every data-section byte so far (magic included)
  std::uint64_t file_offset_ = 0;  // bytes in the file + buffer
  std::vector<Schema> schemas_;
  std::vector<Channel> channels_;
  std::uint64_t message_count_ = 0;
  std::uint64_t first_log_time_ns_ = 0, last_log_time_ns_ = 0;
  bool closed_ = false;
};

}  // namespace odonav::ground
