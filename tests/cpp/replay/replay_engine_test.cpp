// src/replay/replay_engine.cpp: serving the released rx: reads that copy
// across records and never past the caller's buffer, datagrams one at a
// time (an empty one included), a recorded close or device loss where it
// falls, and flush_input.
#include <gtest/gtest.h>

#include <chrono>
#include <cstring>
#include <optional>
#include <string>

#include "posix/transports.hpp"
#include "replay/replay_port.hpp"
#include "support/replay_support.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/port.hpp"

using namespace wiretape;
using namespace std::chrono_literals;
using namespace wiretape::test::replay_support;
using wiretape::test::TempDir;

TEST(ReplaySequence, RecordedCloseReplaysAsPortClosedAtThatPoint) {
  auto port = replay({rx(0, "last words"), event(ms(1), RecordKind::close),
                      rx(ms(2), "never")});
  EXPECT_EQ(port->read_exactly(10), "last words");
  EXPECT_TRUE(port->wait_readable(0s));  // the device is gone
  EXPECT_THROW(read_some(*port), PortClosed);
  EXPECT_THROW(read_some(*port), PortClosed);
}

TEST(ReplaySequence, RecordedDeviceLossReplaysAsPortClosed) {
  auto port = replay({tx(0, "Q"), rx(1, "A"), event(2, RecordKind::device_lost)});
  port->write("Q");
  EXPECT_EQ(read_some(*port), "A");
  EXPECT_THROW(read_some(*port), PortClosed);
}

TEST(ReplaySequence, FlushInputDropsReleasedButUnreadBytes) {
  auto port = replay(hello_session());
  ASSERT_TRUE(port->wait_readable(5s));
  port->flush_input();
  EXPECT_EQ(port->available(), 0u);
  port->write("PING\n");
  EXPECT_EQ(read_some(*port), "PONG\n");
}

TEST(ReplaySequence, DatagramSessionsKeepRecordBoundaries) {
  auto port = replay({tx(0, "Q1"), rx(1, "first"), rx(2, "second"),
                      tx(3, "Q2"), rx(4, "third")},
                     "timing=none", /*datagrams=*/true);
  port->write("Q1");
  EXPECT_EQ(port->available(), 5u);  // the next datagram
  EXPECT_EQ(read_some(*port), "first");
  EXPECT_EQ(read_some(*port, 3), "sec");  // truncated, as recv does
  EXPECT_EQ(read_some(*port, 100, 0ms), "");
  EXPECT_THROW(port->write("Q"), ReplayMismatch);  // half a datagram
}

// An empty datagram is a record like any other (DESIGN.md section 23): the
// replay of a datagram session says it through DatagramPort, where a Port's
// read of 0 bytes cannot.
TEST(ReplaySequence, EmptyDatagramsAreServedAndCheckedAtTheirPlace) {
  auto port = replay({tx(0, ""), rx(1, ""), tx(2, "Q"), rx(3, "A")}, "timing=none",
                     /*datagrams=*/true);
  auto* datagrams = dynamic_cast<detail::DatagramPort*>(port.get());
  ASSERT_NE(datagrams, nullptr);
  char buffer[16];
  EXPECT_EQ(datagrams->receive_datagram(buffer, sizeof buffer), std::nullopt);
  EXPECT_TRUE(datagrams->send_empty_datagram());
  EXPECT_EQ(datagrams->receive_datagram(buffer, sizeof buffer), std::optional<std::size_t>(0));
  EXPECT_EQ(datagrams->receive_datagram(buffer, sizeof buffer), std::nullopt);
  port->write("Q");
  ASSERT_EQ(datagrams->receive_datagram(buffer, sizeof buffer), std::optional<std::size_t>(1));
  EXPECT_EQ(buffer[0], 'A');
}

// Through Port::read, where 0 bytes means nothing now, an empty datagram is
// passed over: available() and read() see the next one.
TEST(ReplaySequence, APortReadPassesOverAnEmptyDatagram) {
  auto port = replay({rx(0, ""), rx(1, "one")}, "timing=none", /*datagrams=*/true);
  EXPECT_EQ(port->available(), 3u);
  EXPECT_EQ(read_some(*port, 100, 0ms), "one");
}

// flexiport kept the rest of a chunk in an overflow buffer and corrupted a
// following read larger than that overflow.
TEST(ReplayFlexiportDefects, OverflowBufferWithReadsLargerThanTheOverflow) {
  auto port = replay({rx(0, "0123456789"), rx(1, "abcdefghij")});
  EXPECT_EQ(read_some(*port, 3), "012");
  std::string buffer(100, '#');
  const std::size_t n = port->read(buffer.data(), buffer.size(), 5s);
  EXPECT_EQ(buffer.substr(0, n), "3456789abcdefghij");
  EXPECT_EQ(buffer.substr(n), std::string(100 - n, '#'));
}

// flexiport's ignoretimes copied a whole recorded chunk into the caller's
// smaller buffer.
TEST(ReplayFlexiportDefects, IgnoretimesWritingPastTheBuffer) {
  auto port = replay({rx(0, std::string(64, 'x'))}, "ignoretimes");
  char buffer[16];
  std::memset(buffer, '#', sizeof buffer);
  EXPECT_EQ(port->read(buffer, 8, 5s), 8u);
  EXPECT_EQ(std::string(buffer, 8), std::string(8, 'x'));
  EXPECT_EQ(std::string(buffer + 8, 8), std::string(8, '#'));
}
