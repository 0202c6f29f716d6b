// Fault injection on replay (faults=, DESIGN.md section 14): the parser's
// grammar and errors, and what a client of a replaying port sees for each
// fault kind in each timing mode.
#include <gtest/gtest.h>

#include <chrono>
#include <string>
#include <vector>

#include "replay/faults.hpp"
#include "replay/replay_config.hpp"
#include "replay/replay_port.hpp"
#include "session/record_source.hpp"
#include "support/port_test_support.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/options.hpp"
#include "wiretape/port.hpp"

using namespace wiretape;
using namespace std::chrono_literals;
using detail::FaultKind;
using detail::FaultWhereKind;
using detail::parse_faults;

namespace {

constexpr std::uint64_t ms(std::uint64_t n) { return n * 1'000'000; }

// Three exchanges: Qn answered by Rn 1 ms later, 400 ms apart, so that
// under timing=session (time alone decides) one exchange's answer is over
// before the next is due.
std::vector<Record> three_exchanges() {
  return {{ms(0), RecordKind::tx, "Q0\n"},   {ms(1), RecordKind::rx, "R0-abcdef\n"},
          {ms(400), RecordKind::tx, "Q1\n"}, {ms(401), RecordKind::rx, "R1-ghijkl\n"},
          {ms(800), RecordKind::tx, "Q2\n"}, {ms(801), RecordKind::rx, "R2-mnopqr\n"}};
}

std::unique_ptr<Port> replay(const std::string& keys,
                             std::vector<Record> records = three_exchanges(),
                             bool datagrams = false) {
  Options options = Options::parse("file=synthetic.wtape," + keys);
  detail::ReplayConfig config = detail::take_replay_config(options);
  config.datagrams = datagrams;
  auto port = detail::open_replay_session(config, detail::vector_source_factory(std::move(records)));
  port->set_timeout(test::kEventDeadline);
  return port;
}

// What one exchange gives: every byte the device sends within `quiet` of the
// last one (or of the write).
std::string answer(Port& port, const std::string& request,
                   std::chrono::milliseconds quiet = 300ms) {
  port.write(request.data(), request.size());
  std::string received;
  char buffer[256];
  for (;;) {
    const std::size_t n = port.read(buffer, sizeof buffer, quiet);
    if (n == 0) return received;
    received.append(buffer, n);
  }
}

std::string flip_distance(const std::string& a, const std::string& b) {
  if (a.size() != b.size()) return "sizes differ";
  int bits = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    bits += __builtin_popcount(static_cast<unsigned char>(a[i] ^ b[i]));
  }
  return std::to_string(bits);
}

}  // namespace

// --- the grammar --------------------------------------------------------------------

TEST(FaultParser, ReadsEveryKindAndPlace) {
  const auto plan = parse_faults(
      "drop@exchange:3; corrupt:4@rx:100;garbage@t:1.5;truncate:2@every:2;duplicate@p:0.25;"
      "delay:50@exchange:0;stall:20@exchange:1;trickle@exchange:2;trickle:3@exchange:2;"
      "silence@exchange:4;disconnect@exchange:5;reconnect:100@exchange:6",
      7);
  ASSERT_EQ(plan.faults.size(), 12u);
  EXPECT_EQ(plan.seed, 7u);
  EXPECT_EQ(plan.faults[0].kind, FaultKind::drop);
  EXPECT_FALSE(plan.faults[0].amount);
  EXPECT_EQ(plan.faults[0].where, FaultWhereKind::exchange);
  EXPECT_EQ(plan.faults[0].where_number, 3u);
  EXPECT_EQ(plan.faults[1].kind_text, "corrupt:4");
  EXPECT_EQ(plan.faults[1].where, FaultWhereKind::rx);
  EXPECT_EQ(plan.faults[2].where, FaultWhereKind::time);
  EXPECT_DOUBLE_EQ(plan.faults[2].where_value, 1.5);
  EXPECT_EQ(plan.faults[3].where, FaultWhereKind::every);
  EXPECT_EQ(plan.faults[4].where, FaultWhereKind::probability);
  EXPECT_EQ(plan.faults[4].where_text, "p:0.25");
  EXPECT_EQ(plan.faults[11].kind, FaultKind::reconnect);
  EXPECT_EQ(*plan.faults[11].amount, 100u);
  EXPECT_TRUE(parse_faults("", 0).empty());
}

TEST(FaultParser, BadInputNamesTheKeyTheItemAndTheGrammar) {
  for (const char* bad :
       {"bogus@exchange:1", "drop", "drop@", "drop@exchange", "drop@exchange:x",
        "drop@when:1", "delay@exchange:1", "duplicate:2@exchange:1", "corrupt:0@exchange:1",
        "drop@every:0", "drop@p:1.5", "drop@t:-1", "stall:abc@exchange:1",
        "drop@exchange:1;silence", "garbage:2000000@exchange:0"}) {
    try {
      parse_faults(bad, 0);
      ADD_FAILURE() << bad << " was accepted";
    } catch (const OptionError& error) {
      EXPECT_EQ(error.key(), "faults") << bad;
      const std::string message = error.what();
      EXPECT_NE(message.find("KIND@WHERE"), std::string::npos) << message;
      EXPECT_NE(message.find("'"), std::string::npos) << message;
    }
  }
}

TEST(FaultParser, OptionsCheckFaultsAndSeedAtOpen) {
  EXPECT_THROW(open_port("type=replay,file=x.wtape,faults=nope@exchange:1"), OptionError);
  try {
    open_port("type=replay,file=x.wtape,seed=3");
    ADD_FAILURE() << "seed without faults was accepted";
  } catch (const OptionError& error) {
    EXPECT_EQ(error.key(), "seed");
  }
}

TEST(FaultParser, SplitMixIsTheReferenceGenerator) {
  // The first outputs of splitmix64 seeded with 0 (Vigna's reference).
  EXPECT_EQ(detail::splitmix64(0), 0xe220a8397b1dcdafULL);
  EXPECT_EQ(detail::splitmix64(0x9e3779b97f4a7c15ULL), 0x6e789e6aa1b965f4ULL);
}

// --- what the client sees, in every timing mode -----------------------------------

class FaultKinds : public ::testing::TestWithParam<std::string> {
 protected:
  std::unique_ptr<Port> faulty(const std::string& faults) {
    return replay("timing=" + GetParam() + ",faults=\"" + faults + "\",seed=5,unused=error");
  }
};

TEST_P(FaultKinds, CleanReplayAnswersEveryExchange) {
  auto port = faulty("");
  EXPECT_EQ(answer(*port, "Q0\n"), "R0-abcdef\n");
  EXPECT_EQ(answer(*port, "Q1\n"), "R1-ghijkl\n");
  EXPECT_EQ(answer(*port, "Q2\n"), "R2-mnopqr\n");
}

TEST_P(FaultKinds, DropLosesTheResponseAndTheNextExchangeGoesOn) {
  auto port = faulty("drop@exchange:1");
  EXPECT_EQ(answer(*port, "Q0\n"), "R0-abcdef\n");
  EXPECT_EQ(answer(*port, "Q1\n"), "");
  EXPECT_EQ(answer(*port, "Q2\n"), "R2-mnopqr\n");
  port->close();  // what the fault dropped is not unused (unused=error)
}

TEST_P(FaultKinds, DropNLosesNBytes) {
  auto port = faulty("drop:3@exchange:1");
  answer(*port, "Q0\n");
  EXPECT_EQ(answer(*port, "Q1\n").size(), 7u);
}

TEST_P(FaultKinds, CorruptFlipsBits) {
  auto port = faulty("corrupt:1@exchange:0");
  EXPECT_EQ(flip_distance(answer(*port, "Q0\n"), "R0-abcdef\n"), "1");
  auto twice = faulty("corrupt:3@exchange:0");
  const std::string got = answer(*twice, "Q0\n");
  EXPECT_NE(got, "R0-abcdef\n");
  EXPECT_EQ(got.size(), 10u);
}

TEST_P(FaultKinds, GarbageInsertsBytes) {
  auto port = faulty("garbage:5@exchange:2");
  answer(*port, "Q0\n");
  answer(*port, "Q1\n");
  EXPECT_EQ(answer(*port, "Q2\n").size(), 15u);
}

TEST_P(FaultKinds, TruncateCutsTheResponse) {
  auto port = faulty("truncate:3@exchange:0");
  EXPECT_EQ(answer(*port, "Q0\n"), "R0-");
  EXPECT_EQ(answer(*port, "Q1\n"), "R1-ghijkl\n");
}

TEST_P(FaultKinds, DuplicateSendsTheResponseTwice) {
  auto port = faulty("duplicate@exchange:1");
  answer(*port, "Q0\n");
  EXPECT_EQ(answer(*port, "Q1\n"), "R1-ghijkl\nR1-ghijkl\n");
}

TEST_P(FaultKinds, DelayIsARealWait) {
  auto port = faulty("delay:200@exchange:1");
  answer(*port, "Q0\n");
  const auto start = std::chrono::steady_clock::now();
  port->write("Q1\n", 3);
  EXPECT_EQ(port->available(), 0u);
  EXPECT_EQ(port->read_line(), "R1-ghijkl\n");
  EXPECT_GE(std::chrono::steady_clock::now() - start, 200ms);
}

TEST_P(FaultKinds, StallIsAGapInsideTheResponse) {
  auto port = faulty("stall:200@exchange:1");
  answer(*port, "Q0\n");
  port->write("Q1\n", 3);
  char buffer[64];
  const std::size_t head = port->read(buffer, sizeof buffer);
  EXPECT_EQ(std::string(buffer, head), "R1-gh");
  const auto start = std::chrono::steady_clock::now();
  EXPECT_EQ(port->read_line(), "ijkl\n");
  EXPECT_GE(std::chrono::steady_clock::now() - start, 150ms);
}

TEST_P(FaultKinds, TrickleSendsOneByteAtATime) {
  auto port = faulty("trickle:30@exchange:1");
  answer(*port, "Q0\n");
  port->write("Q1\n", 3);
  std::string got;
  int reads = 0;
  char buffer[64];
  while (got.size() < 10) {
    const std::size_t n = port->read(buffer, sizeof buffer);
    ASSERT_GT(n, 0u);
    got.append(buffer, n);
    ++reads;
  }
  EXPECT_EQ(got, "R1-ghijkl\n");
  // 30 ms apart: a client far slower than that still needs several reads.
  EXPECT_GE(reads, 4);
}

TEST_P(FaultKinds, SilenceStopsTheDeviceAndSwallowsWrites) {
  auto port = faulty("silence@exchange:1");
  EXPECT_EQ(answer(*port, "Q0\n"), "R0-abcdef\n");
  EXPECT_EQ(answer(*port, "Q1\n"), "");
  // Not a mismatch: the device no longer listens.
  EXPECT_EQ(answer(*port, "anything else\n"), "");
  port->close();
}

TEST_P(FaultKinds, DisconnectLosesTheDevice) {
  auto port = faulty("disconnect@exchange:1");
  answer(*port, "Q0\n");
  port->write("Q1\n", 3);
  char buffer[16];
  EXPECT_THROW(port->read(buffer, sizeof buffer), PortClosed);
  EXPECT_THROW(port->write("Q2\n", 3), PortClosed);
  EXPECT_THROW(port->read(buffer, sizeof buffer), PortClosed);
}

TEST_P(FaultKinds, ReconnectComesBack) {
  auto port = faulty("reconnect:150@exchange:1");
  answer(*port, "Q0\n");
  port->write("Q1\n", 3);
  char buffer[16];
  EXPECT_THROW(port->read(buffer, sizeof buffer), PortClosed);
  // Back after 150 ms: the next exchange is answered.
  const auto deadline = std::chrono::steady_clock::now() + test::kEventDeadline;
  for (;;) {
    try {
      port->write("Q2\n", 3);
      break;
    } catch (const PortClosed&) {
      ASSERT_LT(std::chrono::steady_clock::now(), deadline);
      port->wait_readable(10ms);  // a wait with a deadline, not a sleep
    }
  }
  EXPECT_EQ(port->read_line(), "R2-mnopqr\n");
}

TEST_P(FaultKinds, EveryAndProbabilityPickExchanges) {
  auto every = faulty("drop@every:2");
  EXPECT_EQ(answer(*every, "Q0\n"), "R0-abcdef\n");
  EXPECT_EQ(answer(*every, "Q1\n"), "");
  EXPECT_EQ(answer(*every, "Q2\n"), "R2-mnopqr\n");
  auto never = faulty("drop@p:0");
  EXPECT_EQ(answer(*never, "Q0\n"), "R0-abcdef\n");
  auto always = faulty("drop@p:1");
  EXPECT_EQ(answer(*always, "Q0\n"), "");
}

TEST_P(FaultKinds, RxOffsetAndTimePickRecords) {
  auto by_offset = faulty("truncate:1@rx:12");
  EXPECT_EQ(answer(*by_offset, "Q0\n"), "R0-abcdef\n");
  EXPECT_EQ(answer(*by_offset, "Q1\n"), "R");
  auto by_time = faulty("truncate:2@t:0.5");
  answer(*by_time, "Q0\n");
  EXPECT_EQ(answer(*by_time, "Q1\n"), "R1-ghijkl\n");
  EXPECT_EQ(answer(*by_time, "Q2\n"), "R2");
}

INSTANTIATE_TEST_SUITE_P(EveryTimingMode, FaultKinds,
                         ::testing::Values("none", "session", "causal"),
                         [](const auto& info) { return info.param; });

// --- seeds and datagrams -----------------------------------------------------------------

TEST(FaultSeeds, TheSameSeedGivesTheSameBytes) {
  const auto run = [](int seed) {
    auto port = replay("timing=none,faults=\"corrupt:4@exchange:0;garbage:6@exchange:1\",seed=" +
                       std::to_string(seed));
    std::string both = answer(*port, "Q0\n");
    return both + answer(*port, "Q1\n");
  };
  EXPECT_EQ(run(11), run(11));
  EXPECT_NE(run(11), run(12));
}

TEST(FaultDatagrams, DropLosesADatagramAndDuplicateRepeatsIt) {
  const std::vector<Record> records = {{ms(10), RecordKind::tx, "Q0"},
                                       {ms(20), RecordKind::rx, "A"},
                                       {ms(21), RecordKind::rx, "B"},
                                       {ms(30), RecordKind::tx, "Q1"},
                                       {ms(40), RecordKind::rx, "C"}};
  auto dropped = replay("timing=none,faults=drop:1@exchange:0", records, true);
  dropped->write("Q0", 2);
  char buffer[16];
  ASSERT_EQ(dropped->read(buffer, sizeof buffer), 1u);
  EXPECT_EQ(buffer[0], 'B');
  auto doubled = replay("timing=none,faults=duplicate@exchange:1", records, true);
  doubled->write("Q0", 2);
  doubled->read(buffer, sizeof buffer);
  doubled->read(buffer, sizeof buffer);
  doubled->write("Q1", 2);
  ASSERT_EQ(doubled->read(buffer, sizeof buffer), 1u);
  EXPECT_EQ(buffer[0], 'C');
  ASSERT_EQ(doubled->read(buffer, sizeof buffer), 1u);
  EXPECT_EQ(buffer[0], 'C');
}

// With a profile, exchanges are request frames: a request written in two
// parts is one exchange, however the recording split it.
TEST(FaultProfiles, ExchangesCountRequestFrames) {
  const std::vector<Record> records = {
      {ms(0), RecordKind::tx, "A\n"}, {ms(1), RecordKind::rx, "a\n"},
      {ms(2), RecordKind::tx, "B"},   {ms(3), RecordKind::rx, "?"},
      {ms(4), RecordKind::tx, "\n"},  {ms(5), RecordKind::rx, "b\n"}};
  // Without a profile, "B" and "\n" start exchanges 1 and 2.
  auto bytes = replay("timing=none,unused=ignore,faults=drop@exchange:1", records);
  EXPECT_EQ(answer(*bytes, "A\n"), "a\n");
  EXPECT_EQ(answer(*bytes, "B"), "");
  EXPECT_EQ(answer(*bytes, "\n"), "b\n");
  // With profile=lines, "B\n" is exchange 1: its answer is dropped. The "?"
  // sent before it was complete still belongs to exchange 0 (it is released
  // once the client's frame is whole, as the profile compares frames).
  auto frames = replay("timing=none,unused=ignore,profile=lines,faults=drop@exchange:1", records);
  EXPECT_EQ(answer(*frames, "A\n"), "a\n");
  EXPECT_EQ(answer(*frames, "B"), "");
  EXPECT_EQ(answer(*frames, "\n"), "?");
}

TEST(FaultRequestMatching, ExchangesAreNumberedInServedOrder) {
  // The client asks Q2 first: with match=request it is exchange 0.
  auto port = replay("timing=none,match=request,faults=truncate:2@exchange:0");
  EXPECT_EQ(answer(*port, "Q2\n"), "R2");
  EXPECT_EQ(answer(*port, "Q0\n"), "R0-abcdef\n");
}
