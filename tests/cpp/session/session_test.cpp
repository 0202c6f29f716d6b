// The .wtape format: writing, reading, damage detection, flush policy,
// file-size limits and crash safety.
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/syscall.h>
#include <sys/wait.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include "support/port_test_support.hpp"

#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <memory>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "ports/ports.hpp"
#include "posix/syscalls.hpp"
#include "session/format.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/port.hpp"
#include "wiretape/session.hpp"
#include "wiretape/version.hpp"

using namespace wiretape;
using namespace std::chrono_literals;

namespace {

using wiretape::test::TempDir;

using wiretape::test::read_file;
using wiretape::test::write_file;

std::vector<Record> read_all(SessionReader& reader) {
  std::vector<Record> records;
  Record record;
  while (reader.next(record)) records.push_back(record);
  return records;
}

SessionHeader fixed_header() {
  SessionHeader header;
  header.port_options = "type=loopback,log=x.wtape";
  header.port_type = "loopback";
  header.start_utc = "2026-01-02T03:04:05.000006Z";
  header.host = "testhost";
  header.wiretape_version = "9.9.9";
  header.user_metadata = {{"driver", "hokuyo"}, {"note", "a \"quoted\" word"}};
  return header;
}

std::string write_sample(const std::string& path, int records = 3) {
  SessionWriter writer(path, fixed_header());
  for (int i = 0; i < records; ++i) {
    writer.write(i % 2 ? RecordKind::rx : RecordKind::tx, 1000u * i,
                 "record " + std::to_string(i));
  }
  writer.close();
  return read_file(path);
}

}  // namespace

TEST(Crc32c, MatchesTheStandardCheckValue) {
  EXPECT_EQ(crc32c("123456789", 9), 0xE3069283u);
  EXPECT_EQ(crc32c("", 0), 0u);
  // Continuing a CRC over pieces equals one pass over the whole.
  const std::string text = "The quick brown fox jumps over the lazy dog, twice over.";
  EXPECT_EQ(crc32c(text.data() + 10, text.size() - 10, crc32c(text.data(), 10)),
            crc32c(text.data(), text.size()));
}

// Directions carry any bytes; events a JSON object (the reader checks it).
static std::string payload_of(RecordKind kind) {
  const std::string name(to_string(kind));
  if (kind == RecordKind::rx || kind == RecordKind::tx) {
    return name + std::string(1, '\0') + "\xff";
  }
  return "{\"name\":\"" + name + "\",\"odd\":\"\\u0000\xc3\xbf\"}";
}

TEST(SessionFile, WritesAndReadsBackEveryKindAndTheHeader) {
  TempDir dir;
  const std::string path = dir.file("all.wtape");
  const std::vector<RecordKind> kinds = {
      RecordKind::open, RecordKind::tx, RecordKind::rx, RecordKind::flush_input,
      RecordKind::flush_output, RecordKind::drain, RecordKind::settings,
      RecordKind::modem_lines, RecordKind::line_break, RecordKind::client_connect,
      RecordKind::client_disconnect, RecordKind::device_lost, RecordKind::close};
  {
    SessionWriter writer(path, fixed_header());
    std::uint64_t t = 0;
    for (RecordKind kind : kinds) writer.write(kind, t += 17, payload_of(kind));
    writer.write(RecordKind::rx, t + 1, "");
  }
  SessionReader reader(path);
  const SessionHeader& header = reader.header();
  EXPECT_EQ(header.version_major, 1);
  EXPECT_EQ(header.port_options, "type=loopback,log=x.wtape");
  EXPECT_EQ(header.port_type, "loopback");
  EXPECT_EQ(header.start_utc, "2026-01-02T03:04:05.000006Z");
  EXPECT_EQ(header.host, "testhost");
  EXPECT_EQ(header.wiretape_version, "9.9.9");
  EXPECT_EQ(header.capture, Capture::client);
  EXPECT_EQ(header.source_format, "wiretape");
  EXPECT_EQ(header.user_metadata.at("note"), "a \"quoted\" word");
  EXPECT_EQ(header.user_metadata.at("driver"), "hokuyo");
  const auto records = read_all(reader);
  ASSERT_EQ(records.size(), kinds.size() + 1);
  std::uint64_t t = 0;
  for (std::size_t i = 0; i < kinds.size(); ++i) {
    EXPECT_EQ(records[i].kind, kinds[i]);
    EXPECT_EQ(records[i].t_ns, t += 17);
    EXPECT_EQ(records[i].data, payload_of(kinds[i]));
  }
  EXPECT_TRUE(records.back().data.empty());
  EXPECT_FALSE(reader.damage());
  reader.rewind();
  EXPECT_EQ(read_all(reader).size(), records.size());
}

TEST(SessionFile, AHeaderStartingNowTakesItsFieldsFromTheMachine) {
  TempDir dir;
  const std::string path = dir.file("now.wtape");
  SessionHeader header = SessionHeader::starting_now();
  header.capture = Capture::wire;
  { SessionWriter writer(path, header); }
  SessionReader reader(path);
  EXPECT_EQ(reader.header().capture, Capture::wire);
  EXPECT_EQ(reader.header().wiretape_version, wiretape::version);
  ASSERT_EQ(reader.header().start_utc.size(), 27u) << reader.header().start_utc;
  EXPECT_EQ(reader.header().start_utc.back(), 'Z');
  EXPECT_FALSE(reader.header().host.empty());
}

TEST(SessionFile, LargePayloadsRoundTrip) {
  TempDir dir;
  const std::string path = dir.file("large.wtape");
  std::string big(3 * 1024 * 1024 + 7, '\0');
  for (std::size_t i = 0; i < big.size(); ++i) big[i] = static_cast<char>(i * 31 + 7);
  {
    SessionWriter writer(path, {});
    writer.write(RecordKind::rx, 1, "small");
    writer.write(RecordKind::rx, 2, big);
    writer.write(RecordKind::tx, 3, "after");
  }
  SessionReader reader(path);
  const auto records = read_all(reader);
  ASSERT_EQ(records.size(), 3u);
  EXPECT_EQ(records[1].data, big);
  EXPECT_EQ(records[2].data, "after");
}

// write_filled: the bytes are put in the buffer by the caller's fill, and
// are the record, in order with write()'s; none filled is no record, and a
// fill that throws leaves nothing behind. The bytes it hands back are the
// record's until the next write, across a flush of the writer's own.
TEST(SessionFile, FilledRecordsAreTheBytesTheFillPutInPlace) {
  TempDir dir;
  const std::string path = dir.file("filled.wtape");
  struct Source {
    std::string next;
    bool fail = false;
    std::uint64_t t_ns = 10;
  };
  const SessionWriter::Fill fill = [](void* context, char* room, std::size_t size) {
    auto& source = *static_cast<Source*>(context);
    if (source.fail) throw PortClosed("the device went away");
    const std::size_t n = std::min(size, source.next.size());
    std::memcpy(room, source.next.data(), n);
    return SessionWriter::Filled{n, ++source.t_ns};
  };
  std::string big(1536 * 1024, '\0');
  for (std::size_t i = 0; i < big.size(); ++i) big[i] = static_cast<char>(i * 13 + 1);
  {
    // Flushes only when the buffer passes its bound: big's record is
    // flushed by its own write.
    SessionWriter writer(path, {}, FlushPolicy{std::chrono::milliseconds(60'000)});
    writer.write(RecordKind::tx, 1, "before");
    Source source{"filled in place"};
    std::string_view bytes;
    writer.write_filled(RecordKind::rx, 64, fill, &source, &bytes);
    EXPECT_EQ(bytes, "filled in place");
    source.next.clear();
    writer.write_filled(RecordKind::rx, 64, fill, &source, &bytes);
    EXPECT_TRUE(bytes.empty());
    source.fail = true;
    EXPECT_THROW(writer.write_filled(RecordKind::rx, 64, fill, &source, &bytes), PortClosed);
    source.fail = false;
    source.next = big;
    writer.write_filled(RecordKind::rx, big.size(), fill, &source, &bytes);
    EXPECT_EQ(bytes.size(), big.size());
    EXPECT_TRUE(bytes == big);
    source.next = "cut to its room";
    writer.write_filled(RecordKind::rx, 6, fill, &source, &bytes);
    EXPECT_EQ(bytes, "cut to");
    writer.write(RecordKind::tx, 2, "after");
  }
  SessionReader reader(path);
  const auto records = read_all(reader);
  ASSERT_EQ(records.size(), 5u);
  EXPECT_EQ(records[0].data, "before");
  EXPECT_EQ(records[1].kind, RecordKind::rx);
  EXPECT_EQ(records[1].t_ns, 11u);
  EXPECT_EQ(records[1].data, "filled in place");
  EXPECT_TRUE(records[2].data == big);
  EXPECT_EQ(records[3].data, "cut to");
  EXPECT_EQ(records[4].data, "after");
  EXPECT_FALSE(reader.damage());
}

TEST(SessionFile, MissingEmptyAndForeignFilesAreClearErrors) {
  TempDir dir;
  auto expect_error = [](const std::string& path, const std::string& words,
                         std::uint64_t offset) {
    try {
      SessionReader reader(path);
      ADD_FAILURE() << "no error for " << path;
    } catch (const SessionError& e) {
      EXPECT_NE(std::string(e.what()).find(words), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
      EXPECT_EQ(e.offset(), offset) << e.what();
    }
  };
  // A file that cannot be opened is an I/O error, not a damaged session.
  EXPECT_THROW(SessionReader(dir.file("missing.wtape")), PortError);
  write_file(dir.file("empty.wtape"), "");
  expect_error(dir.file("empty.wtape"), "empty file", 0);
  write_file(dir.file("text.wtape"), "hello, I am a text file and no session\n");
  expect_error(dir.file("text.wtape"), "wrong magic", 0);

  const std::string good = write_sample(dir.file("good.wtape"));
  write_file(dir.file("short.wtape"), good.substr(0, 11));
  expect_error(dir.file("short.wtape"), "truncated header", 11);
  write_file(dir.file("cut-header.wtape"), good.substr(0, 40));
  expect_error(dir.file("cut-header.wtape"), "truncated or corrupt header", 12);

  std::string future = good;
  detail::put_u16le(&future[8], 3);  // 2.0 is compressed chunks: read
  write_file(dir.file("future.wtape"), future);
  expect_error(dir.file("future.wtape"), "newer than this reader", 8);

  std::string absurd = good;
  detail::put_u32le(&absurd[12], 0xFFFFFFF0u);
  write_file(dir.file("absurd-header.wtape"), absurd);
  expect_error(dir.file("absurd-header.wtape"), "claims 4294967280 bytes", 12);
}

TEST(SessionFile, NewerMinorVersionIsRead) {
  TempDir dir;
  std::string bytes = write_sample(dir.file("a.wtape"));
  // Re-seal the header with minor version 7.
  const std::uint32_t json_length = detail::get_u32le(&bytes[12]);
  detail::put_u16le(&bytes[10], 7);
  const std::size_t header_end = 16 + json_length;
  detail::put_u32le(&bytes[header_end], crc32c(bytes.data(), header_end));
  write_file(dir.file("minor.wtape"), bytes);
  SessionReader reader(dir.file("minor.wtape"));
  EXPECT_EQ(reader.header().version_minor, 7);
  EXPECT_EQ(read_all(reader).size(), 3u);
}

TEST(SessionFile, EveryBitFlipIsDetectedAndEverythingBeforeItKept) {
  TempDir dir;
  const std::string good = write_sample(dir.file("good.wtape"), 4);
  SessionReader clean(dir.file("good.wtape"));
  const std::size_t header_end = 16 + detail::get_u32le(&good[12]) + 4;
  // Record boundaries, to know which record a flipped byte belongs to.
  std::vector<std::size_t> starts;
  for (std::size_t at = header_end; at < good.size();
       at += 16 + detail::get_u32le(&good[at]) + 4) {
    starts.push_back(at);
  }
  ASSERT_EQ(starts.size(), 4u);
  const std::string path = dir.file("flipped.wtape");
  for (std::size_t byte = 0; byte < good.size(); ++byte) {
    for (int bit : {0, 5}) {
      std::string bad = good;
      bad[byte] = static_cast<char>(bad[byte] ^ (1 << bit));
      write_file(path, bad);
      if (byte < header_end) {
        EXPECT_THROW(SessionReader{path}, SessionError) << "byte " << byte;
        continue;
      }
      SessionReader reader(path);
      const auto records = read_all(reader);
      std::size_t damaged = 0;
      while (damaged + 1 < starts.size() && starts[damaged + 1] <= byte) ++damaged;
      ASSERT_TRUE(reader.damage()) << "byte " << byte;
      EXPECT_EQ(reader.damage()->offset(), starts[damaged]) << "byte " << byte;
      EXPECT_EQ(records.size(), damaged) << "byte " << byte;
    }
  }
}

TEST(SessionFile, TruncationAtEveryByteKeepsTheWholeRecordsBefore) {
  TempDir dir;
  const std::string good = write_sample(dir.file("good.wtape"), 3);
  const std::size_t header_end = 16 + detail::get_u32le(&good[12]) + 4;
  const std::string path = dir.file("cut.wtape");
  for (std::size_t size = header_end; size < good.size(); ++size) {
    write_file(path, good.substr(0, size));
    SessionReader reader(path);
    const auto records = read_all(reader);
    std::size_t whole = 0;
    std::size_t at = header_end;
    while (at + 16 <= size) {
      const std::size_t end = at + 16 + detail::get_u32le(&good[at]) + 4;
      if (end > size) break;
      ++whole;
      at = end;
    }
    EXPECT_EQ(records.size(), whole) << "size " << size;
    // A cut at a record boundary is a clean end; anywhere else is damage.
    ASSERT_EQ(reader.damage().has_value(), at != size) << "size " << size;
    if (reader.damage()) EXPECT_EQ(reader.damage()->offset(), at);
  }
}

TEST(SessionFile, HostileLengthIsAnErrorNotAnAllocation) {
  TempDir dir;
  std::string bytes = write_sample(dir.file("a.wtape"), 2);
  const std::size_t header_end = 16 + detail::get_u32le(&bytes[12]) + 4;
  detail::put_u32le(&bytes[header_end], 0xFFFFFFFFu);
  write_file(dir.file("hostile.wtape"), bytes);
  SessionReader reader(dir.file("hostile.wtape"));
  EXPECT_TRUE(read_all(reader).empty());
  ASSERT_TRUE(reader.damage());
  EXPECT_EQ(reader.damage()->offset(), header_end);
  EXPECT_NE(std::string(reader.damage()->what()).find("claims a payload of 4294967295"),
            std::string::npos)
      << reader.damage()->what();
}

TEST(SessionFile, UnknownRecordKindsAreSkipped) {
  TempDir dir;
  const std::string path = dir.file("future-kind.wtape");
  {
    SessionWriter writer(path, {});
    writer.write(RecordKind::tx, 1, "before");
    writer.write(static_cast<RecordKind>(0x7f), 2, "{\"from\":\"the future\"}");
    writer.write(RecordKind::rx, 3, "after");
  }
  SessionReader reader(path);
  const auto records = read_all(reader);
  ASSERT_EQ(records.size(), 2u);
  EXPECT_EQ(records[0].data, "before");
  EXPECT_EQ(records[1].data, "after");
  EXPECT_FALSE(reader.damage());
}

TEST(SessionWriter, BufferedRecordsReachTheFileWithinFlushMsWhenIdle) {
  TempDir dir;
  const std::string path = dir.file("idle.wtape");
  SessionHeader header;
  FlushPolicy flush;
  flush.interval = std::chrono::milliseconds(50);
  SessionWriter writer(path, header, flush);
  const std::uint64_t header_size = writer.size();
  EXPECT_EQ(read_file(path).size(), header_size) << "the header is written at once";
  const auto written = std::chrono::steady_clock::now();
  writer.write(RecordKind::rx, 5, "idle data");
  // No flush() call: the flusher must get it to the file on its own.
  const auto deadline = written + 5s;
  std::size_t seen = 0;
  while (std::chrono::steady_clock::now() < deadline) {
    seen = read_file(path).size();
    if (seen == writer.size()) break;
    std::this_thread::yield();
  }
  const auto elapsed = std::chrono::steady_clock::now() - written;
  ASSERT_EQ(seen, writer.size());
  EXPECT_LT(elapsed, 2s);  // loose: 50 ms flush policy, a busy machine
  SessionReader reader(path);
  const auto records = read_all(reader);
  ASSERT_EQ(records.size(), 1u);
  EXPECT_EQ(records[0].data, "idle data");
}

TEST(SessionWriter, ThreadsWritingAtOnceLoseNothing) {
  TempDir dir;
  const std::string path = dir.file("threads.wtape");
  constexpr int per_thread = 2000;
  {
    SessionHeader header;
    FlushPolicy flush;
    flush.interval = std::chrono::milliseconds(1);
    SessionWriter writer(path, header, flush);
    auto work = [&](RecordKind kind) {
      for (int i = 0; i < per_thread; ++i) writer.write(kind, i, std::to_string(i));
    };
    std::thread reader_thread(work, RecordKind::rx);
    std::thread writer_thread(work, RecordKind::tx);
    reader_thread.join();
    writer_thread.join();
  }
  SessionReader reader(path);
  int next_rx = 0;
  int next_tx = 0;
  Record record;
  while (reader.next(record)) {
    int& next = record.kind == RecordKind::rx ? next_rx : next_tx;
    EXPECT_EQ(record.data, std::to_string(next));
    ++next;
  }
  EXPECT_FALSE(reader.damage());
  EXPECT_EQ(next_rx, per_thread);
  EXPECT_EQ(next_tx, per_thread);
}

TEST(SessionWriter, CannotCreateIsAPortErrorNamingThePath) {
  try {
    SessionWriter writer("/nonexistent-dir/x.wtape", {});
    FAIL() << "no error";
  } catch (const PortError& e) {
    EXPECT_EQ(e.code().value(), ENOENT);
    EXPECT_NE(std::string(e.what()).find("/nonexistent-dir/x.wtape"), std::string::npos);
  }
}

TEST(SessionWriter, FileSizeLimitIsAClearErrorAndTheFileStaysReadable) {
  TempDir dir;
  const std::string path = dir.file("limited.wtape");
  int pipe_fds[2];
  ASSERT_EQ(::pipe(pipe_fds), 0);
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    ::close(pipe_fds[0]);
    ::signal(SIGXFSZ, SIG_IGN);
    rlimit limit{};
    limit.rlim_cur = limit.rlim_max = 4096;
    ::setrlimit(RLIMIT_FSIZE, &limit);
    std::string report;
    int written = 0;
    std::unique_ptr<SessionWriter> writer;
    try {
      SessionHeader header;
      FlushPolicy flush;
      flush.interval = std::chrono::milliseconds(1000);
      writer = std::make_unique<SessionWriter>(path, header, flush);
      for (; written < 1000; ++written) {
        writer->write(RecordKind::rx, static_cast<std::uint64_t>(written),
                      std::string(100, static_cast<char>('a' + written % 26)));
        if (written % 5 == 4) writer->flush();
      }
      report = "no error";
    } catch (const PortError& e) {
      report = std::to_string(e.code().value()) + " " + std::to_string(written) + " " +
               std::to_string(writer ? writer->records_written() : 0) + " " + e.what();
    }
    (void)!::write(pipe_fds[1], report.data(), report.size());
    ::_exit(0);
  }
  ::close(pipe_fds[1]);
  std::string report;
  char chunk[512];
  ssize_t n;
  while ((n = ::read(pipe_fds[0], chunk, sizeof chunk)) > 0) report.append(chunk, n);
  ::close(pipe_fds[0]);
  int status = 0;
  ::waitpid(child, &status, 0);
  ASSERT_TRUE(WIFEXITED(status)) << "the writer died of a signal";
  ASSERT_EQ(report.rfind(std::to_string(EFBIG) + " ", 0), 0u) << report;
  EXPECT_NE(report.find(path), std::string::npos) << report;
  int code = 0, failed_at = 0;
  unsigned long long records_written = 0;
  ASSERT_EQ(std::sscanf(report.c_str(), "%d %d %llu", &code, &failed_at, &records_written), 3)
      << report;
  // The file holds whole records only, as many as fit in 4096 bytes.
  EXPECT_LE(read_file(path).size(), 4096u);
  SessionReader reader(path);
  const auto records = read_all(reader);
  EXPECT_FALSE(reader.damage()) << reader.damage()->what();
  // The writer counts what reached the file, not the records it buffered
  // and lost with the failed write.
  EXPECT_EQ(records_written, records.size());
  EXPECT_GT(records.size(), 20u);
  EXPECT_LE(static_cast<int>(records.size()), failed_at + 1);
  for (std::size_t i = 0; i < records.size(); ++i) {
    EXPECT_EQ(records[i].t_ns, i);
    EXPECT_EQ(records[i].data, std::string(100, static_cast<char>('a' + i % 26)));
  }
}

// A recorder killed with SIGKILL loses at most the last flush_ms (flexiport
// defect: its stdio-buffered log lost everything on a crash): the child
// reports each record it has handed to the writer (with the time), and
// everything reported more than flush_ms (plus slack for a loaded machine)
// before the kill must be in the file.
// Compressed (format 2.0) too: each flush of the file flushes the chunk.
static void expect_a_kill_loses_at_most_the_last_flush_ms(Compression compression) {
  TempDir dir;
  const std::string path = dir.file("killed.wtape");
  constexpr int flush_ms = 100;
  int pipe_fds[2];
  ASSERT_EQ(::pipe(pipe_fds), 0);
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    ::close(pipe_fds[0]);
    SessionHeader header;
    FlushPolicy flush;
    flush.interval = std::chrono::milliseconds(flush_ms);
    flush.compression = compression;
    SessionWriter writer(path, header, flush);
    for (std::uint32_t i = 0;; ++i) {
      writer.write(RecordKind::rx, i, "sample " + std::to_string(i));
      if (::write(pipe_fds[1], &i, sizeof i) != sizeof i) ::_exit(1);
      // A steady recorder: a few hundred records a second.
      ::poll(nullptr, 0, 3);
    }
  }
  ::close(pipe_fds[1]);
  using Clock = std::chrono::steady_clock;
  std::vector<std::pair<std::uint32_t, Clock::time_point>> reported;
  const auto start = Clock::now();
  while (Clock::now() - start < 800ms) {
    std::uint32_t i;
    if (::read(pipe_fds[0], &i, sizeof i) != sizeof i) break;
    reported.emplace_back(i, Clock::now());
  }
  ::kill(child, SIGKILL);
  const auto killed = Clock::now();
  int status = 0;
  ::waitpid(child, &status, 0);
  ::close(pipe_fds[0]);
  ASSERT_FALSE(reported.empty());
  // The newest record reported at least flush_ms + slack before the kill.
  const auto slack = 400ms;
  std::int64_t must_have = -1;
  for (const auto& [index, at] : reported) {
    if (killed - at >= std::chrono::milliseconds(flush_ms) + slack) must_have = index;
  }
  ASSERT_GE(must_have, 0) << "the child reported too little before the kill";
  SessionReader reader(path);
  const auto records = read_all(reader);
  ASSERT_GT(static_cast<std::int64_t>(records.size()), must_have);
  for (std::size_t i = 0; i < records.size(); ++i) {
    ASSERT_EQ(records[i].data, "sample " + std::to_string(i));
  }
  // A killed writer holds the file no more: what it left is no unfinished
  // end but damage, if anything.
  EXPECT_FALSE(reader.unfinished()) << reader.unfinished()->what();
  // Everything in the file is whole, or the one record cut by the kill (a
  // compressed file: or its open chunk without a last part).
  if (reader.damage()) {
    const std::string what = reader.damage()->what();
    EXPECT_TRUE(what.find("truncated") != std::string::npos ||
                (compression == Compression::zstd &&
                 what.find("has no last part") != std::string::npos))
        << what;
  }
}

TEST(SessionWriter, KilledRecorderLosesAtMostTheLastFlushMs) {
  expect_a_kill_loses_at_most_the_last_flush_ms(Compression::none);
}

TEST(SessionWriter, KilledCompressedRecorderLosesAtMostTheLastFlushMs) {
  expect_a_kill_loses_at_most_the_last_flush_ms(Compression::zstd);
}

TEST(SessionReader, FollowsAFileThatIsStillBeingWritten) {
  TempDir dir;
  const std::string path = dir.file("live.wtape");
  SessionWriter writer(path, {});
  writer.write(RecordKind::tx, 1, "first");
  writer.flush();
  SessionReader reader(path);
  Record record;
  ASSERT_TRUE(reader.next(record));
  EXPECT_EQ(record.data, "first");
  EXPECT_FALSE(reader.next(record));
  EXPECT_FALSE(reader.damage());
  writer.write(RecordKind::rx, 2, "second");
  writer.flush();
  ASSERT_TRUE(reader.next(record));
  EXPECT_EQ(record.data, "second");
}

TEST(SessionWriter, FullDiskIsAClearPortError) {
  // A full disk through the seam: /dev/full is a device, not a session file.
  TempDir dir;
  const std::string path = dir.file("full.wtape");
  detail::sys::ScopedOverride seam;
  seam->write = [](int, const void*, size_t) -> ssize_t {
    errno = ENOSPC;
    return -1;
  };
  try {
    SessionWriter writer(path, {});
    FAIL() << "no error writing to a full disk";
  } catch (const PortError& e) {
    EXPECT_EQ(e.code().value(), ENOSPC);
    EXPECT_NE(std::string(e.what()).find(path + ": cannot write the session file"),
              std::string::npos)
        << e.what();
  }
}

TEST(SessionWriter, FsyncOptionWritesReadableFiles) {
  TempDir dir;
  const std::string path = dir.file("synced.wtape");
  SessionHeader header;
  FlushPolicy flush;
  flush.fsync = true;
  flush.interval = std::chrono::milliseconds(1);
  {
    SessionWriter writer(path, header, flush);
    for (int i = 0; i < 20; ++i) writer.write(RecordKind::rx, i, "synced");
    writer.flush();
  }
  SessionReader reader(path);
  EXPECT_EQ(read_all(reader).size(), 20u);
  EXPECT_FALSE(reader.damage());
}

// --- closing ----------------------------------------------------------------

namespace {

namespace sys = wiretape::detail::sys;
using wiretape::test::Event;
using wiretape::test::kEventDeadline;

using wiretape::test::holds_fd_on;

pid_t this_thread_id() { return static_cast<pid_t>(::syscall(SYS_gettid)); }

// Whether thread `tid` of this process sleeps (on a lock, in a join) or has
// ended: the kernel's own view, so no guessing with timers.
bool asleep_or_gone(pid_t tid) {
  std::ifstream stat("/proc/self/task/" + std::to_string(tid) + "/stat");
  if (!stat) return true;
  const std::string text((std::istreambuf_iterator<char>(stat)), std::istreambuf_iterator<char>());
  const std::size_t name_end = text.rfind(')');
  if (name_end == std::string::npos || name_end + 2 >= text.size()) return true;
  const char state = text[name_end + 2];
  return state == 'S' || state == 'Z' || state == 'X';
}

// Waits until the thread that stored its id in `tid` sleeps or has ended.
bool wait_asleep_or_gone(const std::atomic<pid_t>& tid) {
  const auto deadline = std::chrono::steady_clock::now() + kEventDeadline;
  while (std::chrono::steady_clock::now() < deadline) {
    const pid_t id = tid.load();
    if (id != 0 && asleep_or_gone(id)) return true;
    std::this_thread::yield();
  }
  return false;
}

}  // namespace

TEST(SessionWriterClose, AWriteDuringTheFinalFlushIsWrittenOrRefusedNeverLost) {
  TempDir dir;
  const std::string path = dir.file("late.wtape");
  SessionWriter* target = nullptr;
  std::atomic<bool> write_late{false};
  bool late_accepted = false;
  std::string late_refusal;
  sys::ScopedOverride seam;
  seam->write = [&](int fd, const void* data, size_t size) -> ssize_t {
    if (write_late.exchange(false)) {
      // close() has taken the buffer and is handing it to the OS.
      try {
        target->write(RecordKind::rx, 2, "late");
        late_accepted = true;
      } catch (const PortError& e) {
        late_refusal = e.what();
      }
    }
    return sys::real().write(fd, data, size);
  };
  SessionHeader header;
  FlushPolicy flush;
  flush.interval = std::chrono::milliseconds(60'000);  // only close() flushes
  SessionWriter writer(path, header, flush);
  target = &writer;
  writer.write(RecordKind::tx, 1, "before");
  write_late = true;
  writer.close();

  SessionReader reader(path);
  const auto records = read_all(reader);
  EXPECT_FALSE(reader.damage());
  ASSERT_GE(records.size(), 1u);
  EXPECT_EQ(records[0].data, "before");
  if (late_accepted) {
    ASSERT_EQ(records.size(), 2u) << "a write close() accepted is not in the file";
    EXPECT_EQ(records[1].data, "late");
  } else {
    EXPECT_EQ(records.size(), 1u);
    EXPECT_NE(late_refusal.find(path), std::string::npos) << late_refusal;
    EXPECT_NE(late_refusal.find("closed"), std::string::npos) << late_refusal;
  }
}

TEST(SessionWriterClose, TwoThreadsClosingAtOnceCloseOnce) {
  TempDir dir;
  const std::string path = dir.file("twice.wtape");
  std::atomic<bool> hold_flusher{false};
  Event flusher_in_write;
  Event release_flusher;
  sys::ScopedOverride seam;
  seam->write = [&](int fd, const void* data, size_t size) -> ssize_t {
    if (hold_flusher.exchange(false)) {
      flusher_in_write.set();
      release_flusher.wait();
    }
    return sys::real().write(fd, data, size);
  };
  SessionHeader header;
  FlushPolicy flush;
  flush.interval = std::chrono::milliseconds(1);
  SessionWriter writer(path, header, flush);
  hold_flusher = true;
  writer.write(RecordKind::tx, 1, "held");
  // The flusher is now busy, so the first close() waits in its join.
  ASSERT_TRUE(flusher_in_write.wait());

  std::atomic<pid_t> first_id{0};
  std::atomic<pid_t> second_id{0};
  std::string first_error;
  std::string second_error;
  const auto close_from = [&writer](std::atomic<pid_t>& id, std::string& error) {
    id = this_thread_id();
    try {
      writer.close();
    } catch (const std::exception& e) {
      error = e.what();
    }
  };
  std::thread first(close_from, std::ref(first_id), std::ref(first_error));
  ASSERT_TRUE(wait_asleep_or_gone(first_id));
  std::thread second(close_from, std::ref(second_id), std::ref(second_error));
  const bool second_waited = wait_asleep_or_gone(second_id);
  release_flusher.set();
  first.join();
  second.join();
  ASSERT_TRUE(second_waited);
  EXPECT_EQ(first_error, "");
  EXPECT_EQ(second_error, "");
  EXPECT_FALSE(holds_fd_on(path));
  EXPECT_THROW(writer.write(RecordKind::tx, 2, "after"), PortError);

  SessionReader reader(path);
  const auto records = read_all(reader);
  EXPECT_FALSE(reader.damage());
  ASSERT_EQ(records.size(), 1u);
  EXPECT_EQ(records[0].data, "held");
}

TEST(SessionWriterClose, CloseAfterAWriteFailureReleasesTheFile) {
  TempDir dir;
  const std::string path = dir.file("failed.wtape");
  std::atomic<bool> fail{false};
  sys::ScopedOverride seam;
  seam->write = [&](int fd, const void* data, size_t size) -> ssize_t {
    if (fail.load()) {
      errno = ENOSPC;
      return -1;
    }
    return sys::real().write(fd, data, size);
  };
  SessionHeader header;
  FlushPolicy flush;
  flush.interval = std::chrono::milliseconds(0);  // every write reaches the OS at once
  SessionWriter writer(path, header, flush);
  ASSERT_TRUE(holds_fd_on(path));
  fail = true;
  EXPECT_THROW(writer.write(RecordKind::tx, 1, "lost"), PortError);
  EXPECT_THROW(writer.close(), PortError);
  EXPECT_FALSE(holds_fd_on(path));
  EXPECT_NO_THROW(writer.close());
}

TEST(SessionWriterClose, ClosingARecordingPortAfterARecordingFailureReleasesTheFile) {
  TempDir dir;
  const std::string path = dir.file("port.wtape");
  std::atomic<int> session_fd{-1};
  std::atomic<bool> fail{false};
  sys::ScopedOverride seam;
  seam->open = [&](const char* name, int flags, mode_t mode) {
    const int fd = sys::real().open(name, flags, mode);
    if (name == path) session_fd = fd;
    return fd;
  };
  seam->write = [&](int fd, const void* data, size_t size) -> ssize_t {
    if (fail.load() && fd == session_fd.load()) {
      errno = ENOSPC;
      return -1;
    }
    return sys::real().write(fd, data, size);
  };
  detail::RecordingConfig config;
  config.path = path;
  config.flush_ms = 0;  // every record reaches the OS at once
  config.raise_errors = true;
  auto port = detail::record_port(open_port("type=loopback"), config);
  ASSERT_TRUE(holds_fd_on(path));
  fail = true;
  port->write("x");  // recorded: the recording fails here
  EXPECT_THROW(port->write("y"), PortError);  // and says so
  port->close();
  EXPECT_FALSE(holds_fd_on(path)) << "the port is closed but the session file is still open";
}
