// Protocol profiles: the registry, SCIP framing under every split of the
// stream, frame names and descriptions, hostile input, and the session
// decoder behind `wiretape show --decode scip`.
#include <gtest/gtest.h>

#include <deque>
#include <random>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "replay/profile.hpp"
#include "replay/profiles/builtin.hpp"
#include "support/port_test_support.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/session.hpp"

using namespace wiretape;
using namespace wiretape::detail;

namespace {

const std::string kRecordingsDir = std::string(WIRETAPE_TEST_DATA_DIR) + "/../../examples/hokuyo/recordings/";
const std::string kFlexiportDir = std::string(WIRETAPE_TEST_DATA_DIR) + "/flexiport/";

// One direction's bytes, concatenated.
std::string stream_of(const std::vector<Record>& records, RecordKind kind) {
  std::string out;
  for (const Record& record : records)
    if (record.kind == kind) out += record.data;
  return out;
}

std::vector<Frame> frame_in_chunks(const Profile& profile, StreamDirection direction,
                                   const std::string& stream,
                                   const std::vector<std::size_t>& chunk_sizes) {
  auto framer = profile.make_framer(direction);
  std::vector<Frame> frames;
  std::size_t offset = 0;
  for (std::size_t i = 0; offset < stream.size(); ++i) {
    const std::size_t size = chunk_sizes.empty() ? stream.size() : chunk_sizes[i % chunk_sizes.size()];
    framer->feed(std::string_view(stream).substr(offset, size), frames);
    offset += size;
  }
  if (auto tail = framer->finish()) frames.push_back(std::move(*tail));
  EXPECT_EQ(framer->pending(), 0u);
  return frames;
}

std::vector<std::size_t> random_chunks(std::mt19937& random, std::size_t max) {
  std::uniform_int_distribution<std::size_t> size(1, max);
  std::vector<std::size_t> sizes(97);
  for (std::size_t& s : sizes) s = size(random);
  return sizes;
}

std::vector<std::string> bytes_of(const std::vector<Frame>& frames) {
  std::vector<std::string> out;
  for (const Frame& frame : frames) out.push_back(frame.bytes);
  return out;
}

std::string joined(const std::vector<Frame>& frames) {
  std::string out;
  for (const Frame& frame : frames) out += frame.bytes;
  return out;
}

// Every split of the stream gives the same frames: whole, byte by byte,
// and seeded random chunks.
void expect_split_independent(const Profile& profile, StreamDirection direction,
                              const std::string& stream) {
  const auto whole = bytes_of(frame_in_chunks(profile, direction, stream, {}));
  EXPECT_EQ(whole, bytes_of(frame_in_chunks(profile, direction, stream, {1})));
  std::mt19937 random(1234);
  for (int round = 0; round < 20; ++round) {
    const auto chunks = random_chunks(random, round % 2 ? 7 : 300);
    EXPECT_EQ(whole, bytes_of(frame_in_chunks(profile, direction, stream, chunks)))
        << "round " << round;
  }
}

}  // namespace

TEST(ProfileRegistry, ScipComesFirst) {
  const std::vector<std::string> names = profile_names();
  ASSERT_FALSE(names.empty());
  EXPECT_EQ(names.front(), "scip");
  for (const std::string& name : names) EXPECT_EQ(find_profile(name)->name(), name);
}

TEST(ProfileRegistry, UnknownNameIsAnOptionErrorListingTheKnownOnes) {
  try {
    find_profile("modbus-xyz");
    FAIL() << "no error";
  } catch (const OptionError& error) {
    EXPECT_EQ(error.key(), "profile");
    const std::string message = error.what();
    EXPECT_NE(message.find("unknown profile 'modbus-xyz'"), std::string::npos) << message;
    for (const std::string& name : profile_names())
      EXPECT_NE(message.find(name), std::string::npos) << message;
  }
}

TEST(ScipFraming, CommandsEndWithLfCrOrCrLf) {
  const auto scip = find_profile("scip");
  const std::string stream = "VV\nPP\r\nII\rBM\nGD0044072501\nQT";
  const auto frames = frame_in_chunks(*scip, StreamDirection::tx, stream, {});
  EXPECT_EQ(bytes_of(frames),
            (std::vector<std::string>{"VV\n", "PP\r\n", "II\r", "BM\n", "GD0044072501\n", "QT"}));
  EXPECT_EQ(frames.back().end, FrameEnd::stream_end);
  EXPECT_EQ(frames.front().end, FrameEnd::delimited);
  expect_split_independent(*scip, StreamDirection::tx, stream);
}

TEST(ScipFraming, ACommandEndedByABareCrIsCompleteAtTheEnd) {
  const auto scip = find_profile("scip");
  const auto frames = frame_in_chunks(*scip, StreamDirection::tx, "QT\r", {});
  ASSERT_EQ(frames.size(), 1u);
  EXPECT_EQ(frames[0].bytes, "QT\r");
  EXPECT_EQ(frames[0].end, FrameEnd::delimited);
}

TEST(ScipFraming, RepliesEndWithAnEmptyLine) {
  const auto scip = find_profile("scip");
  const std::string stream =
      "VV\n00P\nVEND:Hokuyo;[\n\n"   // a reply with one data line
      "\n"                           // an empty reply
      "BM\n02R\n\n"                  // status only
      "MD0044072501001\n00P\n\n"     // a scan command's acknowledgement...
      "MD0044072501000\n99b\nABC\n\n"  // ...and its scans
      "MD0044072501000\n99b\nDEF\n\n"
      "GD\n00";                      // cut short
  const auto frames = frame_in_chunks(*scip, StreamDirection::rx, stream, {});
  EXPECT_EQ(bytes_of(frames),
            (std::vector<std::string>{"VV\n00P\nVEND:Hokuyo;[\n\n", "\n", "BM\n02R\n\n",
                                      "MD0044072501001\n00P\n\n", "MD0044072501000\n99b\nABC\n\n",
                                      "MD0044072501000\n99b\nDEF\n\n", "GD\n00"}));
  EXPECT_EQ(frames.back().end, FrameEnd::stream_end);
  expect_split_independent(*scip, StreamDirection::rx, stream);
}

TEST(ScipFraming, ASwitchFromScip11IsOneCommandAndOneReply) {
  const auto scip = find_profile("scip");
  EXPECT_EQ(bytes_of(frame_in_chunks(*scip, StreamDirection::tx, "SCIP2.0\nVV\n", {})),
            (std::vector<std::string>{"SCIP2.0\n", "VV\n"}));
  EXPECT_EQ(bytes_of(frame_in_chunks(*scip, StreamDirection::rx, "SCIP2.0\n0\n\n", {})),
            (std::vector<std::string>{"SCIP2.0\n0\n\n"}));
  EXPECT_EQ(scip->frame_name(StreamDirection::tx, "SCIP2.0\n"), "SCIP2.0");
  EXPECT_EQ(scip->describe(StreamDirection::tx, "SCIP2.0\n"),
            "SCIP2.0                  SCIP2.0: switch to SCIP 2.0");
}

TEST(ScipFraming, RealRecordingsFrameTheSameUnderEverySplit) {
  const auto scip = find_profile("scip");
  for (const std::string& path :
       {kRecordingsDir + "urg04lx_gd.wtape", kRecordingsDir + "urg04lx_md.wtape",
        kRecordingsDir + "utm30lx_me.wtape", kFlexiportDir + "urg04lx_2011.log",
        kFlexiportDir + "utm30lx_2011.log"}) {
    SCOPED_TRACE(path);
    const auto records = wiretape::test::load_records(path);
    for (auto [kind, direction] : {std::pair{RecordKind::tx, StreamDirection::tx},
                                   std::pair{RecordKind::rx, StreamDirection::rx}}) {
      const std::string stream = stream_of(records, kind);
      ASSERT_FALSE(stream.empty());
      const auto frames = frame_in_chunks(*scip, direction, stream, {});
      EXPECT_EQ(joined(frames), stream);
      for (const Frame& frame : frames) EXPECT_NE(frame.end, FrameEnd::size_limit);
      expect_split_independent(*scip, direction, stream);
    }
  }
}

TEST(ScipFraming, TheFlexiportUrgSessionHasItsTenCommands) {
  const auto scip = find_profile("scip");
  const auto records = wiretape::test::load_records(kFlexiportDir + "urg04lx_2011.log");
  std::vector<std::string> names;
  for (const Frame& frame :
       frame_in_chunks(*scip, StreamDirection::tx, stream_of(records, RecordKind::tx), {}))
    names.push_back(scip->match_key(frame.bytes));
  EXPECT_EQ(names, (std::vector<std::string>{"VV", "VV", "PP", "II", "BM", "CR00", "VV", "PP",
                                             "II", "GD0044072501"}));
}

TEST(ScipNames, CommandCodesAndMeanings) {
  const auto scip = find_profile("scip");
  EXPECT_EQ(scip->frame_name(StreamDirection::tx, "GD0044072501\n"), "GD");
  EXPECT_EQ(scip->frame_name(StreamDirection::rx, "MD0044072501000\n99b\n\n"), "MD");
  EXPECT_EQ(scip->describe(StreamDirection::tx, "GD0044072501\n"),
            "GD0044072501             GD: single scan (3-character ranges)");
  EXPECT_EQ(scip->describe(StreamDirection::tx, "XY\n"),
            "XY                       XY: unknown command");
  EXPECT_EQ(scip->describe(StreamDirection::rx, "VV\n00P\nVEND:Hokuyo;[\n\n"),
            "VV                       reply to VV (version information): ok 00, 1 data "
            "lines, 22 bytes");
  EXPECT_EQ(scip->describe(StreamDirection::rx, "MD0044072501000\n99b\nABC\nDEF\n\n"),
            "MD0044072501000          reply to MD (continuous scans (3-character ranges)): "
            "scan data 99, 2 data lines, 29 bytes");
  EXPECT_EQ(scip->describe(StreamDirection::rx, "BM\n02R\n\n"),
            "BM                       reply to BM (laser on): status 02, 0 data lines, 8 bytes");
  EXPECT_EQ(scip->describe(StreamDirection::rx, "GD"),
            "GD                       reply to GD (single scan (3-character ranges)): "
            "status ??, 0 data lines, 2 bytes");
}

TEST(ScipNames, LongAndBinaryLinesAreShownEscapedAndShortened) {
  const auto scip = find_profile("scip");
  EXPECT_EQ(scip->describe(StreamDirection::tx, std::string("\x01\xff\\\t\n\n", 6)),
            // The command code too is escaped: no control byte reaches a
            // terminal, and bytes >= 0x80 show as what they are (not U+FFFD).
            std::string("\\x01\\xff\\\\\\t             \\x01\\xff: unknown command"));
  const std::string long_echo(30, 'G');
  EXPECT_EQ(scip->describe(StreamDirection::rx, long_echo + "\n00P\n\n"),
            std::string(24, 'G') + "... (+6 bytes) reply to GG (unknown command): ok 00, 0 "
                                   "data lines, 36 bytes");
}

TEST(ScipMatchKey, TheCommandLineWithoutItsLineEnd) {
  const auto scip = find_profile("scip");
  EXPECT_EQ(scip->match_key("GD0044072501\n"), "GD0044072501");
  EXPECT_EQ(scip->match_key("VV\r\n"), "VV");
  EXPECT_EQ(scip->match_key("VV\r"), "VV");
  EXPECT_EQ(scip->match_key("VV;tag\n"), "VV;tag");
}

TEST(ScipHostileInput, ALineWithoutEndIsCutAtTheSizeLimit) {
  const auto scip = find_profile("scip");
  for (StreamDirection direction : {StreamDirection::tx, StreamDirection::rx}) {
    auto framer = scip->make_framer(direction);
    std::vector<Frame> frames;
    const std::string chunk(64 * 1024, 'A');
    for (std::size_t fed = 0; fed < 3 * max_frame_bytes + 10; fed += chunk.size()) {
      framer->feed(chunk, frames);
      EXPECT_LT(framer->pending(), max_frame_bytes);
    }
    ASSERT_EQ(frames.size(), 3u);
    for (const Frame& frame : frames) {
      EXPECT_EQ(frame.bytes.size(), max_frame_bytes);
      EXPECT_EQ(frame.end, FrameEnd::size_limit);
    }
  }
}

TEST(ScipHostileInput, ACrLfAcrossTheSizeLimitDoesNotGrowAFramePastIt) {
  const auto scip = find_profile("scip");
  const std::string stream = std::string(max_frame_bytes - 1, 'A') + "\r\n";
  const auto frames = frame_in_chunks(*scip, StreamDirection::tx, stream, {});
  ASSERT_EQ(frames.size(), 2u);
  EXPECT_EQ(frames[0].bytes.size(), max_frame_bytes);
  EXPECT_EQ(frames[0].end, FrameEnd::size_limit);
  EXPECT_EQ(frames[1].bytes, "\n");
}

TEST(ScipHostileInput, BinaryGarbageIsFramedWithoutLoss) {
  const auto scip = find_profile("scip");
  std::mt19937 random(99);
  std::uniform_int_distribution<int> byte(0, 255);
  std::string garbage(200000, '\0');
  for (char& c : garbage) c = static_cast<char>(byte(random));
  garbage += std::string(1000, '\0');
  for (StreamDirection direction : {StreamDirection::tx, StreamDirection::rx}) {
    const auto frames = frame_in_chunks(*scip, direction, garbage, random_chunks(random, 5000));
    EXPECT_EQ(joined(frames), garbage);
    for (const Frame& frame : frames) {
      EXPECT_LE(frame.bytes.size(), max_frame_bytes);
      scip->describe(direction, frame.bytes);  // describes anything
    }
    expect_split_independent(*scip, direction, garbage);
  }
}

TEST(LinesProfile, LinesEndWithTheDelimiterInEitherDirection) {
  const auto lines = find_profile("lines");
  const std::string stream = "$GPGGA,1*47\n\n$GPRMC,2*11\r\npartial";
  for (StreamDirection direction : {StreamDirection::tx, StreamDirection::rx}) {
    EXPECT_EQ(bytes_of(frame_in_chunks(*lines, direction, stream, {})),
              (std::vector<std::string>{"$GPGGA,1*47\n", "\n", "$GPRMC,2*11\r\n", "partial"}));
    expect_split_independent(*lines, direction, stream);
  }
  EXPECT_EQ(lines->match_key("AT+CSQ\n"), "AT+CSQ");
  EXPECT_EQ(lines->frame_name(StreamDirection::tx, "AT+CSQ\n"), "AT+CSQ");
  EXPECT_EQ(lines->describe(StreamDirection::rx, "+CSQ: 21,0\r\n"), "+CSQ: 21,0\\r\\n");
}

TEST(LinesProfile, AMultiByteDelimiterUnderEverySplit) {
  const auto lines = make_lines_profile("\r\n");
  const std::string stream = "OK\r\nERR\rOR\n\r\n\r\r\nend";
  EXPECT_EQ(bytes_of(frame_in_chunks(*lines, StreamDirection::rx, stream, {})),
            (std::vector<std::string>{"OK\r\n", "ERR\rOR\n\r\n", "\r\r\n", "end"}));
  expect_split_independent(*lines, StreamDirection::rx, stream);
  EXPECT_EQ(lines->match_key("OK\r\n"), "OK");
}

TEST(LinesProfile, AnEmptyDelimiterIsAnOptionError) {
  try {
    make_lines_profile("");
    FAIL() << "no error";
  } catch (const OptionError& error) {
    EXPECT_EQ(error.key(), "delimiter");
    EXPECT_NE(std::string(error.what()).find("delimiter is empty"), std::string::npos);
  }
}

TEST(LinesProfile, GarbageWithoutDelimiterIsCutAtTheSizeLimit) {
  const auto lines = find_profile("lines");
  auto framer = lines->make_framer(StreamDirection::rx);
  std::vector<Frame> frames;
  const std::string chunk(64 * 1024, '\0');
  for (std::size_t fed = 0; fed < 2 * max_frame_bytes + 10; fed += chunk.size()) {
    framer->feed(chunk, frames);
    EXPECT_LT(framer->pending(), max_frame_bytes);
  }
  ASSERT_EQ(frames.size(), 2u);
  EXPECT_EQ(frames[0].end, FrameEnd::size_limit);
  EXPECT_EQ(frames[0].bytes.size(), max_frame_bytes);
}

TEST(SessionDecoder, FramesTakeTheTimeOfTheirFirstByteAndEventsPassThrough) {
  SessionDecoder decoder(find_profile("scip"));
  std::deque<DecodedItem> out;
  decoder.feed(10, RecordKind::open, "{}", out);
  decoder.feed(20, RecordKind::tx, "V", out);
  decoder.feed(30, RecordKind::tx, "V\nP", out);
  decoder.feed(40, RecordKind::rx, "VV\n00P\n", out);
  decoder.feed(50, RecordKind::settings, "{\"baud\":115200}", out);
  decoder.feed(60, RecordKind::tx, "P\nII\nB", out);
  decoder.feed(70, RecordKind::rx, "\nPP", out);
  decoder.finish(out);
  std::vector<std::tuple<std::uint64_t, RecordKind, std::string, bool>> got;
  for (const DecodedItem& item : out) got.emplace_back(item.t_ns, item.kind, item.bytes, item.is_frame);
  using T = std::tuple<std::uint64_t, RecordKind, std::string, bool>;
  EXPECT_EQ(got, (std::vector<T>{
                     T{10, RecordKind::open, "{}", false},
                     T{20, RecordKind::tx, "VV\n", true},
                     T{50, RecordKind::settings, "{\"baud\":115200}", false},
                     T{30, RecordKind::tx, "PP\n", true},
                     T{60, RecordKind::tx, "II\n", true},
                     T{40, RecordKind::rx, "VV\n00P\n\n", true},
                     T{70, RecordKind::rx, "PP", true},  // the tails: rx first
                     T{60, RecordKind::tx, "B", true},
                 }));
  EXPECT_EQ(out[1].description, "VV                       VV: version information");
  EXPECT_TRUE(out[0].description.empty());
}

namespace {

char scip_sum(std::string_view bytes) {
  unsigned sum = 0;
  for (unsigned char byte : bytes) sum += byte;
  return static_cast<char>((sum & 0x3F) + 0x30);
}

// Whether every line of a SCIP 2.0 reply after its echo holds a right sum
// (a parameter line's without its ';', as the real scanners send them).
bool scip_sums_hold(std::string_view reply) {
  std::size_t start = reply.find('\n') + 1;
  while (start < reply.size()) {
    const std::size_t end = reply.find('\n', start);
    const std::string_view line = reply.substr(start, end - start);
    start = end + 1;
    if (line.empty()) continue;
    std::string_view data = line.substr(0, line.size() - 1);
    if (scip_sum(data) == line.back()) continue;
    if (!data.empty() && data.back() == ';') data.remove_suffix(1);
    if (scip_sum(data) != line.back()) return false;
  }
  return true;
}

}  // namespace

TEST(ScipChecksums, AScrubbedSerialNumberGetsItsLineSumAndTheRestStays) {
  const auto profile = find_profile("scip");
  // The URG-04LX's own VV reply (tests/data/flexiport): parameter lines sum
  // without their ';'.
  const std::string vv =
      "VV\n00P\nVEND:Hokuyo Automatic Co.,Ltd.;[\nPROD:SOKUIKI Sensor URG-04LX;[\n"
      "FIRM:3.1.04(02/Aug./2007);a\nPROT:SCIP 2.0;N\nSERI:H0706400;F\n\n";
  ASSERT_TRUE(scip_sums_hold(vv));
  std::string dirty = vv;
  const std::size_t serial = dirty.find("SERI:");
  dirty.replace(serial, 13, std::string(13, '*'));
  ASSERT_FALSE(scip_sums_hold(dirty));
  const std::string fixed = profile->recompute_checksums(StreamDirection::rx, dirty);
  EXPECT_TRUE(scip_sums_hold(fixed)) << fixed;
  EXPECT_EQ(fixed.size(), vv.size());
  // Only the scrubbed line's sum changed; it leaves the ';' out as before.
  EXPECT_EQ(fixed.substr(0, serial), vv.substr(0, serial));
  EXPECT_EQ(fixed.substr(serial, 15), std::string(13, '*') + ";" + scip_sum(std::string(13, '*')));
  EXPECT_EQ(profile->recompute_checksums(StreamDirection::rx, vv), vv);
  // Commands carry no sum.
  EXPECT_EQ(profile->recompute_checksums(StreamDirection::tx, "VV\n"), "VV\n");
}

TEST(ScipChecksums, ScanDataLinesSumOverEveryByteAndAStatusLineToo) {
  const auto profile = find_profile("scip");
  // A data line ending in ';' is data, not a parameter: its sum covers it.
  const std::string data = "0;2;";
  const std::string reply = std::string("GD0044072501\n") + "00" + scip_sum("00") + "\n" +
                            data + scip_sum(data) + "\n\n";
  std::string dirty = reply;
  dirty.replace(dirty.find("0;2;"), 4, "****");
  dirty.replace(13, 2, "**");  // the status
  const std::string fixed = profile->recompute_checksums(StreamDirection::rx, dirty);
  EXPECT_EQ(fixed, std::string("GD0044072501\n") + "**" + scip_sum("**") + "\n" + "****" +
                       scip_sum("****") + "\n\n");
  // SCIP 1.1's one-character status and a reply cut short are left alone.
  EXPECT_EQ(profile->recompute_checksums(StreamDirection::rx, "SCIP2.0\n0\n\n"), "SCIP2.0\n0\n\n");
  EXPECT_EQ(profile->recompute_checksums(StreamDirection::rx, "GD\n00P\n12"), "GD\n00P\n12");
}

TEST(ProfileFromSpec, ANameIsProfileEqualsName) {
  const ProfileSpec read = profile_from_spec(" scip ");
  ASSERT_NE(read.profile, nullptr);
  EXPECT_EQ(read.profile->name(), "scip");
  EXPECT_EQ(read.options, "profile=scip");
  EXPECT_EQ(profile_from_spec("profile=modbus-tcp").profile->name(), "modbus-tcp");
}

TEST(ProfileFromSpec, KeysWithEqualsDeclareAProfileAsTheReplayDoes) {
  const ProfileSpec read = profile_from_spec("framing=fixed:10,echo=0:2");
  ASSERT_NE(read.profile, nullptr);
  EXPECT_EQ(read.options, "framing=fixed:10,echo=0:2");
  // The replay's own reading of the same keys gives the same framing.
  Options options = Options::parse(read.options);
  options.set_port_type("replay");
  const auto replayed = take_profile(options);
  ASSERT_NE(replayed, nullptr);
  EXPECT_EQ(replayed->name(), read.profile->name());
}

TEST(ProfileFromSpec, BadSpecsAreOptionErrorsNamingTheKey) {
  auto key_of = [](const std::string& spec) {
    try {
      profile_from_spec(spec);
    } catch (const OptionError& error) {
      return error.key();
    }
    return std::string("no error");
  };
  EXPECT_EQ(key_of("  "), "profile");
  EXPECT_EQ(key_of("no-such-profile"), "profile");
  EXPECT_EQ(key_of("framing=fixed:10,match=request"), "match");
  EXPECT_EQ(key_of("echo=0:2"), "echo");
  EXPECT_EQ(key_of("profile=scip,framing=fixed:10"), "framing");
}
