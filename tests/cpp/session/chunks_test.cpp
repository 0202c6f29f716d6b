// Compressed sessions (format 2.0, compress=zstd): records in zstd chunks
// read back as written, a flush of the file makes what was written
// readable, damage inside a chunk is reported at its offset with the
// records before it kept, and a chunk that decodes past 4 MiB is refused.
#include <gtest/gtest.h>
#include <zstd.h>

#include <fstream>
#include <optional>
#include <string>
#include <vector>

#include "session/chunks.hpp"
#include "session/format.hpp"
#include "support/port_test_support.hpp"
#include "wiretape/session.hpp"

using namespace wiretape;
using wiretape::test::TempDir;

namespace {

const FlushPolicy zstd_policy{std::chrono::milliseconds(100), false, Compression::zstd};

SessionHeader two_channels() {
  SessionHeader header;
  for (std::uint16_t id = 0; id < 2; ++id) {
    Channel channel;
    channel.id = id;
    channel.name = id == 0 ? "gps" : "imu";
    channel.port_type = "serial";
    channel.port_options = "type=serial,device=/dev/tty" + std::to_string(id);
    header.channels.push_back(channel);
  }
  return header;
}

// An NMEA sentence a GPS sends at 5 Hz: mostly the same bytes.
std::string sentence(int n) {
  return "$GPGGA,12" + std::to_string(100000 + n) + ".00,4807.038,N,01131.000,E,1,08,0.9,545.4,"
         "M,46.9,M,,*" + std::to_string(n % 97) + "\r\n";
}

std::vector<Record> write_records(const std::string& path, int count, FlushPolicy policy) {
  std::vector<Record> records;
  SessionWriter writer(path, two_channels(), policy);
  for (int n = 0; n < count; ++n) {
    Record record;
    record.kind = n % 3 == 0 ? RecordKind::tx : RecordKind::rx;
    record.channel = static_cast<std::uint16_t>(n % 2);
    // Slightly out of order across directions, as a client capture can be.
    record.t_ns = 1'000'000ull * static_cast<std::uint64_t>(n) + (n % 3 == 0 ? 0 : 700);
    record.data = sentence(n);
    writer.write(record);
    records.push_back(record);
  }
  writer.close();
  return records;
}

std::vector<Record> read_all(const std::string& path, std::optional<std::uint16_t> channel,
                             std::optional<SessionError>* damage = nullptr) {
  SessionReader reader(path, channel);
  std::vector<Record> records;
  Record record;
  while (reader.next(record)) records.push_back(record);
  if (damage) *damage = reader.damage();
  return records;
}

void expect_same(const std::vector<Record>& got, const std::vector<Record>& want) {
  ASSERT_EQ(got.size(), want.size());
  for (std::size_t i = 0; i < got.size(); ++i) {
    EXPECT_EQ(got[i].t_ns, want[i].t_ns) << i;
    EXPECT_EQ(got[i].kind, want[i].kind) << i;
    EXPECT_EQ(got[i].channel, want[i].channel) << i;
    EXPECT_EQ(got[i].data, want[i].data) << i;
  }
}

std::string file_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

void write_bytes(const std::string& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes;
}

// The offset of each chunk record in a compressed file.
std::vector<std::uint64_t> chunk_offsets(const std::string& bytes) {
  std::vector<std::uint64_t> offsets;
  std::size_t at = detail::file_header_fixed_size + detail::get_u32le(bytes.data() + 12) +
                   detail::crc_size;
  while (at + detail::record_header_size <= bytes.size()) {
    if (static_cast<std::uint8_t>(bytes[at + 4]) == detail::chunk_record_code) {
      offsets.push_back(at);
    }
    at += detail::record_header_size + detail::get_u32le(bytes.data() + at) + detail::crc_size;
  }
  return offsets;
}

TEST(Chunks, ACompressedSessionReadsBackAsWrittenAndIsFormat2) {
  TempDir dir;
  const std::string path = dir.file("gps.wtape");
  const std::vector<Record> written = write_records(path, 20000, zstd_policy);
  SessionReader reader(path);
  EXPECT_EQ(reader.header().version_major, 2);
  EXPECT_EQ(reader.header().version_minor, 0);
  expect_same(read_all(path, std::nullopt), written);
  std::vector<Record> imu;
  for (const Record& record : written) {
    if (record.channel == 1) imu.push_back(record);
  }
  expect_same(read_all(path, 1), imu);
  const std::string plain = dir.file("plain.wtape");
  write_records(plain, 20000, FlushPolicy{});
  EXPECT_LT(file_bytes(path).size() * 4, file_bytes(plain).size())
      << "NMEA compresses to well under a quarter";
  EXPECT_GT(chunk_offsets(file_bytes(path)).size(), 1u);
}

TEST(Chunks, ARecordTooLargeForAChunkIsWrittenBetweenChunks) {
  TempDir dir;
  const std::string path = dir.file("big.wtape");
  std::vector<Record> written;
  {
    SessionWriter writer(path, SessionHeader{}, zstd_policy);
    const std::string big(3u << 20, 'x');
    for (int n = 0; n < 3; ++n) {
      writer.write(RecordKind::rx, 10 * n, sentence(n));
      writer.write(RecordKind::rx, 10 * n + 5, big);
      written.push_back(Record{static_cast<std::uint64_t>(10 * n), RecordKind::rx, sentence(n), 0});
      written.push_back(Record{static_cast<std::uint64_t>(10 * n + 5), RecordKind::rx, big, 0});
    }
    writer.close();
  }
  std::optional<SessionError> damage;
  expect_same(read_all(path, std::nullopt, &damage), written);
  EXPECT_FALSE(damage) << damage->what();
}

TEST(Chunks, AFlushMakesWhatWasWrittenReadableInsideAnOpenChunk) {
  TempDir dir;
  const std::string path = dir.file("live.wtape");
  SessionWriter writer(path, two_channels(), zstd_policy);
  std::vector<Record> written;
  for (int n = 0; n < 50; ++n) {
    writer.write(RecordKind::rx, static_cast<std::uint64_t>(n), sentence(n), 0);
    written.push_back(Record{static_cast<std::uint64_t>(n), RecordKind::rx, sentence(n), 0});
    if (n % 10 == 9) writer.flush();  // each a part of the one open chunk
  }
  // As a recorder killed now leaves it.
  const std::string copy = dir.file("killed.wtape");
  write_bytes(copy, file_bytes(path));
  std::optional<SessionError> damage;
  expect_same(read_all(copy, std::nullopt, &damage), written);
  ASSERT_TRUE(damage);
  EXPECT_NE(std::string(damage->what()).find("has no last part"), std::string::npos)
      << damage->what();
  EXPECT_EQ(chunk_offsets(file_bytes(copy)).size(), 5u) << "a part per flush";
  writer.close();
}

TEST(Chunks, DamageInAChunkIsReportedAtItsOffsetKeepingTheChunksBefore) {
  TempDir dir;
  const std::string path = dir.file("damaged.wtape");
  const std::vector<Record> written = write_records(path, 40000, zstd_policy);
  std::string bytes = file_bytes(path);
  const std::vector<std::uint64_t> chunks = chunk_offsets(bytes);
  ASSERT_GE(chunks.size(), 2u);
  const std::uint64_t second = chunks[1];
  bytes[second + detail::record_header_size + 40] ^= 0x10;
  write_bytes(path, bytes);
  std::optional<SessionError> damage;
  const std::vector<Record> got = read_all(path, std::nullopt, &damage);
  ASSERT_TRUE(damage);
  EXPECT_EQ(damage->offset(), second);
  ASSERT_GT(got.size(), 0u);
  ASSERT_LT(got.size(), written.size());
  expect_same(got, std::vector<Record>(written.begin(), written.begin() + got.size()));
}

TEST(Chunks, AChunkThatDecodesPastTheCapIsRefused) {
  TempDir dir;
  const std::string path = dir.file("bomb.wtape");
  {
    SessionWriter writer(path, SessionHeader{}, zstd_policy);
    writer.write(RecordKind::rx, 1, "before");
    writer.close();
  }
  // A last part whose frame decodes to 5 MiB of zeros.
  const std::string zeros(5u << 20, '\0');
  std::string frame(ZSTD_compressBound(zeros.size()), '\0');
  frame.resize(ZSTD_compress(&frame[0], frame.size(), zeros.data(), zeros.size(), 3));
  frame.append(detail::chunk_trailer_size, '\0');
  std::string record(detail::record_header_size, '\0');
  detail::put_u32le(&record[0], static_cast<std::uint32_t>(frame.size()));
  record[4] = static_cast<char>(detail::chunk_record_code);
  record[5] = static_cast<char>(detail::chunk_last_part);
  record += frame;
  char crc[detail::crc_size];
  detail::put_u32le(crc, crc32c(record.data(), record.size()));
  record.append(crc, sizeof crc);
  const std::string bytes = file_bytes(path);
  write_bytes(path, bytes + record);
  std::optional<SessionError> damage;
  const std::vector<Record> got = read_all(path, std::nullopt, &damage);
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].data, "before");
  ASSERT_TRUE(damage);
  EXPECT_EQ(damage->offset(), bytes.size());
  EXPECT_NE(std::string(damage->what()).find("4 MiB"), std::string::npos) << damage->what();
}

// Golden files of format 2.0 (tests/data/golden/v2_0*.wtape, made by
// `convert --compress zstd` of all_kinds and v1_2_channels): read, never
// re-created byte for byte (zstd's output may change with its version).
TEST(Chunks, TheCompressedGoldenFilesReadAsTheFilesTheyWereMadeFrom) {
  const std::string golden = std::string(WIRETAPE_TEST_DATA_DIR) + "/golden/";
  for (const auto& [packed, plain] :
       {std::pair<std::string, std::string>{"v2_0", "all_kinds"}, {"v2_0_channels", "v1_2_channels"}}) {
    SCOPED_TRACE(packed);
    EXPECT_EQ(SessionReader(golden + packed + ".wtape").header().version_major, 2);
    std::optional<SessionError> damage;
    expect_same(read_all(golden + packed + ".wtape", std::nullopt, &damage),
                read_all(golden + plain + ".wtape", std::nullopt));
    EXPECT_FALSE(damage);
  }
  expect_same(read_all(golden + "v2_0_channels.wtape", 1),
              read_all(golden + "v1_2_channels.wtape", 1));
}

}  // namespace
