// The per-channel index (format 1.3): written at the close of a file of
// several channels, used by a reader of one channel to read only that
// channel's spans, and ignored (the reader scans every record) when it is
// missing, damaged or followed by records it does not describe.
#include <fcntl.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <cstring>
#include <fstream>
#include <optional>
#include <string>
#include <vector>

#include "posix/syscalls.hpp"
#include "session/format.hpp"
#include "session/reader.hpp"
#include "session/session_index.hpp"
#include "support/port_test_support.hpp"
#include "wiretape/session.hpp"

using namespace wiretape;
using wiretape::test::TempDir;
namespace sys = wiretape::detail::sys;

namespace {

constexpr std::uint16_t channel_count = 4;
constexpr int rounds = 256;
constexpr std::size_t payload_size = 4096;

SessionHeader four_channel_header() {
  SessionHeader header;
  for (std::uint16_t id = 0; id < channel_count; ++id) {
    Channel channel;
    channel.id = id;
    channel.name = "c" + std::to_string(id);
    channel.port_type = "serial";
    channel.port_options = "type=serial,device=/dev/c" + std::to_string(id);
    header.channels.push_back(channel);
  }
  return header;
}

// Channel `id`'s payload of round `round`: its bytes say whose they are.
std::string payload_of(std::uint16_t id, int round, std::size_t size) {
  std::string payload(size, static_cast<char>('a' + id));
  const std::string tag = std::to_string(round);
  std::memcpy(&payload[0], tag.data(), std::min(tag.size(), size));
  return payload;
}

// Four channels' records interleaved round by round, as a recorder of four
// busy ports writes them.
std::string write_four_channels(const TempDir& dir, std::size_t size = payload_size,
                                const char* name = "four.wtape", int rounds = ::rounds) {
  const std::string path = dir.file(name);
  SessionWriter writer(path, four_channel_header());
  std::uint64_t t_ns = 1000;
  for (int round = 0; round < rounds; ++round) {
    for (std::uint16_t id = 0; id < channel_count; ++id) {
      writer.write(RecordKind::rx, t_ns, payload_of(id, round, size), id);
      t_ns += 250;
    }
  }
  writer.close();
  EXPECT_EQ(writer.records_written(), static_cast<std::uint64_t>(rounds * channel_count));
  return path;
}

std::vector<Record> read_records(const std::string& path, std::optional<std::uint16_t> channel,
                                 std::optional<SessionError>* damage = nullptr) {
  SessionReader reader(path, channel);
  std::vector<Record> records;
  Record record;
  while (reader.next(record)) records.push_back(record);
  if (damage) *damage = reader.damage();
  return records;
}

void expect_channel_records(const std::vector<Record>& records, std::uint16_t id,
                            std::size_t size = payload_size) {
  ASSERT_EQ(records.size(), static_cast<std::size_t>(rounds));
  for (int round = 0; round < rounds; ++round) {
    EXPECT_EQ(records[round].channel, id);
    EXPECT_EQ(records[round].data, payload_of(id, round, size)) << "round " << round;
  }
}

// The bytes a reader of `channel` reads through the system-call seam.
std::uint64_t bytes_read_for_channel(const std::string& path, std::uint16_t channel) {
  std::uint64_t total = 0;
  sys::ScopedOverride seam;
  seam->pread = [&total](int fd, void* buffer, size_t size, off_t offset) {
    const ssize_t n = sys::real().pread(fd, buffer, size, offset);
    if (n > 0) total += static_cast<std::uint64_t>(n);
    return n;
  };
  expect_channel_records(read_records(path, channel), channel);
  return total;
}

std::uint64_t file_size(const std::string& path) {
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  return static_cast<std::uint64_t>(in.tellg());
}

std::string file_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

void write_bytes(const std::string& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes;
}

std::optional<detail::IndexFound> index_of(const std::string& path, std::string* why = nullptr) {
  const int fd = ::open(path.c_str(), O_RDONLY);
  auto found = detail::find_session_index(fd, file_size(path), detail::file_header_fixed_size,
                                          channel_count, why);
  ::close(fd);
  return found;
}

// A whole rx record of `channel`, as a writer makes it.
std::string record_bytes(std::uint16_t channel, std::uint64_t t_ns, const std::string& payload) {
  std::string record(detail::record_header_size, '\0');
  detail::put_u32le(&record[0], static_cast<std::uint32_t>(payload.size()));
  record[4] = static_cast<char>(RecordKind::rx);
  detail::put_u16le(&record[6], channel);
  detail::put_u64le(&record[8], t_ns);
  record += payload;
  char crc[detail::crc_size];
  detail::put_u32le(crc, crc32c(record.data(), record.size()));
  return record.append(crc, sizeof crc);
}

TEST(SessionIndex, WrittenAtTheCloseOfAFileOfSeveralChannels) {
  TempDir dir;
  const std::string path = write_four_channels(dir);
  std::string why;
  const auto index = index_of(path, &why);
  ASSERT_TRUE(index) << why;
  EXPECT_EQ(SessionReader(path).header().version_minor, 3);
  // Each 4 KiB record is a page apart from its channel's next: a span each.
  detail::ChannelSpans spans = detail::channel_spans(*index, 1);
  EXPECT_EQ(spans.records(), static_cast<std::uint64_t>(rounds));
  detail::IndexSpan span;
  int count = 0;
  while (spans.next(span)) ++count;
  EXPECT_EQ(count, rounds);
}

TEST(SessionIndex, AReaderReadsAChannelsSpansFromTheFileAsItGoes) {
  // Spans 4 KiB and more apart, enough of them that their encoding is
  // read in several pieces.
  TempDir dir;
  constexpr int many = 3000;
  const std::string path = write_four_channels(dir, 1400, "many.wtape", many);
  std::uint64_t read = 0;
  std::vector<Record> records;
  {
    sys::ScopedOverride seam;
    seam->pread = [&read](int fd, void* buffer, size_t size, off_t offset) {
      const ssize_t n = sys::real().pread(fd, buffer, size, offset);
      if (n > 0) read += static_cast<std::uint64_t>(n);
      return n;
    };
    records = read_records(path, 3);
  }
  EXPECT_LT(read, file_size(path) * 35 / 100) << "the index was not used";
  ASSERT_EQ(records.size(), static_cast<std::size_t>(many));
  for (int round = 0; round < many; ++round) {
    ASSERT_EQ(records[round].data, payload_of(3, round, 1400)) << round;
  }
}

TEST(SessionIndex, NeverHandedOutAsARecord) {
  TempDir dir;
  const std::string path = write_four_channels(dir);
  const std::vector<Record> all = read_records(path, std::nullopt);
  ASSERT_EQ(all.size(), static_cast<std::size_t>(rounds * channel_count));
  for (std::size_t i = 0; i < all.size(); ++i) {
    EXPECT_EQ(all[i].channel, i % channel_count);
    EXPECT_EQ(all[i].kind, RecordKind::rx);
  }
}

TEST(SessionIndex, AReaderOfOneChannelReadsOnlyItsSpans) {
  TempDir dir;
  const std::string path = write_four_channels(dir);
  const std::uint64_t read = bytes_read_for_channel(path, 2);
  // A quarter of the records, the first read's 128 KiB (the header) and the
  // index; a scan reads it all.
  EXPECT_LT(read, file_size(path) * 35 / 100) << read << " of " << file_size(path);
}

TEST(SessionIndex, SmallRecordsCloseTogetherAreOneSpan) {
  TempDir dir;
  const std::string path = write_four_channels(dir, 16, "small.wtape");
  const auto index = index_of(path);
  ASSERT_TRUE(index);
  detail::ChannelSpans spans = detail::channel_spans(*index, 3);
  detail::IndexSpan span;
  ASSERT_TRUE(spans.next(span));
  EXPECT_FALSE(spans.next(span));
  expect_channel_records(read_records(path, 3), 3, 16);
}

TEST(SessionIndex, AFileOfOneChannelHasNone) {
  TempDir dir;
  const std::string path = dir.file("one.wtape");
  {
    SessionWriter writer(path, SessionHeader{});
    writer.write(RecordKind::rx, 1, "abc");
    writer.close();
  }
  std::string why;
  EXPECT_FALSE(index_of(path, &why));
  EXPECT_EQ(why, "no index");
}

TEST(SessionIndex, MissingIndexMeansAScan) {
  TempDir dir;
  const std::string path = write_four_channels(dir);
  const auto index = index_of(path);
  ASSERT_TRUE(index);
  // As a recorder killed before its close leaves it.
  ASSERT_EQ(::truncate(path.c_str(), static_cast<off_t>(index->offset)), 0);
  EXPECT_FALSE(index_of(path));
  EXPECT_GT(bytes_read_for_channel(path, 1), file_size(path) * 9 / 10);
}

TEST(SessionIndex, ADamagedIndexMeansAScan) {
  TempDir dir;
  const std::string path = write_four_channels(dir);
  const auto index = index_of(path);
  ASSERT_TRUE(index);
  std::string bytes = file_bytes(path);
  bytes[index->offset + detail::record_header_size + 5] ^= 0x40;
  write_bytes(path, bytes);
  std::string why;
  EXPECT_FALSE(index_of(path, &why));
  EXPECT_NE(why.find("corrupt"), std::string::npos) << why;
  EXPECT_GT(bytes_read_for_channel(path, 1), file_size(path) * 9 / 10);
}

TEST(SessionIndex, RecordsAfterTheIndexAreFoundByAScan) {
  TempDir dir;
  const std::string path = write_four_channels(dir);
  const std::string extra = payload_of(1, rounds, payload_size);
  write_bytes(path, file_bytes(path) + record_bytes(1, 1'000'000, extra));
  EXPECT_FALSE(index_of(path));
  const std::vector<Record> records = read_records(path, 1);
  ASSERT_EQ(records.size(), static_cast<std::size_t>(rounds + 1));
  EXPECT_EQ(records.back().data, extra);
}

TEST(SessionIndex, DamageInsideASpanStopsThereKeepingWhatCameBefore) {
  TempDir dir;
  const std::string path = write_four_channels(dir);
  const auto index = index_of(path);
  ASSERT_TRUE(index);
  detail::ChannelSpans spans = detail::channel_spans(*index, 1);
  detail::IndexSpan span;
  for (int i = 0; i <= 10; ++i) ASSERT_TRUE(spans.next(span));
  std::string bytes = file_bytes(path);
  bytes[span.begin + detail::record_header_size + 100] ^= 0x01;  // round 10's payload
  write_bytes(path, bytes);
  std::optional<SessionError> damage;
  const std::vector<Record> records = read_records(path, 1, &damage);
  EXPECT_EQ(records.size(), 10u);
  ASSERT_TRUE(damage);
  EXPECT_EQ(damage->offset(), span.begin);
  EXPECT_NE(std::string(damage->what()).find("the 10 records before it are intact"),
            std::string::npos)
      << damage->what();
}

TEST(SessionIndex, RewindReadsTheSpansAgain) {
  TempDir dir;
  const std::string path = write_four_channels(dir);
  SessionReader reader(path, 0);
  Record record;
  int first = 0;
  while (reader.next(record)) ++first;
  reader.rewind();
  int second = 0;
  while (reader.next(record)) {
    EXPECT_EQ(record.data, payload_of(0, second, payload_size));
    ++second;
  }
  EXPECT_EQ(first, rounds);
  EXPECT_EQ(second, rounds);
}

}  // namespace

namespace {

detail::IndexStatus verify_index(const std::string& path) {
  SessionHeader header;
  detail::IndexCheck check;
  auto source = detail::open_session_source(path, header, detail::Streams::refused, std::nullopt,
                                            {}, check.sink());
  Record record;
  while (source->next(record)) {
  }
  return check.status(path, header.channels.size(), source->damage().has_value());
}

TEST(SessionIndexRepair, AClosedFileHasACurrentIndex) {
  TempDir dir;
  const std::string path = write_four_channels(dir);
  EXPECT_EQ(verify_index(path).state, detail::IndexState::current);
  const std::uint64_t size = file_size(path);
  EXPECT_EQ(detail::repair_session_index(path).state, detail::IndexState::current);
  EXPECT_EQ(file_size(path), size) << "nothing appended to a file whose index is current";
}

TEST(SessionIndexRepair, AppendsAMissingIndex) {
  TempDir dir;
  const std::string path = write_four_channels(dir);
  const auto index = index_of(path);
  ASSERT_TRUE(index);
  const std::string closed = file_bytes(path);
  ASSERT_EQ(::truncate(path.c_str(), static_cast<off_t>(index->offset)), 0);
  EXPECT_EQ(verify_index(path).state, detail::IndexState::absent);
  const detail::IndexStatus repaired = detail::repair_session_index(path);
  EXPECT_EQ(repaired.state, detail::IndexState::current);
  EXPECT_EQ(repaired.detail, "appended at byte " + std::to_string(index->offset));
  EXPECT_EQ(file_bytes(path), closed) << "the index the writer would have written";
  EXPECT_LT(bytes_read_for_channel(path, 2), file_size(path) * 35 / 100);
}

TEST(SessionIndexRepair, AppendsAnIndexOfTheRecordsAfterAStaleOne) {
  TempDir dir;
  const std::string path = write_four_channels(dir);
  const std::string extra = payload_of(1, rounds, payload_size);
  write_bytes(path, file_bytes(path) + record_bytes(1, 1'000'000, extra));
  EXPECT_EQ(verify_index(path).state, detail::IndexState::absent);
  EXPECT_EQ(detail::repair_session_index(path).state, detail::IndexState::current);
  EXPECT_EQ(verify_index(path).state, detail::IndexState::current);
  ASSERT_TRUE(index_of(path));
  const std::vector<Record> records = read_records(path, 1);
  ASSERT_EQ(records.size(), static_cast<std::size_t>(rounds + 1));
  EXPECT_EQ(records.back().data, extra);
  EXPECT_EQ(read_records(path, std::nullopt).size(),
            static_cast<std::size_t>(rounds * channel_count + 1));
}

TEST(SessionIndexRepair, AnIndexThatListsOtherSpansIsStale) {
  TempDir dir;
  const std::string a = write_four_channels(dir, payload_size, "a.wtape");
  const std::string b = write_four_channels(dir, 100, "b.wtape");
  // b's records with a's index after them: a CRC that holds, spans that lie.
  const auto index = index_of(a);
  ASSERT_TRUE(index);
  const auto b_index = index_of(b);
  ASSERT_TRUE(b_index);
  std::string bytes = file_bytes(b).substr(0, b_index->offset);
  std::string a_index = file_bytes(a).substr(index->offset);
  detail::put_u64le(&a_index[a_index.size() - detail::crc_size - detail::index_trailer_size],
                    b_index->offset);
  const std::size_t covered = a_index.size() - detail::crc_size;
  detail::put_u32le(&a_index[covered], crc32c(a_index.data(), covered));
  write_bytes(b, bytes + a_index);
  const detail::IndexStatus status = verify_index(b);
  EXPECT_EQ(status.state, detail::IndexState::stale) << status.detail;
}

TEST(SessionIndexRepair, RefusesADamagedFile) {
  TempDir dir;
  const std::string path = write_four_channels(dir);
  const auto index = index_of(path);
  ASSERT_TRUE(index);
  std::string bytes = file_bytes(path).substr(0, index->offset);
  bytes[bytes.size() - 100] ^= 0x01;
  write_bytes(path, bytes);
  EXPECT_EQ(verify_index(path).state, detail::IndexState::unchecked);
  EXPECT_THROW(detail::repair_session_index(path), SessionError);
  EXPECT_EQ(file_size(path), bytes.size());
}

TEST(SessionIndexRepair, AFileOfOneChannelNeedsNone) {
  TempDir dir;
  const std::string path = dir.file("one.wtape");
  {
    SessionWriter writer(path, SessionHeader{});
    writer.write(RecordKind::rx, 1, "abc");
    writer.close();
  }
  EXPECT_EQ(verify_index(path).state, detail::IndexState::not_needed);
  EXPECT_EQ(detail::repair_session_index(path).state, detail::IndexState::not_needed);
}

TEST(SessionIndexGolden, TheChannelsGoldenFileIsReadTheSameWithAndWithoutItsIndex) {
  const std::string golden = std::string(WIRETAPE_TEST_DATA_DIR) + "/golden/";
  const std::string indexed = golden + "v1_2_channels.wtape";  // 1.3, with its index
  const std::string older = golden + "v1_2.wtape";             // the same, as 1.2 wrote it
  const int fd = ::open(indexed.c_str(), O_RDONLY);
  std::string why;
  EXPECT_TRUE(detail::find_session_index(fd, file_size(indexed), detail::file_header_fixed_size,
                                         2, &why))
      << why;
  ::close(fd);
  for (std::uint16_t channel = 0; channel < 2; ++channel) {
    const std::vector<Record> a = read_records(indexed, channel);
    const std::vector<Record> b = read_records(older, channel);
    ASSERT_EQ(a.size(), b.size()) << channel;
    EXPECT_FALSE(a.empty());
    for (std::size_t i = 0; i < a.size(); ++i) {
      EXPECT_EQ(a[i].t_ns, b[i].t_ns);
      EXPECT_EQ(a[i].data, b[i].data);
    }
  }
}

}  // namespace
