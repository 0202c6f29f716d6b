// Fault injection on replay (faults=, DESIGN.md sections 14 and 17): the
// parser's grammar and errors, the fault stage on its own (a pass-through
// without a plan; each kind on the records it is given), and what a client of a replaying port sees for each
// fault kind in each timing mode.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <string>
#include <vector>

#include "replay/fault_stage.hpp"
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
using detail::SessionPlaces;
using detail::SessionShape;

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

namespace {

// The message check_against gives `text` against `session`; "" when it passes.
std::string refusal(const char* text, const SessionPlaces& session) {
  try {
    parse_faults(text, 0).check_against(session);
  } catch (const OptionError& error) {
    EXPECT_EQ(error.key(), "faults");
    return error.what();
  }
  return "";
}

}  // namespace

TEST(FaultPlaces, APlacePastWhatTheReplayServesIsRefused) {
  const SessionPlaces one{{}, {SessionShape{2, 5, 30, 3'500'000'000}}};
  EXPECT_EQ(refusal("drop@exchange:4;drop@rx:29;drop@t:3.5", one), "");
  EXPECT_EQ(refusal("drop@exchange:5", one),
            "drop@exchange:5: the session has 5 exchanges with rx (0..4); exchange 5 is past "
            "its end");
  EXPECT_EQ(refusal("drop@rx:30", one),
            "drop@rx:30: the session has 30 rx bytes; rx byte 30 is past its end");
  // t:S on the session's clock, as the fault stage fires it.
  EXPECT_EQ(refusal("drop@t:3.6", one),
            "drop@t:3.6: the session lasts 3.500 s; t:3.6 is past its end");
  EXPECT_EQ(refusal("drop@exchange:0@channel:gps", one),
            "drop@exchange:0@channel:gps: the session has no channel 'gps' (its channels: "
            "none: the session has one port (leave @channel out))");
}

TEST(FaultPlaces, AChannelsPlaceIsItsOwnAndOneWithoutIsEveryChannels) {
  const SessionPlaces two{{"gps", "rtk"},
                          {SessionShape{0, 3, 9, 1'000'000'000}, SessionShape{0, 2, 6, 0}}};
  EXPECT_EQ(refusal("drop@exchange:2@channel:gps;drop@exchange:2", two), "");
  EXPECT_EQ(refusal("drop@exchange:2@channel:rtk", two),
            "drop@exchange:2@channel:rtk: channel rtk has 2 exchanges with rx (0..1); "
            "exchange 2 is past its end");
  EXPECT_EQ(refusal("drop@exchange:3", two),
            "drop@exchange:3: every channel has 3 exchanges with rx (0..2); exchange 3 is "
            "past its end");
  EXPECT_EQ(refusal("drop@exchange:0@channel:imu", two),
            "drop@exchange:0@channel:imu: the session has no channel 'imu' (its channels: "
            "gps, rtk)");
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

// speed=K scales a fault's waits as it scales the recorded ones (DESIGN §14,
// §22): a driver on a clock K times faster sees the delay it would at K=1.
TEST_P(FaultKinds, SpeedScalesADelay) {
  auto port = replay("timing=" + GetParam() +
                     ",speed=10,faults=\"delay:3000@exchange:1\",seed=5,unused=error");
  answer(*port, "Q0\n");
  const auto start = std::chrono::steady_clock::now();
  port->write("Q1\n", 3);
  EXPECT_EQ(port->read_line(), "R1-ghijkl\n");
  const auto waited = std::chrono::steady_clock::now() - start;
  // timing=session counts it from the recorded (scaled) due time, which
  // the write may come after.
  if (GetParam() != "session") EXPECT_GE(waited, 290ms);
  EXPECT_LT(waited, 2000ms);  // unscaled: 3 s
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
  try {
    port->read(buffer, sizeof buffer);
    ADD_FAILURE() << "the read after a disconnect returned";
  } catch (const PortClosed& error) {
    // The fault's own account, not a recorded loss's.
    EXPECT_NE(std::string(error.what()).find("fault disconnect@exchange:1"), std::string::npos)
        << error.what();
  }
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

// --- the stage on its own --------------------------------------------------------

namespace {

using detail::FaultStage;
using detail::ReleasedRx;
using detail::ReplayTime;
using detail::RxItem;

const ReplayTime kOpen{std::chrono::seconds(1000)};

RxItem rx_item(const std::string& data, std::uint64_t t_ms, std::uint64_t exchange,
               RecordKind kind = RecordKind::rx) {
  RxItem item;
  item.kind = kind;
  item.data = data;
  item.t_ns = ms(t_ms);
  item.due = kOpen + std::chrono::milliseconds(t_ms);
  item.exchange = exchange;
  return item;
}

// Exchange 0 in one record, exchange 1 in two, exchange 2 in one.
void release_three(ReleasedRx& released) {
  released.push(rx_item("R0-abcdef\n", 1, 0));
  released.push(rx_item("R1-ghi", 401, 1));
  released.push(rx_item("jkl\n", 402, 1));
  released.push(rx_item("R2-mnopqr\n", 801, 2));
}

struct Served {
  RecordKind kind;
  std::string data;
  std::uint64_t t_ns;
  std::chrono::milliseconds due;  // after kOpen
  std::uint64_t exchange;
};

// Everything the stage hands the reader, in order, popped.
std::vector<Served> drain(FaultStage& stage, ReplayTime now = kOpen) {
  std::vector<Served> served;
  stage.pull(now);
  while (!stage.empty()) {
    const RxItem& item = stage.front();
    served.push_back(Served{item.kind, std::string(item.payload().substr(item.consumed)),
                            item.t_ns,
                            std::chrono::duration_cast<std::chrono::milliseconds>(item.due - kOpen),
                            item.exchange});
    stage.pop();
    stage.pull(now);
  }
  return served;
}

std::string bytes_of_exchange(const std::vector<Served>& served, std::uint64_t exchange) {
  std::string bytes;
  for (const Served& item : served) {
    if (item.exchange == exchange && item.kind == RecordKind::rx) bytes += item.data;
  }
  return bytes;
}

// A stage with `faults` over release_three(), and the faults it reported.
struct StageRun {
  std::vector<Served> served;
  std::vector<detail::FaultEvent> events;
  bool swallows_writes = false;
  bool rest_unreachable = false;
  bool unread_hidden = false;
};

StageRun run_stage(const std::string& faults) {
  ReleasedRx released(/*recycle_payloads=*/false);
  FaultStage stage(parse_faults(faults, 5), /*datagrams=*/false, released);
  StageRun run;
  stage.on_fault([&run](const detail::FaultEvent& event) { run.events.push_back(event); });
  release_three(released);
  run.served = drain(stage);
  run.swallows_writes = stage.swallows_writes();
  run.rest_unreachable = stage.rest_unreachable();
  run.unread_hidden = !stage.unread().has_value();
  return run;
}

}  // namespace

TEST(FaultStage, WithoutAPlanItIsTheReleasedQueueItself) {
  ReleasedRx released(/*recycle_payloads=*/false);
  FaultStage stage(parse_faults("", 0), /*datagrams=*/false, released);
  EXPECT_FALSE(stage.injects());
  release_three(released);
  released.push(rx_item("", 900, 2, RecordKind::device_lost));
  stage.pull(kOpen);
  // No copy: the reader reads the strategy's records where they are.
  EXPECT_EQ(&stage.front(), &released.front());
  const auto unread = stage.unread();
  ASSERT_TRUE(unread);
  EXPECT_EQ(unread->bytes, 30u);
  EXPECT_EQ(unread->records, 4u);
  std::size_t visited = 0;
  stage.visit([&visited](const RxItem&) { return ++visited < 2; });
  EXPECT_EQ(visited, 2u);

  const std::vector<Served> served = drain(stage);
  ASSERT_EQ(served.size(), 5u);
  const std::vector<std::pair<std::string, std::uint64_t>> expected = {
      {"R0-abcdef\n", 1}, {"R1-ghi", 401}, {"jkl\n", 402}, {"R2-mnopqr\n", 801}, {"", 900}};
  for (std::size_t i = 0; i < served.size(); ++i) {
    EXPECT_EQ(served[i].data, expected[i].first) << i;
    EXPECT_EQ(served[i].t_ns, ms(expected[i].second)) << i;
    EXPECT_EQ(served[i].due, std::chrono::milliseconds(expected[i].second)) << i;
  }
  EXPECT_EQ(served[4].kind, RecordKind::device_lost);
  EXPECT_TRUE(released.empty());
  EXPECT_FALSE(stage.swallows_writes());
  EXPECT_FALSE(stage.rest_unreachable());
}

TEST(FaultStage, ARecordedLossIsTheReadersNotAFaults) {
  ReleasedRx released(/*recycle_payloads=*/false);
  FaultStage stage(parse_faults("drop@exchange:9", 0), /*datagrams=*/false, released);
  released.push(rx_item("", 1, 0, RecordKind::device_lost));
  stage.pull(kOpen);
  ASSERT_FALSE(stage.empty());
  EXPECT_EQ(stage.loss(kOpen + 1h), nullptr);
  EXPECT_EQ(stage.front().kind, RecordKind::device_lost);
}

TEST(FaultStage, APlanThatNeverFiresChangesNothing) {
  // A plan whose fault never fires copies the records but changes nothing.
  const StageRun run = run_stage("drop@exchange:9");
  ASSERT_EQ(run.served.size(), 4u);
  EXPECT_EQ(bytes_of_exchange(run.served, 0), "R0-abcdef\n");
  EXPECT_EQ(bytes_of_exchange(run.served, 1), "R1-ghijkl\n");
  EXPECT_EQ(bytes_of_exchange(run.served, 2), "R2-mnopqr\n");
  EXPECT_EQ(run.served[2].due, 402ms);
  EXPECT_TRUE(run.events.empty());
  EXPECT_FALSE(run.unread_hidden);
}

TEST(FaultStage, EachKindActsOnItsExchangeAndReportsIt) {
  struct Case {
    std::string kind;
    std::string exchange_1;  // what the client gets of exchange 1, "*": checked below
  };
  for (const Case& c : std::vector<Case>{{"drop", ""},
                                         {"drop:2", "*"},
                                         {"corrupt", "*"},
                                         {"garbage:3", "*"},
                                         {"truncate:2", "R1"},
                                         {"duplicate", "R1-ghiR1-ghijkl\n"},
                                         {"delay:50", "R1-ghijkl\n"},
                                         {"stall:50", "R1-ghijkl\n"},
                                         {"trickle:2", "R1-ghijkl\n"},
                                         {"silence", ""},
                                         {"disconnect", ""},
                                         {"reconnect:50", ""}}) {
    SCOPED_TRACE(c.kind);
    const StageRun run = run_stage(c.kind + "@exchange:1");
    const std::string got = bytes_of_exchange(run.served, 1);
    if (c.exchange_1 != "*") EXPECT_EQ(got, c.exchange_1);
    EXPECT_EQ(bytes_of_exchange(run.served, 0), "R0-abcdef\n");
    ASSERT_FALSE(run.events.empty());
    EXPECT_EQ(run.events.front().exchange, 1u);
    EXPECT_EQ(run.events.front().where, "exchange:1");
    EXPECT_TRUE(run.unread_hidden);  // a fault fired: nothing counts as unused
    const bool ends = c.kind == "silence" || c.kind == "disconnect";
    EXPECT_EQ(bytes_of_exchange(run.served, 2), ends ? "" : "R2-mnopqr\n");
    EXPECT_EQ(run.rest_unreachable, ends);
    EXPECT_EQ(run.swallows_writes, c.kind == "silence");
    const std::string first_record = "R1-ghi";
    if (c.kind == "drop:2") EXPECT_EQ(got.size(), 8u);
    if (c.kind == "corrupt") {
      EXPECT_EQ(flip_distance(got.substr(0, 6), first_record), "1");
      EXPECT_EQ(got.substr(6), "jkl\n");
    }
    if (c.kind == "garbage:3") EXPECT_EQ(got.size(), 13u);
    std::vector<std::chrono::milliseconds> dues;
    for (const Served& item : run.served) {
      if (item.exchange == 1) dues.push_back(item.due);
    }
    if (c.kind == "delay:50") {
      EXPECT_EQ(dues, (std::vector<std::chrono::milliseconds>{451ms, 452ms}));
    }
    if (c.kind == "stall:50") {  // half the first record, a gap, the rest
      ASSERT_EQ(run.served.size(), 5u);
      EXPECT_EQ(run.served[1].data, "R1-");
      EXPECT_EQ(run.served[1].due, 401ms);
      EXPECT_EQ(run.served[2].data, "ghi");
      EXPECT_EQ(run.served[2].due, 451ms);
    }
    if (c.kind == "trickle:2") {  // one byte per record, 2 ms apart
      ASSERT_EQ(dues.size(), 10u);
      for (std::size_t i = 1; i < dues.size(); ++i) EXPECT_GE(dues[i] - dues[i - 1], 1ms) << i;
      EXPECT_EQ(dues[5] - dues[0], 10ms);
    }
    if (c.kind == "disconnect" || c.kind == "reconnect:50") {
      const auto loss = std::find_if(run.served.begin(), run.served.end(), [](const Served& item) {
        return item.kind == RecordKind::device_lost;
      });
      ASSERT_NE(loss, run.served.end());
      EXPECT_EQ(loss->exchange, 1u);
      EXPECT_NE(loss->data.find("went away"), std::string::npos) << loss->data;
    }
  }
}

TEST(FaultStage, AReconnectIsALossUntilItIsOver) {
  ReleasedRx released(/*recycle_payloads=*/false);
  FaultStage stage(parse_faults("reconnect:50@exchange:1", 0), /*datagrams=*/false, released);
  stage.on_fault([](const detail::FaultEvent&) {});
  release_three(released);
  stage.pull(kOpen);
  stage.pop();  // exchange 0
  // The loss is due when exchange 1 is (401 ms), and over 50 ms later.
  EXPECT_EQ(stage.loss(kOpen + 400ms), nullptr);
  const RxItem* loss = stage.loss(kOpen + 402ms);
  ASSERT_NE(loss, nullptr);
  EXPECT_NE(loss->data.find("for 50 ms"), std::string::npos) << loss->data;
  EXPECT_EQ(stage.loss(kOpen + 452ms), nullptr);
  // Back: the rest of exchange 1 was lost with the device, exchange 2 comes.
  ASSERT_FALSE(stage.empty());
  EXPECT_EQ(stage.front().payload(), "R2-mnopqr\n");
}

TEST(FaultStage, ReadsTheExchangeFromTheItem) {
  // The stage trusts item.exchange (set by the strategy): records numbered 7
  // are exchange 7, wherever they are in the queue.
  ReleasedRx released(/*recycle_payloads=*/false);
  FaultStage stage(parse_faults("drop@exchange:7", 0), /*datagrams=*/false, released);
  stage.on_fault([](const detail::FaultEvent&) {});
  released.push(rx_item("first", 1, 7));
  released.push(rx_item("second", 2, 8));
  const std::vector<Served> served = drain(stage);
  ASSERT_EQ(served.size(), 1u);
  EXPECT_EQ(served[0].data, "second");
}

// --- what faults leave behind for a virtual device's next client session ----------

namespace {

// Two client sessions of one device: each has a stage of its own (a new
// engine), sharing the port's FaultMemory. Session 1 is exchanges 0 and 1,
// session 2 exchanges 2 and 3 (numbered per file), both recorded from 1 ms.
struct TwoSessions {
  std::vector<Served> first;
  std::vector<Served> second;
  std::vector<detail::FaultEvent> events;
  bool second_swallows_writes = false;
  bool second_rest_unreachable = false;
  bool second_unread_hidden = false;
  std::string second_loss;  // the loss due at once in session 2, if any
};

TwoSessions run_two_sessions(const std::string& faults) {
  const detail::FaultPlan plan = parse_faults(faults, 5);
  const auto memory = std::make_shared<detail::FaultMemory>();
  TwoSessions run;
  const auto record = [&run](const detail::FaultEvent& event) { run.events.push_back(event); };
  {
    ReleasedRx released(/*recycle_payloads=*/false);
    FaultStage stage(plan, /*datagrams=*/false, released, memory);
    stage.on_fault(record);
    released.push(rx_item("a-first\n", 1, 0));
    released.push(rx_item("b-first\n", 401, 1));
    run.first = drain(stage);
  }
  ReleasedRx released(/*recycle_payloads=*/false);
  FaultStage stage(plan, /*datagrams=*/false, released, memory);
  stage.on_fault(record);
  if (const RxItem* loss = stage.loss(kOpen)) run.second_loss = loss->data;
  if (run.second_loss.empty()) {
    released.push(rx_item("c-second\n", 1, 2));
    released.push(rx_item("d-second\n", 401, 3));
    run.second = drain(stage);
  }
  run.second_swallows_writes = stage.swallows_writes();
  run.second_rest_unreachable = stage.rest_unreachable();
  run.second_unread_hidden = !stage.unread().has_value();
  return run;
}

}  // namespace

TEST(FaultMemory, SilenceLastsIntoTheNextClientSession) {
  const TwoSessions run = run_two_sessions("silence@exchange:1");
  ASSERT_EQ(run.first.size(), 1u);
  EXPECT_EQ(run.first[0].data, "a-first\n");
  // "nothing more, ever" (docs/faults.md): not the second client's answers.
  EXPECT_TRUE(run.second.empty()) << run.second[0].data;
  EXPECT_TRUE(run.second_swallows_writes);
  EXPECT_TRUE(run.second_rest_unreachable);
  EXPECT_TRUE(run.second_unread_hidden);
  EXPECT_EQ(run.events.size(), 1u);
}

TEST(FaultMemory, ADisconnectIsStillALossInTheNextClientSession) {
  const TwoSessions run = run_two_sessions("disconnect@exchange:0");
  ASSERT_EQ(run.first.size(), 1u);
  EXPECT_EQ(run.first[0].kind, RecordKind::device_lost);
  EXPECT_NE(run.second_loss.find("disconnect@exchange:0"), std::string::npos) << run.second_loss;
  EXPECT_TRUE(run.second_rest_unreachable);
  EXPECT_EQ(run.events.size(), 1u);
}

TEST(FaultMemory, OnceOnlyPlacesDoNotFireAgainInTheNextClientSession) {
  // rx:0 and t:0 are both in each session's first record: once per device.
  for (const std::string faults : {"duplicate@rx:0", "duplicate@t:0"}) {
    SCOPED_TRACE(faults);
    const TwoSessions run = run_two_sessions(faults);
    EXPECT_EQ(bytes_of_exchange(run.first, 0), "a-first\na-first\n");
    EXPECT_EQ(bytes_of_exchange(run.second, 2), "c-second\n");
    EXPECT_EQ(run.events.size(), 1u);
    EXPECT_FALSE(run.second_swallows_writes);
  }
}

TEST(FaultMemory, AFaultInAnEarlierClientSessionHidesUnusedData) {
  // Once any fault fired, the replay does not report unused data at close
  // (docs/faults.md), whichever session's engine closes.
  const TwoSessions run = run_two_sessions("duplicate@exchange:0");
  EXPECT_EQ(bytes_of_exchange(run.second, 2), "c-second\n");
  EXPECT_TRUE(run.second_unread_hidden);
  EXPECT_FALSE(run.second_rest_unreachable);
}

TEST(FaultMemory, RxBytesAreCountedOnAcrossClientSessions) {
  // rx:N is an offset in what the device served, as exchanges are numbered
  // per file: byte 18 is the 's' of the second session's "c-second\n" (the
  // first session served 16 bytes), where the session's shape puts it.
  const TwoSessions run = run_two_sessions("duplicate@rx:18");
  EXPECT_EQ(bytes_of_exchange(run.first, 0), "a-first\n");
  EXPECT_EQ(bytes_of_exchange(run.first, 1), "b-first\n");
  EXPECT_EQ(bytes_of_exchange(run.second, 2), "c-second\nc-second\n");
  ASSERT_EQ(run.events.size(), 1u);
  EXPECT_NE(run.events[0].detail.find("rx byte 16"), std::string::npos) << run.events[0].detail;
}

TEST(FaultMemory, ASilenceRemembersWhichFaultItWas) {
  const detail::FaultPlan plan = parse_faults("silence@exchange:1", 5);
  const auto memory = std::make_shared<detail::FaultMemory>();
  ReleasedRx released(/*recycle_payloads=*/false);
  FaultStage stage(plan, /*datagrams=*/false, released, memory);
  stage.on_fault([](const detail::FaultEvent&) {});
  released.push(rx_item("a\n", 1, 0));
  released.push(rx_item("b\n", 401, 1));
  drain(stage);
  EXPECT_TRUE(memory->silenced);
  EXPECT_EQ(memory->silenced_by, "silence@exchange:1");
}
