// src/replay/replay_engine.cpp: serving the released rx: reads that copy
// across records and never past the caller's buffer, datagrams one at a
// time (an empty one included), a recorded close or device loss where it
// falls, flush_input, and the peek that lets a compound read take a line
// at once.
#include <gtest/gtest.h>

#include <chrono>
#include <cstring>
#include <optional>
#include <string>

#include "posix/transports.hpp"
#include "replay/replay_engine.hpp"
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

TEST(ReplayPeek, PeekShowsTheDueRxAcrossRecordsWithoutConsumingIt) {
  const detail::ReplayTime start = detail::ReplayTime{} + std::chrono::hours(1);
  detail::ReplayEngine engine(config_from("timing=session"),
                              detail::vector_source_factory({rx(0, "AB\nC"), rx(ms(1), "D\n"),
                                                             rx(ms(5), "later\n")}),
                              start);
  char buffer[16];
  EXPECT_EQ(engine.peek(buffer, sizeof buffer, start), std::optional<std::size_t>(4));
  EXPECT_EQ(std::string(buffer, 4), "AB\nC");
  EXPECT_EQ(engine.peek(buffer, sizeof buffer, start + 2ms), std::optional<std::size_t>(6));
  EXPECT_EQ(std::string(buffer, 6), "AB\nCD\n");  // the second record is due, the third not
  EXPECT_EQ(engine.peek(buffer, 2, start + 2ms), std::optional<std::size_t>(2));
  EXPECT_EQ(engine.read(buffer, 3, start + 2ms), 3u);  // the peeks left it all there
  EXPECT_EQ(std::string(buffer, 3), "AB\n");
  EXPECT_EQ(engine.peek(buffer, sizeof buffer, start + 2ms), std::optional<std::size_t>(3));
  EXPECT_EQ(std::string(buffer, 3), "CD\n");
  EXPECT_EQ(engine.read(buffer, sizeof buffer, start + 2ms), 3u);
  EXPECT_EQ(engine.peek(buffer, sizeof buffer, start + 2ms), std::optional<std::size_t>(0));
}

TEST(ReplayPeek, PeekLeavesARecordedCloseAndDatagramsToRead) {
  const detail::ReplayTime start = detail::ReplayTime{} + std::chrono::hours(1);
  detail::ReplayEngine closing(config_from("timing=none"),
                               detail::vector_source_factory({rx(0, "A"), event(ms(1), RecordKind::close), rx(ms(2), "never")}),
                               start);
  char buffer[16];
  EXPECT_EQ(closing.peek(buffer, sizeof buffer, start), std::optional<std::size_t>(1));
  EXPECT_EQ(closing.read(buffer, sizeof buffer, start), 1u);
  EXPECT_EQ(closing.peek(buffer, sizeof buffer, start), std::nullopt);
  EXPECT_THROW(closing.read(buffer, sizeof buffer, start), PortClosed);
  detail::ReplayConfig datagrams = config_from("timing=none");
  datagrams.datagrams = true;
  detail::ReplayEngine datagram(datagrams, detail::vector_source_factory({rx(0, "one")}), start);
  EXPECT_EQ(datagram.peek(buffer, sizeof buffer, start), std::nullopt);
}

TEST(ReplayPeek, ReadUntilTakesLinesAcrossRecordsAndStopsAtEachDelimiter) {
  auto port = replay({rx(0, "one\ntw"), rx(ms(1), "o\nthree"), rx(ms(2), "\n"),
                      event(ms(3), RecordKind::close), rx(ms(4), "never")});
  EXPECT_EQ(port->read_until("\n"), "one\n");
  EXPECT_EQ(port->read_until("\n"), "two\n");
  EXPECT_EQ(port->read_until("\n"), "three\n");
  EXPECT_THROW(port->read_until("\n"), PortClosed);  // the recorded close, after the lines
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
