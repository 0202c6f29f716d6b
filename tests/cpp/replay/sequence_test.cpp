// src/replay/sequence.cpp: match=sequence: what a client is entitled to
// read after what it wrote, the checks of its bytes (check=off, data, past
// the recording, datagrams) and of its settings and lines (check=timing),
// a recorded close or loss at a write, and the report of what was unused.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "posix/transports.hpp"
#include "replay/replay_port.hpp"
#include "session/record_source.hpp"
#include "support/replay_support.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/port.hpp"
#include "wiretape/session.hpp"

using namespace wiretape;
using namespace std::chrono_literals;
using namespace wiretape::test::replay_support;
using wiretape::test::TempDir;

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

TEST(ReplaySequence, WritePastARecordedCloseRaisesPortClosed) {
  auto port = replay({tx(0, "Q"), event(1, RecordKind::close), rx(2, "late")});
  port->write("Q");
  EXPECT_THROW(port->write("R"), PortClosed);
}

TEST(ReplaySequence, EventsAreNotCheckedUnderCheckData) {
  auto port = replay({event(0, RecordKind::open), tx(1, "Q"),
                      {2, RecordKind::settings, "{\"baud\":115200}"},
                      {3, RecordKind::modem_lines, "{\"dtr\":true}"},
                      rx(4, "A")});
  port->write("Q");
  EXPECT_EQ(read_some(*port), "A");
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
