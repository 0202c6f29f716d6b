// The built-in protocol profiles beyond scip and lines (nmea, slcan,
// modbus-rtu, modbus-tcp, mavlink): framing under every split, broken frames
// reported as such, match keys and response fixes; replay with a profile
// (request frames matched by key, responses fixed, mismatches naming the
// field); and a profile registered through the public C++ interface.
#include <gtest/gtest.h>

#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "replay/profile.hpp"
#include "replay/profiles/checksums.hpp"
#include "replay/profiles/declared.hpp"
#include "replay/replay_config.hpp"
#include "replay/replay_port.hpp"
#include "session/record_source.hpp"
#include "support/port_test_support.hpp"
#include "util/hex.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/options.hpp"
#include "wiretape/port.hpp"
#include "wiretape/profile.hpp"

using namespace wiretape;

namespace {

std::vector<Frame> frames_of(const Profile& profile, StreamDirection direction,
                             const std::string& stream, std::size_t chunk) {
  auto framer = profile.make_framer(direction);
  std::vector<Frame> frames;
  for (std::size_t at = 0; at < stream.size(); at += chunk) {
    framer->feed(std::string_view(stream).substr(at, chunk), frames);
  }
  if (auto tail = framer->finish()) frames.push_back(std::move(*tail));
  return frames;
}

// Frames and their ends, the same for every chunk size.
std::vector<Frame> frames_any_split(const Profile& profile, StreamDirection direction,
                                    const std::string& stream) {
  const std::vector<Frame> whole = frames_of(profile, direction, stream, stream.size() + 1);
  for (std::size_t chunk = 1; chunk <= 9; ++chunk) {
    const std::vector<Frame> split = frames_of(profile, direction, stream, chunk);
    EXPECT_EQ(split.size(), whole.size()) << "chunk " << chunk;
    for (std::size_t i = 0; i < std::min(split.size(), whole.size()); ++i) {
      EXPECT_EQ(split[i].bytes, whole[i].bytes) << "chunk " << chunk << " frame " << i;
      EXPECT_EQ(split[i].end, whole[i].end) << "chunk " << chunk << " frame " << i;
    }
  }
  return whole;
}

std::string be16(unsigned value) {
  return {static_cast<char>(value >> 8), static_cast<char>(value & 0xFF)};
}

// A Modbus TCP frame: MBAP header and PDU.
std::string mbap(unsigned tid, unsigned unit, const std::string& pdu) {
  return be16(tid) + be16(0) + be16(static_cast<unsigned>(pdu.size() + 1)) +
         static_cast<char>(unit) + pdu;
}

std::string read_holding(unsigned address, unsigned count) {
  return std::string("\x03", 1) + be16(address) + be16(count);
}

std::string rtu(const std::string& body) {
  const std::uint16_t crc = detail::crc16_modbus(body);
  return body + static_cast<char>(crc & 0xFF) + static_cast<char>(crc >> 8);
}

std::string nmea(const std::string& body) {
  char sum[4];
  std::snprintf(sum, sizeof sum, "%02X", detail::xor8(body));
  return "$" + body + "*" + sum + "\r\n";
}

// A MAVLink v1 HEARTBEAT (CRC_EXTRA 50) with sequence `seq`.
std::string heartbeat_v1(unsigned seq) {
  std::string packet = {static_cast<char>(0xFE), 9, static_cast<char>(seq), 1, 1, 0};
  packet += std::string("\x00\x00\x00\x00\x02\x03\x51\x04\x03", 9);
  std::uint16_t crc = detail::crc16_x25(std::string_view(packet).substr(1));
  const char extra = 50;
  crc = detail::crc16_x25(std::string_view(&extra, 1), crc);
  packet += static_cast<char>(crc & 0xFF);
  packet += static_cast<char>(crc >> 8);
  return packet;
}

// A MAVLink v2 PARAM_REQUEST_LIST (21, CRC_EXTRA 159) with sequence `seq`.
std::string param_request_list_v2(unsigned seq) {
  std::string packet = {static_cast<char>(0xFD), 2, 0, 0, static_cast<char>(seq), (char)255, 0,
                        21, 0, 0};
  packet += std::string("\x01\x01", 2);
  std::uint16_t crc = detail::crc16_x25(std::string_view(packet).substr(1));
  const char extra = static_cast<char>(159);
  crc = detail::crc16_x25(std::string_view(&extra, 1), crc);
  packet += static_cast<char>(crc & 0xFF);
  packet += static_cast<char>(crc >> 8);
  return packet;
}

std::unique_ptr<Port> replay(std::vector<Record> records, const std::string& keys) {
  Options options = Options::parse("file=synthetic.wtape," + keys);
  detail::ReplayConfig config = detail::take_replay_config(options);
  auto port = detail::open_replay_session(config, detail::vector_source_factory(std::move(records)));
  port->set_timeout(test::kEventDeadline);
  return port;
}

Record tx(std::uint64_t t, std::string data) { return {t, RecordKind::tx, std::move(data)}; }
Record rx(std::uint64_t t, std::string data) { return {t, RecordKind::rx, std::move(data)}; }

}  // namespace

TEST(Checksums, KnownValues) {
  EXPECT_EQ(detail::crc16_modbus("123456789"), 0x4B37);
  EXPECT_EQ(detail::crc16_ccitt("123456789"), 0x29B1);
  EXPECT_EQ(detail::crc16_x25("123456789"), 0x6F91);
  EXPECT_EQ(detail::crc32_zlib("123456789"), 0xCBF43926u);
}

TEST(BuiltinProfiles, EachIsRegisteredAfterScip) {
  const std::vector<std::string> names = profile_names();
  for (const char* name : {"scip", "lines", "nmea", "slcan", "modbus-rtu", "modbus-tcp", "mavlink"}) {
    EXPECT_NE(std::find(names.begin(), names.end(), name), names.end()) << name;
    EXPECT_EQ(find_profile(name)->name(), name);
  }
  EXPECT_EQ(names.front(), "scip");
}

TEST(ModbusTcp, FramesByLengthKeysWithoutTransactionIdAndFixesIt) {
  const auto profile = find_profile("modbus-tcp");
  const std::string a = mbap(1, 1, read_holding(0, 10));
  const std::string b = mbap(2, 1, read_holding(100, 2));
  const auto frames = frames_any_split(*profile, StreamDirection::tx, a + b);
  ASSERT_EQ(frames.size(), 2u);
  EXPECT_EQ(frames[0].bytes, a);
  EXPECT_EQ(frames[1].bytes, b);
  EXPECT_EQ(profile->match_key(mbap(7, 1, read_holding(0, 10))), profile->match_key(a));
  EXPECT_NE(profile->match_key(b), profile->match_key(a));
  const std::string response = mbap(1, 1, std::string("\x03\x02\x00\x2a", 4));
  EXPECT_EQ(profile->fix_response(a, mbap(0x1234, 1, read_holding(0, 10)), response),
            mbap(0x1234, 1, std::string("\x03\x02\x00\x2a", 4)));
  EXPECT_EQ(profile->frame_name(StreamDirection::tx, a), "read holding registers");
  EXPECT_NE(profile->describe(StreamDirection::tx, a).find("address 0 count 10"),
            std::string::npos);
  EXPECT_EQ(profile->field_name(StreamDirection::tx, a, 9), "address");
}

TEST(ModbusTcp, BadLengthAndProtocolIdAreBrokenFrames) {
  const auto profile = find_profile("modbus-tcp");
  const std::string bad_length = be16(1) + be16(0) + be16(0x0400);
  const std::string good = mbap(2, 1, read_holding(0, 1));
  auto frames = frames_any_split(*profile, StreamDirection::tx, bad_length + good);
  ASSERT_EQ(frames.size(), 2u);
  EXPECT_EQ(frames[0].end, FrameEnd::broken);
  EXPECT_NE(frames[0].problem.find("bad length 1024"), std::string::npos);
  EXPECT_EQ(frames[1].bytes, good);
  frames = frames_any_split(*profile, StreamDirection::tx, be16(1) + be16(9) + be16(6));
  ASSERT_EQ(frames.size(), 1u);
  EXPECT_NE(frames[0].problem.find("protocol id 9"), std::string::npos);
}

TEST(ModbusRtu, FramesByFunctionCodeAndChecksTheCrc) {
  const auto profile = find_profile("modbus-rtu");
  const std::string request = rtu(std::string("\x01", 1) + read_holding(0, 2));
  std::string bad = rtu(std::string("\x01\x06\x00\x01\x00\x03", 6));
  bad.back() ^= 0x55;
  const std::string garbage = "\x01\x63";
  // With no silence to go by, garbage is seen where no function code fits.
  const auto frames =
      frames_any_split(*profile, StreamDirection::tx, request + bad + request + garbage);
  ASSERT_EQ(frames.size(), 5u);
  EXPECT_EQ(frames[0].bytes, request);
  EXPECT_EQ(frames[0].end, FrameEnd::delimited);
  EXPECT_EQ(frames[1].end, FrameEnd::broken);
  EXPECT_NE(frames[1].problem.find("bad CRC"), std::string::npos);
  EXPECT_EQ(frames[2].bytes, request);
  EXPECT_EQ(frames[3].end, FrameEnd::broken);  // 0x01 before 0x63: garbage
  EXPECT_NE(frames[3].problem.find("garbage"), std::string::npos);
  EXPECT_EQ(frames[4].end, FrameEnd::stream_end);
  EXPECT_EQ(profile->match_key(request), request.substr(0, request.size() - 2));
  const std::string reply = rtu(std::string("\x01\x03\x04\x00\x01\x00\x02", 7));
  const auto replies = frames_any_split(*profile, StreamDirection::rx, reply + reply);
  ASSERT_EQ(replies.size(), 2u);
  EXPECT_EQ(replies[1].bytes, reply);
}

TEST(Nmea, SentencesWithChecksumsGarbageAndBadSums) {
  const auto profile = find_profile("nmea");
  const std::string gga = nmea("GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,");
  std::string bad = nmea("GPRMC,1,2,3");
  bad[bad.size() - 3] = bad[bad.size() - 3] == '0' ? '1' : '0';
  const auto frames =
      frames_any_split(*profile, StreamDirection::rx, gga + "junk\r\n" + bad + gga);
  ASSERT_EQ(frames.size(), 4u);
  EXPECT_EQ(frames[0].end, FrameEnd::delimited);
  EXPECT_EQ(frames[1].end, FrameEnd::broken);
  EXPECT_NE(frames[1].problem.find("not an NMEA sentence"), std::string::npos);
  EXPECT_EQ(frames[2].end, FrameEnd::broken);
  EXPECT_NE(frames[2].problem.find("bad checksum"), std::string::npos);
  EXPECT_EQ(profile->frame_name(StreamDirection::rx, gga), "$GPGGA");
  EXPECT_EQ(profile->match_key(gga).find('*'), std::string::npos);
}

TEST(Slcan, CommandsEndWithCrAndBelIsAnErrorReply) {
  const auto profile = find_profile("slcan");
  const auto frames = frames_any_split(*profile, StreamDirection::tx, "C\rS6\rO\rt1232AABB\r");
  ASSERT_EQ(frames.size(), 4u);
  EXPECT_EQ(frames[3].bytes, "t1232AABB\r");
  EXPECT_EQ(profile->frame_name(StreamDirection::tx, "O\r"), "open channel");
  const auto replies = frames_any_split(*profile, StreamDirection::rx, "\r\a\rz\r");
  EXPECT_EQ(replies.size(), 4u);
  EXPECT_EQ(profile->field_name(StreamDirection::tx, "t1232AABB\r", 5), "data");
}

TEST(Mavlink, V1AndV2PacketsKeysWithoutSequenceAndCrc) {
  const auto profile = find_profile("mavlink");
  const std::string stream = heartbeat_v1(0) + "\x11\x22" + param_request_list_v2(5) + heartbeat_v1(1);
  const auto frames = frames_any_split(*profile, StreamDirection::tx, stream);
  ASSERT_EQ(frames.size(), 4u);
  EXPECT_EQ(frames[0].end, FrameEnd::delimited) << frames[0].problem;
  EXPECT_EQ(frames[1].end, FrameEnd::broken);
  EXPECT_NE(frames[1].problem.find("garbage"), std::string::npos);
  EXPECT_EQ(frames[2].end, FrameEnd::delimited) << frames[2].problem;
  EXPECT_EQ(profile->frame_name(StreamDirection::tx, frames[2].bytes), "PARAM_REQUEST_LIST");
  EXPECT_EQ(profile->match_key(heartbeat_v1(0)), profile->match_key(heartbeat_v1(9)));
  EXPECT_EQ(profile->match_key(param_request_list_v2(0)),
            profile->match_key(param_request_list_v2(77)));
  std::string corrupt = heartbeat_v1(3);
  corrupt[8] ^= 1;
  const auto broken = frames_any_split(*profile, StreamDirection::tx, corrupt);
  ASSERT_EQ(broken.size(), 1u);
  EXPECT_EQ(broken[0].end, FrameEnd::broken);
  EXPECT_NE(broken[0].problem.find("bad CRC"), std::string::npos);
}

TEST(ProfileReplay, ModbusTcpServesReorderedPollsWithTheClientsTransactionIds) {
  const std::string reply_a = std::string("\x03\x02\x00\x0a", 4);
  const std::string reply_b = std::string("\x03\x02\x00\x0b", 4);
  auto port = replay({tx(1, mbap(1, 1, read_holding(0, 1))), rx(2, mbap(1, 1, reply_a)),
                      tx(3, mbap(2, 1, read_holding(5, 1))), rx(4, mbap(2, 1, reply_b))},
                     "timing=none,match=request,profile=modbus-tcp,repeat=last");
  // Another order, other ids, split anyhow, and one poll more than recorded.
  const std::string second = mbap(0x100, 1, read_holding(5, 1));
  port->write_all(second.substr(0, 3));
  port->write_all(second.substr(3));
  EXPECT_EQ(port->read_exactly(11), mbap(0x100, 1, reply_b));
  port->write_all(mbap(0x101, 1, read_holding(0, 1)));
  EXPECT_EQ(port->read_exactly(11), mbap(0x101, 1, reply_a));
  port->write_all(mbap(0x102, 1, read_holding(0, 1)));
  EXPECT_EQ(port->read_exactly(11), mbap(0x102, 1, reply_a));
}

TEST(ProfileReplay, AMismatchNamesTheFrameAndTheFieldAndShowsTheClosestFrames) {
  auto port = replay({tx(1, mbap(1, 1, read_holding(0, 1))), rx(2, mbap(1, 1, "\x03\x02\x00\x0a"))},
                     "timing=none,match=request,profile=modbus-tcp,unused=ignore");
  try {
    port->write_all(mbap(9, 1, read_holding(7, 1)));
    FAIL() << "no mismatch";
  } catch (const ReplayMismatch& error) {
    const std::string message = error.what();
    EXPECT_NE(message.find("read holding registers"), std::string::npos) << message;
    EXPECT_NE(message.find("field 'address'"), std::string::npos) << message;
    EXPECT_NE(message.find("closest recorded frames"), std::string::npos) << message;
  }
}

TEST(ProfileReplay, MavlinkStepsInAnotherOrderWithAnExtraHeartbeat) {
  auto port = replay({tx(1, param_request_list_v2(0)), rx(2, "[params]"),
                      tx(3, heartbeat_v1(1)), rx(4, "[hb]")},
                     "timing=none,match=request,profile=mavlink,repeat=last");
  port->write_all(heartbeat_v1(40));
  EXPECT_EQ(port->read_exactly(4), "[hb]");
  port->write_all(heartbeat_v1(41));
  EXPECT_EQ(port->read_exactly(4), "[hb]");
  port->write_all(param_request_list_v2(42));
  EXPECT_EQ(port->read_exactly(8), "[params]");
}

TEST(ProfileReplay, UnknownProfileIsAnOptionErrorNamingTheKey) {
  try {
    replay({}, "match=request,profile=modbus-xyz");
    FAIL() << "accepted";
  } catch (const OptionError& error) {
    EXPECT_EQ(error.key(), "profile");
    EXPECT_NE(std::string(error.what()).find("modbus-tcp"), std::string::npos);
  }
}

namespace {

// A protocol of the test's own: frames of 4 bytes, the last one a counter.
class CounterProfile final : public Profile {
 public:
  std::string_view name() const override { return "counter4"; }
  std::string_view summary() const override { return "4-byte frames, a counter last"; }
  std::unique_ptr<Framer> make_framer(StreamDirection) const override {
    class Fixed final : public BufferingFramer {
     public:
      void feed(std::string_view bytes, std::vector<Frame>& frames) override {
        for (char byte : bytes) {
          buffer_ += byte;
          if (buffer_.size() == 4) cut(FrameEnd::delimited, frames);
        }
      }
    };
    return std::make_unique<Fixed>();
  }
  std::string match_key(std::string_view request) const override {
    return std::string(request.substr(0, 3));
  }
  bool fixes_responses() const override { return true; }
  std::string fix_response(std::string_view, std::string_view actual,
                           std::string_view response) const override {
    return std::string(response) + std::string(actual.substr(3, 1));
  }
  std::string frame_name(StreamDirection, std::string_view frame) const override {
    return std::string(frame.substr(0, 3));
  }
  std::string describe(StreamDirection, std::string_view frame) const override {
    return std::string(frame);
  }
};

}  // namespace

TEST(ProfileInterface, ARegisteredProfileIsFoundByName) {
  register_profile("counter4", [] { return std::make_shared<CounterProfile>(); });
  EXPECT_THROW(register_profile("scip", [] { return std::make_shared<CounterProfile>(); }),
               std::invalid_argument);
  // Its fix applies to its whole frames (a response cut short is served as
  // recorded): each answer gets the client's counter.
  auto port = replay({tx(1, "abc1"), rx(2, "AAAA"), tx(3, "xyz2"), rx(4, "XXXX")},
                     "timing=none,match=request,profile=counter4");
  port->write_all("xyz9abc8");
  EXPECT_EQ(port->read_exactly(10), "XXXX9AAAA8");
}

// --- profiles declared in options ----------------------------------------------

namespace {

void expect_spec_error(const std::string& keys, const std::string& key, const std::string& text) {
  try {
    replay({}, "match=request," + keys);
    FAIL() << keys << " was accepted";
  } catch (const OptionError& error) {
    EXPECT_EQ(error.key(), key) << keys;
    const std::string message = error.what();
    EXPECT_NE(message.find(text), std::string::npos) << message;
    EXPECT_NE(message.find("the grammar is"), std::string::npos) << message;
  }
}

}  // namespace

TEST(DeclaredProfile, BadSpecsNameTheKeyAndShowTheGrammar) {
  expect_spec_error("framing=delimiter:0g", "framing", "not 1 to 32 bytes in hex");
  expect_spec_error("framing=length:0:3:0", "framing", "SIZE '3'");
  expect_spec_error("framing=length:0:2:0:xx", "framing", "neither be nor le");
  expect_spec_error("framing=fixed:0", "framing", "not a size");
  expect_spec_error("framing=lines", "framing", "'lines' is not a framing");
  expect_spec_error("framing=gap:0", "framing", "not from 1 to 60000 ms");
  expect_spec_error("framing=fixed:4,ignore=1", "ignore", "'1' is not OFFSET:LEN");
  expect_spec_error("framing=fixed:4,echo=0:0", "echo", "LEN '0'");
  expect_spec_error("framing=fixed:4,checksum=md5@-1", "checksum", "'md5' is not a checksum");
  expect_spec_error("framing=fixed:4,checksum=sum8", "checksum", "no '@OFFSET'");
  expect_spec_error("ignore=0:1", "ignore", "needs framing=");
}

TEST(DeclaredProfile, LengthFramingIgnoreEchoAndChecksumReplay) {
  // [id][len][cmd...][sum8]: the frame is len + 3 bytes; id is echoed.
  const auto frame = [](char id, const std::string& body) {
    std::string bytes = std::string(1, id) + static_cast<char>(body.size()) + body;
    return bytes + static_cast<char>(detail::sum8(bytes));
  };
  auto port = replay({tx(1, frame('a', "GET")), rx(2, frame('a', "42")),
                      tx(3, frame('b', "PUT")), rx(4, frame('b', "OK"))},
                     "timing=none,match=request,framing=length:1:1:3,echo=0:1,"
                     "checksum=sum8@-1");
  const std::string put = frame('z', "PUT");
  port->write_all(put.substr(0, 2));
  port->write_all(put.substr(2));
  EXPECT_EQ(port->read_exactly(5), frame('z', "OK"));
  port->write_all(frame('y', "GET"));
  EXPECT_EQ(port->read_exactly(5), frame('y', "42"));
  std::string bad = frame('x', "GET");
  bad.back() ^= 1;
  try {
    port->write_all(bad);
    FAIL() << "a bad checksum was accepted";
  } catch (const ReplayMismatch& error) {
    EXPECT_NE(std::string(error.what()).find("bad checksum"), std::string::npos) << error.what();
  }
}

TEST(ProfileSequence, CheckDataComparesKeysFrameByFrame) {
  const std::string reply = std::string("\x03\x02\x00\x0a", 4);
  const std::vector<Record> records = {tx(1, mbap(1, 1, read_holding(0, 1))), rx(2, mbap(1, 1, reply)),
                                       tx(3, mbap(2, 1, read_holding(5, 1))), rx(4, mbap(2, 1, reply))};
  auto port = replay(records, "timing=none,profile=modbus-tcp");
  const std::string first = mbap(70, 1, read_holding(0, 1));
  port->write_all(first.substr(0, 5));
  port->write_all(first.substr(5));
  // The response carries the client's transaction id in sequence mode too.
  EXPECT_EQ(port->read_exactly(11), mbap(70, 1, reply));
  try {
    port->write_all(mbap(71, 1, read_holding(6, 1)));
    FAIL() << "a different address was accepted";
  } catch (const ReplayMismatch& error) {
    const std::string message = error.what();
    EXPECT_NE(message.find("field 'address' differs"), std::string::npos) << message;
  }
}

TEST(ProfileReplay, ARecordingTheProfileCannotFrameIsAnErrorAtOpenNamingTheOffset) {
  const std::string good = mbap(1, 1, read_holding(0, 1));
  const std::string bad_length = be16(2) + be16(0) + be16(0x0400);
  try {
    replay({tx(1, good), rx(2, mbap(1, 1, "\x03\x02\x00\x0a")), tx(3'000'000'000, bad_length)},
           "timing=none,match=request,profile=modbus-tcp");
    FAIL() << "opened";
  } catch (const OptionError& error) {
    const std::string message = error.what();
    EXPECT_EQ(error.key(), "profile");
    EXPECT_NE(message.find("tx byte offset 12"), std::string::npos) << message;
    EXPECT_NE(message.find("session time 3.000000 s"), std::string::npos) << message;
    EXPECT_NE(message.find("bad length 1024"), std::string::npos) << message;
  }
}

TEST(ProfileDecode, ShowMarksBrokenFramesWithTheirProblem) {
  detail::SessionDecoder decoder(find_profile("modbus-tcp"));
  std::deque<detail::DecodedItem> items;
  decoder.feed(Record{1, RecordKind::tx, be16(2) + be16(0) + be16(0x0400)}, items);
  ASSERT_EQ(items.size(), 1u);
  EXPECT_NE(items[0].description.find("BROKEN (bad length 1024"), std::string::npos)
      << items[0].description;
}

TEST(DeclaredProfile, GapFramingCutsRequestsBySilenceInTheRecordingAndTheClient) {
  // Two requests recorded 100 ms apart in two records each, 1 ms apart.
  const std::uint64_t ms = 1'000'000;
  auto port = replay({tx(0, "RE"), tx(1 * ms, "AD"), rx(5 * ms, "[read]"),
                      tx(100 * ms, "ST"), tx(101 * ms, "OP"), rx(105 * ms, "[stop]")},
                     "timing=none,match=request,framing=gap:20");
  port->write_all("STOP");
  // The frame ends after 20 ms of the client's silence: a blocked read waits.
  EXPECT_EQ(port->read_exactly(6), "[stop]");
  port->write_all("READ");
  EXPECT_EQ(port->read_exactly(6), "[read]");
  port->write_all("NOPE");
  // Found in the silence after it; the next write reports it.
  const auto deadline = std::chrono::steady_clock::now() + test::kEventDeadline;
  bool raised = false;
  while (!raised && std::chrono::steady_clock::now() < deadline) {
    std::string none(1, '\0');
    port->read(none.data(), 1, std::chrono::milliseconds(30));
    try {
      port->write_all("X");
    } catch (const ReplayMismatch& error) {
      raised = true;
      EXPECT_NE(std::string(error.what()).find("NOPE"), std::string::npos) << error.what();
    }
  }
  EXPECT_TRUE(raised);
}

TEST(DeclaredProfile, GapFramingInSequenceModeIsAnOptionError) {
  try {
    replay({}, "framing=gap:20");
    FAIL() << "accepted";
  } catch (const OptionError& error) {
    EXPECT_EQ(error.key(), "framing");
    EXPECT_NE(std::string(error.what()).find("match=request"), std::string::npos);
  }
}

// --- checksums recomputed over scrubbed bytes (wiretape edit --redact) --------

namespace {

// `frame` with the bytes [at, at + length) overwritten by '*', as a
// redaction leaves them.
std::string scrubbed(std::string frame, std::size_t at, std::size_t length) {
  frame.replace(at, length, std::string(length, '*'));
  return frame;
}

// The one frame `bytes` makes, with how it ended.
Frame only_frame(const Profile& profile, StreamDirection direction, const std::string& bytes) {
  const std::vector<Frame> frames = frames_of(profile, direction, bytes, bytes.size() + 1);
  EXPECT_EQ(frames.size(), 1u);
  return frames.empty() ? Frame{} : frames[0];
}

}  // namespace

TEST(RecomputeChecksums, NmeaSentencesGetTheirSumOverTheScrubbedText) {
  const auto profile = find_profile("nmea");
  const std::string gga = nmea("GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,");
  const std::string dirty = scrubbed(gga, 14, 8);
  EXPECT_EQ(only_frame(*profile, StreamDirection::rx, dirty).end, FrameEnd::broken);
  const std::string fixed = profile->recompute_checksums(StreamDirection::rx, dirty);
  EXPECT_EQ(fixed, nmea("GPGGA,123519,********,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,"));
  EXPECT_EQ(only_frame(*profile, StreamDirection::rx, fixed).end, FrameEnd::delimited);
  // A sentence without a checksum, and garbage, stay as they are.
  EXPECT_EQ(profile->recompute_checksums(StreamDirection::tx, "$PX,1\r\n"), "$PX,1\r\n");
  EXPECT_EQ(profile->recompute_checksums(StreamDirection::rx, "junk*00\r\n"), "junk*00\r\n");
}

TEST(RecomputeChecksums, ModbusRtuFramesGetTheirCrcInBothDirections) {
  const auto profile = find_profile("modbus-rtu");
  const std::string reply = rtu(std::string("\x01\x03\x04\x00\x01\x00\x02", 7));
  const std::string dirty = scrubbed(reply, 3, 4);
  EXPECT_EQ(only_frame(*profile, StreamDirection::rx, dirty).end, FrameEnd::broken);
  const std::string fixed = profile->recompute_checksums(StreamDirection::rx, dirty);
  EXPECT_EQ(fixed, rtu(std::string("\x01\x03\x04****", 7)));
  EXPECT_EQ(only_frame(*profile, StreamDirection::rx, fixed).end, FrameEnd::delimited);
  const std::string request = rtu(std::string("\x01", 1) + read_holding(0, 2));
  EXPECT_EQ(profile->recompute_checksums(StreamDirection::tx, scrubbed(request, 2, 2)),
            rtu(scrubbed(std::string("\x01", 1) + read_holding(0, 2), 2, 2)));
  // Garbage (no function code it knows) is left as it is.
  EXPECT_EQ(profile->recompute_checksums(StreamDirection::tx, "\x01\x63"), "\x01\x63");
}

TEST(RecomputeChecksums, MavlinkPacketsOfKnownMessagesGetTheirCrc) {
  const auto profile = find_profile("mavlink");
  const std::string heartbeat = heartbeat_v1(7);
  const std::string dirty = scrubbed(heartbeat, 6, 4);
  EXPECT_EQ(only_frame(*profile, StreamDirection::tx, dirty).end, FrameEnd::broken);
  const std::string fixed = profile->recompute_checksums(StreamDirection::tx, dirty);
  EXPECT_EQ(fixed.substr(0, fixed.size() - 2), dirty.substr(0, dirty.size() - 2));
  EXPECT_EQ(only_frame(*profile, StreamDirection::tx, fixed).end, FrameEnd::delimited);
  const std::string v2 = param_request_list_v2(3);
  const std::string fixed_v2 =
      profile->recompute_checksums(StreamDirection::tx, scrubbed(v2, 10, 1));
  EXPECT_EQ(only_frame(*profile, StreamDirection::tx, fixed_v2).end, FrameEnd::delimited);
  EXPECT_EQ(profile->recompute_checksums(StreamDirection::rx, "\x11\x22"), "\x11\x22");
}

TEST(RecomputeChecksums, DeclaredProfilesRecomputeTheirChecksumAndOthersChangeNothing) {
  Options options = Options::parse("framing=length:1:1:3,checksum=sum8@-1");
  const auto profile = detail::take_declared_profile(options);
  ASSERT_NE(profile, nullptr);
  const std::string body = std::string("a\x03GET", 5);
  const std::string frame = body + static_cast<char>(detail::sum8(body));
  const std::string dirty = scrubbed(frame, 2, 3);
  EXPECT_EQ(only_frame(*profile, StreamDirection::rx, dirty).end, FrameEnd::broken);
  const std::string fixed = profile->recompute_checksums(StreamDirection::rx, dirty);
  EXPECT_EQ(fixed.back(), static_cast<char>(detail::sum8(dirty.substr(0, 5))));
  EXPECT_EQ(only_frame(*profile, StreamDirection::rx, fixed).end, FrameEnd::delimited);
  // No checksum to recompute: the frame comes back as it was.
  for (const char* name : {"lines", "slcan", "modbus-tcp"}) {
    EXPECT_EQ(find_profile(name)->recompute_checksums(StreamDirection::rx, "t1****\r"),
              "t1****\r")
        << name;
  }
}

// --- text made from device bytes (issue 23) ----------------------------------------------

namespace {

using namespace std::string_literals;

// Whether `text` is valid UTF-8 (no overlong forms, no surrogates, nothing
// past U+10FFFF): what Python's str() of it needs.
bool is_valid_utf8(std::string_view text) {
  std::size_t i = 0;
  while (i < text.size()) {
    const auto byte = static_cast<unsigned char>(text[i]);
    std::size_t length = 0;
    std::uint32_t code = 0;
    if (byte < 0x80) {
      ++i;
      continue;
    } else if ((byte & 0xE0) == 0xC0) {
      length = 2, code = byte & 0x1F;
    } else if ((byte & 0xF0) == 0xE0) {
      length = 3, code = byte & 0x0F;
    } else if ((byte & 0xF8) == 0xF0) {
      length = 4, code = byte & 0x07;
    } else {
      return false;
    }
    if (i + length > text.size()) return false;
    for (std::size_t k = 1; k < length; ++k) {
      const auto next = static_cast<unsigned char>(text[i + k]);
      if ((next & 0xC0) != 0x80) return false;
      code = (code << 6) | (next & 0x3F);
    }
    const std::uint32_t smallest[] = {0, 0, 0x80, 0x800, 0x10000};
    if (code < smallest[length] || code > 0x10FFFF || (code >= 0xD800 && code <= 0xDFFF)) {
      return false;
    }
    i += length;
  }
  return true;
}

// No byte a terminal acts on: text shown by show, diff and reports.
bool has_no_control_bytes(std::string_view text) {
  for (unsigned char byte : text) {
    if (byte < 0x20 || byte == 0x7F) return false;
  }
  return true;
}

// Random streams, and streams that look like each protocol with bytes >= 0x80
// and control bytes where its text goes.
std::vector<std::string> hostile_streams() {
  std::mt19937 random(23);
  std::vector<std::string> streams = {
      "$GPGGA,1,2*\xff\xfe\r\n"s,
      "$GPGGA,1,2*\x1b[\r\n"s,
      "$\xc3(,1*00\n"s,
      "\xff\xfe\n\x1b]0;x\x07\n"s,
      "V\xff\n00P\n\n\x1b\x9b\n\xe9\xe9\n\n"s,
      "\xe9\xe9\xe9\r\a"s,
      "t\xff\xff\xff\x32\r"s,
  };
  for (int n = 0; n < 300; ++n) {
    std::string stream(std::uniform_int_distribution<int>(1, 300)(random), '\0');
    for (char& byte : stream) {
      // Bias towards the bytes that end or begin frames.
      const int pick = std::uniform_int_distribution<int>(0, 15)(random);
      const char specials[] = {'\n', '\r', '$', '!', '*', ',', '\a', static_cast<char>(0xFE),
                               static_cast<char>(0xFD)};
      byte = pick < 9 ? specials[pick]
                      : static_cast<char>(std::uniform_int_distribution<int>(0, 255)(random));
    }
    streams.push_back(stream);
  }
  return streams;
}

}  // namespace

TEST(ProfileText, EveryProfileMakesValidUtf8FromAnyDeviceBytes) {
  const std::vector<std::string> streams = hostile_streams();
  std::vector<std::pair<std::string, std::shared_ptr<const Profile>>> profiles;
  for (const std::string& name : profile_names()) {
    // The profile ProfileInterface registers is this program's own, not a
    // built-in: its names are the raw bytes.
    if (name != "counter4") profiles.emplace_back(name, find_profile(name));
  }
  // Declared profiles of every framing, with a checksum.
  for (const char* spec : {"framing=delimiter:0d0a,checksum=xor8@-3",
                           "framing=length:1:1:2,checksum=crc16-modbus@-2",
                           "framing=fixed:5,ignore=0:1,checksum=sum8@-1"}) {
    Options options = Options::parse(spec);
    profiles.emplace_back(spec, detail::take_declared_profile(options));
  }
  for (const auto& [name, profile] : profiles) {
    for (StreamDirection direction : {StreamDirection::tx, StreamDirection::rx}) {
      for (const std::string& stream : streams) {
        std::vector<Frame> frames = frames_of(*profile, direction, stream, stream.size() + 1);
        frames.push_back(Frame{stream, FrameEnd::delimited, {}});  // the whole stream, unframed
        for (const Frame& frame : frames) {
          const std::string where = name + (direction == StreamDirection::tx ? " tx " : " rx ") +
                                    detail::escape_bytes(frame.bytes, 80);
          for (const std::string& text :
               {profile->frame_name(direction, frame.bytes), profile->describe(direction, frame.bytes),
                frame.problem}) {
            EXPECT_TRUE(is_valid_utf8(text)) << where << ": " << detail::escape_bytes(text, 200);
            EXPECT_TRUE(has_no_control_bytes(text)) << where << ": " << detail::escape_bytes(text, 200);
          }
          for (std::size_t offset = 0; offset <= frame.bytes.size(); ++offset) {
            const std::string field = profile->field_name(direction, frame.bytes, offset);
            EXPECT_TRUE(is_valid_utf8(field) && has_no_control_bytes(field))
                << where << " offset " << offset << ": " << detail::escape_bytes(field, 200);
          }
        }
      }
    }
  }
}

TEST(ProfileText, AnNmeaChecksumOfNonAsciiBytesIsABrokenFrameShownEscaped) {
  const auto profile = find_profile("nmea");
  const std::string sentence = "$GPGGA,1,2*\xff\xfe\r\n"s;
  const auto frames = frames_any_split(*profile, StreamDirection::rx, sentence);
  ASSERT_EQ(frames.size(), 1u);
  EXPECT_EQ(frames[0].end, FrameEnd::broken);
  EXPECT_EQ(frames[0].problem, "bad checksum field '*\\xff\\xfe'");
  // A sign or a single digit is no checksum either (sscanf's %2x took them).
  EXPECT_EQ(frames_any_split(*profile, StreamDirection::rx, "$GPGGA,1*+5\r\n")[0].end,
            FrameEnd::broken);
  EXPECT_EQ(frames_any_split(*profile, StreamDirection::rx, "$GPGGA,1*5 \r\n")[0].end,
            FrameEnd::broken);
}

TEST(ProfileText, AClientSentenceWithNonAsciiChecksumIsAMismatchWithUtf8Text) {
  for (const char* mode : {"match=request", "match=sequence,check=data"}) {
    auto port = replay({tx(1, nmea("PXXX,1")), rx(2, nmea("GPTXT,ok"))},
                       std::string("timing=none,profile=nmea,unused=ignore,") + mode);
    try {
      port->write_all("$PXXX,1*\xff\xfe\r\n"s);
      FAIL() << mode << ": no mismatch";
    } catch (const ReplayMismatch& error) {
      const std::string message = error.what();
      EXPECT_TRUE(is_valid_utf8(message)) << mode << ": " << detail::escape_bytes(message, 400);
      EXPECT_NE(message.find("\\xff\\xfe"), std::string::npos) << mode << ": " << message;
    }
  }
}

TEST(ProfileText, ScipNamesEscapeWhatIsNotPrintableAscii) {
  const auto profile = find_profile("scip");
  EXPECT_EQ(profile->frame_name(StreamDirection::tx, "\xff\x1b\n"s), "\\xff\\x1b");
  EXPECT_EQ(profile->frame_name(StreamDirection::tx, "VV\n"), "VV");
}
