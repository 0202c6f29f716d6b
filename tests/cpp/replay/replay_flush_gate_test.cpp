// Replay waits for the client's flush where the recording shows one
// (DESIGN.md section 12): rx recorded after a client's flush_input or
// flush_output is entitled only once the client has flushed as often.
#include <gtest/gtest.h>

#include <chrono>
#include <string>
#include <vector>

#include "replay/replay_config.hpp"
#include "replay/replay_port.hpp"
#include "session/record_source.hpp"
#include "wiretape/options.hpp"
#include "wiretape/port.hpp"
#include "wiretape/session.hpp"

using namespace wiretape;
using namespace std::chrono_literals;

namespace {

Record record(std::uint64_t t, RecordKind kind, std::string data = {}) {
  return {t, kind, std::move(data)};
}

std::unique_ptr<Port> replay(std::vector<Record> records, const std::string& keys) {
  Options options = Options::parse("file=synthetic.wtape," + keys);
  detail::ReplayConfig config = detail::take_replay_config(options);
  options.finish("replay");
  return detail::open_replay_session(config, detail::vector_source_factory(std::move(records)));
}

std::string read_now(Port& port) {
  std::string buffer(256, '\0');
  buffer.resize(port.read(buffer.data(), buffer.size(), std::chrono::nanoseconds(0)));
  return buffer;
}

std::vector<Record> flushed_greeting() {
  return {record(0, RecordKind::open, "{}"),
          record(1'000, RecordKind::rx, "boot"),
          record(2'000, RecordKind::flush_input, "{}"),
          record(3'000, RecordKind::rx, "HELLO"),
          record(4'000, RecordKind::flush_output, "{}"),
          record(5'000, RecordKind::rx, "AGAIN")};
}

}  // namespace

TEST(ReplayFlushGate, RxAfterARecordedFlushWaitsForTheClientsFlush) {
  auto port = replay(flushed_greeting(), "timing=none,unused=ignore");
  EXPECT_EQ(read_now(*port), "boot");
  EXPECT_EQ(read_now(*port), "");
  port->flush_input();
  EXPECT_EQ(read_now(*port), "HELLO");
  EXPECT_EQ(read_now(*port), "");
  port->flush_output();
  EXPECT_EQ(read_now(*port), "AGAIN");
  port->close();
}

TEST(ReplayFlushGate, TheFlushDropsOnlyWhatWasReleasedBeforeIt) {
  auto port = replay(flushed_greeting(), "timing=none,unused=ignore");
  port->flush_input();  // "boot" unread: dropped; "HELLO" released after
  EXPECT_EQ(read_now(*port), "HELLO");
  port->close();
}

TEST(ReplayFlushGate, AVirtualDevicesRedeliveringFlushCountsWithoutDropping) {
  auto port = replay(flushed_greeting(), "timing=none,unused=ignore");
  detail::replay_client_flushed(*port);
  EXPECT_EQ(read_now(*port), "bootHELLO");
  port->close();
}

TEST(ReplayFlushGate, SessionTimingIsDecidedByTimeAlone) {
  auto port = replay(flushed_greeting(), "timing=session,unused=ignore");
  port->set_timeout(5s);
  std::string got;
  while (got.size() < 14) {
    std::string buffer(64, '\0');
    buffer.resize(port->read(buffer.data(), buffer.size()));
    got += buffer;
  }
  EXPECT_EQ(got, "bootHELLOAGAIN");
  port->close();
}

// DESIGN.md section 12: a recorded flush gates rx only as long as the client
// could still make it. Flushes made back to back can reach the bridge as one
// (TIOCPKT), so a client may flush fewer times than recorded: the gate gives
// up flush_wait after the rx would be due.
TEST(ReplayFlushGate, AGateTheClientNeverOpensGivesUpAfterFlushWait) {
  auto port = replay(flushed_greeting(), "timing=none,unused=ignore,flush_wait=50");
  port->set_timeout(10s);
  EXPECT_EQ(read_now(*port), "boot");
  const auto start = std::chrono::steady_clock::now();
  std::string got;
  while (got.size() < 10) got += port->read_exactly(10 - got.size());
  EXPECT_EQ(got, "HELLOAGAIN");
  EXPECT_GE(std::chrono::steady_clock::now() - start, 50ms);
  port->close();
}

TEST(ReplayFlushGate, FewerFlushesThanRecordedStillServeEverything) {
  // connect, flush, rx $A, flush, rx $B, rx $C (the repro): the
  // client's two flushes arrived as one.
  std::vector<Record> records = {record(0, RecordKind::open, "{}"),
                                 record(1'000, RecordKind::flush_input, "{}"),
                                 record(2'000, RecordKind::rx, "$A"),
                                 record(3'000, RecordKind::flush_input, "{}"),
                                 record(4'000, RecordKind::rx, "$B"),
                                 record(5'000, RecordKind::rx, "$C")};
  auto port = replay(records, "timing=none");
  port->set_timeout(10s);
  detail::replay_client_flushed(*port);
  EXPECT_EQ(port->read_exactly(6), "$A$B$C");
  port->close();
}

// Issue 37: once the client has written past the place of the recorded
// flushes, they can no longer come, and the rx they held is due at once
// (not flush_wait later: a client that gives up sooner is not starved).
TEST(ReplayFlushGate, AWritePastTheRecordedFlushesReleasesTheRxTheyHeld) {
  std::vector<Record> records = {record(0, RecordKind::open, "{}"),
                                 record(1'000, RecordKind::flush_input, "{}"),
                                 record(2'000, RecordKind::rx, "GREETING"),
                                 record(3'000, RecordKind::tx, "CMD"),
                                 record(4'000, RecordKind::rx, "RESP")};
  auto port = replay(records, "timing=none,unused=error,flush_wait=60000");
  EXPECT_EQ(read_now(*port), "");  // the greeting waits for the recorded flush
  port->write_all("CMD");
  EXPECT_EQ(read_now(*port), "GREETINGRESP");
  port->close();  // all of it served: nothing unused, nothing held
}

// The motor-controller SDK: two flushes recorded before its ping,
// one made; its reply is due when the ping is written.
TEST(ReplayFlushGate, AClientThatFlushedOnceOfTwiceIsAnsweredAtItsWrite) {
  std::vector<Record> records = {record(0, RecordKind::open, "{}"),
                                 record(1'000, RecordKind::flush_input, "{}"),
                                 record(2'000, RecordKind::flush_input, "{}"),
                                 record(3'000, RecordKind::tx, "PING:00001"),
                                 record(4'000, RecordKind::rx, "STATUS")};
  auto port = replay(records, "timing=none,unused=error,flush_wait=60000");
  port->flush_input();
  port->write_all("PING:00001");
  EXPECT_EQ(read_now(*port), "STATUS");
  port->close();
}

// A flush recorded after the client's last recorded write still gates: the
// client may still make it.
TEST(ReplayFlushGate, AFlushRecordedAfterTheWriteStillWaitsForTheClient) {
  std::vector<Record> records = {record(0, RecordKind::open, "{}"),
                                 record(1'000, RecordKind::tx, "CMD"),
                                 record(2'000, RecordKind::flush_input, "{}"),
                                 record(3'000, RecordKind::rx, "RESP")};
  auto port = replay(records, "timing=none,unused=ignore,flush_wait=60000");
  port->write_all("CMD");
  EXPECT_EQ(read_now(*port), "");
  port->flush_input();
  EXPECT_EQ(read_now(*port), "RESP");
  port->close();
}

// The flush the client made is the later one: the one it skipped came
// before a write it made.
TEST(ReplayFlushGate, ASkippedFlushBeforeAWriteDoesNotCountAgainstALaterOne) {
  std::vector<Record> records = {record(0, RecordKind::open, "{}"),
                                 record(1'000, RecordKind::flush_input, "{}"),
                                 record(2'000, RecordKind::tx, "CMD"),
                                 record(3'000, RecordKind::flush_input, "{}"),
                                 record(4'000, RecordKind::rx, "RESP")};
  auto port = replay(records, "timing=none,unused=error,flush_wait=60000");
  port->write_all("CMD");
  EXPECT_EQ(read_now(*port), "");
  port->flush_input();
  EXPECT_EQ(read_now(*port), "RESP");
  port->close();
}

TEST(ReplayFlushGate, RxHeldAfterTheClientsLastWriteIsOnlyUnused) {
  auto port = replay(flushed_greeting(), "timing=none,unused=error,flush_wait=60000");
  EXPECT_EQ(read_now(*port), "boot");
  try {
    port->close();
    FAIL() << "unused=error must report the unread rx";
  } catch (const ReplayMismatch& mismatch) {
    EXPECT_NE(std::string(mismatch.what()).find("were never read"), std::string::npos)
        << mismatch.what();
    EXPECT_EQ(std::string(mismatch.what()).find("entitled"), std::string::npos);
  }
}
