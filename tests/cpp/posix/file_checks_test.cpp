// The files sessions are read from and written to (issue 16, DESIGN §6
// "Special files"): a session reader reads a FIFO as a stream, waiting for its
// writer interruptibly; replay, flexiport imports and the session writer refuse
// a FIFO at once rather than wait on it; the session writer never writes
// through a symbolic link or over a device; a flexiport export writes through
// them; nothing is written over the session being read.
#include <fcntl.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <functional>
#include <future>
#include <string>
#include <thread>

#include "posix/file_checks.hpp"
#include "posix/syscalls.hpp"
#include "support/port_test_support.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/port.hpp"
#include "wiretape/session.hpp"

namespace wiretape {
namespace {

using test::read_file;
using test::TempDir;
using test::write_file;

constexpr auto deadline = std::chrono::seconds(10);

std::string write_sample(const std::string& path) {
  SessionHeader header;
  header.port_type = "serial";
  SessionWriter writer(path, header);
  writer.write(RecordKind::open, 0, "{}");
  writer.write(RecordKind::tx, 1000, "PING\n");
  writer.write(RecordKind::rx, 2000, "PONG\n");
  writer.close();
  return read_file(path);
}

// Runs `action` on a thread. If it is still busy after the deadline (the
// defect: open() waiting for the FIFO's other end), the test fails and the
// FIFO's other end comes and goes until the action gives up: each open
// releases a waiting open(), each close ends a waiting read() or write().
void finishes_promptly(const std::string& fifo, const std::function<void()>& action) {
  std::promise<void> done;
  std::future<void> finished = done.get_future();
  std::thread worker([&] {
    try {
      action();
    } catch (...) {
    }
    done.set_value();
  });
  if (finished.wait_for(deadline) != std::future_status::ready) {
    ADD_FAILURE() << "still waiting on " << fifo << " after the deadline";
    while (finished.wait_for(std::chrono::milliseconds(50)) != std::future_status::ready) {
      const int release = ::open(fifo.c_str(), O_RDWR | O_NONBLOCK);
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
      if (release >= 0) ::close(release);
    }
  }
  worker.join();
}

// The error `action` throws, as text; fails the test when it throws none.
template <typename Error>
std::string error_of(const std::function<void()>& action) {
  try {
    action();
  } catch (const Error& error) {
    return error.what();
  }
  ADD_FAILURE() << "no error";
  return "";
}

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

class FileChecks : public ::testing::Test {
 protected:
  // A test that fails lets a writer reach a FIFO nobody reads.
  void SetUp() override { ::signal(SIGPIPE, SIG_IGN); }
  TempDir dir;
};

// Writes `bytes` into `fifo` from a thread, a few bytes at a time, once a
// reader has opened it (the thread's open() waits for one).
std::thread fifo_writer(const std::string& fifo, std::string bytes) {
  return std::thread([fifo, bytes = std::move(bytes)] {
    const int fd = ::open(fifo.c_str(), O_WRONLY);
    if (fd < 0) return;
    for (std::size_t done = 0; done < bytes.size();) {
      const ssize_t n = ::write(fd, bytes.data() + done, std::min<std::size_t>(7, bytes.size() - done));
      if (n <= 0) break;
      done += static_cast<std::size_t>(n);
    }
    ::close(fd);
  });
}

TEST_F(FileChecks, ASessionReaderReadsAFifoAsAStream) {
  const std::string bytes = write_sample(dir.file("s.wtape"));
  const std::string fifo = dir.file("fifo");  // no suffix: not looked into
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  std::thread writer = fifo_writer(fifo, bytes);
  int records = 0;
  bool damaged = true;
  std::string message;
  finishes_promptly(fifo, [&] {
    message = error_of<PortError>([&] {
      SessionReader reader(fifo);
      Record record;
      while (reader.next(record)) ++records;
      damaged = reader.damage().has_value();
      reader.rewind();  // a stream cannot be read again
    });
  });
  writer.join();
  EXPECT_EQ(records, 3);
  EXPECT_FALSE(damaged);
  EXPECT_TRUE(contains(message, fifo + ": a pipe or FIFO cannot be read again")) << message;
}

TEST_F(FileChecks, AStreamsLengthFieldIsBelievedOnlyAsFarAsItsBytesArrive) {
  std::string bytes = write_sample(dir.file("s.wtape"));
  // A record header claiming ~4 GiB, then 100 bytes and the end.
  const std::string claim("\xf0\xff\xff\xff\x10\0\0\0\0\0\0\0\0\0\0\0", 16);
  bytes += claim + std::string(100, 'x');
  const std::string fifo = dir.file("fifo.wtape");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  std::thread writer = fifo_writer(fifo, bytes);
  rusage before {};
  ::getrusage(RUSAGE_SELF, &before);
  std::string damage;
  int records = 0;
  finishes_promptly(fifo, [&] {
    SessionReader reader(fifo);
    Record record;
    while (reader.next(record)) ++records;
    if (reader.damage()) damage = reader.damage()->what();
  });
  writer.join();
  rusage after {};
  ::getrusage(RUSAGE_SELF, &after);
  EXPECT_EQ(records, 3);
  EXPECT_TRUE(contains(damage, "claims a payload of 4294967280 bytes, but the file holds only "
                               "100 more bytes")) << damage;
  EXPECT_LT(after.ru_maxrss - before.ru_maxrss, 64 * 1024) << "KiB more at the peak";
}

std::atomic<bool> stop_waiting{false};

struct WaitInterrupted {};

void interrupt_when_asked() {
  if (stop_waiting.load()) throw WaitInterrupted{};
}

TEST_F(FileChecks, WaitingForAWriterEndsWhenTheInterruptionCheckSaysSo) {
  const std::string fifo = dir.file("fifo.wtape");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  detail::set_interruption_check(&interrupt_when_asked);
  std::atomic<bool> interrupted{false};
  std::atomic<bool> opening{false};
  std::thread stopper([&] {
    while (!opening.load()) std::this_thread::yield();
    stop_waiting.store(true);
  });
  finishes_promptly(fifo, [&] {
    try {
      opening.store(true);
      SessionReader reader(fifo);  // no writer ever comes
    } catch (const WaitInterrupted&) {
      interrupted.store(true);
    }
  });
  stopper.join();
  detail::set_interruption_check(nullptr);
  stop_waiting.store(false);
  EXPECT_TRUE(interrupted.load());
}

TEST_F(FileChecks, AFifoAsAReplaySessionIsRefusedAtOnce) {
  const std::string fifo = dir.file("fifo.wtape");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  std::string message;
  finishes_promptly(fifo, [&] {
    message = error_of<PortError>([&] { open_port("type=replay,file=" + fifo); });
  });
  EXPECT_TRUE(contains(message, fifo + " is a FIFO, not a regular file")) << message;
}

TEST_F(FileChecks, AFifoInAFlexiportPairIsRefusedAtOnce) {
  const std::string prefix = dir.file("pair.log");
  ASSERT_EQ(::mkfifo((prefix + "r").c_str(), 0600), 0);
  write_file(prefix + "w", "");
  std::string message;
  finishes_promptly(prefix + "r", [&] {
    message = error_of<PortError>([&] { SessionReader reader(prefix); });
  });
  EXPECT_TRUE(contains(message, prefix + "r is a FIFO, not a regular file")) << message;
}

TEST_F(FileChecks, AFifoAsTheSessionToWriteIsRefusedAtOnce) {
  const std::string fifo = dir.file("fifo.wtape");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  std::string message;
  finishes_promptly(fifo, [&] {
    message = error_of<PortError>([&] { SessionWriter writer(fifo, {}); });
  });
  EXPECT_TRUE(contains(message, fifo + " is a FIFO, not a regular file")) << message;
}

TEST_F(FileChecks, AFlexiportExportWritesThroughAFifo) {
  const std::string session = dir.file("s.wtape");
  write_sample(session);
  const std::string expected = dir.file("expected.log");
  export_flexiport(session, expected);
  const std::string prefix = dir.file("out.log");
  write_file(prefix + "r", "an earlier export, longer than the new one: " + std::string(500, 'x'));
  ASSERT_EQ(::mkfifo((prefix + "w").c_str(), 0600), 0);
  std::string received;
  std::thread reader([&] {
    const int fd = ::open((prefix + "w").c_str(), O_RDONLY);
    char chunk[256];
    for (ssize_t n; fd >= 0 && (n = ::read(fd, chunk, sizeof chunk)) > 0;) received.append(chunk, n);
    if (fd >= 0) ::close(fd);
  });
  finishes_promptly(prefix + "w", [&] { export_flexiport(session, prefix); });
  reader.join();
  EXPECT_EQ(received, read_file(expected + "w"));
  EXPECT_EQ(read_file(prefix + "r"), read_file(expected + "r"));
  struct stat info {};
  ASSERT_EQ(::lstat((prefix + "w").c_str(), &info), 0);
  EXPECT_TRUE(S_ISFIFO(info.st_mode));
}

TEST_F(FileChecks, ADeviceIsNotAnEmptySession) {
  const std::string message =
      error_of<PortError>([] { SessionReader reader("/dev/zero"); });
  EXPECT_TRUE(contains(message, "/dev/zero is a character device, not a regular file"))
      << message;
  write_file(dir.file("empty.wtape"), "");
  EXPECT_TRUE(contains(error_of<SessionError>([&] { SessionReader reader(dir.file("empty.wtape")); }),
                       "empty file"));
}

TEST_F(FileChecks, AFileThatCannotBeOpenedIsAnIoErrorNotDamage) {
  const std::string path = dir.file("s.wtape");
  write_sample(path);
  detail::sys::ScopedOverride seam;
  seam->open = [](const char*, int, mode_t) {
    errno = EACCES;
    return -1;
  };
  const std::string message = error_of<PortError>([&] { SessionReader reader(path); });
  EXPECT_TRUE(contains(message, path + ": cannot open")) << message;
  EXPECT_TRUE(contains(message, "Permission denied")) << message;
}

TEST_F(FileChecks, ReplayLoggingToItsOwnFileIsRefused) {
  const std::string path = dir.file("s.wtape");
  const std::string bytes = write_sample(path);
  const std::string link = dir.file("link.wtape");
  ASSERT_EQ(::symlink(path.c_str(), link.c_str()), 0);
  const std::string hard = dir.file("hard.wtape");
  ASSERT_EQ(::link(path.c_str(), hard.c_str()), 0);
  for (const auto& [file, log] : {std::pair{path, path}, std::pair{link, path},
                                  std::pair{path, hard}}) {
    const std::string message = error_of<PortError>(
        [&, &file = file, &log = log] { open_port("type=replay,file=" + file + ",log=" + log); });
    EXPECT_TRUE(contains(message, log + " is the same file as " + file)) << message;
    EXPECT_EQ(read_file(path), bytes);
  }
}

TEST_F(FileChecks, AWriterNeverEmptiesASessionBeingRead) {
  const std::string path = dir.file("s.wtape");
  const std::string bytes = write_sample(path);
  const std::string hard = dir.file("hard.wtape");
  ASSERT_EQ(::link(path.c_str(), hard.c_str()), 0);
  {
    SessionReader reader(path);
    const std::string message =
        error_of<PortError>([&] { SessionWriter writer(hard, {}); });
    EXPECT_TRUE(contains(message, hard + " is the same file as " + path)) << message;
    EXPECT_EQ(read_file(path), bytes);
  }
  // Once nothing reads it, it is an ordinary output.
  SessionWriter writer(hard, {});
  writer.close();
  EXPECT_NE(read_file(path), bytes);
}

TEST_F(FileChecks, AFlexiportExportOntoItsOwnLogIsRefused) {
  const std::string session = dir.file("s.wtape");
  write_sample(session);
  const std::string prefix = dir.file("pair.log");
  export_flexiport(session, prefix);
  const std::string reads = read_file(prefix + "r");
  const std::string writes = read_file(prefix + "w");
  const std::string message = error_of<PortError>([&] { export_flexiport(prefix, prefix); });
  EXPECT_TRUE(contains(message, "is the same file as")) << message;
  EXPECT_EQ(read_file(prefix + "r"), reads);
  EXPECT_EQ(read_file(prefix + "w"), writes);
}

TEST_F(FileChecks, WritersDoNotWriteThroughSymbolicLinks) {
  const std::string target = dir.file("target.bin");
  write_file(target, "keep me");
  const std::string link = dir.file("out.wtape");
  ASSERT_EQ(::symlink(target.c_str(), link.c_str()), 0);
  EXPECT_TRUE(contains(error_of<PortError>([&] { SessionWriter writer(link, {}); }),
                       link + " is a symbolic link, not a regular file"));

  EXPECT_EQ(read_file(target), "keep me");
  struct stat info {};
  ASSERT_EQ(::lstat(link.c_str(), &info), 0);
  EXPECT_TRUE(S_ISLNK(info.st_mode));
}

TEST_F(FileChecks, AFlexiportExportFollowsSymbolicLinks) {
  const std::string session = dir.file("s.wtape");
  write_sample(session);
  const std::string expected = dir.file("expected.log");
  export_flexiport(session, expected);
  const std::string target = dir.file("target.bin");
  write_file(target, "an earlier file, longer than the export: " + std::string(500, 'x'));
  const std::string prefix = dir.file("pair.log");
  ASSERT_EQ(::symlink(target.c_str(), (prefix + "r").c_str()), 0);
  ASSERT_EQ(::symlink("/dev/null", (prefix + "w").c_str()), 0);
  export_flexiport(session, prefix);
  EXPECT_EQ(read_file(target), read_file(expected + "r"));
  struct stat info {};
  for (const char* suffix : {"r", "w"}) {
    ASSERT_EQ(::lstat((prefix + suffix).c_str(), &info), 0);
    EXPECT_TRUE(S_ISLNK(info.st_mode)) << suffix;
  }
  ASSERT_EQ(::stat("/dev/null", &info), 0);
  EXPECT_TRUE(S_ISCHR(info.st_mode));
  // What cannot be written through is refused, before either file is emptied.
  const std::string other = dir.file("dir.log");
  write_file(other + "r", "keep me");
  ASSERT_EQ(::mkdir((other + "w").c_str(), 0700), 0);
  EXPECT_TRUE(contains(error_of<PortError>([&] { export_flexiport(session, other); }),
                       other + "w is a directory, not a regular file"));
  EXPECT_EQ(read_file(other + "r"), "keep me");
}

TEST_F(FileChecks, ADeviceIsNotAnOutput) {
  // /dev/null is looked at (lstat), never opened or emptied.
  EXPECT_TRUE(contains(error_of<PortError>([] { SessionWriter writer("/dev/null", {}); }),
                       "/dev/null is a character device, not a regular file"));
  EXPECT_TRUE(contains(error_of<PortError>([&] { SessionWriter writer(dir.path, {}); }),
                       dir.path + " is a directory, not a regular file"));
}

TEST_F(FileChecks, AnExistingRegularOutputIsEmptiedAndRewritten) {
  const std::string path = dir.file("s.wtape");
  write_file(path, std::string(100000, 'x'));
  write_sample(path);
  SessionReader reader(path);
  Record record;
  int records = 0;
  while (reader.next(record)) ++records;
  EXPECT_EQ(records, 3);
  EXPECT_FALSE(reader.damage().has_value());
}

}  // namespace
}  // namespace wiretape
