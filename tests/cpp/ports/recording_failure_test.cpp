// Recording that fails part-way (issue 16): how an OS error becomes text, a
// writer past the file-size limit (EFBIG, never SIGXFSZ), the session file
// released after a failure, and a bridge that keeps forwarding when its
// recording fails.
#include <fcntl.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <filesystem>
#include <functional>
#include <string>
#include <thread>
#include <vector>

#include "ports/ports.hpp"
#include "posix/fd_port.hpp"
#include "posix/syscalls.hpp"
#include "support/port_test_support.hpp"
#include "wiretape/bridge.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/session.hpp"
#include "wiretape/wiretape.hpp"

namespace wiretape {
namespace {

namespace sys = detail::sys;
using namespace std::chrono_literals;
using test::TempDir;

constexpr auto kDeadline = 10s;

std::size_t count_of(const std::string& text, const std::string& part) {
  std::size_t count = 0;
  for (auto at = text.find(part); at != std::string::npos; at = text.find(part, at + 1)) ++count;
  return count;
}

using wiretape::test::holds_fd_on;

// Polls `condition` until it holds or the deadline passes (no blind sleep of
// the whole deadline).
bool eventually(const std::function<bool()>& condition) {
  const auto end = std::chrono::steady_clock::now() + kDeadline;
  while (!condition()) {
    if (std::chrono::steady_clock::now() > end) return false;
    std::this_thread::sleep_for(1ms);
  }
  return true;
}

// Fails writes of the file at `path` with `error` once `failing` is set;
// everything else reaches the OS.
class FailingFileWrites {
 public:
  FailingFileWrites(std::string path, int error) : path_(std::move(path)), error_(error) {
    seam_->open = [this](const char* name, int flags, mode_t mode) {
      const int fd = sys::real().open(name, flags, mode);
      if (name == path_ && (flags & O_ACCMODE) != O_RDONLY) fd_ = fd;  // not a reader's
      return fd;
    };
    seam_->write = [this](int fd, const void* data, size_t size) -> ssize_t {
      if (failing && fd == fd_.load()) {
        errno = error_;
        return -1;
      }
      return sys::real().write(fd, data, size);
    };
  }
  std::atomic<bool> failing{false};

 private:
  std::string path_;
  int error_;
  std::atomic<int> fd_{-1};
  sys::ScopedOverride seam_;  // last: restored before the members it uses go
};

// --- messages (system_error_message itself: tests/cpp/core/errors_test.cpp) ---

TEST(SystemErrorMessage, ADeviceThatWentAwayIsNamedOnce) {
  for (const int error : {EIO, ECONNRESET, ENXIO, EACCES}) {
    try {
      detail::raise_os_error(error, "serial /dev/ttyX", "read");
      FAIL() << "no error";
    } catch (const PortError& e) {
      const std::string text = e.what();
      EXPECT_EQ(count_of(text, std::generic_category().message(error)), 1u) << text;
      EXPECT_EQ(text.find("Success"), std::string::npos) << text;
      EXPECT_EQ(text.rfind("serial /dev/ttyX: read failed", 0), 0u) << text;
    }
  }
}

// --- the writer past the file-size limit --------------------------------------------

struct ChildOutcome {
  bool exited = false;      // false: killed by a signal
  int signal = 0;
  std::string report;       // what the child wrote to the pipe
};

// Runs `body` in a child under a 4 KiB file-size limit with SIGXFSZ at its
// default action (kill), as in a C++ program that never heard of it.
ChildOutcome run_under_file_size_limit(const std::function<std::string()>& body) {
  int report_pipe[2];
  if (::pipe(report_pipe) != 0) throw std::runtime_error("pipe");
  const pid_t child = ::fork();
  if (child == 0) {
    ::close(report_pipe[0]);
    ::signal(SIGXFSZ, SIG_DFL);
    rlimit limit{};
    limit.rlim_cur = limit.rlim_max = 4096;
    ::setrlimit(RLIMIT_FSIZE, &limit);
    std::string report;
    try {
      report = body();
    } catch (const std::exception& e) {
      report = std::string("unexpected: ") + e.what();
    }
    (void)!::write(report_pipe[1], report.data(), report.size());
    ::_exit(0);
  }
  ::close(report_pipe[1]);
  ChildOutcome outcome;
  char chunk[512];
  ssize_t n;
  while ((n = ::read(report_pipe[0], chunk, sizeof chunk)) > 0) outcome.report.append(chunk, n);
  ::close(report_pipe[0]);
  int status = 0;
  ::waitpid(child, &status, 0);
  outcome.exited = WIFEXITED(status);
  if (WIFSIGNALED(status)) outcome.signal = WTERMSIG(status);
  return outcome;
}

void expect_whole_records_only(const std::string& path) {
  SessionReader reader(path);
  Record record;
  std::size_t count = 0;
  while (reader.next(record)) ++count;
  EXPECT_FALSE(reader.damage()) << reader.damage()->what();
  EXPECT_GT(count, 0u);
  EXPECT_LE(std::filesystem::file_size(path), 4096u);
}

TEST(WriterPastTheFileSizeLimit, AWriteOnTheCallersThreadFailsWithEfbigNotSigxfsz) {
  TempDir dir;
  const std::string path = dir.file("limited.wtape");
  const ChildOutcome outcome = run_under_file_size_limit([&] {
    SessionHeader header;
    FlushPolicy flush;
    flush.interval = std::chrono::milliseconds(0);  // every record is written on this thread
    SessionWriter writer(path, header, flush);
    for (int i = 0; i < 1000; ++i) {
      try {
        writer.write(RecordKind::rx, static_cast<std::uint64_t>(i), std::string(100, 'r'));
      } catch (const PortError& e) {
        return std::to_string(e.code().value()) + " " + e.what();
      }
    }
    return std::string("no error");
  });
  ASSERT_TRUE(outcome.exited) << "the writer was killed by signal " << outcome.signal;
  EXPECT_EQ(outcome.report.rfind(std::to_string(EFBIG) + " ", 0), 0u) << outcome.report;
  EXPECT_NE(outcome.report.find(path), std::string::npos) << outcome.report;
  EXPECT_NE(outcome.report.find("file-size limit of 4096 bytes"), std::string::npos)
      << outcome.report;
  EXPECT_EQ(count_of(outcome.report, std::generic_category().message(EFBIG)), 1u)
      << outcome.report;
  expect_whole_records_only(path);
}

TEST(WriterPastTheFileSizeLimit, TheFlusherThreadFailsWithEfbigNotSigxfsz) {
  TempDir dir;
  const std::string path = dir.file("flusher.wtape");
  const ChildOutcome outcome = run_under_file_size_limit([&] {
    SessionHeader header;
    FlushPolicy flush;
    flush.interval = std::chrono::milliseconds(1);  // the flusher thread does the writing
    SessionWriter writer(path, header, flush);
    int written = 0;
    const bool failed = eventually([&] {
      try {
        writer.write(RecordKind::tx, static_cast<std::uint64_t>(written++), std::string(100, 't'));
      } catch (const PortError&) {
        return true;
      }
      return writer.failure().has_value();
    });
    if (!failed) return std::string("no error");
    return std::to_string(writer.failure()->code().value()) + " " + writer.failure()->what();
  });
  ASSERT_TRUE(outcome.exited) << "the writer was killed by signal " << outcome.signal;
  EXPECT_EQ(outcome.report.rfind(std::to_string(EFBIG) + " ", 0), 0u) << outcome.report;
  expect_whole_records_only(path);
}

TEST(WriterPastTheFileSizeLimit, ASignalBlockedByTheCallerStaysBlocked) {
  sigset_t blocked;
  sigemptyset(&blocked);
  sigaddset(&blocked, SIGXFSZ);
  sigset_t before;
  ASSERT_EQ(pthread_sigmask(SIG_BLOCK, nullptr, &before), 0);
  TempDir dir;
  {
    SessionHeader header;
    FlushPolicy flush;
    flush.interval = std::chrono::milliseconds(0);
    SessionWriter writer(dir.file("mask.wtape"), header, flush);
    writer.write(RecordKind::tx, 1, "x");
  }
  sigset_t after;
  ASSERT_EQ(pthread_sigmask(SIG_BLOCK, nullptr, &after), 0);
  EXPECT_EQ(sigismember(&before, SIGXFSZ), sigismember(&after, SIGXFSZ));
}

// --- the file is released after a failure ----------------------------------------------

TEST(ReleasedAfterAFailure, AWriterLetsGoOfItsFileAtTheFailure) {
  TempDir dir;
  const std::string path = dir.file("full.wtape");
  FailingFileWrites disk(path, ENOSPC);
  SessionHeader header;
  FlushPolicy flush;
  flush.interval = std::chrono::milliseconds(0);
  SessionWriter writer(path, header, flush);
  writer.write(RecordKind::tx, 1, "kept");
  disk.failing = true;
  try {
    writer.write(RecordKind::tx, 2, "lost");
    FAIL() << "no error";
  } catch (const PortError& e) {
    EXPECT_EQ(e.code().value(), ENOSPC);
    EXPECT_NE(std::string(e.what()).find(path + ": cannot write the session file: No space left"),
              std::string::npos)
        << e.what();
  }
  EXPECT_FALSE(holds_fd_on(path)) << "the file is held after the failure, before close()";
  EXPECT_THROW(writer.close(), PortError);
  const auto records = test::load_records(path);
  ASSERT_EQ(records.size(), 1u);
  EXPECT_EQ(records[0].data, "kept");
}

TEST(ReleasedAfterAFailure, ARecordingPortWhosePortFailsToCloseLetsGoOfItsFile) {
  TempDir dir;
  const std::string session = dir.file("recorded.wtape");
  const std::string log = dir.file("log.wtape");
  {
    SessionWriter writer(session, {});
    writer.write(RecordKind::open, 0, "{}");
    writer.write(RecordKind::rx, 1, "never read");
  }
  // unused=error: close() raises the mismatch for the rx never read.
  auto port = open_port("type=replay,file=" + session + ",unused=error,log=" + log);
  ASSERT_TRUE(holds_fd_on(log));
  EXPECT_THROW(port->close(), ReplayMismatch);
  EXPECT_FALSE(holds_fd_on(log)) << "the port is closed but its session file is still open";
  SessionReader reader(log);
  Record record;
  std::vector<RecordKind> kinds;
  while (reader.next(record)) kinds.push_back(record.kind);
  EXPECT_FALSE(reader.damage());
  ASSERT_FALSE(kinds.empty());
  EXPECT_EQ(kinds.back(), RecordKind::close);
}

// --- a bridge whose recording fails ----------------------------------------------------

std::string exchange(int fd, const std::string& data) {
  std::size_t done = 0;
  while (done < data.size()) {
    const ssize_t n = ::write(fd, data.data() + done, data.size() - done);
    if (n <= 0) return "write failed";
    done += static_cast<std::size_t>(n);
  }
  return test::read_count(fd, data.size());
}

std::size_t messages_with(const Bridge& bridge, const std::string& part) {
  std::size_t count = 0;
  for (const auto& message : bridge.messages()) count += message.find(part) != std::string::npos;
  return count;
}

TEST(BridgeRecordingFailure, ForwardingGoesOnTheFailureIsReportedOnceAndTheFileIsValid) {
  TempDir dir;
  const std::string path = dir.file("bridge.wtape");
  FailingFileWrites disk(path, ENOSPC);
  BridgeOptions options;
  options.device = "type=loopback";
  options.client_side = BridgeClientSide::tcp;
  options.output = path;
  options.flush_ms = 1;
  options.quiet = true;
  Bridge bridge(options);
  bridge.start();
  const int client = test::connect_tcp(bridge.listen_address());
  ASSERT_GE(client, 0);
  EXPECT_EQ(exchange(client, "before"), "before");
  ASSERT_TRUE(eventually([&] {
    try {
      return test::load_records(path).size() >= 3;  // open, client_connect, tx
    } catch (const SessionError&) {
      return false;  // caught in the middle of a flush
    }
  })) << "the first records never reached the file";
  disk.failing = true;
  ASSERT_TRUE(eventually([&] {
    EXPECT_EQ(exchange(client, "during"), "during");
    return messages_with(bridge, "recording stopped") > 0;
  })) << "the failure was not reported";
  EXPECT_TRUE(bridge.running());
  for (int i = 0; i < 5; ++i) EXPECT_EQ(exchange(client, "after"), "after");
  ::close(client);
  bridge.stop();
  ASSERT_TRUE(bridge.wait(kDeadline));
  const BridgeResult result = bridge.result();
  EXPECT_EQ(result.outcome, BridgeOutcome::failed);
  EXPECT_NE(result.message.find(path), std::string::npos) << result.message;
  EXPECT_NE(result.message.find("No space left on device"), std::string::npos) << result.message;
  EXPECT_EQ(messages_with(bridge, "recording stopped"), 1u);
  EXPECT_FALSE(holds_fd_on(path));
  const auto records = test::load_records(path);  // throws when damaged
  ASSERT_FALSE(records.empty());
  EXPECT_EQ(records.front().kind, RecordKind::open);
  EXPECT_NE(records.back().kind, RecordKind::close);
}

}  // namespace
}  // namespace wiretape
