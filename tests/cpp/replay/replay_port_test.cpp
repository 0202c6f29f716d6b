// src/replay/replay_port.cpp: type=replay as a port: opened from a file
// through open_port (aliases, udp sessions as datagrams, damaged and foreign
// files), the end of the session (at_end, a read that would block forever,
// the unused policy at close), the pollable handle and its pipe through the
// system-call seam, and threads.
#include <sys/types.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <future>
#include <string>
#include <vector>

#include "posix/syscalls.hpp"
#include "support/replay_support.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/port.hpp"
#include "wiretape/session.hpp"

using namespace wiretape;
using namespace std::chrono_literals;
using namespace wiretape::test::replay_support;
using wiretape::test::TempDir;

TEST(ReplaySequence, FileOpenedThroughOpenPortReplays) {
  TempDir dir;
  const std::string path = write_session(dir, hello_session());
  auto port = open_port("type=replay,timing=none,timeout=5,file=" + path);
  EXPECT_EQ(port->type(), "replay");
  EXPECT_EQ(port->read_line(), "HELLO\n");
  port->write_all("PING\nTIME\n");
  EXPECT_EQ(port->read_exactly(14), "PONG\n12:00\nOK\n");
  port->close();
  EXPECT_FALSE(port->is_open());
  EXPECT_THROW(port->available(), PortClosed);
}

TEST(ReplaySequence, LogreaderIsAnAlias) {
  TempDir dir;
  const std::string path = write_session(dir, hello_session());
  auto port = open_port("type=logreader,ignoretimes,timeout=5,file=" + path);
  EXPECT_EQ(port->read_line(), "HELLO\n");
}

TEST(ReplaySequence, UdpSessionFileReplaysAsDatagrams) {
  TempDir dir;
  const std::string path =
      write_session(dir, {rx(0, "one"), rx(1, "two")}, "udp");
  auto port = open_port("type=replay,timing=none,timeout=5,file=" + path);
  EXPECT_EQ(read_some(*port), "one");
  EXPECT_EQ(read_some(*port), "two");
}

// Issue 37: the replay starts with the line the recorded device opened
// with, so that a virtual device tells the client's settings changes from
// it as the proxy that recorded them did (a client setting the rate the
// device had is no change, in the recording or in the replay).
TEST(ReplaySettings, TheReplayStartsWithTheRecordedPortsLineSettings) {
  TempDir dir;
  const std::string path = dir.file("fast.wtape");
  SessionHeader header;
  header.port_type = "serial";
  header.port_options = "type=serial,device=/dev/ttyUSB0,baud=115200,parity=even,stopbits=2";
  SessionWriter writer(path, header);
  writer.write(rx(ms(1), "HI"));
  writer.close();
  auto port = open_port("type=replay,timing=none,unused=ignore,file=" + path);
  const SerialSettings settings = port->serial_settings();
  EXPECT_EQ(settings.baud, 115200u);
  EXPECT_EQ(settings.parity, Parity::even);
  EXPECT_EQ(settings.stop_bits, 2);
  EXPECT_EQ(settings.data_bits, 8);  // a serial port's default where they say none
  // A recorded port without line settings: a serial port's defaults.
  EXPECT_EQ(open_port("type=replay,unused=ignore,file=" + write_session(dir, {rx(0, "x")}))
                ->serial_settings(),
            SerialSettings{});
}

TEST(ReplayEnd, AfterTheLastRecordReadsTimeOutLikeASilentDevice) {
  auto port = replay({rx(0, "only")});
  EXPECT_EQ(read_some(*port), "only");
  const auto start = std::chrono::steady_clock::now();
  EXPECT_EQ(read_some(*port, 10, 50ms), "");
  EXPECT_GE(std::chrono::steady_clock::now() - start, 40ms);
  EXPECT_FALSE(port->wait_readable(20ms));
  EXPECT_EQ(port->read_exactly(4, 20ms), "");
}

TEST(ReplayEnd, AReadThatWouldBlockForeverRaisesInsteadOfHanging) {
  auto port = replay({rx(0, "only")});
  port->set_timeout(forever);
  EXPECT_EQ(read_some(*port, 10, forever), "only");
  EXPECT_THROW(read_some(*port, 10, forever), PortClosed);
}

TEST(ReplayEnd, AtEndClosedRaisesOnEveryRead) {
  auto port = replay({rx(0, "only")}, "timing=none,at_end=closed");
  EXPECT_EQ(read_some(*port), "only");
  EXPECT_TRUE(port->wait_readable(0s));
  EXPECT_THROW(read_some(*port, 10, 1s), PortClosed);
  EXPECT_THROW(read_some(*port, 10, 0s), PortClosed);
}

TEST(ReplayEnd, UnusedErrorRaisesAtClose) {
  auto port = replay(hello_session(), "timing=none,unused=error");
  EXPECT_EQ(read_some(*port), "HELLO\n");
  try {
    port->close();
    FAIL() << "unused data not reported";
  } catch (const ReplayMismatch& mismatch) {
    const std::string report = mismatch.what();
    EXPECT_NE(report.find("never read"), std::string::npos) << report;
    EXPECT_NE(report.find("10 recorded tx bytes were never written"),
              std::string::npos)
        << report;
  }
  EXPECT_FALSE(port->is_open());
}

TEST(ReplayEnd, UnusedWarnAndIgnoreDoNotRaise) {
  for (const char* keys : {"timing=none,unused=warn", "timing=none,unused=ignore"}) {
    auto port = replay(hello_session(), keys);
    EXPECT_NO_THROW(port->close()) << keys;
  }
}

TEST(ReplayEnd, FullyConsumedSessionClosesCleanlyUnderUnusedError) {
  auto port = replay(hello_session(), "timing=none,unused=error");
  EXPECT_EQ(port->read_line(), "HELLO\n");
  port->write_all("PING\nTIME\n");
  EXPECT_EQ(port->read_exactly(14), "PONG\n12:00\nOK\n");
  EXPECT_NO_THROW(port->close());
}

TEST(ReplayTiming, ReadNeverBlocksPastItsTimeout) {
  auto port = replay({tx(0, "Q"), rx(ms(5000), "late")}, "timing=causal");
  port->write("Q");
  const auto start = std::chrono::steady_clock::now();
  EXPECT_EQ(read_some(*port, 10, 50ms), "");
  const auto waited = std::chrono::steady_clock::now() - start;
  EXPECT_GE(waited, 45ms);
  EXPECT_LT(waited, 2s);
}

TEST(ReplayHandle, ReadableExactlyWhenDataIsAvailable) {
  auto port = replay({tx(0, "Q"), rx(ms(80), "AB")}, "timing=causal");
  const int fd = port->native_handle();
  ASSERT_GE(fd, 0);
  EXPECT_FALSE(test::fd_readable(fd, 0ms));
  port->write("Q");
  EXPECT_FALSE(test::fd_readable(fd, 0ms));  // entitled, not yet due
  // The scheduler raises the handle when the answer falls due.
  ASSERT_TRUE(test::fd_readable(fd, 5000ms));
  EXPECT_EQ(port->available(), 2u);
  EXPECT_EQ(read_some(*port, 1), "A");
  EXPECT_TRUE(test::fd_readable(fd, 0ms));
  EXPECT_EQ(read_some(*port, 1), "B");
  EXPECT_FALSE(test::fd_readable(fd, 0ms));
  port->close();
  EXPECT_EQ(port->native_handle(), -1);
}

// The readiness pipe is made when native_handle() is first asked for (a
// client that never polls costs none), and made and closed through the
// system-call seam.
TEST(ReplayHandle, ReadinessPipeGoesThroughTheSystemCallSeam) {
  {
    detail::sys::ScopedOverride seam;
    int pipes = 0;
    seam->pipe = [&pipes](int*) {
      ++pipes;
      errno = EMFILE;
      return -1;
    };
    auto port = replay(hello_session(), "timing=none,unused=ignore");
    EXPECT_EQ(port->read_until("\n"), "HELLO\n");
    port->write("PING\n");
    EXPECT_EQ(port->read_until("\n"), "PONG\n");
    EXPECT_EQ(pipes, 0);  // read and written without one
    try {
      port->native_handle();
      FAIL() << "the faked pipe failure was not seen";
    } catch (const PortError& error) {
      EXPECT_EQ(error.code().value(), EMFILE);
      EXPECT_NE(std::string(error.what()).find("readiness pipe"), std::string::npos)
          << error.what();
    }
  }
  detail::sys::ScopedOverride seam;
  std::vector<int> made;
  std::vector<int> closed;
  seam->pipe = [&made](int* fds) {
    const int result = detail::sys::real().pipe(fds);
    if (result == 0) made.assign({fds[0], fds[1]});
    return result;
  };
  seam->close = [&closed](int fd) {
    closed.push_back(fd);
    return detail::sys::real().close(fd);
  };
  auto port = replay(hello_session(), "timing=none,unused=ignore");
  EXPECT_TRUE(made.empty());
  const int handle = port->native_handle();
  ASSERT_EQ(made.size(), 2u);
  EXPECT_EQ(handle, made[0]);
  EXPECT_EQ(port->native_handle(), handle);  // made once
  port->close();
  EXPECT_NE(std::find(closed.begin(), closed.end(), made[0]), closed.end());
  EXPECT_NE(std::find(closed.begin(), closed.end(), made[1]), closed.end());
}

// A session the client only read (no tx, no line records) is read once:
// what the close checks for unused data the read cursor already saw.
TEST(ReplayUnused, ClosingAReadOnlySessionDoesNotReadTheFileAgain) {
  TempDir dir;
  std::vector<Record> records;
  const std::string chunk(4096, 'r');
  constexpr int kRecords = 512;  // 2 MiB: sixteen of the reader's buffers
  for (int i = 0; i < kRecords; ++i) records.push_back(rx(ms(i), chunk));
  const std::string path = write_session(dir, records);
  auto port = open_port("type=replay,timing=none,unused=error,file=" + path);
  std::string buffer(65536, '\0');
  std::size_t total = 0;
  while (total < kRecords * chunk.size()) {
    const std::size_t got = port->read(buffer.data(), buffer.size(), 5s);
    ASSERT_GT(got, 0u) << "the replay stopped after " << total << " bytes";
    total += got;
  }
  detail::sys::ScopedOverride seam;
  std::size_t bytes_read_at_close = 0;
  seam->read = [&bytes_read_at_close](int fd, void* out, size_t size) {
    const ssize_t got = detail::sys::real().read(fd, out, size);
    if (got > 0) bytes_read_at_close += static_cast<std::size_t>(got);
    return got;
  };
  // Session files are read at their offsets.
  seam->pread = [&bytes_read_at_close](int fd, void* out, size_t size, off_t offset) {
    const ssize_t got = detail::sys::real().pread(fd, out, size, offset);
    if (got > 0) bytes_read_at_close += static_cast<std::size_t>(got);
    return got;
  };
  EXPECT_NO_THROW(port->close());
  EXPECT_LT(bytes_read_at_close, 65536u);
}

TEST(ReplayHandle, ReadableInTimingNoneToo) {
  auto port = replay(hello_session());
  EXPECT_TRUE(test::fd_readable(port->native_handle(), 0ms));
  port->read_line();
  EXPECT_FALSE(test::fd_readable(port->native_handle(), 0ms));
  port->write("PING\n");
  EXPECT_TRUE(test::fd_readable(port->native_handle(), 0ms));
}

TEST(ReplayThreads, CloseFromAnotherThreadWakesABlockedRead) {
  auto port = replay({tx(0, "Q"), rx(1, "A")});
  port->set_timeout(forever);
  auto reader = std::async(std::launch::async, [&] {
    char byte;
    try {
      port->read(&byte, 1);
      return false;
    } catch (const PortClosed&) {
      return true;
    }
  });
  // The read blocks: it is entitled to nothing until "Q" is written.
  EXPECT_EQ(reader.wait_for(100ms), std::future_status::timeout);
  port->close();
  ASSERT_EQ(reader.wait_for(test::kEventDeadline), std::future_status::ready);
  EXPECT_TRUE(reader.get());
}

TEST(ReplayThreads, ReaderAndWriterRunAtOnce) {
  std::vector<Record> session;
  std::string expected;
  for (int i = 0; i < 200; ++i) {
    session.push_back(tx(i * 2, "q" + std::to_string(i) + ";"));
    session.push_back(rx(i * 2 + 1, "a" + std::to_string(i) + ";"));
    expected += "a" + std::to_string(i) + ";";
  }
  auto port = replay(session);
  auto reader = std::async(std::launch::async,
                           [&] { return port->read_exactly(expected.size()); });
  for (int i = 0; i < 200; ++i) port->write_all("q" + std::to_string(i) + ";");
  ASSERT_EQ(reader.wait_for(test::kEventDeadline), std::future_status::ready);
  EXPECT_EQ(reader.get(), expected);
}

// flexiport's BytesAvailable looped forever once recorded data fell due.
TEST(ReplayFlexiportDefects, BytesAvailableLoopingOnceDataIsDue) {
  auto port = replay({rx(ms(30), "due")}, "timing=session");
  ASSERT_TRUE(port->wait_readable(5s));
  auto answer = std::async(std::launch::async, [&] { return port->available(); });
  ASSERT_EQ(answer.wait_for(test::kEventDeadline), std::future_status::ready);
  EXPECT_EQ(answer.get(), 3u);
}

TEST(ReplayFiles, DamagedSessionReplaysUpToTheDamage) {
  TempDir dir;
  const std::string path =
      write_session(dir, {rx(0, "intact "), rx(1, "record"), rx(2, std::string(100, 'z'))});
  // Cut the last record in half.
  ASSERT_EQ(::truncate(path.c_str(), static_cast<off_t>(std::filesystem::file_size(path) - 50)), 0);
  auto port = open_port("type=replay,timing=none,timeout=5,unused=ignore,file=" + path);
  EXPECT_EQ(port->read_exactly(13), "intact record");
  EXPECT_EQ(read_some(*port, 10, 20ms), "");
}

TEST(ReplayFiles, NotASessionIsAClearErrorAtOpen) {
  TempDir dir;
  const std::string path = dir.file("junk.wtape");
  {
    std::FILE* file = std::fopen(path.c_str(), "wb");
    ASSERT_NE(file, nullptr);
    std::fputs("this is not a session", file);
    std::fclose(file);
  }
  try {
    open_port("type=replay,file=" + path);
    FAIL() << "junk accepted";
  } catch (const SessionError& error) {
    EXPECT_NE(std::string(error.what()).find("junk.wtape"), std::string::npos) << error.what();
  }
}
