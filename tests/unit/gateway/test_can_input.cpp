// odonav-gateway's CAN input without DDS: the candump -L parser (good and malformed lines), the
// J1939 PGN rule, the CCVS1 and ETC1 decoders and DBC signals (byte orders, sign, scale) with
// known frames and known numbers, the counter wrap, the odometer channels (integration, counters,
// averaging two tracks), the problem counters and the Health list.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "odonav/gateway/can_decoders.hpp"
#include "odonav/gateway/candump_source.hpp"
#include "odonav/gateway/sensor_health.hpp"
#include "odonav/gateway/sensor_source.hpp"
#include "odonav/config.hpp"

using namespace odonav;
using namespace odonav::gateway;

namespace {

CanFrame frame_of(const std::string& line) {
  const CandumpLine l = parse_candump_line(line);
  EXPECT_EQ(l.kind, CandumpLine::Kind::kFrame) << line << ": " << l.error;
  return l.frame;
}

CanOdometerConfig config(const std::string& channels, double pulses_per_m = 100.0) {
  CanOdometerConfig c;
  c.channels = parse_can_channels(channels);
  c.pulses_per_m = pulses_per_m;
  return c;
}

}  // namespace

// ---- the candump -L text ---------------------------------------------------------------------

TEST(CandumpParser, ReadsClassicExtendedFdRemoteAndErrorFrames) {
  CanFrame f = frame_of("(1700000000.123456) can0 18FEF100#0011223344556677");
  EXPECT_DOUBLE_EQ(f.t_s, 1700000000.123456);
  EXPECT_TRUE(f.extended);
  EXPECT_EQ(f.id, 0x18FEF100u);
  ASSERT_EQ(f.size, 8u);
  EXPECT_EQ(f.data[0], 0x00);
  EXPECT_EQ(f.data[7], 0x77);

  f = frame_of("(12.5) vcan1 123#DEADBEEF");
  EXPECT_FALSE(f.extended);
  EXPECT_EQ(f.id, 0x123u);
  EXPECT_EQ(f.size, 4u);
  EXPECT_EQ(f.data[1], 0xAD);

  f = frame_of("(1.000000) can0 7FF#");  // zero data bytes
  EXPECT_EQ(f.size, 0u);
  f = frame_of("(1.000000) can0 123#R");
  EXPECT_TRUE(f.remote);
  f = frame_of("(1.000000) can0 123#R4");
  EXPECT_TRUE(f.remote);
  f = frame_of("(1.000000) can0 20000080#0000000000000000");  // CAN_ERR_FLAG | CAN_ERR_CRTL... as candump prints it
  EXPECT_TRUE(f.error_frame);
  f = frame_of("(1.000000) can0 12345678##1" + std::string(24, 'A'));  // CAN FD, 12 bytes, BRS flag
  EXPECT_TRUE(f.fd);
  EXPECT_EQ(f.size, 12u);
  f = frame_of("(1.000000) can0 123#0102 R\r");  // candump -x direction, CR LF
  EXPECT_EQ(f.size, 2u);
  f = frame_of("(1.000000) can0 123#1122334455667788_C");  // classic DLC 12 with 8 bytes (candump -8)
  EXPECT_EQ(f.size, 8u);

  EXPECT_EQ(parse_candump_line("").kind, CandumpLine::Kind::kIgnored);
  EXPECT_EQ(parse_candump_line("# a comment").kind, CandumpLine::Kind::kIgnored);
}

TEST(CandumpParser, WritesWhatItReads) {
  CanFrame f;
  f.t_s = 1700000000.25;
  f.id = 0x0CF00203;
  f.extended = true;
  f.size = 8;
  for (std::size_t i = 0; i < 8; ++i) f.data[i] = static_cast<std::uint8_t>(0x10 * i + 1);
  const std::string line = candump_line(f);
  EXPECT_EQ(line, "(1700000000.250000) can0 0CF00203#0111213141516171");
  const CanFrame back = frame_of(line);
  EXPECT_EQ(back.id, f.id);
  EXPECT_EQ(back.data, f.data);
}

TEST(CandumpParser, RejectsMalformedLinesWithAReason) {
  for (const char* bad : {
           "garbage",
           "(1700000000.1) can0",                // no frame
           "1700000000.1 can0 123#00",           // stamp without parentheses
           "(17000000x0.1) can0 123#00",         // stamp not a number
           "(1.0.0) can0 123#00",                // two points
           "() can0 123#00",                     // empty stamp
           "(1.0) can0 12300",                   // no '#'
           "(1.0) can0 1234#00",                 // 4-digit identifier
           "(1.0) can0 800#00",                  // 11-bit above 7FF
           "(1.0) can0 4FFFFFFF#00",             // 29-bit above 1FFFFFFF, not an error frame
           "(1.0) can0 12G#00",                  // not hex
           "(1.0) can0 123#001",                 // odd digit count
           "(1.0) can0 123#0011223344556677AA",  // 9 bytes classic
           "(1.0) can0 123#ZZ",                  // not hex data
           "(1.0) can0 123##",                   // FD without flags
           "(1.0) can0 123##0"
           "00112233445566778899",       // FD length 10 does not exist
           "(1.0) can0 123#RR",          // remote with a bad DLC
           "(1.0) can0 123#00 X",        // unknown trailing field
           "(1.0) can0 123#00 R extra",  // too many fields
           "(1.0) can0 123#00_3",        // '_dlc' below 9
       }) {
    const CandumpLine l = parse_candump_line(bad);
    EXPECT_EQ(l.kind, CandumpLine::Kind::kMalformed) << bad;
    EXPECT_FALSE(l.error.empty()) << bad;
  }
  // Binary noise never crashes.
  std::string noise;
  for (int i = 0; i < 300; ++i) noise.push_back(static_cast<char>((i * 37) & 0xFF));
  EXPECT_EQ(parse_candump_line(noise).kind, CandumpLine::Kind::kMalformed);
}

TEST(CandumpParser, SourceNamesALogOrStandardInput) {
  SourceSpec s = parse_source("candump:/logs/drive 1.log");
  EXPECT_EQ(s.kind, SourceSpec::Kind::kCandump);
  EXPECT_EQ(s.name, "/logs/drive 1.log");
  EXPECT_EQ(parse_source("candump:-").name, "-");
  EXPECT_THROW(parse_source("candump:"), ConfigError);
  EXPECT_THROW(parse_source("candump"), ConfigError);
}

// ---- J1939 ------------------------------------------------------------------------------------

TEST(J1939, PgnOfPdu1AndPdu2Identifiers) {
  EXPECT_EQ(j1939_pgn(0x18FEF100), 0xFEF1u);   // CCVS1, priority 6, SA 0
  EXPECT_EQ(j1939_pgn(0x0CF00203), 0xF002u);   // ETC1, priority 3, SA 3
  EXPECT_EQ(j1939_pgn(0x18EA0017), 0xEA00u);   // request, PDU1: DA 0x00 is not part of the PGN
  EXPECT_EQ(j1939_pgn(0x18EAFF17), 0xEA00u);   // the same to the global address
  EXPECT_EQ(j1939_pgn(0x1CEF2A31), 0xEF00u);   // proprietary A, PDU1
  EXPECT_EQ(j1939_pgn(0x19FEF100), 0x1FEF1u);  // data page 1
  EXPECT_EQ(j1939_source_address(0x0CF00203), 3u);
}

TEST(J1939, Ccvs1WheelBasedSpeedKnownFrames) {
  // Bytes 2-3 (1-based) little-endian, 1/256 km/h per bit: 0x3200 = 12800 -> 50 km/h.
  Decoded d = ccvs1_wheel_speed_mps(frame_of("(1.0) can0 18FEF100#FF0032FFFFFFFFFF"));
  ASSERT_EQ(d.status, DecodeStatus::kOk);
  EXPECT_DOUBLE_EQ(d.value, 50.0 / 3.6);
  d = ccvs1_wheel_speed_mps(frame_of("(1.0) can0 18FEF100#FF8025FFFFFFFFFF"));  // 0x2580 = 9600 -> 37.5 km/h
  EXPECT_DOUBLE_EQ(d.value, 37.5 / 3.6);
  d = ccvs1_wheel_speed_mps(frame_of("(1.0) can0 18FEF100#FFFAFAFFFFFFFFFF"));  // 0xFAFA: 250.977 km/h, the top
  EXPECT_DOUBLE_EQ(d.value, 0xFAFA / 256.0 / 3.6);
  EXPECT_EQ(ccvs1_wheel_speed_mps(frame_of("(1.0) can0 18FEF100#FF12FEFFFFFFFFFF")).status, DecodeStatus::kError);
  EXPECT_EQ(ccvs1_wheel_speed_mps(frame_of("(1.0) can0 18FEF100#FFFFFFFFFFFFFFFF")).status,
            DecodeStatus::kNotAvailable);
  EXPECT_EQ(ccvs1_wheel_speed_mps(frame_of("(1.0) can0 18FEF100#FF00")).status, DecodeStatus::kTooShort);
}

TEST(J1939, Etc1OutputShaftSpeedKnownFrames) {
  // 0x2EE0 = 12000 x 0.125 = 1500 rpm = 25 rev/s.
  const Decoded d = etc1_output_shaft_rev_per_s(frame_of("(1.0) can0 0CF00203#C0E02EFFFFFFFFFF"));
  ASSERT_EQ(d.status, DecodeStatus::kOk);
  EXPECT_DOUBLE_EQ(d.value, 25.0);
  EXPECT_EQ(etc1_output_shaft_rev_per_s(frame_of("(1.0) can0 0CF00203#C0FFFFFFFFFFFFFF")).status,
            DecodeStatus::kNotAvailable);
}

// ---- DBC signals ------------------------------------------------------------------------------

TEST(CanSignal, IntelAndMotorolaByteOrders) {
  CanFrame f = frame_of("(1.0) can0 123#3412ABCD");
  SignalSpec s;
  s.id = 0x123;
  s.start_bit = 0;
  s.length_bits = 16;
  EXPECT_EQ(*extract_raw(f, s), 0x1234u);  // Intel: LSB at bit 0
  s.start_bit = 20;
  s.length_bits = 8;  // bits 20..27: high nibble of byte 2 (0xA), low nibble of byte 3 (0xD)
  EXPECT_EQ(*extract_raw(f, s), 0xDAu);
  s.order = SignalSpec::ByteOrder::kMotorola;
  s.start_bit = 7;
  s.length_bits = 16;  // Motorola: MSB is bit 7 of byte 0, then byte 1
  EXPECT_EQ(*extract_raw(f, s), 0x3412u);
  s.start_bit = 19;
  s.length_bits = 8;  // low nibble of byte 2 (0xB), then high nibble of byte 3 (0xC)
  EXPECT_EQ(*extract_raw(f, s), 0xBCu);
  s.start_bit = 7;
  s.length_bits = 32;
  EXPECT_EQ(*extract_raw(f, s), 0x3412ABCDu);
  s.start_bit = 31;
  s.length_bits = 16;  // would need byte 4 of a 4-byte frame
  EXPECT_FALSE(extract_raw(f, s).has_value());
  EXPECT_EQ(decode_signal(f, s).status, DecodeStatus::kTooShort);
}

TEST(CanSignal, SignScaleOffsetAndInsertRoundTrip) {
  SignalSpec s;
  s.start_bit = 8;
  s.length_bits = 16;
  s.is_signed = true;
  s.scale = 0.01;
  s.offset = 0.5;
  CanFrame f = frame_of("(1.0) can0 123#00FEFF00");  // Intel bits 8..23 = 0xFFFE = -2
  Decoded d = decode_signal(f, s);
  ASSERT_EQ(d.status, DecodeStatus::kOk);
  EXPECT_DOUBLE_EQ(d.value, -2 * 0.01 + 0.5);
  s.is_signed = false;
  EXPECT_DOUBLE_EQ(decode_signal(f, s).value, 65534 * 0.01 + 0.5);
  EXPECT_EQ(signed_raw(0x7FF, SignalSpec{0, false, 0, 12, SignalSpec::ByteOrder::kIntel, true}), 2047);
  EXPECT_EQ(signed_raw(0x800, SignalSpec{0, false, 0, 12, SignalSpec::ByteOrder::kIntel, true}), -2048);
  // Any place, both orders: insert then extract gives the value back, other bits untouched.
  for (auto order : {SignalSpec::ByteOrder::kIntel, SignalSpec::ByteOrder::kMotorola}) {
    for (unsigned start : {0u, 3u, 7u, 13u, 31u}) {
      for (unsigned length : {1u, 5u, 12u, 24u}) {
        SignalSpec t;
        t.order = order;
        t.start_bit = start;
        t.length_bits = length;
        if (!check_signal(t, 8).empty()) continue;
        CanFrame g;
        g.size = 8;
        g.data.fill(0xA5);
        const std::uint64_t v = 0x5A5A5A5A5Aull & ((1ull << length) - 1);
        insert_raw(g, t, v);
        EXPECT_EQ(*extract_raw(g, t), v) << start << " " << length;
        int changed = 0;
        for (std::size_t i = 0; i < 8; ++i) changed += __builtin_popcount(g.data[i] ^ 0xA5);
        EXPECT_LE(changed, static_cast<int>(length));
      }
    }
  }
  SignalSpec wide;
  wide.order = SignalSpec::ByteOrder::kMotorola;
  wide.start_bit = 60;  // bit 4 of byte 7, Motorola downwards: runs off the end after 5 bits
  wide.length_bits = 16;
  EXPECT_FALSE(check_signal(wide, 8).empty());
}

TEST(CanSignal, CounterIncrementWraps) {
  EXPECT_EQ(counter_increment(65530, 4, 16), 10u);
  EXPECT_EQ(counter_increment(10, 25, 16), 15u);
  EXPECT_EQ(counter_increment(4294967290u, 5, 32), 11u);
  EXPECT_EQ(counter_increment(3, 0, 2), 1u);
  EXPECT_EQ(counter_increment(~0ull, 0, 64), 1u);
}

// ---- channels and the odometer ---------------------------------------------------------------

TEST(CanChannels, ParsesEveryFormAndRefusesBadOnes) {
  auto c = parse_can_channels("ccvs1");
  ASSERT_EQ(c.size(), 1u);
  EXPECT_EQ(c[0].kind, CanChannelSpec::Kind::kCcvs1);
  c = parse_can_channels("etc1:sa=3; signal:id=18FF1021,start=7,length=16,order=motorola,as=counter,wrap=12");
  ASSERT_EQ(c.size(), 2u);
  EXPECT_EQ(*c[0].source_address, 3u);
  EXPECT_EQ(c[1].kind, CanChannelSpec::Kind::kSignalCounter);
  EXPECT_TRUE(c[1].signal.extended);
  EXPECT_EQ(c[1].signal.id, 0x18FF1021u);
  EXPECT_EQ(c[1].counter_width_bits, 12u);
  c = parse_can_channels("signal:id=1A0,start=0,length=16,signed=1,scale=0.01,offset=-1,as=speed");
  EXPECT_FALSE(c[0].signal.extended);
  EXPECT_DOUBLE_EQ(c[0].signal.scale, 0.01);
  for (const char* bad : {"", "ccvs2", "ccvs1:sa=256", "ccvs1:x=1", "signal:id=123,start=0,length=8",
                          "signal:id=1234,start=0,length=8,as=speed", "signal:id=800,start=0,length=8,as=speed",
                          "signal:id=123,start=510,length=8,as=speed", "signal:id=123,start=0,length=65,as=speed",
                          "signal:id=123,start=0,length=8,as=speed,scale=0", "signal:id=123,start=0,length=8,as=x",
                          "signal:id=123,start=0,length=8,as=counter,signed=1",
                          "signal:id=123,start=0,length=8,as=counter,wrap=9", "ccvs1;;etc1"}) {
    EXPECT_THROW(parse_can_channels(bad), ConfigError) << bad;
  }
  CanOdometerConfig cfg = config("ccvs1");
  cfg.pulses_per_m = 0.0;
  EXPECT_THROW(CanOdometer{cfg}, ConfigError);
}

TEST(CanOdometer, CcvsSpeedIsIntegratedIntoWholePulses) {
  CanOdometer odo(config("ccvs1", 100.0));  // 100 pulses/m
  // 36 km/h = 10 m/s = 1000 pulses/s: raw 36 x 256 = 9216 = 0x2400. Every 125 ms (stamps exact
  // in binary, so no rounding sits on a pulse edge): 125 pulses more.
  std::vector<OdometerSample> out;
  for (int i = 0; i < 5; ++i) {
    char line[96];
    std::snprintf(line, sizeof(line), "(%.6f) can0 18FEF100#FF0024FFFFFFFFFF", 100.0 + 0.125 * i);
    if (auto s = odo.parse_line(line)) out.push_back(*s);
  }
  ASSERT_EQ(out.size(), 5u);
  for (int i = 0; i < 5; ++i) {
    EXPECT_EQ(out[i].pulses, static_cast<std::uint32_t>(125 * i)) << i;
    EXPECT_EQ(out[i].direction, 1);
  }
  EXPECT_DOUBLE_EQ(out[4].t_s, 100.5);
  // A speed ramp 0 -> 18 km/h (5 m/s) in 1 s: the trapezoid gives 2.5 m = 250 pulses exactly.
  CanOdometer ramp(config("ccvs1", 100.0));
  ASSERT_FALSE(ramp.parse_line("(0.000000) can0 18FEF100#FF0000FFFFFFFFFF") == std::nullopt);
  const auto s = ramp.parse_line("(1.000000) can0 18FEF100#FF0012FFFFFFFFFF");  // 0x1200 = 4608 = 18 km/h
  ASSERT_TRUE(s);
  EXPECT_EQ(s->pulses, 250u);
}

TEST(CanOdometer, Etc1AsPulsesPerRevolutionOrThroughGearAndSprocket) {
  // 1500 rpm = 25 rev/s for 0.25 s: 6.25 revolutions, x 60 pulses/revolution = 375 pulses.
  CanOdometerConfig c = config("etc1:sa=3");
  c.etc1_pulses_per_rev = 60.0;
  CanOdometer pulses(c);
  pulses.parse_line("(10.000000) can0 0CF00203#C0E02EFFFFFFFFFF");
  EXPECT_EQ(pulses.parse_line("(10.250000) can0 0CF00203#C0E02EFFFFFFFFFF")->pulses, 375u);
  EXPECT_FALSE(pulses.parse_line("(10.300000) can0 0CF00204#C0E02EFFFFFFFFFF"));  // another sender
  EXPECT_EQ(pulses.counters().unknown, 1u);
  // Gear ratio 10 and a 0.3 m sprocket: 2.5 sprocket rev/s x 2 pi 0.3 m = 4.712 m/s; 0.25 s at
  // 100 pulses/m: 117.8 pulses -> 117 whole pulses.
  c.etc1_pulses_per_rev = 0.0;
  c.gear_ratio = 10.0;
  c.sprocket_radius_m = 0.3;
  CanOdometer speed(c);
  speed.parse_line("(10.000000) can0 0CF00203#C0E02EFFFFFFFFFF");
  EXPECT_EQ(speed.parse_line("(10.250000) can0 0CF00203#C0E02EFFFFFFFFFF")->pulses, 117u);
}

TEST(CanOdometer, CounterSignalWrapsAndSignedSpeedReverses) {
  CanOdometer odo(config("signal:id=123,start=0,length=16,as=counter"));
  EXPECT_EQ(odo.parse_line("(1.00) can0 123#FAFF")->pulses, 65530u);  // the first raw value
  EXPECT_EQ(odo.parse_line("(1.01) can0 123#FFFF")->pulses, 65535u);
  EXPECT_EQ(odo.parse_line("(1.02) can0 123#0400")->pulses, 65540u);  // wrapped: +5, not -65531
  // A 32-bit counter is published exactly as sent, wrap at 2^32 included.
  CanOdometer wide(config("signal:id=18FF1021,start=7,length=32,order=motorola,as=counter"));
  EXPECT_EQ(wide.parse_line("(1.00) can0 18FF1021#FFFFFFFE")->pulses, 4294967294u);
  EXPECT_EQ(wide.parse_line("(1.01) can0 18FF1021#00000003")->pulses, 3u);
  // A signed speed in 0.01 m/s: -2 m/s for 0.5 s at 100 pulses/m: 100 pulses, reversing.
  CanOdometer rev(config("signal:id=1A0,start=0,length=16,signed=1,scale=0.01,as=speed"));
  rev.parse_line("(5.0) can0 1A0#38FF");  // 0xFF38 = -200 -> -2 m/s
  const auto s = rev.parse_line("(5.5) can0 1A0#38FF");
  ASSERT_TRUE(s);
  EXPECT_EQ(s->pulses, 100u);
  EXPECT_EQ(s->direction, -1);
}

TEST(CanOdometer, TwoTracksAreAveraged) {
  // Left and right track counters in one frame (bytes 0-1 and 2-3, Intel): the odometer counts
  // the mean, whole pulses.
  CanOdometer odo(
      config("signal:id=18FF0A21,start=0,length=16,as=counter;signal:id=18FF0A21,start=16,length=16,as=counter"));
  EXPECT_EQ(odo.parse_line("(1.00) can0 18FF0A21#E8030000")->pulses, 500u);  // 1000 and 0
  EXPECT_EQ(odo.parse_line("(1.01) can0 18FF0A21#EB030500")->pulses, 504u);  // 1003 and 5: 504
  // Left and right speeds in two frames: a sample at each frame of the first, once both have a value.
  CanOdometer two(config(
      "signal:id=101,start=0,length=16,scale=0.01,as=speed;signal:id=102,start=0,length=16,scale=0.01,as=speed"));
  EXPECT_FALSE(two.parse_line("(2.000) can0 101#E803"));  // 10 m/s left; no right value yet
  EXPECT_FALSE(two.parse_line("(2.005) can0 102#D007"));  // 20 m/s right: not the first channel
  // At 2.1 s: left 0.1 s x 10 m/s = 100 pulses... x 100 pulses/m = 100; right extrapolated 0.095 s x 20 m/s x 100 = 190.
  const auto s = two.parse_line("(2.100) can0 101#E803");
  ASSERT_TRUE(s);
  EXPECT_EQ(s->pulses, 145u);  // floor((100 + 190) / 2)
  EXPECT_EQ(two.counters().samples, 1u);
}

TEST(CanOdometer, BadFramesAreCountedNeverFatal) {
  CanOdometer odo(config("ccvs1"));
  std::vector<std::string> lines{
      "(10.0) can0 18FEF100#FF0024FFFFFFFFFF",   // good: sample
      "(10.1) can0 123#00",                      // unknown id
      "(10.1) can0 18FEF100#FF0024FFFFFFFFFF",   // good
      "(10.1) can0 18FEF100#FF0024FFFFFFFFFF",   // same stamp: stale
      "(10.05) can0 18FEF100#FF0024FFFFFFFFFF",  // back in time: out of order
      "(10.2) can0 18FEF100#FFFFFFFFFFFFFFFF",   // not available: undecodable
      "(10.3) can0 18FEF100#FF00",               // too short: undecodable
      "this is not candump",                     // malformed
      "",                                        // ignored
      "(10.4) can0 18FEF100#FF0024FFFFFFFFFF",   // good again
  };
  std::size_t samples = 0;
  for (const auto& l : lines) samples += odo.parse_line(l).has_value();
  const CanCounters& c = odo.counters();
  EXPECT_EQ(samples, 3u);
  EXPECT_EQ(c.lines, 10u);
  EXPECT_EQ(c.frames, 8u);
  EXPECT_EQ(c.decoded, 3u);
  EXPECT_EQ(c.samples, 3u);
  EXPECT_EQ(c.unknown, 1u);
  EXPECT_EQ(c.stale, 1u);
  EXPECT_EQ(c.out_of_order, 1u);
  EXPECT_EQ(c.undecodable, 2u);
  EXPECT_EQ(c.malformed, 1u);
  EXPECT_EQ(c.problems(), 5u);
}

TEST(CanOdometer, StreamSplitsLinesAndSkipsOverlongOnes) {
  CanOdometer odo(config("ccvs1"));
  CandumpStream stream(odo);
  std::vector<OdometerSample> out;
  const std::string a = "(1.0) can0 18FEF100#FF0024FFFFFFFFFF\r\n(1.125) can0 18FEF";
  stream.feed(a, out);
  EXPECT_EQ(out.size(), 1u);
  stream.feed("100#FF0024FFFFFFFFFF\n" + std::string(5000, 'x') + "\n(1.25) can0 18FEF100#FF0024FFFFFFFFFF", out);
  EXPECT_EQ(out.size(), 2u);
  stream.finish(out);  // the last line without '\n'
  ASSERT_EQ(out.size(), 3u);
  EXPECT_EQ(out[2].pulses, 250u);
  EXPECT_EQ(odo.counters().malformed, 1u);
  EXPECT_EQ(odo.counters().lines, 4u);
}

TEST(CanOdometer, ReadsALogFileAndRefusesADirectory) {
  const auto dir = std::filesystem::temp_directory_path() / "odonav-can-input-test";
  std::filesystem::create_directories(dir);
  const auto path = dir / "log.txt";
  {
    std::ofstream o(path);
    for (int i = 0; i < 100; ++i) o << "(" << 50 + i * 0.125 << ") can0 18FEF100#FF0024FFFFFFFFFF\n";
  }
  CanOdometer odo(config("ccvs1"));
  const auto samples = read_candump_file(path.string(), odo);
  ASSERT_EQ(samples.size(), 100u);
  EXPECT_EQ(samples.back().pulses, 12375u);  // 12.375 s at 1000 pulses/s
  CanOdometer again(config("ccvs1"));
  EXPECT_THROW(read_candump_file(dir.string(), again), DatasetError);
  EXPECT_THROW(read_candump_file((dir / "missing").string(), again), DatasetError);
  EXPECT_THROW(read_candump_file("/dev/zero", again), DatasetError);  // never ends: refused, not read
  std::filesystem::remove_all(dir);
}

TEST(CanOdometer, HealthListsTheCanCountersAndWarnsOnProblemsOnly) {
  CanCounters c;
  c.lines = 10;
  c.unknown = 4;
  SourceHealth h = can_source_health(c);
  EXPECT_FALSE(h.warn);  // other traffic on the bus is normal
  ASSERT_EQ(h.counters.size(), 8u);
  EXPECT_EQ(h.counters[0].first, "can_lines_read");
  EXPECT_EQ(h.counters[4].first, "can_frames_unknown");
  EXPECT_EQ(h.counters[4].second, 4.0);
  c.stale = 1;
  EXPECT_TRUE(can_source_health(c).warn);
  const SourceHealth both = combine(replay_source_health({1, 1, 1}, 0), can_source_health(c));
  EXPECT_TRUE(both.warn);
  EXPECT_EQ(both.counters.size(), 11u);
  EXPECT_EQ(both.trailing_counters.size(), 1u);
}
