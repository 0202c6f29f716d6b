// src/replay/request.cpp: match=request: exchanges served in the client's
// order, unmatched bytes, repeat, the unused report, timing counted from the
// match; the gap rule of DESIGN.md section 13 (a complete request
// that is also a proper prefix of a longer request recorded earlier waits up
// to `gap` ms of quiet for more bytes), checked on the engine with a clock
// the test drives, over random splits and pauses; the index that makes
// matching linear; and responses read from the session when served.
#include <gtest/gtest.h>

#include "support/port_test_support.hpp"
#include "support/replay_support.hpp"

#include <chrono>
#include <random>
#include <string>
#include <vector>

#include "replay/replay_config.hpp"
#include "replay/replay_engine.hpp"
#include "replay/replay_port.hpp"
#include "replay/request.hpp"
#include "session/record_source.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/options.hpp"
#include "wiretape/port.hpp"
#include "wiretape/session.hpp"

using namespace wiretape;
using namespace std::chrono_literals;
using namespace wiretape::test::replay_support;
using detail::ReplayConfig;
using detail::ReplayEngine;
using detail::ReplayTime;

namespace {


// The keys of a match=request replay.
ReplayConfig request_config_from(const std::string& keys) {
  Options options = Options::parse("file=synthetic.wtape,match=request," + keys);
  return detail::take_replay_config(options);
}

struct Exchange {
  std::vector<std::string> request_writes;  // as the recording split them
  std::string response;
};

std::vector<Record> session_of(const std::vector<Exchange>& exchanges) {
  std::vector<Record> records;
  std::uint64_t t = 0;
  for (const Exchange& exchange : exchanges) {
    for (const std::string& write : exchange.request_writes) {
      records.push_back({t += ms(1), RecordKind::tx, write});
    }
    records.push_back({t += ms(1), RecordKind::rx, exchange.response});
  }
  return records;
}

// An slcan session: `C\r` and `O\r` written with no answer between them make
// one exchange whose request begins with a complete later request, `C\r`.
std::vector<Exchange> slcan_exchanges() {
  return {{{"C\r", "O\r"}, "[close+open]"},
          {{"C\r"}, "[close]"},
          {{"O\r"}, "[open]"},
          {{"t1230\r"}, "[frame]"},
          {{"V\r"}, "[version]"},
          {{"V\rv\r"}, "[both versions]"},  // recorded later: no wait
          {{"S6\r", "O\r"}, "[speed+open]"},
          {{"S6\r"}, "[speed]"}};
}

std::string client_stream(const std::vector<Exchange>& exchanges) {
  std::string stream;
  for (const Exchange& exchange : exchanges) {
    for (const std::string& write : exchange.request_writes) stream += write;
  }
  return stream;
}

// Drives an engine with a clock of the test's.
class Drive {
 public:
  Drive(const std::vector<Exchange>& exchanges, const std::string& keys)
      : start_(ReplayTime{} + 1h),
        now_(start_),
        engine_(request_config_from(keys), detail::vector_source_factory(session_of(exchanges)),
                start_) {}

  void write(const std::string& bytes) { engine_.write(bytes.data(), bytes.size(), now_); }
  void pass(std::chrono::nanoseconds time) { now_ += time; }
  std::string read_all() {
    std::string out;
    char buffer[256];
    for (;;) {
      const std::size_t n = engine_.read(buffer, sizeof buffer, now_);
      if (n == 0) return out;
      out.append(buffer, n);
    }
  }
  ReplayEngine::Outlook outlook() { return engine_.outlook(now_); }
  ReplayTime now() const { return now_; }

 private:
  ReplayTime start_;
  ReplayTime now_;
  ReplayEngine engine_;
};

}  // namespace

TEST(RequestGap, ACompleteShorterRequestWaitsForTheLongerOneRecordedEarlier) {
  Drive drive(slcan_exchanges(), "timing=none,gap=50,unused=ignore");
  drive.write("C\r");
  EXPECT_EQ(drive.read_all(), "");
  const ReplayEngine::Outlook waiting = drive.outlook();
  EXPECT_EQ(waiting.state, ReplayEngine::ReadState::waiting);
  ASSERT_TRUE(waiting.wake.has_value());
  EXPECT_EQ(*waiting.wake, drive.now() + 50ms);
  drive.pass(10ms);
  drive.write("O\r");
  EXPECT_EQ(drive.read_all(), "[close+open]");
}

TEST(RequestGap, AfterGapOfQuietTheShorterRequestIsTaken) {
  Drive drive(slcan_exchanges(), "timing=none,gap=50,unused=ignore");
  drive.write("C\r");
  drive.pass(49ms);
  EXPECT_EQ(drive.read_all(), "");
  drive.pass(1ms);
  EXPECT_EQ(drive.read_all(), "[close]");
  drive.write("O\r");
  EXPECT_EQ(drive.read_all(), "[open]");
}

TEST(RequestGap, BytesThatCannotExtendTheLongerRequestEndTheWaitAtOnce) {
  Drive drive(slcan_exchanges(), "timing=none,gap=50,unused=ignore");
  drive.write("C\rt1230\r");
  EXPECT_EQ(drive.read_all(), "[close][frame]");
}

TEST(RequestGap, ALongerRequestRecordedLaterIsNoReasonToWait) {
  Drive drive(slcan_exchanges(), "timing=none,gap=50,unused=ignore");
  drive.write("V\r");
  EXPECT_EQ(drive.read_all(), "[version]");
  EXPECT_FALSE(drive.outlook().wake.has_value());
}

TEST(RequestGap, GapZeroTakesTheShorterRequestAtOnce) {
  Drive drive(slcan_exchanges(), "timing=none,gap=0,unused=ignore");
  drive.write("C\r");
  EXPECT_EQ(drive.read_all(), "[close]");
}

TEST(RequestGap, BytesLeftAfterTheWaitThatMatchNothingAreAMismatchAtTheNextWrite) {
  Drive drive(slcan_exchanges(), "timing=none,gap=50,unused=ignore");
  drive.write("C\rO");  // O could still become O\r
  drive.pass(60ms);
  EXPECT_EQ(drive.read_all(), "[close]");
  EXPECT_THROW(drive.write("x"), ReplayMismatch);
}

TEST(RequestGap, GapNeedsMatchRequestAndIsInMilliseconds) {
  EXPECT_EQ(request_config_from("gap=7").gap, 7ms);
  EXPECT_EQ(request_config_from("").gap, 50ms);
  try {
    open_port("type=replay,file=x.wtape,gap=10");
    FAIL() << "gap without match=request was accepted";
  } catch (const OptionError& error) {
    EXPECT_EQ(error.key(), "gap");
    EXPECT_NE(std::string(error.what()).find("match=request"), std::string::npos);
  }
}

// Property: however the client's bytes are split into writes, and whatever
// pauses shorter than gap come between them, the recorded run replays with
// the recorded responses in order.
TEST(RequestGapProperty, RandomSplitsAndShortPausesServeTheRecordedExchanges) {
  const std::vector<Exchange> exchanges = slcan_exchanges();
  const std::string stream = client_stream(exchanges);
  std::string expected;
  for (const Exchange& exchange : exchanges) expected += exchange.response;
  std::mt19937 random(20261124);
  for (int round = 0; round < 500; ++round) {
    Drive drive(exchanges, "timing=none,gap=50");
    std::string served;
    std::size_t at = 0;
    while (at < stream.size()) {
      const std::size_t size = std::min<std::size_t>(
          stream.size() - at, std::uniform_int_distribution<std::size_t>(1, 7)(random));
      drive.write(stream.substr(at, size));
      at += size;
      // A pause below gap, read through or not.
      drive.pass(std::chrono::milliseconds(
          std::uniform_int_distribution<int>(0, 49)(random)));
      if (random() % 2 == 0) served += drive.read_all();
    }
    drive.pass(50ms);
    served += drive.read_all();
    ASSERT_EQ(served, expected) << "round " << round;
  }
}

// Property: pauses of gap or more after each whole request (the client waits
// for its answer) change nothing either; the shorter request is then taken
// only where the client really sent it alone.
TEST(RequestGapProperty, ClientsWaitingForEachAnswerGetTheRecordedOnes) {
  const std::vector<Exchange> exchanges = slcan_exchanges();
  std::mt19937 random(7);
  for (int round = 0; round < 200; ++round) {
    Drive drive(exchanges, "timing=none,gap=50");
    for (const Exchange& exchange : exchanges) {
      std::string request;
      for (const std::string& write : exchange.request_writes) request += write;
      std::size_t at = 0;
      while (at < request.size()) {
        const std::size_t size = std::min<std::size_t>(
            request.size() - at, std::uniform_int_distribution<std::size_t>(1, 3)(random));
        drive.write(request.substr(at, size));
        at += size;
        drive.pass(std::chrono::milliseconds(
            std::uniform_int_distribution<int>(0, 49)(random)));
      }
      drive.pass(std::chrono::milliseconds(
          std::uniform_int_distribution<int>(50, 500)(random)));
      ASSERT_EQ(drive.read_all(), exchange.response) << "round " << round;
    }
  }
}

// Through the port: a blocked read is woken when the gap ends.
TEST(RequestGapPort, ABlockedReadGetsTheShorterRequestsAnswerAfterTheGap) {
  ReplayConfig config = request_config_from("timing=none,gap=20,unused=ignore");
  auto port = detail::open_replay_session(
      config, detail::vector_source_factory(session_of(slcan_exchanges())));
  port->write_all("C\r");
  std::string answer(7, '\0');
  ASSERT_EQ(port->read(answer.data(), answer.size(), test::kEventDeadline), 7u);
  EXPECT_EQ(answer, "[close]");
}

// The index: many distinct requests match in time linear in the session.
TEST(RequestIndex, ManyExchangesInAnyOrderAreServed) {
  std::vector<Exchange> exchanges;
  for (int i = 0; i < 20000; ++i) {
    exchanges.push_back({{"GET " + std::to_string(i) + "\n"}, "V" + std::to_string(i) + "\n"});
  }
  Drive drive(exchanges, "timing=none");
  for (int i = 19999; i >= 0; --i) {
    drive.write("GET " + std::to_string(i) + "\n");
    ASSERT_EQ(drive.read_all(), "V" + std::to_string(i) + "\n");
  }
}

// Responses past the kept bytes are read from the session when served, in
// any order, also across a rewind.
TEST(RequestIndex, ResponsesPastTheKeptBytesAreReadFromTheSession) {
  std::vector<Exchange> exchanges;
  const std::size_t response_size = 64 * 1024;
  const int count = static_cast<int>(2 * detail::kKeptResponseBytes / response_size);
  for (int i = 0; i < count; ++i) {
    exchanges.push_back({{"R" + std::to_string(i) + "\n"},
                         std::string(response_size - 1, static_cast<char>('a' + i % 26)) + "\n"});
  }
  Drive drive(exchanges, "timing=none");
  std::mt19937 random(3);
  std::vector<int> order(static_cast<std::size_t>(count));
  for (int i = 0; i < count; ++i) order[static_cast<std::size_t>(i)] = i;
  std::shuffle(order.begin(), order.end(), random);
  for (const int i : order) {
    drive.write("R" + std::to_string(i) + "\n");
    ASSERT_EQ(drive.read_all(), exchanges[static_cast<std::size_t>(i)].response) << i;
  }
}

// DESIGN.md section 12: in match=request connection order is free. The k-th
// connection gets the k-th recorded connection's greeting (the last one's
// past them) and matches every recorded connection's exchanges, its own
// first; a greeting recorded for another connection is not served.
namespace {

Record client_event(std::uint64_t t, RecordKind kind, const std::string& peer) {
  return {t, kind, "{\"peer\":\"" + peer + "\",\"role\":\"control\"}"};
}

std::vector<Record> two_connections() {
  return {{0, RecordKind::open, "{}"},
          {ms(1), RecordKind::rx, "said to nobody\n"},
          client_event(ms(2), RecordKind::client_connect, "a"),
          {ms(3), RecordKind::rx, "hello a\n"},
          {ms(4), RecordKind::tx, "A1\n"},
          {ms(5), RecordKind::rx, "a1\n"},
          client_event(ms(6), RecordKind::client_disconnect, "a"),
          {ms(7), RecordKind::rx, "between\n"},
          client_event(ms(8), RecordKind::client_connect, "b"),
          {ms(9), RecordKind::rx, "hello b\n"},
          {ms(10), RecordKind::tx, "B1\n"},
          {ms(11), RecordKind::rx, "b1\n"},
          {ms(12), RecordKind::tx, "A1\n"},
          {ms(13), RecordKind::rx, "a1 again\n"},
          client_event(ms(14), RecordKind::client_disconnect, "b")};
}

std::unique_ptr<Port> replay_of(const std::vector<Record>& records) {
  Options options = Options::parse("file=synthetic.wtape,match=request,timing=none,gap=0");
  auto port = detail::open_replay_session(detail::take_replay_config(options),
                                          detail::vector_source_factory(records));
  port->set_timeout(test::kEventDeadline);
  return port;
}

std::string read_now(Port& port) {
  std::string buffer(256, '\0');
  buffer.resize(port.read(buffer.data(), buffer.size(), std::chrono::nanoseconds(0)));
  return buffer;
}

}  // namespace

TEST(RequestConnectionOrder, TheFirstConnectionIsServedTheSecondRecordedConnectionsRequests) {
  auto port = replay_of(two_connections());
  ASSERT_TRUE(detail::replay_begin_client_session(*port));
  EXPECT_EQ(port->read_exactly(8), "hello a\n");
  port->write_all("B1\n");  // recorded in connection b only
  EXPECT_EQ(port->read_exactly(3), "b1\n");
  EXPECT_EQ(read_now(*port), "");  // b's greeting and the rx between are nobody's
  detail::replay_await_client(*port);
  ASSERT_TRUE(detail::replay_begin_client_session(*port));
  EXPECT_EQ(port->read_exactly(8), "hello b\n");
  port->write_all("A1\n");  // its own exchange first
  EXPECT_EQ(port->read_exactly(9), "a1 again\n");
  port->write_all("A1\n");  // then connection a's
  EXPECT_EQ(port->read_exactly(3), "a1\n");
  port->close();
}

TEST(RequestConnectionOrder, ConnectionsPastTheRecordedOnesGetTheLastGreeting) {
  auto port = replay_of(two_connections());
  for (int k = 1; k <= 3; ++k) {
    ASSERT_TRUE(detail::replay_begin_client_session(*port)) << k;
    EXPECT_EQ(port->read_exactly(8), k == 1 ? "hello a\n" : "hello b\n") << k;
    port->write_all("A1\n");
    EXPECT_EQ(port->read_exactly(3).substr(0, 2), "a1") << k;
    detail::replay_await_client(*port);
  }
  port->close();
}

TEST(RequestConnectionOrder, TheUnusedReportCountsTheConnectionsOwnExchanges) {
  auto port = replay_of(two_connections());
  ASSERT_TRUE(detail::replay_begin_client_session(*port));
  EXPECT_EQ(port->read_exactly(8), "hello a\n");
  port->write_all("A1\n");
  EXPECT_EQ(port->read_exactly(3), "a1\n");
  ::testing::internal::CaptureStderr();
  port->close();
  EXPECT_EQ(::testing::internal::GetCapturedStderr(), "");
}

TEST(RequestConnectionOrder, AMonitorJoiningIsNoConnectionOfItsOwn) {
  std::vector<Record> records = two_connections();
  records.insert(records.begin() + 4,
                 {ms(3), RecordKind::client_connect, "{\"peer\":\"m\",\"role\":\"monitor\"}"});
  auto port = replay_of(records);
  ASSERT_TRUE(detail::replay_begin_client_session(*port));
  EXPECT_EQ(port->read_exactly(8), "hello a\n");
  port->write_all("A1\n");
  EXPECT_EQ(port->read_exactly(3), "a1\n");
  port->write_all("B1\n");
  EXPECT_EQ(port->read_exactly(3), "b1\n");
  EXPECT_EQ(read_now(*port), "");
  port->close();
}

// --- through a replay: serving, repeat, unused, timing ------------------------------------

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
