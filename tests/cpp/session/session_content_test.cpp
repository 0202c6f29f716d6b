// Hostile content in files whose CRCs are all valid: the reader refusing
// what a command could not use (non-UTF-8 header strings, deeply nested
// event payloads, absurd times), so that what `verify` accepts every command
// can read. The JSON parser's own limits: tests/cpp/util/json_test.cpp.
#include <unistd.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <iterator>
#include <optional>
#include <string>
#include <vector>

#include "session/format.hpp"
#include "session/header.hpp"
#include "support/port_test_support.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/session.hpp"

using namespace wiretape;

namespace {

using wiretape::test::TempDir;
using wiretape::test::write_file;

const char* const good_header =
    R"({"port_options":"type=loopback","port_type":"loopback",)"
    R"("start_utc":"2026-01-02T03:04:05.000006Z","wiretape_version":"0.1.0",)"
    R"("host":"h","capture":"client","metadata":{}})";

// A session file built byte by byte, with every CRC right, so that only its
// content can be wrong.
class RawSession {
 public:
  explicit RawSession(const std::string& header_json = good_header) {
    std::string fixed(detail::file_header_fixed_size, '\0');
    std::copy(std::begin(detail::session_magic), std::end(detail::session_magic),
              fixed.begin());
    detail::put_u16le(&fixed[8], detail::session_version_major);
    detail::put_u16le(&fixed[10], detail::session_version_minor);
    detail::put_u32le(&fixed[12], static_cast<std::uint32_t>(header_json.size()));
    bytes_ = fixed + header_json;
    append_crc(0);
  }

  // Returns the record's offset.
  std::uint64_t add(RecordKind kind, std::uint64_t t_ns, const std::string& payload) {
    const std::uint64_t offset = bytes_.size();
    std::string head(detail::record_header_size, '\0');
    detail::put_u32le(&head[0], static_cast<std::uint32_t>(payload.size()));
    head[4] = static_cast<char>(kind);
    detail::put_u64le(&head[8], t_ns);
    bytes_ += head + payload;
    append_crc(offset);
    return offset;
  }

  std::string write(const TempDir& dir, const std::string& name = "s.wtape") const {
    const std::string path = dir.file(name);
    write_file(path, bytes_);
    return path;
  }

 private:
  void append_crc(std::size_t from) {
    char crc[detail::crc_size];
    detail::put_u32le(crc, wiretape::crc32c(bytes_.data() + from, bytes_.size() - from));
    bytes_.append(crc, sizeof crc);
  }

  std::string bytes_;
};

std::string nested(int levels) {
  return std::string(static_cast<std::size_t>(levels), '[') +
         std::string(static_cast<std::size_t>(levels), ']');
}

// The records read, and the damage (offset, message) if any.
struct ReadResult {
  std::size_t records = 0;
  std::optional<SessionError> damage;
};

ReadResult read_through(const std::string& path) {
  SessionReader reader(path);
  ReadResult result;
  Record record;
  while (reader.next(record)) ++result.records;
  result.damage = reader.damage();
  return result;
}

}  // namespace

// --- the reader ----------------------------------------------------------------------

TEST(HostileSession, AGoodRawSessionReads) {
  TempDir dir;
  RawSession session;
  session.add(RecordKind::open, 0, R"({"description":"x"})");
  session.add(RecordKind::tx, 5, "VV\n");
  session.add(RecordKind::close, detail::max_record_t_ns, "");
  const ReadResult result = read_through(session.write(dir));
  EXPECT_EQ(result.records, 3u);
  EXPECT_FALSE(result.damage) << result.damage->what();
}

TEST(HostileSession, NonUtf8HeaderStringsAreRefusedAtOpenWithTheOffset) {
  TempDir dir;
  for (const std::string header :
       {std::string(R"({"port_options":"type=serial,device=/dev/tty)") + "\xff" + R"("})",
        std::string(R"({"host":"h)") + "\xc0\xaf" + R"("})",
        std::string(R"({"metadata":{"k":"\ud800"}})"),
        std::string(R"({"metadata":{"k)") + "\xfe" + R"(":"v"}})"}) {
    const std::string path = RawSession(header).write(dir);
    try {
      SessionReader reader(path);
      ADD_FAILURE() << "opened a header with " << ::testing::PrintToString(header);
    } catch (const SessionError& e) {
      EXPECT_GT(e.offset(), detail::file_header_fixed_size);
      const std::string what = e.what();
      EXPECT_TRUE(what.find("UTF-8") != std::string::npos ||
                  what.find("surrogate") != std::string::npos)
          << what;
    }
  }
}

TEST(HostileSession, StartTimesOutOfRangeOrShapeAreRefusedAtOpen) {
  TempDir dir;
  for (const char* start : {"9999-12-31T23:59:59Z", "1900-01-01T00:00:00Z", "yesterday",
                            "2026-13-01T00:00:00Z", "2026-01-01T00:00:00.1234567890Z",
                            "2026-01-01 00:00:00Z"}) {
    const std::string path =
        RawSession(std::string(R"({"start_utc":")") + start + R"("})").write(dir);
    try {
      SessionReader reader(path);
      ADD_FAILURE() << "opened start_utc " << start;
    } catch (const SessionError& e) {
      EXPECT_NE(std::string(e.what()).find("start_utc"), std::string::npos) << e.what();
    }
  }
  for (const char* start : {"", "2026-01-02T03:04:05Z", "2261-12-31T23:59:59.999999999Z"}) {
    const std::string path =
        RawSession(std::string(R"({"start_utc":")") + start + R"("})").write(dir);
    EXPECT_NO_THROW(SessionReader reader(path)) << start;
  }
}

TEST(HostileSession, AnEscapeSequenceInAnErrorMessageIsEscaped) {
  TempDir dir;
  const std::string path = RawSession(R"({"capture":"\u001b[2Jwire"})").write(dir);
  try {
    SessionReader reader(path);
    FAIL();
  } catch (const SessionError& e) {
    EXPECT_EQ(std::string(e.what()).find('\x1b'), std::string::npos) << e.what();
  }
}

TEST(HostileSession, DeeplyNestedEventPayloadIsDamageAtItsRecord) {
  TempDir dir;
  RawSession session;
  session.add(RecordKind::tx, 1, "A");
  const std::uint64_t offset =
      session.add(RecordKind::settings, 2, R"({"baud":9600,"x":)" + nested(50'000) + "}");
  session.add(RecordKind::rx, 3, "B");
  const ReadResult result = read_through(session.write(dir));
  EXPECT_EQ(result.records, 1u);
  ASSERT_TRUE(result.damage);
  EXPECT_EQ(result.damage->offset(), offset);
  const std::string what = result.damage->what();
  EXPECT_NE(what.find("settings event payload"), std::string::npos) << what;
  EXPECT_NE(what.find("deeper than 64"), std::string::npos) << what;
}

TEST(HostileSession, EventPayloadsMustBeUtf8JsonObjects) {
  TempDir dir;
  for (const std::string payload :
       {std::string("not json"), std::string("[1,2]"), std::string("{\"error\":\"\xff\"}"),
        std::string(R"({"error":"\udfff"})")}) {
    RawSession session;
    const std::uint64_t offset = session.add(RecordKind::device_lost, 7, payload);
    const ReadResult result = read_through(session.write(dir));
    ASSERT_TRUE(result.damage) << payload;
    EXPECT_EQ(result.damage->offset(), offset);
  }
  // Members the table does not know are for newer readers: accepted.
  RawSession session;
  session.add(RecordKind::close, 7, R"({"future":[{"a":1}]})");
  EXPECT_FALSE(read_through(session.write(dir)).damage);
}

TEST(HostileSession, TimesBeyondTheBoundAreDamageAtTheirRecord) {
  TempDir dir;
  RawSession session;
  session.add(RecordKind::rx, detail::max_record_t_ns, "ok");
  const std::uint64_t offset = session.add(RecordKind::rx, UINT64_MAX, "late");
  const ReadResult result = read_through(session.write(dir));
  EXPECT_EQ(result.records, 1u);
  ASSERT_TRUE(result.damage);
  EXPECT_EQ(result.damage->offset(), offset);
  EXPECT_NE(std::string(result.damage->what()).find("18446744073709551615"),
            std::string::npos)
      << result.damage->what();
}

// --- the writer ----------------------------------------------------------------------

TEST(HostileSession, TheWriterRefusesAHeaderTheReaderWouldRefuse) {
  TempDir dir;
  SessionHeader header;
  header.user_metadata = {{"note", "bad \xff byte"}};
  try {
    SessionWriter writer(dir.file("a.wtape"), header);
    FAIL();
  } catch (const OptionError& e) {
    EXPECT_EQ(e.key(), "meta_note");
  }
  header.user_metadata.clear();
  header.start_utc = "9999-01-01T00:00:00Z";
  EXPECT_THROW(SessionWriter(dir.file("b.wtape"), header), OptionError);
  // Refused before the file is created.
  EXPECT_NE(::access(dir.file("a.wtape").c_str(), F_OK), 0);
  EXPECT_NE(::access(dir.file("b.wtape").c_str(), F_OK), 0);
}

TEST(HostileSession, TheWriterRefusesARecordTheReaderWouldStopAt) {
  TempDir dir;
  SessionWriter writer(dir.file("c.wtape"), SessionHeader{});
  EXPECT_THROW(writer.write(RecordKind::rx, detail::max_record_t_ns + 1, "x"),
               std::invalid_argument);
  EXPECT_THROW(writer.write(RecordKind::settings, 1, "not json"), std::invalid_argument);
  EXPECT_THROW(writer.write(RecordKind::close, 1, nested(100)), std::invalid_argument);
  writer.write(RecordKind::close, 2, "");
  writer.write(RecordKind::rx, detail::max_record_t_ns, "\xff");
  writer.close();
  const ReadResult result = read_through(dir.file("c.wtape"));
  EXPECT_EQ(result.records, 2u);
  EXPECT_FALSE(result.damage);
}
