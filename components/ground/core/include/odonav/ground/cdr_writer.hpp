#pragma once
// A little-endian plain-CDR (XCDR1) writer for the standard ROS 2 messages the ground station
// derives (sensor_msgs/NavSatFix, diagnostic_msgs/DiagnosticArray): the bytes rmw implementations
// put on the wire, encapsulation header {0x00, 0x01, 0x00, 0x00} first. Primitives are aligned to
// their size, counted from the end of the encapsulation header, as CDR requires. odonav's own topics
// are serialized by their generated type support instead; these types have none in the contract.
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

namespace odonav::ground {

class CdrWriter {
 public:
  CdrWriter() { bytes_ = {0x00, 0x01, 0x00, 0x00}; }  // CDR_LE, no options

  void u8(std::uint8_t v) { put(&v, 1); }
  void i8(std::int8_t v) { put(&v, 1); }
  void u16(std::uint16_t v) { put(&v, 2); }
  void i32(std::int32_t v) { put(&v, 4); }
  void u32(std::uint32_t v) { put(&v, 4); }
  void f64(double v) { put(&v, 8); }
  /// A string: uint32 length counting the terminating NUL, the bytes, the NUL.
  void str(const std::string& s) {
    u32(static_cast<std::uint32_t>(s.size() + 1));
    bytes_.insert(bytes_.end(), s.begin(), s.end());
    bytes_.push_back(0);
  }
  /// The length prefix of an unbounded sequence.
  void sequence_length(std::size_t n) { u32(static_cast<std::uint32_t>(n)); }

  const std::vector<std::uint8_t>& bytes() const { return bytes_; }
  std::vector<std::uint8_t> take() { return std::move(bytes_); }

 private:
  static_assert(sizeof(double) == 8, "IEEE 754 binary64 expected");
  static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__, "CDR_LE is written in host order");
  void put(const void* v, std::size_t size) {
    // Alignment is relative to the payload (after the 4-byte encapsulation header). This host is
    // little-endian (x86-64 / aarch64 Linux), matching the CDR_LE header.
    const std::size_t offset = bytes_.size() - 4;
    bytes_.resize(bytes_.size() + (size - offset % size) % size, 0);
    const auto* p = static_cast<const std::uint8_t*>(v);
    bytes_.insert(bytes_.end(), p, p + size);
  }
  std::vector<std::uint8_t> bytes_;
};

}  // namespace odonav::ground
