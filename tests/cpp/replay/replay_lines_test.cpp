// type=replay and the serial line (DESIGN.md section 20): the device's
// recorded modem inputs are released like rx, and the client's DTR, RTS and
// break are checked like its bytes (check=data) where the recording holds
// the device's lines. Expectations come from the recording (an oracle that
// reads it), not from the replay.
#include <gtest/gtest.h>

#include "support/port_test_support.hpp"

#include <chrono>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "replay/replay_config.hpp"
#include "replay/replay_port.hpp"
#include "session/record_kinds.hpp"
#include "session/record_source.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/options.hpp"
#include "wiretape/port.hpp"
#include "wiretape/session.hpp"

using namespace wiretape;
using namespace std::chrono_literals;
using wiretape::detail::ModemInputs;
using wiretape::detail::ReplayConfig;

namespace {

constexpr std::uint64_t ms(std::uint64_t n) { return n * 1'000'000; }

Record rx(std::uint64_t t, std::string data) { return {t, RecordKind::rx, std::move(data)}; }
Record tx(std::uint64_t t, std::string data) { return {t, RecordKind::tx, std::move(data)}; }
Record device_lines(std::uint64_t t, bool cts, bool dsr, bool ri, bool cd) {
  return {t, RecordKind::modem_lines, detail::modem_inputs_payload({cts, dsr, ri, cd})};
}
Record dtr(std::uint64_t t, bool level) {
  return {t, RecordKind::modem_lines, level ? R"({"dtr":true,"applied":true})"
                                            : R"({"dtr":false,"applied":true})"};
}
Record line_break(std::uint64_t t) {
  return {t, RecordKind::line_break, R"({"duration_ms":250,"applied":true})"};
}

// A board reset: DTR low for 100 ms, then high; the device answers with CTS
// and a banner, and changes its lines again in the middle of a response.
std::vector<Record> reset_session(std::uint64_t cts_answer_t = ms(150)) {
  return {{0, RecordKind::open, R"({"description":"serial /dev/ttyUSB0"})"},
          device_lines(0, false, true, false, false),
          dtr(ms(1), false),
          dtr(ms(101), true),
          device_lines(cts_answer_t, true, true, false, false),
          rx(cts_answer_t + ms(10), "BOOT\n"),
          tx(cts_answer_t + ms(50), "PING\n"),
          rx(cts_answer_t + ms(60), "PO"),
          device_lines(cts_answer_t + ms(65), false, true, true, true),
          rx(cts_answer_t + ms(70), "NG\n"),
          line_break(cts_answer_t + ms(80)),
          tx(cts_answer_t + ms(400), "BYE\n"),
          {cts_answer_t + ms(500), RecordKind::close, ""}};
}

// The same session as recorded before lines were recorded (or from a pty):
// the client's line events, none of the device's.
std::vector<Record> without_device_lines(std::vector<Record> records) {
  std::vector<Record> kept;
  for (Record& record : records) {
    if (record.kind == RecordKind::modem_lines &&
        detail::modem_inputs_of(record.data, {}).has_value()) {
      continue;
    }
    kept.push_back(std::move(record));
  }
  return kept;
}

// The oracle: the device's lines a client sees once it has written
// `tx_written` bytes, with everything so entitled released (timing=none).
ModemInputs released_lines(const std::vector<Record>& records, std::size_t tx_written) {
  ModemInputs lines;  // a modem's line-up levels before any recorded
  std::size_t tx_seen = 0;
  for (const Record& record : records) {
    if (record.kind == RecordKind::tx) {
      tx_seen += record.data.size();
      if (tx_seen > tx_written) break;
    }
    if (record.kind != RecordKind::modem_lines) continue;
    if (const auto inputs = detail::modem_inputs_of(record.data, lines)) lines = *inputs;
  }
  return lines;
}

// The oracle for timing=session: the lines whose recorded time has come.
ModemInputs lines_at(const std::vector<Record>& records, std::uint64_t t_ns) {
  ModemInputs lines;
  for (const Record& record : records) {
    if (record.kind != RecordKind::modem_lines || record.t_ns > t_ns) continue;
    if (const auto inputs = detail::modem_inputs_of(record.data, lines)) lines = *inputs;
  }
  return lines;
}

ModemInputs lines_of(Port& port) {
  return {port.cts(), port.dsr(), port.ri(), port.cd()};
}

std::unique_ptr<Port> replay(std::vector<Record> records, const std::string& keys) {
  Options options = Options::parse("file=board.wtape," + keys);
  ReplayConfig config = detail::take_replay_config(options);
  options.finish("replay");
  auto port = detail::open_replay_session(config, detail::vector_source_factory(std::move(records)));
  port->set_timeout(test::kEventDeadline);
  return port;
}

std::string read_exactly(Port& port, std::size_t n) { return port.read_exactly(n, 5s); }

// What the recorded client did, done again.
void reset_and_talk(Port& port) {
  port.set_dtr(false);
  port.set_dtr(true);
  EXPECT_EQ(read_exactly(port, 5), "BOOT\n");
  port.write_all("PING\n");
  EXPECT_EQ(read_exactly(port, 5), "PONG\n");
  port.send_break(250ms);
  port.write_all("BYE\n");
}

std::string mismatch_of(const std::function<void()>& act) {
  try {
    act();
  } catch (const ReplayMismatch& mismatch) {
    return mismatch.what();
  }
  return "(no mismatch)";
}

void expect_contains(const std::string& text, const std::string& part) {
  EXPECT_NE(text.find(part), std::string::npos) << "expected \"" << part << "\" in:\n" << text;
}

}  // namespace

// --- served ----------------------------------------------------------------------

TEST(ReplayLines, TimingNoneReleasesTheDeviceLinesWithTheirEntitlement) {
  const auto records = reset_session();
  auto port = replay(records, "timing=none");
  // Before the first write: everything recorded before it.
  EXPECT_EQ(lines_of(*port), released_lines(records, 0));
  EXPECT_TRUE(port->cts());  // the answer to the reset is there at once
  port->set_dtr(false);
  port->set_dtr(true);
  EXPECT_EQ(read_exactly(*port, 5), "BOOT\n");
  EXPECT_EQ(lines_of(*port), released_lines(records, 0));
  port->write_all("PING\n");
  // Released with the response, in order, whether or not "PO" was read.
  EXPECT_EQ(lines_of(*port), released_lines(records, 5));
  EXPECT_FALSE(port->cts());
  EXPECT_TRUE(port->ri());
  EXPECT_EQ(read_exactly(*port, 5), "PONG\n");
  port->send_break(250ms);
  port->write_all("BYE\n");
  EXPECT_EQ(lines_of(*port), released_lines(records, 9));
  port->close();
}

TEST(ReplayLines, TimingSessionReleasesTheDeviceLinesAtTheirRecordedTimes) {
  // The answer late enough that a loaded machine still sees the lines before it.
  const std::uint64_t answer = ms(1000);
  const auto records = reset_session(answer);
  const auto before_open = std::chrono::steady_clock::now();  // the replay's clock starts later
  auto port = replay(records, "timing=session,unused=ignore");
  EXPECT_EQ(lines_of(*port), lines_at(records, 0));
  EXPECT_FALSE(port->cts());
  port->set_dtr(false);
  port->set_dtr(true);
  const auto deadline = before_open + test::kEventDeadline;
  while (!port->cts() && std::chrono::steady_clock::now() < deadline) {
    port->wait_readable(5ms);  // an event to wait on: the banner comes 10 ms later
  }
  const auto seen = std::chrono::steady_clock::now() - before_open;
  EXPECT_TRUE(port->cts());
  EXPECT_GE(seen, std::chrono::nanoseconds(answer));
  EXPECT_EQ(lines_of(*port), lines_at(records, answer));
  EXPECT_EQ(read_exactly(*port, 5), "BOOT\n");
}

TEST(ReplayLines, ARecordingWithoutLineEventsReportsTheLineUp) {
  auto port = replay(without_device_lines(reset_session()), "timing=none,unused=ignore");
  const ModemInputs up{true, true, false, true};
  EXPECT_EQ(lines_of(*port), up);
  port->write_all("PING\n");
  EXPECT_EQ(lines_of(*port), up);
}

TEST(ReplayLines, ARecordingWithoutDeviceLinesChecksNoLines) {
  auto port = replay(without_device_lines(reset_session()), "timing=none");
  // No pulse, an extra one, a break nowhere recorded: none is checked.
  port->set_dtr(true);
  port->set_dtr(false);
  port->set_rts(false);
  port->write_all("PING\n");
  EXPECT_EQ(read_exactly(*port, 10), "BOOT\nPONG\n");
  port->write_all("BYE\n");
  EXPECT_NO_THROW(port->close());
}

// --- checked -----------------------------------------------------------------------

TEST(ReplayLines, TheRecordedClientPasses) {
  for (const char* keys : {"timing=none", "timing=causal", "timing=session"}) {
    SCOPED_TRACE(keys);
    auto port = replay(reset_session(), std::string(keys) + ",unused=error");
    reset_and_talk(*port);
    EXPECT_NO_THROW(port->close());
  }
}

TEST(ReplayLines, AMissingResetPulseIsAMismatchNamingTheLine) {
  for (const char* keys : {"timing=none", "timing=session"}) {
    SCOPED_TRACE(keys);
    auto port = replay(reset_session(), std::string(keys) + ",unused=ignore");
    EXPECT_EQ(read_exactly(*port, 5), "BOOT\n");
    const std::string report = mismatch_of([&] { port->write_all("PING\n"); });
    expect_contains(report, "the recording has DTR low before these bytes, and the client "
                            "did not make it");
    expect_contains(report, "session time 0.001000 s, exchange");
    expect_contains(report, "expected line change: DTR low");
    expect_contains(report, "actual line change:   (none)");
  }
}

TEST(ReplayLines, AnExtraPulseIsAMismatch) {
  auto port = replay(reset_session(), "timing=none,unused=ignore");
  port->set_dtr(false);
  port->set_dtr(true);
  const std::string report = mismatch_of([&] { port->set_dtr(false); });
  expect_contains(report, "the client made DTR low where the recording has none");
  expect_contains(report, "expected line change: (none)");
  expect_contains(report, "actual line change:   DTR low");
}

TEST(ReplayLines, AWrongLevelIsAMismatchWithBothLevels) {
  auto port = replay(reset_session(), "timing=none,unused=ignore");
  const std::string report = mismatch_of([&] { port->set_dtr(true); });
  expect_contains(report, "the client made DTR high; the recording has DTR low");
  expect_contains(report, "session time 0.001000 s");
  expect_contains(report, "expected line change: DTR low");
  expect_contains(report, "actual line change:   DTR high");
}

// Issue 37: a client that skips its reset pulse and sends a break is told
// the event expected there, its own, and the recorded writes that follow
// (not that the recorded writes end there).
TEST(ReplayLines, ALineMismatchNamesBothEventsAndTheRecordedWritesThatFollow) {
  auto port = replay(reset_session(), "timing=none,unused=ignore");
  const std::string report = mismatch_of([&] { port->send_break(250ms); });
  expect_contains(report, "the client made a break; the recording has DTR low");
  expect_contains(report, "at tx byte offset 0, session time 0.001000 s");
  expect_contains(report, "expected line change: DTR low");
  expect_contains(report, "actual line change:   a break");
  expect_contains(report, "recorded writes that follow: 50 49 4e 47 0a  |PING.|");
  EXPECT_EQ(report.find("end here"), std::string::npos) << report;
}

TEST(ReplayLines, AnExtraChangeAfterTheLastWriteSaysTheRecordedWritesEnd) {
  auto port = replay(reset_session(), "timing=none,unused=ignore");
  reset_and_talk(*port);
  const std::string report = mismatch_of([&] { port->set_dtr(false); });
  expect_contains(report, "the client made DTR low where the recording has none");
  expect_contains(report, "recorded writes that follow: (none: the recorded writes end here)");
}

TEST(ReplayLines, AnotherLineIsAMismatch) {
  auto port = replay(reset_session(), "timing=none,unused=ignore");
  const std::string report = mismatch_of([&] { port->set_rts(false); });
  expect_contains(report, "the client made RTS low; the recording has DTR low");
}

TEST(ReplayLines, TheBreakIsCheckedAmongTheBytesButNotItsLength) {
  {
    auto port = replay(reset_session(), "timing=none");
    port->set_dtr(false);
    port->set_dtr(true);
    port->write_all("PING\n");
    port->send_break(3ms);  // another length: the client's timing, not checked
    port->write_all("BYE\n");
  }
  {
    auto port = replay(reset_session(), "timing=none");
    port->set_dtr(false);
    port->set_dtr(true);
    port->write_all("PING\n");
    const std::string report = mismatch_of([&] { port->write_all("BYE\n"); });
    expect_contains(report, "the recording has a break before these bytes");
  }
}

TEST(ReplayLines, ALineChangeAfterTheLastWriteNeverMadeIsUnused) {
  auto records = reset_session();
  records.insert(records.end() - 1, dtr(ms(640), false));
  auto port = replay(records, "timing=none,unused=error");
  reset_and_talk(*port);
  try {
    port->close();
    FAIL() << "a line change never made was not reported";
  } catch (const ReplayMismatch& mismatch) {
    expect_contains(mismatch.what(), "1 recorded line changes of the client were never made "
                                     "(the first: DTR low at session time 0.640000 s)");
  }
}

TEST(ReplayLines, ALineChangeInASessionTheClientNeverWroteToIsUnused) {
  // No tx at all: the read cursor passes the line records, so the close
  // still looks for the client's line changes.
  const std::vector<Record> records = {
      {0, RecordKind::open, R"({"description":"serial /dev/ttyUSB0"})"},
      device_lines(0, true, true, false, false), rx(ms(10), "BOOT\n"), dtr(ms(20), false),
      rx(ms(30), "READY\n"), {ms(40), RecordKind::close, ""}};
  auto port = replay(records, "timing=none,unused=error");
  EXPECT_EQ(read_exactly(*port, 11), "BOOT\nREADY\n");
  try {
    port->close();
    FAIL() << "a line change never made was not reported";
  } catch (const ReplayMismatch& mismatch) {
    expect_contains(mismatch.what(), "1 recorded line changes of the client were never made "
                                     "(the first: DTR low at session time 0.020000 s)");
  }
}

TEST(ReplayLines, CheckOffChecksNoLines) {
  auto port = replay(reset_session(), "timing=none,check=off,unused=ignore");
  port->set_rts(false);
  port->write_all("PING\n");
  EXPECT_EQ(lines_of(*port), released_lines(reset_session(), 5));
}

TEST(ReplayLines, RequestModeServesTheLinesBeforeTheFirstRequestAndChecksNone) {
  const auto records = reset_session();
  auto port = replay(records, "timing=none,match=request,unused=ignore");
  EXPECT_EQ(lines_of(*port), released_lines(records, 0));
  port->set_rts(false);  // not checked
  port->write_all("PING\n");
  EXPECT_EQ(read_exactly(*port, 10), "BOOT\nPONG\n");
}

TEST(ReplayLines, WithAProfileSequenceModeChecksTheLinesAmongTheFrames) {
  {
    auto port = replay(reset_session(), "timing=none,profile=lines,unused=error");
    reset_and_talk(*port);
    EXPECT_NO_THROW(port->close());
  }
  {
    auto port = replay(reset_session(), "timing=none,profile=lines,unused=ignore");
    EXPECT_EQ(read_exactly(*port, 5), "BOOT\n");
    const std::string report = mismatch_of([&] { port->write_all("PING\n"); });
    expect_contains(report, "expected line change: DTR low");
  }
}

TEST(ReplayLines, WithAProfileRequestModeServesTheLinesAndChecksNone) {
  const auto records = reset_session();
  auto port = replay(records, "timing=none,profile=lines,match=request,unused=ignore");
  EXPECT_EQ(lines_of(*port), released_lines(records, 0));
  port->write_all("PING\n");
  EXPECT_EQ(read_exactly(*port, 10), "BOOT\nPONG\n");
  EXPECT_EQ(lines_of(*port), released_lines(records, 0));  // later changes: not served
}
