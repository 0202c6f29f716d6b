// type=replay: entitlement, timing modes, checks, request matching, end of
// session, the pollable handle, and flexiport's replay defects.
#include <poll.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include "support/port_test_support.hpp"

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <cstdio>
#include <filesystem>
#include <future>
#include <string>
#include <thread>
#include <vector>

#include "posix/syscalls.hpp"
#include "posix/transports.hpp"
#include "session/record_source.hpp"
#include "replay/replay_config.hpp"
#include "replay/replay_engine.hpp"
#include "replay/replay_port.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/options.hpp"
#include "wiretape/port.hpp"
#include "wiretape/session.hpp"

using namespace wiretape;
using namespace std::chrono_literals;
using wiretape::detail::ReplayConfig;

namespace {

constexpr std::uint64_t ms(std::uint64_t n) { return n * 1'000'000; }

Record rx(std::uint64_t t, std::string data) {
  return {t, RecordKind::rx, std::move(data)};
}
Record tx(std::uint64_t t, std::string data) {
  return {t, RecordKind::tx, std::move(data)};
}
Record event(std::uint64_t t, RecordKind kind) { return {t, kind, ""}; }

ReplayConfig config_from(const std::string& keys) {
  Options options = Options::parse("file=synthetic.wtape," + keys);
  ReplayConfig config = detail::take_replay_config(options);
  options.finish("replay");
  return config;
}

std::unique_ptr<Port> replay(std::vector<Record> records,
                             const std::string& keys = "timing=none",
                             bool datagrams = false) {
  ReplayConfig config = config_from(keys);
  config.datagrams = datagrams;
  auto port = detail::open_replay_session(
      config, detail::vector_source_factory(std::move(records)));
  port->set_timeout(test::kEventDeadline);
  return port;
}

std::string read_some(Port& port, std::size_t size = 4096,
                      Timeout timeout = 5s) {
  std::string buffer(size, '\0');
  buffer.resize(port.read(buffer.data(), size, timeout));
  return buffer;
}

using wiretape::test::TempDir;

std::string write_session(const TempDir& dir, const std::vector<Record>& records,
                          const std::string& port_type = "serial") {
  const std::string path = dir.file("session.wtape");
  SessionHeader header;
  header.port_type = port_type;
  SessionWriter writer(path, header);
  for (const Record& record : records) writer.write(record);
  writer.close();
  return path;
}

// A typical command/response session with a greeting.
std::vector<Record> hello_session() {
  return {rx(ms(1), "HELLO\n"), tx(ms(10), "PING\n"), rx(ms(20), "PONG\n"),
          tx(ms(30), "TIME\n"), rx(ms(40), "12:00\n"), rx(ms(45), "OK\n")};
}

// Upper time bounds mean nothing under ThreadSanitizer's slowdown.
bool under_thread_sanitizer() {
#if defined(__SANITIZE_THREAD__)
  return true;
#else
  return std::getenv("WIRETAPE_TSAN") != nullptr;
#endif
}

}  // namespace

// --- options -------------------------------------------------------------------

TEST(ReplayOptions, DefaultsFollowTheDesign) {
  const ReplayConfig config = config_from("");
  EXPECT_EQ(config.timing, detail::ReplayTiming::causal);
  EXPECT_EQ(config.check, detail::ReplayCheck::data);
  EXPECT_EQ(config.match, detail::ReplayMatch::sequence);
  EXPECT_EQ(config.unmatched, detail::ReplayUnmatched::error);
  EXPECT_EQ(config.repeat, detail::ReplayRepeat::none);
  EXPECT_EQ(config.unused, detail::ReplayUnused::warn);
  EXPECT_EQ(config.at_end, detail::ReplayAtEnd::silent);
  EXPECT_EQ(config.tolerance, 100ms);
  EXPECT_DOUBLE_EQ(config.speed, 1.0);
}

TEST(ReplayOptions, EveryKeyIsParsed) {
  const ReplayConfig config = config_from(
      "timing=session,speed=2.5,check=timing,tolerance=20,match=request,"
      "unmatched=silent,repeat=cycle,unused=error,at_end=closed");
  EXPECT_EQ(config.timing, detail::ReplayTiming::session);
  EXPECT_DOUBLE_EQ(config.speed, 2.5);
  EXPECT_EQ(config.check, detail::ReplayCheck::timing);
  EXPECT_EQ(config.tolerance, 20ms);
  EXPECT_EQ(config.match, detail::ReplayMatch::request);
  EXPECT_EQ(config.unmatched, detail::ReplayUnmatched::silent);
  EXPECT_EQ(config.repeat, detail::ReplayRepeat::cycle);
  EXPECT_EQ(config.unused, detail::ReplayUnused::error);
  EXPECT_EQ(config.at_end, detail::ReplayAtEnd::closed);
  EXPECT_EQ(config_from("repeat=last").repeat, detail::ReplayRepeat::last);
  EXPECT_EQ(config_from("unused=ignore").unused, detail::ReplayUnused::ignore);
}

TEST(ReplayOptions, FlexiportSpellingsMapToTheNewKeys) {
  EXPECT_EQ(config_from("strictness=0").check, detail::ReplayCheck::off);
  EXPECT_EQ(config_from("strictness=1").check, detail::ReplayCheck::data);
  EXPECT_EQ(config_from("strictness=2").check, detail::ReplayCheck::timing);
  EXPECT_EQ(config_from("ignoretimes").timing, detail::ReplayTiming::none);
}

// flexiport documented jitter in ms but applied it in µs; µs it is.
TEST(ReplayOptions, JitterIsInMicroseconds) {
  EXPECT_EQ(config_from("jitter=1500").tolerance, 1500us);
  EXPECT_EQ(config_from("tolerance=1500").tolerance, 1500ms);
}

TEST(ReplayOptions, BadValuesNameTheKey) {
  for (const std::string keys :
       {"timing=fast", "speed=0", "speed=abc", "check=strict", "tolerance=-1",
        "match=any", "unmatched=ignore", "repeat=always", "unused=maybe",
        "at_end=open", "strictness=3", "jitter=-5"}) {
    const std::string key = keys.substr(0, keys.find('='));
    try {
      config_from(keys);
      ADD_FAILURE() << keys << " was accepted";
    } catch (const OptionError& error) {
      EXPECT_EQ(error.key(), key) << keys << ": " << error.what();
      EXPECT_NE(std::string(error.what()).find(key), std::string::npos);
    }
  }
}

TEST(ReplayOptions, CheckTimingWithoutAClockIsAnOptionError) {
  for (const std::string keys :
       {"check=timing,timing=none", "strictness=2,ignoretimes"}) {
    try {
      config_from(keys);
      ADD_FAILURE() << keys << " was accepted";
    } catch (const OptionError& error) {
      EXPECT_EQ(error.key(), "check") << error.what();
    }
  }
}

TEST(ReplayOptions, ContradictoryFlexiportSpellingsAreErrors) {
  EXPECT_THROW(config_from("check=data,strictness=1"), OptionError);
  EXPECT_THROW(config_from("tolerance=5,jitter=5"), OptionError);
  EXPECT_THROW(config_from("timing=causal,ignoretimes"), OptionError);
}

TEST(ReplayOptions, FileIsRequiredAndMustExist) {
  try {
    open_port("type=replay");
    ADD_FAILURE() << "replay without file was accepted";
  } catch (const OptionError& error) {
    EXPECT_EQ(error.key(), "file");
  }
  EXPECT_ANY_THROW(open_port("type=replay,file=/nonexistent/none.wtape"));
}

// --- sequence entitlement ------------------------------------------------------------

TEST(ReplaySequence, GreetingIsReleasedAtOpenAndAnswersWaitForTheirRequest) {
  auto port = replay(hello_session());
  EXPECT_EQ(read_some(*port), "HELLO\n");
  EXPECT_EQ(port->available(), 0u);
  EXPECT_EQ(read_some(*port, 64, 0ms), "");  // PONG is not entitled yet
  port->write("PI");
  EXPECT_EQ(port->available(), 0u);
  port->write("NG\n");
  EXPECT_EQ(port->available(), 5u);
  EXPECT_EQ(read_some(*port), "PONG\n");
  port->write_all("TIME\n");
  EXPECT_EQ(port->read_exactly(9), "12:00\nOK\n");
}

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

TEST(ReplaySequence, MismatchReportShowsOffsetTimeHexAndExchange) {
  auto port = replay(hello_session());
  port->write("PING\nTI");
  try {
    port->write("XE\n");
    FAIL() << "mismatch not detected";
  } catch (const ReplayMismatch& mismatch) {
    EXPECT_EQ(mismatch.tx_offset(), 7u);
    EXPECT_EQ(mismatch.session_time_ns(), ms(30));
    EXPECT_EQ(mismatch.exchange(), 1);
    const std::string report = mismatch.what();
    EXPECT_NE(report.find("offset 7"), std::string::npos) << report;
    EXPECT_NE(report.find("0.030000 s"), std::string::npos) << report;
    EXPECT_NE(report.find("4d 45 0a  |ME.|"), std::string::npos) << report;
    EXPECT_NE(report.find("58 45 0a  |XE.|"), std::string::npos) << report;
    EXPECT_NE(report.find("|PING.TI|"), std::string::npos) << report;
    EXPECT_NE(report.find("exchange 1"), std::string::npos) << report;
  }
}

TEST(ReplaySequence, WritingPastTheRecordingIsAMismatch) {
  auto port = replay({tx(0, "A"), rx(1, "B")});
  port->write("A");
  EXPECT_THROW(port->write("C"), ReplayMismatch);
}

TEST(ReplaySequence, CheckOffAcceptsAnyBytesButCountsThem) {
  auto port = replay(hello_session(), "timing=none,check=off");
  EXPECT_EQ(read_some(*port), "HELLO\n");
  port->write("xxxx");
  EXPECT_EQ(port->available(), 0u);
  port->write("x");
  EXPECT_EQ(read_some(*port), "PONG\n");
  port->write("anything and more");
}

TEST(ReplaySequence, RecordedCloseReplaysAsPortClosedAtThatPoint) {
  auto port = replay({rx(0, "last words"), event(ms(1), RecordKind::close),
                      rx(ms(2), "never")});
  EXPECT_EQ(port->read_exactly(10), "last words");
  EXPECT_TRUE(port->wait_readable(0s));  // the device is gone
  EXPECT_THROW(read_some(*port), PortClosed);
  EXPECT_THROW(read_some(*port), PortClosed);
}

// The close that ends a recording is the client closing its port: the end,
// where at_end applies, not a device that went away.
TEST(ReplaySequence, CloseThatEndsTheRecordingIsTheEndNotALoss) {
  auto port = replay({tx(0, "Q"), rx(1, "A"), event(2, RecordKind::close)});
  port->write("Q");
  EXPECT_EQ(read_some(*port), "A");
  EXPECT_FALSE(port->wait_readable(20ms));
  EXPECT_EQ(read_some(*port, 10, 20ms), "");
  EXPECT_THROW(port->write("more"), ReplayMismatch);
  auto request = replay({tx(0, "Q"), rx(1, "A"), event(2, RecordKind::close)},
                        "timing=none,match=request");
  request->write("Q");
  EXPECT_EQ(read_some(*request), "A");
  EXPECT_EQ(read_some(*request, 10, 20ms), "");
  auto closed = replay({rx(1, "A"), event(2, RecordKind::close)},
                       "timing=none,at_end=closed");
  EXPECT_EQ(read_some(*closed), "A");
  EXPECT_THROW(read_some(*closed), PortClosed);
}

TEST(ReplaySequence, WritePastARecordedCloseRaisesPortClosed) {
  auto port = replay({tx(0, "Q"), event(1, RecordKind::close), rx(2, "late")});
  port->write("Q");
  EXPECT_THROW(port->write("R"), PortClosed);
}

TEST(ReplaySequence, RecordedDeviceLossReplaysAsPortClosed) {
  auto port = replay({tx(0, "Q"), rx(1, "A"), event(2, RecordKind::device_lost)});
  port->write("Q");
  EXPECT_EQ(read_some(*port), "A");
  EXPECT_THROW(read_some(*port), PortClosed);
}

TEST(ReplaySequence, EventsAreNotCheckedUnderCheckData) {
  auto port = replay({event(0, RecordKind::open), tx(1, "Q"),
                      {2, RecordKind::settings, "{\"baud\":115200}"},
                      {3, RecordKind::modem_lines, "{\"dtr\":true}"},
                      rx(4, "A")});
  port->write("Q");
  EXPECT_EQ(read_some(*port), "A");
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

TEST(ReplaySequence, ADatagramWhereAnEmptyOneWasRecordedIsAMismatch) {
  auto port = replay({tx(0, ""), rx(1, ""), tx(2, "Q"), rx(3, "A")}, "timing=none",
                     /*datagrams=*/true);
  EXPECT_THROW(port->write("Q"), ReplayMismatch);
}

TEST(ReplaySequence, AnEmptyDatagramWhereBytesWereRecordedIsAMismatch) {
  auto port = replay({tx(0, "Q"), rx(1, "A")}, "timing=none", /*datagrams=*/true);
  auto* datagrams = dynamic_cast<detail::DatagramPort*>(port.get());
  ASSERT_NE(datagrams, nullptr);
  EXPECT_THROW(datagrams->send_empty_datagram(), ReplayMismatch);
}

TEST(ReplaySequence, UdpSessionFileReplaysAsDatagrams) {
  TempDir dir;
  const std::string path =
      write_session(dir, {rx(0, "one"), rx(1, "two")}, "udp");
  auto port = open_port("type=replay,timing=none,timeout=5,file=" + path);
  EXPECT_EQ(read_some(*port), "one");
  EXPECT_EQ(read_some(*port), "two");
}

// --- end of the session ------------------------------------------------------------

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

// A long command/response session made on the fly (no memory of its own):
// each exchange is "Q\n" and a 4 KiB answer. Every source the factory makes
// counts the records and payload bytes it hands out.
struct HandedOut {
  std::atomic<std::uint64_t> records{0};
  std::atomic<std::uint64_t> bytes{0};
};

class LongSessionSource final : public detail::RecordSource {
 public:
  LongSessionSource(std::uint64_t exchanges, std::shared_ptr<HandedOut> counts)
      : exchanges_(exchanges), counts_(std::move(counts)) {}
  bool next(Record& record) override {
    if (position_ >= 2 * exchanges_) return false;
    const std::uint64_t exchange = position_ / 2;
    record.t_ns = ms(10 * exchange) + (position_ % 2);
    if (position_ % 2 == 0) {
      record.kind = RecordKind::tx;
      record.data = "Q\n";
    } else {
      record.kind = RecordKind::rx;
      record.data.assign(kAnswerBytes, static_cast<char>('a' + exchange % 26));
    }
    ++position_;
    ++counts_->records;
    counts_->bytes += record.data.size();
    return true;
  }
  void rewind() override { position_ = 0; }
  const std::optional<SessionError>& damage() const override { return no_damage_; }

  static constexpr std::size_t kAnswerBytes = 4096;

 private:
  std::uint64_t exchanges_;
  std::shared_ptr<HandedOut> counts_;
  std::uint64_t position_ = 0;
  std::optional<SessionError> no_damage_;
};

// Closing a session the client left early must not read the rest of it (under
// the port's lock) to count what was unused: the close reads a bounded
// amount, and the report still says what was left and that there is more.
TEST(ReplayEnd, ClosingEarlyReadsABoundedAmountToReportWhatWasUnused) {
  static constexpr std::uint64_t kExchanges = 20000;  // 80 MiB of answers
  for (const char* keys : {"timing=none", "timing=none,unused=error"}) {
    SCOPED_TRACE(keys);
    auto counts = std::make_shared<HandedOut>();
    auto port = detail::open_replay_session(
        config_from(keys), [counts]() -> std::unique_ptr<detail::RecordSource> {
          return std::make_unique<LongSessionSource>(kExchanges, counts);
        });
    port->set_timeout(test::kEventDeadline);
    port->write_all("Q\n");
    EXPECT_EQ(port->read_exactly(LongSessionSource::kAnswerBytes).size(),
              LongSessionSource::kAnswerBytes);
    const std::uint64_t before_close = counts->bytes;
    std::string report;
    testing::internal::CaptureStderr();
    try {
      port->close();
    } catch (const ReplayMismatch& mismatch) {
      report = mismatch.what();
    }
    const std::string warning = testing::internal::GetCapturedStderr();
    if (report.empty()) report = warning;
    EXPECT_FALSE(port->is_open());
    EXPECT_FALSE(report.empty());
    EXPECT_EQ(std::string(keys).find("unused=error") != std::string::npos,
              warning.empty())
        << "unused=error raises, unused=warn warns";
    const std::uint64_t read_at_close = counts->bytes - before_close;
    EXPECT_LT(read_at_close, 8u << 20) << "bytes read to close the port";
    EXPECT_NE(report.find("at least"), std::string::npos) << report;
    EXPECT_NE(report.find("recorded rx bytes"), std::string::npos) << report;
    EXPECT_NE(report.find("were never read"), std::string::npos) << report;
    EXPECT_NE(report.find("recorded tx bytes were never written"), std::string::npos)
        << report;
  }
}

// Under the bound the count stays exact.
TEST(ReplayEnd, UnusedReportCountsExactlyUnderTheBound) {
  auto port = replay(hello_session(), "timing=none,unused=error");
  EXPECT_EQ(port->read_line(), "HELLO\n");
  port->write_all("PING\n");
  try {
    port->close();
    FAIL() << "unused data not reported";
  } catch (const ReplayMismatch& mismatch) {
    const std::string report = mismatch.what();
    EXPECT_NE(report.find(": 14 recorded rx bytes (3 records) were never read; "
                          "5 recorded tx bytes were never written"),
              std::string::npos)
        << report;
    EXPECT_EQ(report.find("at least"), std::string::npos) << report;
  }
}

// An empty datagram a client never read or wrote is a record unused like any
// other (DESIGN.md section 23).
TEST(ReplayEnd, UnusedEmptyDatagramsAreReported) {
  auto port = replay({tx(0, "Q"), rx(1, "A"), tx(2, ""), rx(3, "")},
                     "timing=none,unused=error", /*datagrams=*/true);
  port->write("Q");
  EXPECT_EQ(read_some(*port), "A");
  try {
    port->close();
    FAIL() << "the unused empty datagrams were not reported";
  } catch (const ReplayMismatch& mismatch) {
    const std::string report = mismatch.what();
    EXPECT_NE(report.find(": 0 recorded rx bytes (1 record) were never read; "
                          "0 recorded tx bytes (1 datagram) were never written"),
              std::string::npos)
        << report;
  }
}

// The write cursor's source is not read at close: what the client never
// wrote is counted from where the read cursor got to, exactly, even after a
// long stream the client read in full.
TEST(ReplayEnd, UnwrittenTxAfterALongStreamIsCountedExactly) {
  std::vector<Record> session = {tx(0, "Q")};
  for (int i = 0; i < 1000; ++i) session.push_back(rx(ms(1) + i, std::string(4096, 'r')));
  session.push_back(tx(ms(2000), "BYE"));
  session.push_back(rx(ms(2001), "ok"));
  auto port = replay(session, "timing=none,unused=error");
  port->write("Q");
  EXPECT_EQ(port->read_exactly(1000 * 4096).size(), 1000u * 4096);
  try {
    port->close();
    FAIL() << "unused data not reported";
  } catch (const ReplayMismatch& mismatch) {
    const std::string report = mismatch.what();
    EXPECT_NE(report.find(": 2 recorded rx bytes (1 record) were never read; "
                          "3 recorded tx bytes were never written"),
              std::string::npos)
        << report;
    EXPECT_EQ(report.find("at least"), std::string::npos) << report;
  }
}

// A client that wrote everything and read little: the write cursor is far
// ahead of the read cursor, and none of the tx counts as unused.
TEST(ReplayEnd, WriteCursorAheadOfTheReadCursorLeavesNoTxUnused) {
  std::vector<Record> session;
  std::string all_requests;
  for (std::uint64_t i = 0; i < 2000; ++i) {
    session.push_back(tx(ms(2 * i), "Q\n"));
    session.push_back(rx(ms(2 * i + 1), std::string(4096, 'a')));
    all_requests += "Q\n";
  }
  auto port = replay(session, "timing=none,unused=error");
  port->write_all(all_requests);
  try {
    port->close();
    FAIL() << "unused data not reported";
  } catch (const ReplayMismatch& mismatch) {
    const std::string report = mismatch.what();
    EXPECT_NE(report.find("recorded rx bytes"), std::string::npos) << report;
    EXPECT_EQ(report.find("tx bytes"), std::string::npos) << report;
  }
}

// --- request mode --------------------------------------------------------------------

std::vector<Record> command_session() {
  return {rx(0, "GREET\n"),   tx(ms(10), "VV\n"), rx(ms(11), "version 1\n"),
          tx(ms(20), "PP\n"), rx(ms(21), "params\n"),
          tx(ms(30), "MD\n"), rx(ms(31), "scan 1\n"), rx(ms(41), "scan 2\n"),
          tx(ms(50), "VV\n"), rx(ms(51), "version 2\n")};
}

TEST(ReplayRequest, ServesExchangesInTheClientsOrderAndSplits) {
  auto port = replay(command_session(), "timing=none,match=request");
  EXPECT_EQ(port->read_line(), "GREET\n");
  port->write("P");
  port->write("P\nM");
  EXPECT_EQ(port->read_line(), "params\n");
  port->write("D\n");
  // Unprompted rx (the second scan) belongs to the exchange before it.
  EXPECT_EQ(port->read_exactly(14), "scan 1\nscan 2\n");
  port->write("VV\nVV\n");
  EXPECT_EQ(port->read_exactly(20), "version 1\nversion 2\n");
}

TEST(ReplayRequest, UnmatchedBytesAreAMismatchNamingTheClosestRequests) {
  auto port = replay(command_session(), "timing=none,match=request");
  port->write("P");
  try {
    port->write("X\n");
    FAIL() << "unmatched request accepted";
  } catch (const ReplayMismatch& mismatch) {
    const std::string report = mismatch.what();
    EXPECT_NE(report.find("closest unused requests"), std::string::npos) << report;
    EXPECT_NE(report.find("|PP.|"), std::string::npos) << report;
    EXPECT_EQ(mismatch.exchange(), 1);
    EXPECT_EQ(mismatch.tx_offset(), 1u);
  }
  // The client can go on after the mismatch.
  port->write("PP\n");
  EXPECT_EQ(port->read_exactly(6, 0s), "GREET\n");
  EXPECT_EQ(port->read_line(), "params\n");
}

TEST(ReplayRequest, UnmatchedSilentSwallowsBytesLikeADeviceThatIgnoresThem) {
  auto port = replay(command_session(), "timing=none,match=request,unmatched=silent");
  port->read_line();
  port->write("garbage\nPP\n");
  EXPECT_EQ(port->read_line(), "params\n");
  EXPECT_EQ(port->available(), 0u);
}

TEST(ReplayRequest, UsedUpExchangeIsAMismatchWithoutRepeat) {
  auto port = replay(command_session(), "timing=none,match=request");
  port->write("PP\n");
  EXPECT_THROW(port->write("PP\n"), ReplayMismatch);
}

TEST(ReplayRequest, RepeatLastServesTheLastUseAgain) {
  auto port = replay(command_session(), "timing=none,match=request,repeat=last");
  port->read_line();
  port->write("VV\nVV\nVV\n");
  EXPECT_EQ(port->read_exactly(30), "version 1\nversion 2\nversion 2\n");
}

TEST(ReplayRequest, RepeatCycleRestartsFromTheFirstUse) {
  auto port = replay(command_session(), "timing=none,match=request,repeat=cycle");
  port->read_line();
  port->write("VV\nVV\nVV\nVV\n");
  EXPECT_EQ(port->read_exactly(40),
            "version 1\nversion 2\nversion 1\nversion 2\n");
}

TEST(ReplayRequest, UnusedExchangesAreReportedAtClose) {
  auto port = replay(command_session(), "timing=none,match=request,unused=error");
  port->read_line();
  port->write("VV\n");
  port->read_line();
  try {
    port->close();
    FAIL() << "unused exchanges not reported";
  } catch (const ReplayMismatch& mismatch) {
    EXPECT_NE(std::string(mismatch.what()).find("3 of 4 recorded exchanges"),
              std::string::npos)
        << mismatch.what();
  }
}

// --- timing --------------------------------------------------------------------------

TEST(ReplayTiming, SessionTimingReleasesAtRecordedTimeWithoutWaitingForWrites) {
  const auto opened = std::chrono::steady_clock::now();
  auto port = replay({tx(0, "Q"), rx(ms(150), "A")}, "timing=session");
  EXPECT_EQ(port->available(), 0u);
  ASSERT_TRUE(port->wait_readable(5s));  // no write: time alone decides
  EXPECT_GE(std::chrono::steady_clock::now() - opened, 140ms);
  EXPECT_EQ(read_some(*port), "A");
}

TEST(ReplayTiming, SpeedScalesTheSession) {
  if (under_thread_sanitizer()) {
    GTEST_SKIP() << "upper time bounds are not meaningful under ThreadSanitizer";
  }
  const auto opened = std::chrono::steady_clock::now();
  auto port = replay({rx(ms(400), "A")}, "timing=session,speed=4");
  ASSERT_TRUE(port->wait_readable(5s));
  const auto waited = std::chrono::steady_clock::now() - opened;
  EXPECT_GE(waited, 90ms);
  EXPECT_LT(waited, 390ms);
}

TEST(ReplayTiming, CausalTimingCountsFromTheClientsWrite) {
  auto port = replay({tx(0, "Q"), rx(ms(100), "A")}, "timing=causal");
  // The client is slow to ask: nothing is released meanwhile.
  EXPECT_FALSE(port->wait_readable(200ms));
  const auto asked = std::chrono::steady_clock::now();
  port->write("Q");
  EXPECT_EQ(port->available(), 0u);
  EXPECT_EQ(read_some(*port, 10, 5s), "A");
  EXPECT_GE(std::chrono::steady_clock::now() - asked, 90ms);
}

// flexiport keyed replay to wall time only: a client slower than the
// recording got answers before asking, and fell out of step for the rest of
// the session. Causal timing shifts the rest of the session instead.
TEST(ReplayTiming, WallTimeOnlyReplayBreakingUnderASlowClient) {
  const std::vector<Record> session = {tx(0, "A"), rx(ms(20), "a"),
                                       tx(ms(40), "B"), rx(ms(60), "b")};
  auto causal = replay(session, "timing=causal");
  auto wall = replay(session, "timing=session");
  // The client stalls far longer than the whole recording before it starts.
  EXPECT_FALSE(causal->wait_readable(300ms));
  // Wall time alone hands out answers nobody asked for yet...
  EXPECT_EQ(wall->available(), 2u);
  // ...causal timing shifts the rest of the session instead.
  EXPECT_EQ(causal->available(), 0u);
  const auto asked = std::chrono::steady_clock::now();
  causal->write("A");
  EXPECT_EQ(causal->available(), 0u);
  EXPECT_EQ(read_some(*causal, 10, 5s), "a");
  EXPECT_GE(std::chrono::steady_clock::now() - asked, 15ms);
  causal->write("B");
  EXPECT_EQ(causal->available(), 0u);
  EXPECT_EQ(read_some(*causal, 10, 5s), "b");
}

TEST(ReplayTiming, CheckTimingRejectsAWriteFarTooEarly) {
  auto port = replay({tx(ms(500), "A")}, "timing=session,check=timing,tolerance=50");
  try {
    port->write("A");
    FAIL() << "early write accepted";
  } catch (const ReplayMismatch& mismatch) {
    EXPECT_NE(std::string(mismatch.what()).find("early"), std::string::npos)
        << mismatch.what();
  }
}

// A timing mismatch shows what the client wrote as actual, against the
// recorded bytes as expected (the data check comes after the timing check,
// so the two may differ).
TEST(ReplayTiming, TimingMismatchReportShowsTheClientsBytesAsActual) {
  auto port = replay({tx(ms(500), "AB")}, "timing=session,check=timing,tolerance=50");
  try {
    port->write("XY");
    FAIL() << "early write accepted";
  } catch (const ReplayMismatch& mismatch) {
    const std::string report = mismatch.what();
    EXPECT_NE(report.find("too early"), std::string::npos) << report;
    EXPECT_NE(report.find("  expected: 41 42  |AB|\n"), std::string::npos) << report;
    EXPECT_NE(report.find("  actual:   58 59  |XY|\n"), std::string::npos) << report;
  }
}

TEST(ReplayTiming, CheckTimingRejectsAWriteFarTooLate) {
  auto port = replay({tx(0, "A"), tx(ms(10), "B")},
                     "timing=causal,check=timing,tolerance=50");
  port->write("A");
  EXPECT_FALSE(port->wait_readable(200ms));
  try {
    port->write("B");
    FAIL() << "late write accepted";
  } catch (const ReplayMismatch& mismatch) {
    EXPECT_NE(std::string(mismatch.what()).find("late"), std::string::npos)
        << mismatch.what();
  }
}

TEST(ReplayTiming, CheckTimingAcceptsWritesWithinTolerance) {
  if (under_thread_sanitizer()) {
    GTEST_SKIP() << "upper time bounds are not meaningful under ThreadSanitizer";
  }
  auto port = replay({tx(0, "A"), rx(ms(1), "a"), tx(ms(2), "B")},
                     "timing=causal,check=timing,tolerance=2000");
  port->write("A");
  EXPECT_EQ(read_some(*port), "a");
  EXPECT_NO_THROW(port->write("B"));
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

// --- the pollable handle and threads ----------------------------------------------------

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

// The readiness pipe is made and closed through the system-call seam.
TEST(ReplayHandle, ReadinessPipeGoesThroughTheSystemCallSeam) {
  {
    detail::sys::ScopedOverride seam;
    seam->pipe = [](int*) {
      errno = EMFILE;
      return -1;
    };
    try {
      replay(hello_session());
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
  ASSERT_EQ(made.size(), 2u);
  EXPECT_EQ(port->native_handle(), made[0]);
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

// --- flexiport's replay defects -------------------------------------------------------

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

// flexiport's BytesAvailable looped forever once recorded data fell due.
TEST(ReplayFlexiportDefects, BytesAvailableLoopingOnceDataIsDue) {
  auto port = replay({rx(ms(30), "due")}, "timing=session");
  ASSERT_TRUE(port->wait_readable(5s));
  auto answer = std::async(std::launch::async, [&] { return port->available(); });
  ASSERT_EQ(answer.wait_for(test::kEventDeadline), std::future_status::ready);
  EXPECT_EQ(answer.get(), 3u);
}

// flexiport could not replay a session without writes (a GPS, say).
TEST(ReplayFlexiportDefects, SessionWithNoWrites) {
  for (const char* keys : {"timing=none", "timing=causal", "timing=session,speed=10"}) {
    auto port = replay({rx(0, "$GPGGA,1\r\n"), rx(ms(20), "$GPGGA,2\r\n")}, keys);
    EXPECT_EQ(port->read_line(), "$GPGGA,1\r\n") << keys;
    EXPECT_EQ(port->read_line(), "$GPGGA,2\r\n") << keys;
  }
}

TEST(ReplayFlexiportDefects, SessionWithNoReads) {
  auto port = replay({tx(0, "cmd1\n"), tx(ms(10), "cmd2\n")}, "timing=causal");
  port->write_all("cmd1\ncmd2\n");
  EXPECT_THROW(port->write("more"), ReplayMismatch);
  EXPECT_EQ(read_some(*port, 10, 20ms), "");
}

// --- more modes -------------------------------------------------------------------------

TEST(ReplayRequest, DatagramRequestsMatchWholeDatagrams) {
  auto port = replay({tx(0, "GET a"), rx(1, "A"), tx(2, "GET b"), rx(3, "B")},
                     "timing=none,match=request", /*datagrams=*/true);
  port->write("GET b");
  EXPECT_EQ(read_some(*port), "B");
  EXPECT_THROW(port->write("GET"), ReplayMismatch);  // not a whole request
  port->write("GET a");
  EXPECT_EQ(read_some(*port), "A");
}

TEST(ReplayRequest, CausalTimingCountsFromTheMatch) {
  auto port = replay({tx(0, "Q"), rx(ms(60), "A")}, "timing=causal,match=request");
  EXPECT_FALSE(port->wait_readable(100ms));  // nothing asked, nothing released
  const auto asked = std::chrono::steady_clock::now();
  port->write("Q");
  EXPECT_EQ(port->available(), 0u);
  EXPECT_EQ(read_some(*port, 10, 5s), "A");
  EXPECT_GE(std::chrono::steady_clock::now() - asked, 50ms);
}

TEST(ReplayRequest, CheckTimingRejectsARequestFarTooEarly) {
  auto port = replay({tx(ms(500), "Q"), rx(ms(501), "A")},
                     "timing=session,match=request,check=timing,tolerance=50");
  EXPECT_THROW(port->write("Q"), ReplayMismatch);
}

TEST(ReplayRequest, TimingMismatchReportShowsTheRequestAndTheClientsBytes) {
  auto port = replay({tx(ms(500), "Q1\n"), rx(ms(501), "A")},
                     "timing=session,match=request,check=timing,tolerance=50");
  port->write("Q");
  try {
    port->write("1\n");
    FAIL() << "early request accepted";
  } catch (const ReplayMismatch& mismatch) {
    const std::string report = mismatch.what();
    EXPECT_NE(report.find("too early"), std::string::npos) << report;
    EXPECT_NE(report.find("  expected: 51 31 0a  |Q1.|\n"), std::string::npos)
        << report;
    EXPECT_NE(report.find("  actual:   51 31 0a  |Q1.|\n"), std::string::npos)
        << report;
  }
}

TEST(ReplayTiming, CausalSpeedScalesTheGaps) {
  auto port = replay({tx(0, "Q"), rx(ms(2000), "A")}, "timing=causal,speed=20");
  const auto asked = std::chrono::steady_clock::now();
  port->write("Q");
  EXPECT_EQ(read_some(*port, 10, 5s), "A");  // 100 ms, not 2 s
  EXPECT_GE(std::chrono::steady_clock::now() - asked, 90ms);
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

// --- recorded events ------------------------------------------------------------------

std::vector<Record> baud_session() {
  return {{0, RecordKind::settings,
           "{\"baud\":115200,\"databits\":8,\"stopbits\":1,\"parity\":\"none\",\"flow\":\"none\"}"},
          {1, RecordKind::modem_lines, "{\"dtr\":true}"},
          tx(2, "Q"),
          rx(3, "A")};
}

TEST(ReplayEvents, CheckTimingRequiresTheRecordedSettingsInOrder) {
  const char* keys = "timing=causal,check=timing,tolerance=5000";
  {
    auto port = replay(baud_session(), keys);
    port->set_baud(115200);  // compared with what the recording holds
    port->set_dtr(true);
    port->write("Q");
    EXPECT_EQ(read_some(*port), "A");
  }
  {
    auto port = replay(baud_session(), keys);
    try {
      port->set_baud(9600);
      FAIL() << "wrong baud accepted";
    } catch (const ReplayMismatch& mismatch) {
      EXPECT_NE(std::string(mismatch.what()).find("\"baud\":115200"), std::string::npos)
          << mismatch.what();
    }
  }
  {
    auto port = replay(baud_session(), keys);
    try {
      port->write("Q");
      FAIL() << "a write skipping the recorded settings was accepted";
    } catch (const ReplayMismatch& mismatch) {
      EXPECT_NE(std::string(mismatch.what()).find("did not make it"), std::string::npos)
          << mismatch.what();
    }
  }
  {
    auto port = replay(baud_session(), keys);
    SerialSettings settings;
    settings.baud = 115200;
    port->configure(settings);
    EXPECT_THROW(port->send_break(250ms), ReplayMismatch);  // dtr was recorded
  }
}

TEST(ReplayEvents, EventMismatchReportNamesBothEvents) {
  auto port = replay(baud_session(), "timing=causal,check=timing,tolerance=5000");
  try {
    port->set_baud(9600);
    FAIL() << "wrong baud accepted";
  } catch (const ReplayMismatch& mismatch) {
    EXPECT_NE(std::string(mismatch.what())
                  .find("the client made a settings {\"baud\":9600} event; "
                        "the recording has settings {\"baud\":115200,"),
              std::string::npos)
        << mismatch.what();
  }
}

TEST(ReplayEvents, CheckDataDoesNotCheckEvents) {
  auto port = replay(baud_session(), "timing=none,check=data");
  port->set_baud(9600);
  port->set_rts(false);
  port->send_break(10ms);
  port->write("Q");
  EXPECT_EQ(read_some(*port), "A");
  EXPECT_EQ(port->serial_settings().baud, 9600u);
}
