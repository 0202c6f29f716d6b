// flexiport's two-file logs: import (both formats, merged by time), export,
// byte-for-byte round trips of the real Hokuyo recordings.
#include <unistd.h>

#include <gtest/gtest.h>

#include "support/port_test_support.hpp"

#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "session/format.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/session.hpp"

using namespace wiretape;

namespace {

const std::string shared = std::string(WIRETAPE_TEST_DATA_DIR) + "/flexiport/";

using wiretape::test::TempDir;

using wiretape::test::read_file;
using wiretape::test::write_file;

struct Chunk {
  std::uint64_t sec = 0;
  std::uint64_t usec = 0;
  std::string data;
};

// An independent decoder of the new format, as the README describes it.
std::vector<Chunk> decode_new(const std::string& bytes) {
  std::vector<Chunk> chunks;
  std::size_t at = 0;
  while (at < bytes.size()) {
    if (bytes.size() - at < 12) throw std::runtime_error("bad test data");
    Chunk chunk;
    chunk.sec = detail::get_u32be(&bytes[at]);
    chunk.usec = detail::get_u32be(&bytes[at + 4]);
    const std::size_t length = detail::get_u32be(&bytes[at + 8]);
    chunk.data = bytes.substr(at + 12, length);
    at += 12 + length;
    chunks.push_back(chunk);
  }
  return chunks;
}

std::string encode_old(const std::vector<Chunk>& chunks) {
  std::string out;
  for (const Chunk& chunk : chunks) {
    char header[24];
    detail::put_u64le(header, chunk.sec);
    detail::put_u64le(header + 8, chunk.usec);
    detail::put_u64le(header + 16, chunk.data.size());
    out.append(header, sizeof header);
    out += chunk.data;
  }
  return out;
}

std::string encode_new(const std::vector<Chunk>& chunks) {
  std::string out;
  for (const Chunk& chunk : chunks) {
    char header[12];
    detail::put_u32be(header, static_cast<std::uint32_t>(chunk.sec));
    detail::put_u32be(header + 4, static_cast<std::uint32_t>(chunk.usec));
    detail::put_u32be(header + 8, static_cast<std::uint32_t>(chunk.data.size()));
    out.append(header, sizeof header);
    out += chunk.data;
  }
  return out;
}

std::vector<Record> read_all(SessionReader& reader) {
  std::vector<Record> records;
  Record record;
  while (reader.next(record)) records.push_back(record);
  return records;
}

// Every chunk of both files is a record, with its time, in file order per
// direction, and the merge is ordered by time with writes first on ties.
void expect_faithful_import(const std::vector<Record>& records,
                            const std::vector<Chunk>& reads,
                            const std::vector<Chunk>& writes) {
  std::size_t r = 0;
  std::size_t w = 0;
  std::uint64_t last_t = 0;
  RecordKind last_kind = RecordKind::tx;
  for (const Record& record : records) {
    ASSERT_TRUE(record.kind == RecordKind::rx || record.kind == RecordKind::tx);
    const bool is_read = record.kind == RecordKind::rx;
    const std::vector<Chunk>& chunks = is_read ? reads : writes;
    std::size_t& index = is_read ? r : w;
    ASSERT_LT(index, chunks.size());
    const Chunk& chunk = chunks[index++];
    EXPECT_EQ(record.t_ns, chunk.sec * 1'000'000'000ull + chunk.usec * 1000ull);
    EXPECT_EQ(record.data, chunk.data);
    EXPECT_GE(record.t_ns, last_t);
    if (record.t_ns == last_t) {
      EXPECT_FALSE(last_kind == RecordKind::rx && record.kind == RecordKind::tx)
          << "a write follows a read at the same time " << record.t_ns;
    }
    last_t = record.t_ns;
    last_kind = record.kind;
  }
  EXPECT_EQ(r, reads.size());
  EXPECT_EQ(w, writes.size());
}

class RealRecording : public ::testing::TestWithParam<std::string> {};

}  // namespace

TEST_P(RealRecording, EveryByteAndTimestampIsImported) {
  const std::string prefix = shared + GetParam() + ".log";
  const auto reads = decode_new(read_file(prefix + "r"));
  const auto writes = decode_new(read_file(prefix + "w"));
  ASSERT_GT(reads.size(), 100u);
  ASSERT_GE(writes.size(), 10u);
  for (const std::string& name : {prefix, prefix + "r", prefix + "w"}) {
    SessionReader reader(name);
    const SessionHeader& header = reader.header();
    EXPECT_EQ(header.source_format, "flexiport");
    EXPECT_EQ(header.source_details.at("read_format"), "new");
    EXPECT_EQ(header.source_details.at("write_format"), "new");
    const std::string base = prefix.substr(prefix.rfind('/') + 1);
    EXPECT_EQ(header.source_files, (std::vector<std::string>{base + "r", base + "w"}));
    // The logs hold no start time, host or port: none is invented.
    EXPECT_EQ(header.start_utc, "");
    EXPECT_EQ(header.host, "");
    EXPECT_EQ(header.version_major, 0);
    const auto records = read_all(reader);
    EXPECT_FALSE(reader.damage());
    expect_faithful_import(records, reads, writes);
  }
}

TEST_P(RealRecording, RoundTripsByteForByteThroughWtape) {
  TempDir dir;
  const std::string prefix = shared + GetParam() + ".log";
  const std::string wtape = dir.file("session.wtape");
  {
    SessionReader reader(prefix);
    SessionWriter writer(wtape, {});
    Record record;
    while (reader.next(record)) writer.write(record);
  }
  export_flexiport(wtape, dir.file("out.log"));
  EXPECT_EQ(read_file(dir.file("out.logr")), read_file(prefix + "r"));
  EXPECT_EQ(read_file(dir.file("out.logw")), read_file(prefix + "w"));
  // Straight from flexiport to flexiport, too.
  export_flexiport(prefix, dir.file("direct.log"));
  EXPECT_EQ(read_file(dir.file("direct.logr")), read_file(prefix + "r"));
  EXPECT_EQ(read_file(dir.file("direct.logw")), read_file(prefix + "w"));
}

TEST_P(RealRecording, OldFormatIsDetectedAndReadTheSame) {
  TempDir dir;
  const std::string prefix = shared + GetParam() + ".log";
  const auto reads = decode_new(read_file(prefix + "r"));
  const auto writes = decode_new(read_file(prefix + "w"));
  write_file(dir.file("old.logr"), encode_old(reads));
  write_file(dir.file("old.logw"), encode_old(writes));
  SessionReader reader(dir.file("old.log"));
  EXPECT_EQ(reader.header().source_details.at("read_format"), "old");
  EXPECT_EQ(reader.header().source_details.at("write_format"), "old");
  const auto records = read_all(reader);
  EXPECT_FALSE(reader.damage());
  expect_faithful_import(records, reads, writes);
  // Exported in the new format, it equals the original.
  export_flexiport(dir.file("old.log"), dir.file("new.log"));
  EXPECT_EQ(read_file(dir.file("new.logr")), read_file(prefix + "r"));
  EXPECT_EQ(read_file(dir.file("new.logw")), read_file(prefix + "w"));
}

INSTANTIATE_TEST_SUITE_P(Hokuyo, RealRecording,
                         ::testing::Values("urg04lx_2011", "utm30lx_2011"));

TEST(FlexiportLog, EqualTimesPutTheWriteBeforeTheRead) {
  TempDir dir;
  write_file(dir.file("s.logr"), encode_new({{1, 5, "answer"}, {2, 0, "late"}}));
  write_file(dir.file("s.logw"), encode_new({{0, 9, "first"}, {1, 5, "question"}, {2, 0, "tie"}}));
  SessionReader reader(dir.file("s.log"));
  const auto records = read_all(reader);
  std::vector<std::string> order;
  for (const auto& record : records) order.push_back(record.data);
  EXPECT_EQ(order, (std::vector<std::string>{"first", "question", "answer", "tie", "late"}));
}

TEST(FlexiportLog, SessionWithNoWritesIsRead) {
  TempDir dir;
  write_file(dir.file("gps.logr"), encode_new({{0, 1, "$GPGGA"}, {1, 1, "$GPRMC"}}));
  write_file(dir.file("gps.logw"), "");
  SessionReader reader(dir.file("gps.log"));
  EXPECT_EQ(read_all(reader).size(), 2u);
  EXPECT_FALSE(reader.damage());
}

TEST(FlexiportLog, MissingPartnerFileIsNamed) {
  TempDir dir;
  write_file(dir.file("half.logr"), encode_new({{0, 1, "x"}}));
  try {
    SessionReader reader(dir.file("half.log"));
    FAIL() << "no error";
  } catch (const SessionError& e) {
    EXPECT_NE(std::string(e.what()).find("half.logw: missing"), std::string::npos) << e.what();
  }
}

TEST(FlexiportLog, TruncatedChunkStopsWithItsOffset) {
  TempDir dir;
  std::string reads = encode_new({{0, 1, "one"}, {0, 2, "two"}, {0, 3, "three"}});
  reads.resize(reads.size() - 2);
  write_file(dir.file("cut.logr"), reads);
  write_file(dir.file("cut.logw"), "");
  SessionReader reader(dir.file("cut.log"));
  const auto records = read_all(reader);
  ASSERT_EQ(records.size(), 2u);
  ASSERT_TRUE(reader.damage());
  EXPECT_EQ(reader.damage()->offset(), 30u);
  EXPECT_NE(std::string(reader.damage()->what()).find("cut.logr"), std::string::npos);
}

TEST(FlexiportLog, AbsurdLengthIsDamageNotAnAllocation) {
  TempDir dir;
  std::string reads = encode_new({{0, 1, "one"}, {0, 2, "two"}});
  detail::put_u32be(&reads[15 + 8], 0xFFFFFFF0u);
  write_file(dir.file("bad.logr"), reads);
  write_file(dir.file("bad.logw"), "");
  SessionReader reader(dir.file("bad.log"));
  EXPECT_EQ(read_all(reader).size(), 1u);
  ASSERT_TRUE(reader.damage());
  EXPECT_EQ(reader.damage()->offset(), 15u);
}

TEST(FlexiportLog, ExportDropsEventsAndKeepsMicroseconds) {
  TempDir dir;
  {
    SessionWriter writer(dir.file("s.wtape"), {});
    writer.write(RecordKind::open, 0, "{}");
    writer.write(RecordKind::tx, 1'500'000'123ull, "VV\n");
    writer.write(RecordKind::rx, 2'000'999'999ull, "VV\n00P\n");
    writer.write(RecordKind::close, 3'000'000'000ull, "{}");
  }
  export_flexiport(dir.file("s.wtape"), dir.file("e.log"));
  const auto writes = decode_new(read_file(dir.file("e.logw")));
  const auto reads = decode_new(read_file(dir.file("e.logr")));
  ASSERT_EQ(writes.size(), 1u);
  ASSERT_EQ(reads.size(), 1u);
  EXPECT_EQ(writes[0].sec, 1u);
  EXPECT_EQ(writes[0].usec, 500'000u);
  EXPECT_EQ(reads[0].sec, 2u);
  EXPECT_EQ(reads[0].usec, 999u);
  EXPECT_EQ(reads[0].data, "VV\n00P\n");
}
