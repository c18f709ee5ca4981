#include "odonav/ground/mcap_writer.hpp"

#include <zlib.h>

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstring>
#include <limits>
#include <stdexcept>

namespace odonav::ground {

namespace {

// Opcodes of the MCAP spec.
constexpr std::uint8_t kOpHeader = 0x01;
constexpr std::uint8_t kOpFooter = 0x02;
constexpr std::uint8_t kOpSchema = 0x03;
constexpr std::uint8_t kOpChannel = 0x04;
constexpr std::uint8_t kOpMessage = 0x05;
constexpr std::uint8_t kOpStatistics = 0x0B;
constexpr std::uint8_t kOpSummaryOffset = 0x0E;
constexpr std::uint8_t kOpDataEnd = 0x0F;
constexpr std::array<std::uint8_t, 8> kMagic{0x89, 'M', 'C', 'A', 'P', '0', '\r', '\n'};

// Little-endian primitives of the spec: every integer is little endian; strings and byte arrays are
// prefixed by a uint32 length; maps by their uint32 byte length.
void put_u8(std::string& out, std::uint8_t v) { out.push_back(static_cast<char>(v)); }
void put_u16(std::string& out, std::uint16_t v) {
  for (int i = 0; i < 2; ++i) out.push_back(static_cast<char>((v >> (8 * i)) & 0xFF));
}
void put_u32(std::string& out, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) out.push_back(static_cast<char>((v >> (8 * i)) & 0xFF));
}
void put_u64(std::string& out, std::uint64_t v) {
  for (int i = 0; i < 8; ++i) out.push_back(static_cast<char>((v >> (8 * i)) & 0xFF));
}
void put_string(std::string& out, const std::string& s) {
  if (s.size() > std::numeric_limits<std::uint32_t>::max()) throw std::length_error("MCAP string too long");
  put_u32(out, static_cast<std::uint32_t>(s.size()));
  out += s;
}
void put_record(std::string& out, std::uint8_t opcode, const std::string& content) {
  put_u8(out, opcode);
  put_u64(out, content.size());
  out += content;
}

}  // namespace

std::uint32_t crc32_update(std::uint32_t crc, const std::uint8_t* data, std::size_t size) {
  // zlib's CRC-32 (the one MCAP specifies), fed in pieces its uInt length can hold.
  uLong c = crc;
  while (size > 0) {
    const uInt n = static_cast<uInt>(std::min<std::size_t>(size, std::numeric_limits<uInt>::max()));
    c = ::crc32(c, data, n);
    data += n;
    size -= n;
  }
  return static_cast<std::uint32_t>(c);
}

McapWriter::McapWriter(const std::string& path, Options options) : path_(path), options_(std::move(options)) {
  fd_ = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd_ < 0) {
    throw std::runtime_error("MCAP: cannot create '" + path + "': " + std::strerror(errno));
  }
  buffer_.append(reinterpret_cast<const char*>(kMagic.data()), kMagic.size());
  std::string header;
  put_string(header, options_.profile);
  put_string(header, options_.library);
  put_record(buffer_, kOpHeader, header);
  file_offset_ = buffer_.size();
  // The magic and Header go out at once: even an empty recording is a recognisable MCAP file.
  flush_locked();
}

McapWriter::~McapWriter() {
  try {
    close();
  } catch (...) {
    // A destructor must not throw; close() explicitly to see the error.
  }
  if (fd_ >= 0) ::close(fd_);
}

void McapWriter::append_schema(std::string& out, const Schema& s) {
  std::string content;
  put_u16(content, s.id);
  put_string(content, s.name);
  put_string(content, s.encoding);
  put_string(content, s.data);  // `bytes` with a uint32 length prefix, same layout as a string
  put_record(out, kOpSchema, content);
}

void McapWriter::append_channel(std::string& out, const Channel& c) {
  std::string content;
  put_u16(content, c.id);
  put_u16(content, c.schema_id);
  put_string(content, c.topic);
  put_string(content, c.message_encoding);
  std::string map;
  for (const auto& [key, value] : c.metadata) {
    put_string(map, key);
    put_string(map, value);
  }
  put_u32(content, static_cast<std::uint32_t>(map.size()));
  content += map;
  put_record(out, kOpChannel, content);
}

std::uint16_t McapWriter::add_schema(const std::string& name, const std::string& encoding, const std::string& data) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (closed_) throw std::logic_error("MCAP '" + path_ + "': add_schema after close");
  if (schemas_.size() >= 65535) throw std::length_error("MCAP '" + path_ + "': more than 65535 schemas");
  Schema s{static_cast<std::uint16_t>(schemas_.size() + 1), name, encoding, data};  // 0 means "no schema"
  const std::size_t before = buffer_.size();
  append_schema(buffer_, s);
  file_offset_ += buffer_.size() - before;
  schemas_.push_back(std::move(s));
  return schemas_.back().id;
}

std::uint16_t McapWriter::add_channel(std::uint16_t schema_id, const std::string& topic,
                                      const std::string& message_encoding,
                                      const std::map<std::string, std::string>& metadata) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (closed_) throw std::logic_error("MCAP '" + path_ + "': add_channel after close");
  if (schema_id > schemas_.size()) {
    throw std::invalid_argument("MCAP '" + path_ + "': channel '" + topic + "' refers to unknown schema id " +
                                std::to_string(schema_id));
  }
  if (channels_.size() >= 65536) throw std::length_error("MCAP '" + path_ + "': more than 65536 channels");
  Channel c;
  c.id = static_cast<std::uint16_t>(channels_.size());
  c.schema_id = schema_id;
  c.topic = topic;
  c.message_encoding = message_encoding;
  c.metadata = metadata;
  const std::size_t before = buffer_.size();
  append_channel(buffer_, c);
  file_offset_ += buffer_.size() - before;
  channels_.push_back(std::move(c));
  return channels_.back().id;
}

void McapWriter::write_message(std::uint16_t channel_id, std::uint64_t log_time_ns, std::uint64_t publish_time_ns,
                               const std::uint8_t* data, std::size_t size) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (closed_) throw std::logic_error("MCAP '" + path_ + "': write_message after close");
  if (channel_id >= channels_.size()) {
    throw std::invalid_argument("MCAP '" + path_ + "': unknown channel id " + std::to_string(channel_id));
  }
  Channel& c = channels_[channel_id];
  const std::size_t before = buffer_.size();
  put_u8(buffer_, kOpMessage);
  put_u64(buffer_, 2 + 4 + 8 + 8 + static_cast<std::uint64_t>(size));
  put_u16(buffer_, channel_id);
  put_u32(buffer_, c.next_sequence++);
  put_u64(buffer_, log_time_ns);
  put_u64(buffer_, publish_time_ns);
  buffer_.append(reinterpret_cast<const char*>(data), size);
  file_offset_ += buffer_.size() - before;
  ++c.message_count;
  if (message_count_ == 0 || log_time_ns < first_log_time_ns_) first_log_time_ns_ = log_time_ns;
  if (message_count_ == 0 || log_time_ns > last_log_time_ns_) last_log_time_ns_ = log_time_ns;
  ++message_count_;
  if (buffer_.size() >= options_.max_buffer_bytes) flush_locked();
}

void McapWriter::write_to_file(const std::string& bytes) {
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd_, bytes.data() + done, bytes.size() - done);
    if (n < 0) {
      if (errno == EINTR) continue;
      throw std::runtime_error("MCAP: cannot write '" + path_ + "': " + std::strerror(errno));
    }
    done += static_cast<std::size_t>(n);
  }
}

void McapWriter::flush_locked() {
  if (buffer_.empty() || fd_ < 0) return;
  data_crc_ = crc32_update(data_crc_, reinterpret_cast<const std::uint8_t*>(buffer_.data()), buffer_.size());
  std::string out;
  out.swap(buffer_);
  write_to_file(out);
}

void McapWriter::flush() {
  std::lock_guard<std::mutex> lock(mutex_);
  if (closed_) return;
  flush_locked();
}

void McapWriter::close() {
  std::lock_guard<std::mutex> lock(mutex_);
  if (closed_) return;
  closed_ = true;
  flush_locked();  // the data section is complete in the file and in data_crc_

  std::string tail;
  {
    std::string data_end;
    put_u32(data_end, data_crc_);
    put_record(tail, kOpDataEnd, data_end);
  }
  const std::uint64_t summary_start = file_offset_ + tail.size();
  std::string summary;
  // Groups of the summary section, each indexed by a Summary Offset record.
  struct Group {
    std::uint8_t opcode;
    std::uint64_t start, length;
  };
  std::vector<Group> groups;
  auto begin_group = [&](std::uint8_t opcode) { groups.push_back({opcode, summary_start + summary.size(), 0}); };
  auto end_group = [&] { groups.back().length = summary_start + summary.size() - groups.back().start; };
  if (!schemas_.empty()) {
    begin_group(kOpSchema);
    for (const Schema& s : schemas_) append_schema(summary, s);
    end_group();
  }
  if (!channels_.empty()) {
    begin_group(kOpChannel);
    for (const Channel& c : channels_) append_channel(summary, c);
    end_group();
  }
  {
    begin_group(kOpStatistics);
    std::string stats;
    put_u64(stats, message_count_);
    put_u16(stats, static_cast<std::uint16_t>(schemas_.size()));
    put_u32(stats, static_cast<std::uint32_t>(channels_.size()));
    put_u32(stats, 0);  // attachments
    put_u32(stats, 0);  // metadata
    put_u32(stats, 0);  // chunks (unchunked file)
    put_u64(stats, message_count_ ? first_log_time_ns_ : 0);
    put_u64(stats, message_count_ ? last_log_time_ns_ : 0);
    std::string counts;
    for (const Channel& c : channels_) {
      put_u16(counts, c.id);
      put_u64(counts, c.message_count);
    }
    put_u32(stats, static_cast<std::uint32_t>(counts.size()));
    stats += counts;
    put_record(summary, kOpStatistics, stats);
    end_group();
  }
  const std::uint64_t summary_offset_start = summary_start + summary.size();
  for (const Group& g : groups) {
    std::string so;
    put_u8(so, g.opcode);
    put_u64(so, g.start);
    put_u64(so, g.length);
    put_record(summary, kOpSummaryOffset, so);
  }
  // Footer: the summary CRC covers the summary section and the Footer up to summary_offset_start.
  std::string footer_prefix;
  put_u8(footer_prefix, kOpFooter);
  put_u64(footer_prefix, 8 + 8 + 4);
  put_u64(footer_prefix, summary_start);
  put_u64(footer_prefix, summary_offset_start);
  std::uint32_t crc = crc32_update(0, reinterpret_cast<const std::uint8_t*>(summary.data()), summary.size());
  crc = crc32_update(crc, reinterpret_cast<const std::uint8_t*>(footer_prefix.data()), footer_prefix.size());
  tail += summary;
  tail += footer_prefix;
  put_u32(tail, crc);
  tail.append(reinterpret_cast<const char*>(kMagic.data()), kMagic.size());
  write_to_file(tail);
  file_offset_ += tail.size();
  const int fd = fd_;
  fd_ = -1;
  if (::close(fd) != 0) throw std::runtime_error("MCAP: cannot close '" + path_ + "': " + std::strerror(errno));
}

std::uint64_t McapWriter::message_count() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return message_count_;
}

std::uint64_t McapWriter::channel_message_count(std::uint16_t channel_id) const {
  std::lock_guard<std::mutex> lock(mutex_);
  return channel_id < channels_.size() ? channels_[channel_id].message_count : 0;
}

}  // namespace odonav::ground
