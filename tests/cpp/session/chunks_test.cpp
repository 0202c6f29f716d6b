// Compressed sessions (format 2.0, compress=zstd): records in zstd chunks
// read back as written, a flush of the file makes what was written
// readable, damage inside a chunk is reported at its offset with the
// records before it kept, and a chunk that decodes past 4 MiB is refused.
// A file of several channels ends with an index of its chunks; a file still
// being written ends in an unfinished chunk, which is not damage.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <unistd.h>
#include <zstd.h>

#include <algorithm>
#include <fstream>
#include <optional>
#include <string>
#include <vector>

#include "posix/syscalls.hpp"
#include "session/chunks.hpp"
#include "session/format.hpp"
#include "session/reader.hpp"
#include "session/session_index.hpp"
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

// A flush sends a chunk's entries ahead in a part; a record too large for a
// chunk then ends the chunk with a last part that holds no entry. The next
// chunk's times still count from 0 (a recorder flushing by time under load
// writes exactly this).
TEST(Chunks, AChunkAfterOneWhoseLastPartIsEmptyReadsItsOwnTimes) {
  TempDir dir;
  const std::string path = dir.file("parts.wtape");
  std::vector<Record> written;
  {
    SessionWriter writer(path, SessionHeader{}, zstd_policy);
    const std::string big(3u << 20, 'x');
    const auto write = [&](std::uint64_t t_ns, const std::string& data) {
      writer.write(RecordKind::rx, t_ns, data);
      written.push_back(Record{t_ns, RecordKind::rx, data, 0});
    };
    write(10, sentence(0));
    writer.flush();  // the chunk's only entry, in a part of its own
    write(15, big);  // ends the chunk: its last part is empty
    write(20, sentence(1));
    write(27, sentence(2));
    writer.close();
  }
  std::optional<SessionError> damage;
  expect_same(read_all(path, std::nullopt, &damage), written);
  EXPECT_FALSE(damage) << damage->what();
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

SessionHeader four_channels() {
  SessionHeader header;
  for (std::uint16_t id = 0; id < 4; ++id) {
    Channel channel;
    channel.id = id;
    channel.name = "c" + std::to_string(id);
    channel.port_type = "serial";
    channel.port_options = "type=serial,device=/dev/c" + std::to_string(id);
    header.channels.push_back(channel);
  }
  return header;
}

// Bytes that zstd barely shrinks, so that a few MiB of records make
// several chunks.
std::string noise(std::uint32_t& state, std::size_t size) {
  std::string bytes(size, '\0');
  for (char& byte : bytes) {
    state = state * 1664525u + 1013904223u;
    byte = static_cast<char>(state >> 24);
  }
  return bytes;
}

// Four channels, compressed: channel 0 busy for the first half of the file,
// channel 3 for the second, 1 and 2 a sentence now and then throughout (so
// that every chunk holds them).
std::vector<Record> write_phased_channels(const std::string& path) {
  std::vector<Record> records;
  SessionWriter writer(path, four_channels(), zstd_policy);
  std::uint32_t state = 1;
  std::uint64_t t_ns = 0;
  const auto write = [&](std::uint16_t channel, std::string data) {
    records.push_back(Record{t_ns, RecordKind::rx, std::move(data), channel});
    writer.write(records.back());
    t_ns += 1000;
  };
  for (int n = 0; n < 1600; ++n) {
    write(n < 800 ? 0 : 3, noise(state, 4096));
    if (n % 16 == 0) write(static_cast<std::uint16_t>(1 + n % 2), sentence(n));
  }
  writer.close();
  return records;
}

std::vector<Record> of_channel(const std::vector<Record>& records, std::uint16_t channel) {
  std::vector<Record> kept;
  for (const Record& record : records) {
    if (record.channel == channel) kept.push_back(record);
  }
  return kept;
}

std::optional<detail::IndexFound> index_of(const std::string& path, std::string* why = nullptr,
                                           std::size_t channels = 4) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  auto found = detail::find_session_index(fd, file_bytes(path).size(),
                                          detail::file_header_fixed_size, channels, why);
  ::close(fd);
  return found;
}

// What `wiretape verify` says of the file's index.
detail::IndexStatus verify_index(const std::string& path) {
  SessionHeader header;
  detail::IndexCheck check;
  auto source = detail::open_session_source(path, header, detail::Streams::refused,
                                            std::nullopt, {}, check.sink());
  Record record;
  while (source->next(record)) {
  }
  return check.status(path, header.channels.size(), source->damage().has_value());
}

// The bytes a reader of `channel` reads through the system-call seam.
std::uint64_t bytes_read(const std::string& path, std::uint16_t channel,
                         std::vector<Record>& records) {
  std::uint64_t total = 0;
  detail::sys::ScopedOverride seam;
  seam->pread = [&total](int fd, void* buffer, size_t size, off_t offset) {
    const ssize_t n = detail::sys::real().pread(fd, buffer, size, offset);
    if (n > 0) total += static_cast<std::uint64_t>(n);
    return n;
  };
  seam->read = [&total](int fd, void* buffer, size_t size) {
    const ssize_t n = detail::sys::real().read(fd, buffer, size);
    if (n > 0) total += static_cast<std::uint64_t>(n);
    return n;
  };
  records = read_all(path, channel);
  return total;
}

TEST(CompressedIndex, AFileOfSeveralChannelsEndsWithAnIndexOfItsChunks) {
  TempDir dir;
  const std::string path = dir.file("four.wtape");
  const std::vector<Record> written = write_phased_channels(path);
  const std::string bytes = file_bytes(path);
  ASSERT_GT(chunk_offsets(bytes).size(), 4u);
  const auto found = index_of(path);
  ASSERT_TRUE(found);
  EXPECT_EQ(static_cast<std::uint8_t>(bytes[found->offset + 4]), detail::index_record_code);
  EXPECT_EQ(verify_index(path).state, detail::IndexState::current);
  // Each span begins at a chunk's first part and ends past a chunk's last.
  const std::vector<std::uint64_t> chunks = chunk_offsets(bytes);
  for (std::uint16_t channel = 0; channel < 4; ++channel) {
    detail::ChannelSpans spans = detail::channel_spans(*found, channel);
    EXPECT_EQ(spans.records(), of_channel(written, channel).size()) << channel;
    detail::IndexSpan span;
    while (spans.next(span)) {
      EXPECT_NE(std::find(chunks.begin(), chunks.end(), span.begin), chunks.end())
          << "channel " << channel << "'s span at " << span.begin;
      const bool ends_before_a_record = span.end == found->offset ||
                                        std::find(chunks.begin(), chunks.end(), span.end) !=
                                            chunks.end();
      EXPECT_TRUE(ends_before_a_record) << "channel " << channel << "'s span ending at "
                                        << span.end;
    }
  }
  expect_same(read_all(path, std::nullopt), written);
  for (std::uint16_t channel = 0; channel < 4; ++channel) {
    SCOPED_TRACE(channel);
    std::vector<Record> got;
    const std::uint64_t read = bytes_read(path, channel, got);
    expect_same(got, of_channel(written, channel));
    // Channels 0 and 3 live in half the chunks each: their reader skips the rest.
    if (channel == 0 || channel == 3) EXPECT_LT(read, bytes.size() * 2 / 3) << read;
  }
}

TEST(CompressedIndex, VerifyRepairAppendsTheIndexTheWriterWrites) {
  TempDir dir;
  const std::string path = dir.file("four.wtape");
  const std::vector<Record> written = write_phased_channels(path);
  const std::string whole = file_bytes(path);
  const auto found = index_of(path);
  ASSERT_TRUE(found);
  write_bytes(path, whole.substr(0, found->offset));
  EXPECT_EQ(verify_index(path).state, detail::IndexState::absent);
  expect_same(read_all(path, 3), of_channel(written, 3));  // by a scan
  const detail::IndexStatus repaired = detail::repair_session_index(path);
  EXPECT_EQ(repaired.state, detail::IndexState::current) << repaired.detail;
  EXPECT_EQ(file_bytes(path), whole) << "the index verify appends is the writer's";
  EXPECT_EQ(verify_index(path).state, detail::IndexState::current);
}

TEST(CompressedIndex, ADamagedIndexIsReportedWithItsOffsetAndTheFileIsScanned) {
  TempDir dir;
  const std::string path = dir.file("four.wtape");
  const std::vector<Record> written = write_phased_channels(path);
  std::string bytes = file_bytes(path);
  const auto found = index_of(path);
  ASSERT_TRUE(found);
  bytes[found->offset + detail::record_header_size + 30] ^= 0x04;
  write_bytes(path, bytes);
  std::string why;
  EXPECT_FALSE(index_of(path, &why));
  EXPECT_NE(why.find("at byte " + std::to_string(found->offset)), std::string::npos) << why;
  // Every record is read by a scan, which reaches the index last and
  // reports it, at its offset, as the damage it is.
  for (const std::optional<std::uint16_t> channel :
       {std::optional<std::uint16_t>{}, std::optional<std::uint16_t>{0},
        std::optional<std::uint16_t>{3}}) {
    std::optional<SessionError> damage;
    expect_same(read_all(path, channel, &damage),
                channel ? of_channel(written, *channel) : written);
    ASSERT_TRUE(damage);
    EXPECT_EQ(damage->offset(), found->offset) << damage->what();
  }
  EXPECT_EQ(verify_index(path).state, detail::IndexState::unchecked);
  EXPECT_THROW(detail::repair_session_index(path), SessionError);
}

TEST(CompressedIndex, ARecordWrittenBetweenChunksIsASpanOfItsOwn) {
  TempDir dir;
  const std::string path = dir.file("big.wtape");
  std::vector<Record> written;
  {
    SessionWriter writer(path, two_channels(), zstd_policy);
    const std::string big(3u << 19, 'x');  // over the 512 KiB a chunk takes
    for (int n = 0; n < 4; ++n) {
      written.push_back(Record{static_cast<std::uint64_t>(10 * n), RecordKind::rx, sentence(n), 0});
      written.push_back(Record{static_cast<std::uint64_t>(10 * n + 5), RecordKind::rx, big, 1});
      writer.write(written[written.size() - 2]);
      writer.write(written.back());
    }
    writer.close();
  }
  EXPECT_EQ(verify_index(path).state, detail::IndexState::current);
  for (std::uint16_t channel = 0; channel < 2; ++channel) {
    std::optional<SessionError> damage;
    expect_same(read_all(path, channel, &damage), of_channel(written, channel));
    EXPECT_FALSE(damage) << damage->what();
  }
  const std::string whole = file_bytes(path);
  const auto found = index_of(path, nullptr, 2);
  ASSERT_TRUE(found);
  write_bytes(path, whole.substr(0, found->offset));
  EXPECT_EQ(detail::repair_session_index(path).state, detail::IndexState::current);
  EXPECT_EQ(file_bytes(path), whole);
}

// Records of a channel the header does not list (65535, the largest id)
// are in chunks like the others, and not in the index, which lists the
// header's channels.
TEST(CompressedIndex, AnUnlistedChannelInAChunkIsLeftOutOfTheIndex) {
  TempDir dir;
  const std::string path = dir.file("stray.wtape");
  std::vector<Record> listed;
  {
    SessionWriter writer(path, two_channels(), zstd_policy);
    for (int n = 0; n < 10; ++n) {
      listed.push_back(Record{static_cast<std::uint64_t>(n), RecordKind::rx, sentence(n),
                              static_cast<std::uint16_t>(n % 2)});
      writer.write(listed.back());
      writer.write(RecordKind::rx, static_cast<std::uint64_t>(n), "stray", 0xFFFF);
    }
    writer.close();
  }
  EXPECT_EQ(verify_index(path).state, detail::IndexState::current);
  expect_same(read_all(path, std::nullopt), listed);
  expect_same(read_all(path, 1), of_channel(listed, 1));
}

// A reader of a file its writer still holds (a recorder running): the end
// is where the writer is, a warning, not damage.
TEST(Unfinished, AFileStillBeingWrittenEndsInAnUnfinishedChunkNotInDamage) {
  TempDir dir;
  const std::string path = dir.file("live.wtape");
  SessionWriter writer(path, two_channels(), zstd_policy);
  std::vector<Record> written;
  for (int n = 0; n < 30; ++n) {
    written.push_back(Record{static_cast<std::uint64_t>(n), RecordKind::rx, sentence(n), 0});
    writer.write(written.back());
    if (n % 10 == 9) writer.flush();
  }
  const std::vector<std::uint64_t> chunks = chunk_offsets(file_bytes(path));
  ASSERT_FALSE(chunks.empty());
  SessionReader reader(path);
  std::vector<Record> got;
  Record record;
  while (reader.next(record)) got.push_back(record);
  expect_same(got, written);
  EXPECT_FALSE(reader.damage()) << reader.damage()->what();
  ASSERT_TRUE(reader.unfinished());
  EXPECT_EQ(reader.unfinished()->offset(), chunks.front());
  const std::string what = reader.unfinished()->what();
  EXPECT_NE(what.find("still being written"), std::string::npos) << what;
  EXPECT_NE(what.find("unfinished chunk at byte " + std::to_string(chunks.front())),
            std::string::npos)
      << what;
  EXPECT_THROW(detail::repair_session_index(path), SessionError)
      << "no index is appended to a file its writer still writes";
  writer.close();
  // Closed: the last part and the index came, the same reader reads it all.
  reader.rewind();
  SessionReader closed(path);
  got.clear();
  while (closed.next(record)) got.push_back(record);
  expect_same(got, written);
  EXPECT_FALSE(closed.damage());
  EXPECT_FALSE(closed.unfinished());
}

TEST(Unfinished, ARecordCutByTheEndOfAFileStillBeingWrittenIsUnfinished) {
  TempDir dir;
  const std::string path = dir.file("live.wtape");
  SessionWriter writer(path, SessionHeader{}, FlushPolicy{});
  writer.write(RecordKind::rx, 1, "whole");
  writer.flush();
  const std::uint64_t end = file_bytes(path).size();
  {
    // Half a record header, as a reader sees a write in flight.
    std::ofstream(path, std::ios::binary | std::ios::app) << std::string(7, '\x01');
  }
  SessionReader reader(path);
  Record record;
  ASSERT_TRUE(reader.next(record));
  EXPECT_EQ(record.data, "whole");
  EXPECT_FALSE(reader.next(record));
  EXPECT_FALSE(reader.damage()) << reader.damage()->what();
  ASSERT_TRUE(reader.unfinished());
  EXPECT_EQ(reader.unfinished()->offset(), end);
  EXPECT_NE(std::string(reader.unfinished()->what()).find("unfinished record"),
            std::string::npos);
}

TEST(Unfinished, DamageInTheMiddleOfAFileStillBeingWrittenIsDamage) {
  TempDir dir;
  const std::string path = dir.file("live.wtape");
  SessionWriter writer(path, two_channels(), zstd_policy);
  for (int n = 0; n < 30; ++n) {
    writer.write(RecordKind::rx, static_cast<std::uint64_t>(n), sentence(n), 0);
    if (n % 10 == 9) writer.flush();
  }
  const std::vector<std::uint64_t> chunks = chunk_offsets(file_bytes(path));
  ASSERT_EQ(chunks.size(), 3u);
  {
    // A bit flipped in the second part (by another descriptor: the
    // writer's keeps its place).
    const int fd = ::open(path.c_str(), O_RDWR | O_CLOEXEC);
    char byte = 0;
    ASSERT_EQ(::pread(fd, &byte, 1, static_cast<off_t>(chunks[1] + 20)), 1);
    byte ^= 0x08;
    ASSERT_EQ(::pwrite(fd, &byte, 1, static_cast<off_t>(chunks[1] + 20)), 1);
    ::close(fd);
  }
  std::optional<SessionError> damage;
  SessionReader reader(path);
  Record record;
  std::size_t count = 0;
  while (reader.next(record)) ++count;
  EXPECT_EQ(count, 10u) << "the records of the first part";
  ASSERT_TRUE(reader.damage());
  EXPECT_EQ(reader.damage()->offset(), chunks[1]);
  EXPECT_FALSE(reader.unfinished());
  writer.close();
}

// Golden files of format 2.0 (tests/data/golden/v2_0*.wtape, made by
// `convert --compress zstd` of all_kinds and v1_2_channels; v2_0_channels
// before compressed files had an index, v2_0_index with it): read, never
// re-created byte for byte (zstd's output may change with its version).
TEST(Chunks, TheCompressedGoldenFilesReadAsTheFilesTheyWereMadeFrom) {
  const std::string golden = std::string(WIRETAPE_TEST_DATA_DIR) + "/golden/";
  for (const auto& [packed, plain] :
       {std::pair<std::string, std::string>{"v2_0", "all_kinds"},
        {"v2_0_channels", "v1_2_channels"},
        {"v2_0_index", "v1_2_channels"}}) {
    SCOPED_TRACE(packed);
    EXPECT_EQ(SessionReader(golden + packed + ".wtape").header().version_major, 2);
    std::optional<SessionError> damage;
    expect_same(read_all(golden + packed + ".wtape", std::nullopt, &damage),
                read_all(golden + plain + ".wtape", std::nullopt));
    EXPECT_FALSE(damage);
  }
  expect_same(read_all(golden + "v2_0_channels.wtape", 1),
              read_all(golden + "v1_2_channels.wtape", 1));
  // v2_0_index ends with its index (its one chunk holds both channels),
  // read through it by a reader of one channel.
  std::string why;
  const int fd = ::open((golden + "v2_0_index.wtape").c_str(), O_RDONLY | O_CLOEXEC);
  const auto spans = detail::find_channel_spans(
      fd, file_bytes(golden + "v2_0_index.wtape").size(), detail::file_header_fixed_size, 2, 1,
      &why);
  ::close(fd);
  ASSERT_TRUE(spans) << why;
  EXPECT_EQ(spans->records(), 4u);
  EXPECT_EQ(verify_index(golden + "v2_0_index.wtape").state, detail::IndexState::current);
  EXPECT_EQ(verify_index(golden + "v2_0_channels.wtape").state, detail::IndexState::absent);
  for (std::uint16_t channel = 0; channel < 2; ++channel) {
    expect_same(read_all(golden + "v2_0_index.wtape", channel),
                read_all(golden + "v1_2_channels.wtape", channel));
  }
}

}  // namespace
