#include "odonav/gateway/candump_source.hpp"

#include <spdlog/spdlog.h>

#include <charconv>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "odonav/config.hpp"

namespace odonav::gateway {

namespace {

constexpr double kPi = 3.14159265358979323846;

ConfigError channel_error(const std::string& channel, const std::string& why) {
  return ConfigError("--can-odometer '" + channel + "': " + why +
                     " (accepted: ccvs1[:sa=N], etc1[:sa=N], signal:id=<3|8 hex digits>,start=<bit>,length=<bits>,"
                     "as=counter|speed[,order=intel|motorola][,signed=0|1][,scale=X][,offset=X][,wrap=<bits>]; "
                     "several separated by ';')");
}

std::vector<std::string> split(const std::string& s, char sep) {
  std::vector<std::string> out;
  std::string cur;
  std::istringstream in(s);
  while (std::getline(in, cur, sep)) out.push_back(cur);
  if (!s.empty() && s.back() == sep) out.emplace_back();
  return out;
}

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t");
  if (b == std::string::npos) return "";
  return s.substr(b, s.find_last_not_of(" \t") - b + 1);
}

bool parse_unsigned(const std::string& s, unsigned long max, unsigned long& out) {
  if (s.empty()) return false;
  const auto r = std::from_chars(s.data(), s.data() + s.size(), out);
  return r.ec == std::errc() && r.ptr == s.data() + s.size() && out <= max;
}

bool parse_finite(const std::string& s, double& out) {
  if (s.empty()) return false;
  const auto r = std::from_chars(s.data(), s.data() + s.size(), out);
  return r.ec == std::errc() && r.ptr == s.data() + s.size() && std::isfinite(out);
}

CanChannelSpec parse_channel(const std::string& text) {
  CanChannelSpec c;
  const std::size_t colon = text.find(':');
  const std::string kind = trim(text.substr(0, colon));
  const std::vector<std::string> params =
      colon == std::string::npos ? std::vector<std::string>{} : split(text.substr(colon + 1), ',');
  if (kind == "ccvs1" || kind == "etc1") {
    c.kind = kind == "ccvs1" ? CanChannelSpec::Kind::kCcvs1 : CanChannelSpec::Kind::kEtc1;
    for (const std::string& p0 : params) {
      const std::string p = trim(p0);
      unsigned long sa = 0;
      if (p.rfind("sa=", 0) != 0 || !parse_unsigned(p.substr(3), 255, sa))
        throw channel_error(text, "'" + p + "' is not sa=<source address 0..255>");
      c.source_address = static_cast<std::uint8_t>(sa);
    }
    return c;
  }
  if (kind != "signal") throw channel_error(text, "unknown decoder '" + kind + "'");
  bool have_id = false, have_start = false, have_length = false, have_as = false;
  unsigned long wrap = 0;
  for (const std::string& p0 : params) {
    const std::string p = trim(p0);
    const std::size_t eq = p.find('=');
    if (eq == std::string::npos) throw channel_error(text, "'" + p + "' is not key=value");
    const std::string key = p.substr(0, eq), v = p.substr(eq + 1);
    unsigned long u = 0;
    if (key == "id") {
      if ((v.size() != 3 && v.size() != 8) || v.find_first_not_of("0123456789abcdefABCDEF") != std::string::npos)
        throw channel_error(text,
                            "id '" + v + "' is neither 3 hex digits (11-bit) nor 8 (29-bit), as candump prints it");
      c.signal.id = static_cast<std::uint32_t>(std::stoul(v, nullptr, 16));
      c.signal.extended = v.size() == 8;
      have_id = true;
    } else if (key == "start") {
      if (!parse_unsigned(v, 511, u)) throw channel_error(text, "start '" + v + "' is not a bit 0..511");
      c.signal.start_bit = static_cast<unsigned>(u);
      have_start = true;
    } else if (key == "length") {
      if (!parse_unsigned(v, 64, u) || u == 0) throw channel_error(text, "length '" + v + "' is not 1..64 bits");
      c.signal.length_bits = static_cast<unsigned>(u);
      have_length = true;
    } else if (key == "order") {
      if (v == "intel")
        c.signal.order = SignalSpec::ByteOrder::kIntel;
      else if (v == "motorola")
        c.signal.order = SignalSpec::ByteOrder::kMotorola;
      else
        throw channel_error(text, "order '" + v + "' is not intel or motorola");
    } else if (key == "signed") {
      if (v != "0" && v != "1") throw channel_error(text, "signed '" + v + "' is not 0 or 1");
      c.signal.is_signed = v == "1";
    } else if (key == "scale") {
      if (!parse_finite(v, c.signal.scale) || c.signal.scale == 0.0)
        throw channel_error(text, "scale '" + v + "' is not a finite non-zero number");
    } else if (key == "offset") {
      if (!parse_finite(v, c.signal.offset)) throw channel_error(text, "offset '" + v + "' is not a finite number");
    } else if (key == "wrap") {
      if (!parse_unsigned(v, 64, wrap) || wrap == 0) throw channel_error(text, "wrap '" + v + "' is not 1..64 bits");
    } else if (key == "as") {
      if (v == "counter")
        c.kind = CanChannelSpec::Kind::kSignalCounter;
      else if (v == "speed")
        c.kind = CanChannelSpec::Kind::kSignalSpeed;
      else
        throw channel_error(text, "as '" + v + "' is not counter or speed");
      have_as = true;
    } else {
      throw channel_error(text, "unknown key '" + key + "'");
    }
  }
  if (!have_id || !have_start || !have_length || !have_as)
    throw channel_error(text, "id, start, length and as are required");
  const std::string why = check_signal(c.signal);
  if (!why.empty()) throw channel_error(text, why);
  if (c.kind == CanChannelSpec::Kind::kSignalCounter) {
    if (c.signal.is_signed) throw channel_error(text, "a counter is unsigned");
    c.counter_width_bits = wrap ? static_cast<unsigned>(wrap) : c.signal.length_bits;
    if (c.counter_width_bits > c.signal.length_bits) throw channel_error(text, "wrap wider than the signal");
  } else if (wrap) {
    throw channel_error(text, "wrap applies to as=counter only");
  }
  return c;
}

}  // namespace

std::string to_string(const CanChannelSpec& spec) {
  const auto sa = [&] { return spec.source_address ? ":sa=" + std::to_string(*spec.source_address) : std::string(); };
  switch (spec.kind) {
    case CanChannelSpec::Kind::kCcvs1: return "ccvs1" + sa();
    case CanChannelSpec::Kind::kEtc1: return "etc1" + sa();
    default: break;
  }
  char id[16];
  std::snprintf(id, sizeof(id), spec.signal.extended ? "%08X" : "%03X", spec.signal.id);
  std::ostringstream s;
  s << "signal:id=" << id << ",start=" << spec.signal.start_bit << ",length=" << spec.signal.length_bits
    << ",order=" << (spec.signal.order == SignalSpec::ByteOrder::kIntel ? "intel" : "motorola")
    << ",signed=" << (spec.signal.is_signed ? 1 : 0) << ",scale=" << spec.signal.scale
    << ",offset=" << spec.signal.offset
    << (spec.kind == CanChannelSpec::Kind::kSignalCounter
            ? ",as=counter,wrap=" + std::to_string(spec.counter_width_bits)
            : std::string(",as=speed"));
  return s.str();
}

std::vector<CanChannelSpec> parse_can_channels(const std::string& text) {
  std::vector<CanChannelSpec> out;
  for (const std::string& part : split(text, ';')) {
    const std::string t = trim(part);
    if (t.empty()) throw channel_error(text, "an empty channel");
    out.push_back(parse_channel(t));
  }
  if (out.empty()) throw channel_error(text, "no channel");
  return out;
}

void validate(const CanOdometerConfig& c) {
  const auto in = [](double v, double lo, double hi) { return std::isfinite(v) && v > lo && v <= hi; };
  if (c.channels.empty()) throw ConfigError("--can-odometer: no channel");
  if (!in(c.pulses_per_m, 0.0, 1e6)) throw ConfigError("--can-pulses-per-m: must be in (0, 1e6] pulses/m");
  if (!in(c.gear_ratio, 0.0, 1000.0)) throw ConfigError("--can-gear-ratio: must be in (0, 1000]");
  if (!in(c.sprocket_radius_m, 0.0, 5.0)) throw ConfigError("--can-sprocket-radius-m: must be in (0, 5] m");
  if (!(std::isfinite(c.etc1_pulses_per_rev) && c.etc1_pulses_per_rev >= 0.0 && c.etc1_pulses_per_rev <= 1e6))
    throw ConfigError("--can-etc1-pulses-per-rev: must be in [0, 1e6] pulses/revolution");
}

CanOdometer::CanOdometer(CanOdometerConfig config) : config_(std::move(config)) {
  validate(config_);
  channels_.resize(config_.channels.size());
}

bool CanOdometer::matches(const CanChannelSpec& spec, const CanFrame& frame) const {
  if (frame.remote || frame.error_frame) return false;
  switch (spec.kind) {
    case CanChannelSpec::Kind::kCcvs1:
    case CanChannelSpec::Kind::kEtc1: {
      if (!frame.extended) return false;  // J1939 uses 29-bit identifiers only
      const std::uint32_t pgn = spec.kind == CanChannelSpec::Kind::kCcvs1 ? kPgnCcvs1 : kPgnEtc1;
      return j1939_pgn(frame.id) == pgn &&
             (!spec.source_address || *spec.source_address == j1939_source_address(frame.id));
    }
    default: return frame.extended == spec.signal.extended && frame.id == spec.signal.id;
  }
}

Decoded CanOdometer::value(const CanChannelSpec& spec, const CanFrame& frame) const {
  switch (spec.kind) {
    case CanChannelSpec::Kind::kCcvs1: {
      Decoded d = ccvs1_wheel_speed_mps(frame);
      d.value *= config_.pulses_per_m;
      return d;
    }
    case CanChannelSpec::Kind::kEtc1: {
      Decoded d = etc1_output_shaft_rev_per_s(frame);
      // Pulses per shaft revolution, or the track speed: shaft rev/s / gear ratio x 2 pi r.
      d.value = config_.etc1_pulses_per_rev > 0.0
                    ? d.value * config_.etc1_pulses_per_rev
                    : d.value / config_.gear_ratio * 2.0 * kPi * config_.sprocket_radius_m * config_.pulses_per_m;
      return d;
    }
    case CanChannelSpec::Kind::kSignalCounter: {
      const auto raw = extract_raw(frame, spec.signal);
      if (!raw) return {DecodeStatus::kTooShort, 0.0};
      const std::uint64_t mask =
          spec.counter_width_bits >= 64 ? ~std::uint64_t{0} : (std::uint64_t{1} << spec.counter_width_bits) - 1;
      return {DecodeStatus::kOk, static_cast<double>(*raw & mask)};
    }
    case CanChannelSpec::Kind::kSignalSpeed: {
      Decoded d = decode_signal(frame, spec.signal);
      d.value *= config_.pulses_per_m;
      return d;
    }
  }
  return {DecodeStatus::kError, 0.0};
}

void CanOdometer::problem(std::uint64_t line_number, const std::string& what) {
  if (++logged_ <= 20) spdlog::warn("candump line {}: {}", line_number, what);
  if (logged_ == 20) spdlog::warn("candump: further problems are only counted (health can_* counters)");
}

void CanOdometer::overlong_line() {
  ++counters_.lines;
  ++counters_.malformed;
  problem(counters_.lines, "longer than " + std::to_string(kMaxCandumpLineBytes) + " bytes: skipped");
}

std::optional<OdometerSample> CanOdometer::parse_line(std::string_view line) {
  const std::uint64_t n = ++counters_.lines;
  const CandumpLine l = parse_candump_line(line);
  if (l.kind == CandumpLine::Kind::kIgnored) return std::nullopt;
  if (l.kind == CandumpLine::Kind::kMalformed) {
    ++counters_.malformed;
    problem(n, "malformed: " + l.error);
    return std::nullopt;
  }
  return process(l.frame, n);
}

std::optional<OdometerSample> CanOdometer::process(const CanFrame& frame, std::uint64_t line_number) {
  ++counters_.frames;
  if (last_frame_t_s_ && frame.t_s < *last_frame_t_s_) {
    ++counters_.out_of_order;
    problem(line_number, "stamp " + std::to_string(frame.t_s) + " s is before the previous frame's (" +
                             std::to_string(*last_frame_t_s_) + " s): dropped");
    return std::nullopt;
  }
  last_frame_t_s_ = frame.t_s;
  bool matched = false, used = false, first_channel_updated = false;
  for (std::size_t i = 0; i < channels_.size(); ++i) {
    const CanChannelSpec& spec = config_.channels[i];
    if (!matches(spec, frame)) continue;
    matched = true;
    Channel& ch = channels_[i];
    if (ch.has_value && frame.t_s <= ch.last_t_s) {
      ++counters_.stale;
      problem(line_number, to_string(spec) + ": frame not after the channel's last one (t=" +
                               std::to_string(frame.t_s) + " s): dropped");
      continue;
    }
    const Decoded d = value(spec, frame);
    if (d.status != DecodeStatus::kOk || !std::isfinite(d.value)) {
      ++counters_.undecodable;
      problem(line_number, to_string(spec) + ": no value (" + to_string(d.status) + ", " + std::to_string(frame.size) +
                               " data bytes)");
      continue;
    }
    if (spec.kind == CanChannelSpec::Kind::kSignalCounter) {
      const auto raw = static_cast<std::uint64_t>(d.value);
      ch.count = ch.has_value
                     ? ch.count + static_cast<double>(counter_increment(ch.last_raw, raw, spec.counter_width_bits))
                     : static_cast<double>(raw);
      ch.last_raw = raw;
    } else {
      // Trapezoid rule between this channel's frames; distance counts forward and backward alike.
      if (ch.has_value) ch.count += 0.5 * (std::abs(ch.rate) + std::abs(d.value)) * (frame.t_s - ch.last_t_s);
      ch.rate = d.value;
    }
    ch.has_value = true;
    ch.last_t_s = frame.t_s;
    used = true;
    if (i == 0) first_channel_updated = true;
  }
  if (!matched) {
    ++counters_.unknown;
    return std::nullopt;
  }
  if (used) ++counters_.decoded;
  if (!first_channel_updated) return std::nullopt;
  double sum = 0.0, rate_sum = 0.0;
  std::size_t rates = 0;
  for (std::size_t i = 0; i < channels_.size(); ++i) {
    const Channel& ch = channels_[i];
    if (!ch.has_value) return std::nullopt;
    double count = ch.count;
    if (config_.channels[i].kind != CanChannelSpec::Kind::kSignalCounter) {
      count += std::abs(ch.rate) * std::max(0.0, frame.t_s - ch.last_t_s);  // extrapolated to this stamp
      rate_sum += ch.rate;
      ++rates;
    }
    sum += count;
  }
  const double mean = sum / static_cast<double>(channels_.size());
  if (rates > 0 && rate_sum != 0.0) direction_ = rate_sum < 0.0 ? -1 : 1;
  OdometerSample s;
  s.t_s = frame.t_s;
  s.pulses = static_cast<std::uint32_t>(std::fmod(std::floor(mean), 4294967296.0));  // exact: whole pulses mod 2^32
  s.direction = direction_;
  ++counters_.samples;
  return s;
}

void CandumpStream::feed(std::string_view bytes, std::vector<OdometerSample>& out) {
  for (char c : bytes) {
    if (c == '\n') {
      if (skipping_overlong_)
        skipping_overlong_ = false;
      else if (auto s = odometer_.parse_line(pending_))
        out.push_back(*s);
      pending_.clear();
      continue;
    }
    if (skipping_overlong_) continue;
    pending_.push_back(c);
    if (pending_.size() > kMaxCandumpLineBytes + 1) {  // +1: a '\r' before the '\n'
      odometer_.overlong_line();
      pending_.clear();
      skipping_overlong_ = true;
    }
  }
}

void CandumpStream::finish(std::vector<OdometerSample>& out) {
  if (!pending_.empty() && !skipping_overlong_)
    if (auto s = odometer_.parse_line(pending_)) out.push_back(*s);
  pending_.clear();
  skipping_overlong_ = false;
}

std::vector<OdometerSample> read_candump_file(const std::string& path, CanOdometer& odometer) {
  // As the dataset reader: regular files only (a FIFO or /dev/zero would never end; a pipe is
  // candump:-), at most kMaxDatasetFileBytes (decoded whole before the replay starts).
  std::error_code ec;
  const auto status = std::filesystem::status(path, ec);
  if (ec || !std::filesystem::exists(status)) throw DatasetError(path + ": cannot open the candump log (no such file)");
  if (!std::filesystem::is_regular_file(status))
    throw DatasetError(path +
                       ": not a regular file (a directory, FIFO or device); for a pipe or a live bus use candump:-");
  const auto size = std::filesystem::file_size(path, ec);
  if (!ec && size > kMaxDatasetFileBytes)
    throw DatasetError(path + ": " + std::to_string(size) + " bytes, more than the 2 GiB a log may have: split it");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw DatasetError(path + ": cannot open the candump log");
  std::vector<OdometerSample> out;
  CandumpStream stream(odometer);
  std::string buffer(1 << 16, '\0');
  while (in) {
    in.read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
    const std::streamsize n = in.gcount();
    if (n > 0) stream.feed(std::string_view(buffer.data(), static_cast<std::size_t>(n)), out);
  }
  if (in.bad()) throw DatasetError(path + ": read error");
  stream.finish(out);
  return out;
}

Dataset load_candump_source(const std::string& log_path, CanOdometer& odometer, const std::string& companion_dir,
                            BadRowPolicy policy, DatasetReadReport* report) {
  Dataset d;
  if (!companion_dir.empty()) {
    d = read_dataset(companion_dir, policy, report);
    d.truth.clear();  // the truth of the dataset's own odometer, not of this log
  }
  d.odometer = read_candump_file(log_path, odometer);
  return d;
}

}  // namespace odonav::gateway
