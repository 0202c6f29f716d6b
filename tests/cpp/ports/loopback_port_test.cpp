#include <gtest/gtest.h>

#include <chrono>
#include <string>
#include <thread>

#include "support/port_test_support.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/port.hpp"

using namespace std::chrono_literals;
using wiretape::open_port;
using wiretape::test::fd_readable;

TEST(Loopback, WrittenBytesAreReadBack) {
  auto port = open_port("type=loopback,timeout=1");
  EXPECT_EQ(port->type(), "loopback");
  EXPECT_TRUE(port->is_open());
  EXPECT_EQ(port->write_all("hello\nworld"), 11u);
  EXPECT_EQ(port->available(), 11u);
  EXPECT_EQ(port->read_line(), "hello\n");
  char buffer[3];
  EXPECT_EQ(port->read(buffer, sizeof buffer), 3u);
  EXPECT_EQ(std::string(buffer, 3), "wor");
  EXPECT_EQ(port->read_exactly(2), "ld");
}

TEST(Loopback, ZeroTimeoutPollsAndReadTimesOutReturningZero) {
  auto port = open_port("type=loopback,timeout=0");
  char byte;
  const auto start = std::chrono::steady_clock::now();
  EXPECT_EQ(port->read(&byte, 1), 0u);
  EXPECT_EQ(port->read(&byte, 1, 50ms), 0u);
  EXPECT_GE(std::chrono::steady_clock::now() - start, 50ms);
}

TEST(Loopback, CompoundReadsReturnPartialDataOnTimeout) {
  auto port = open_port("type=loopback,timeout=0.05");
  port->write_all("abc");
  EXPECT_EQ(port->read_exactly(10), "abc");
  port->write_all("no newline");
  EXPECT_EQ(port->read_line(), "no newline");
  port->write_all("xy");
  EXPECT_FALSE(port->skip_until("\n"));
  EXPECT_EQ(port->available(), 0u);
}

TEST(Loopback, NativeHandleIsReadableExactlyWhenDataIsAvailable) {
  auto port = open_port("type=loopback,timeout=0");
  const int handle = port->native_handle();
  ASSERT_GE(handle, 0);
  EXPECT_FALSE(fd_readable(handle, 0ms));
  port->write_all("ab");
  EXPECT_TRUE(fd_readable(handle, 0ms));
  char byte;
  ASSERT_EQ(port->read(&byte, 1), 1u);
  EXPECT_TRUE(fd_readable(handle, 0ms)) << "one byte is still available";
  ASSERT_EQ(port->read(&byte, 1), 1u);
  EXPECT_FALSE(fd_readable(handle, 0ms));
  port->write_all("cd");
  port->flush_input();
  EXPECT_EQ(port->available(), 0u);
  EXPECT_FALSE(fd_readable(handle, 0ms));
}

TEST(Loopback, BlockingReadWakesWhenAnotherThreadWrites) {
  auto port = open_port("type=loopback");  // default timeout blocks
  wiretape::test::Event reading;
  std::thread writer([&] {
    ASSERT_TRUE(reading.wait());
    port->write_all("late");
  });
  reading.set();
  EXPECT_EQ(port->read_exactly(4), "late");
  writer.join();
}

TEST(Loopback, CloseFromAnotherThreadEndsAForeverRead) {
  auto port = open_port("type=loopback");
  wiretape::test::Event reading;
  std::thread closer([&] {
    ASSERT_TRUE(reading.wait());
    port->close();
  });
  // Whether close() lands before or during the wait, a read that would
  // block forever ends with PortClosed instead of hanging.
  reading.set();
  char byte;
  EXPECT_THROW(port->read(&byte, 1), wiretape::PortClosed);
  closer.join();
  EXPECT_FALSE(port->is_open());
  EXPECT_EQ(port->native_handle(), -1);
  EXPECT_THROW(port->write_all("x"), wiretape::PortClosed);
  EXPECT_THROW(port->available(), wiretape::PortClosed);
}

TEST(Loopback, WaitReadableTellsTheTruth) {
  auto port = open_port("type=loopback");
  EXPECT_FALSE(port->wait_readable(0s));
  EXPECT_FALSE(port->wait_readable(20ms));
  port->write_all("x");
  EXPECT_TRUE(port->wait_readable(0s));
}

TEST(Loopback, AccessModesAreEnforced) {
  auto read_only = open_port("type=loopback,access=readonly");
  EXPECT_THROW(read_only->write_all("x"), wiretape::PortError);
  auto write_only = open_port("type=loopback,writeonly");
  char byte;
  EXPECT_THROW(write_only->read(&byte, 1), wiretape::PortError);
}

TEST(Loopback, UnknownKeyIsRejected) {
  EXPECT_THROW(open_port("type=loopback,baud=9600"), wiretape::OptionError);
}
