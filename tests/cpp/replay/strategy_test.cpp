// src/replay/strategy.cpp: what the replay engine shares with its match
// strategies: the released rx queue (its byte count, the payload buffers it
// keeps, the device's lines released like rx), the mismatch report, the
// wildcards of redacted bytes, and whether a recorded close is a loss or the
// end.
#include <gtest/gtest.h>

#include <chrono>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "replay/strategy.hpp"
#include "session/record_kinds.hpp"
#include "support/replay_support.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/port.hpp"

using namespace wiretape;
using namespace std::chrono_literals;
using namespace wiretape::test::replay_support;
using wiretape::detail::MismatchReport;
using wiretape::detail::ModemInputs;
using wiretape::detail::ReleasedRx;
using wiretape::detail::ReplayMatch;
using wiretape::detail::ReplayTime;
using wiretape::detail::RxItem;
using wiretape::detail::Wildcards;

namespace {

RxItem item(std::string data) {
  RxItem made;
  made.data = std::move(data);
  return made;
}

// The report `raise` throws.
std::string report_of(const std::function<void()>& raise) {
  try {
    raise();
  } catch (const ReplayMismatch& mismatch) {
    return mismatch.what();
  }
  ADD_FAILURE() << "no ReplayMismatch was raised";
  return {};
}

bool goes_on(std::vector<Record> records) {
  auto source = detail::vector_source_factory(std::move(records))();
  return detail::session_goes_on(*source);
}

}  // namespace

// --- the released rx ------------------------------------------------------------------

TEST(ReleasedRx, CountsTheBytesQueued) {
  ReleasedRx released(/*recycle_payloads=*/false);
  EXPECT_TRUE(released.empty());
  released.push(item("abc"));
  released.push(item("defgh"));
  EXPECT_EQ(released.size(), 2u);
  EXPECT_EQ(released.bytes(), 8u);
  EXPECT_EQ(released.front().data, "abc");
  released.pop_front();
  EXPECT_EQ(released.bytes(), 5u);
  EXPECT_EQ(released.front().data, "defgh");
  released.pop_front();
  EXPECT_TRUE(released.empty());
  EXPECT_EQ(released.bytes(), 0u);
}

TEST(ReleasedRx, KeepsReadPayloadsForReuseOnlyWhenAskedTo) {
  ReleasedRx recycling(/*recycle_payloads=*/true);
  EXPECT_LT(recycling.spare_payload().capacity(), 1000u);  // none kept yet
  recycling.push(item(std::string(1000, 'x')));
  recycling.pop_front();
  const std::string spare = recycling.spare_payload();
  EXPECT_TRUE(spare.empty());
  EXPECT_GE(spare.capacity(), 1000u);
  ReleasedRx keeping_none(/*recycle_payloads=*/false);
  keeping_none.push(item(std::string(1000, 'x')));
  keeping_none.pop_front();
  EXPECT_LT(keeping_none.spare_payload().capacity(), 1000u);
}

// Memory stays independent of the session: no more than the look-ahead's
// bytes are kept.
TEST(ReleasedRx, KeptPayloadsAreBoundedByTheLookAhead) {
  ReleasedRx released(/*recycle_payloads=*/true);
  const std::size_t record = detail::kLookaheadBytes / 4;
  for (int i = 0; i < 16; ++i) released.recycle_payload(std::string(record, 'x'));
  std::size_t kept = 0;
  while (true) {
    // A fresh string each time: assigning into one would keep its buffer.
    const std::string spare = released.spare_payload();
    if (spare.capacity() < record) break;
    kept += spare.capacity();
  }
  EXPECT_LE(kept, detail::kLookaheadBytes);
  EXPECT_GE(kept, 3 * record);
}

TEST(ReleasedRx, DeviceLinesChangeAtTheirDueTimeInRecordedOrder) {
  ReleasedRx released(false);
  const ReplayTime open = ReplayTime(std::chrono::seconds(50));
  const ModemInputs line_up;  // a modem's levels before any change
  ModemInputs cts_low = line_up;
  cts_low.cts = false;
  ModemInputs ringing = cts_low;
  ringing.ri = true;
  released.push_lines(open + 10ms, cts_low);
  released.push_lines(open + 20ms, ringing);
  EXPECT_EQ(released.device_lines(open), line_up);
  EXPECT_EQ(released.device_lines(open + 10ms), cts_low);
  EXPECT_EQ(released.device_lines(open + 15ms), cts_low);
  EXPECT_EQ(released.device_lines(open + 1s), ringing);
  EXPECT_EQ(released.device_lines(open + 2s), ringing);  // the last change stays
}

// --- the mismatch report --------------------------------------------------------------

TEST(MismatchReport, TheBeforeLineHoldsTheLastSixteenAcceptedBytes) {
  MismatchReport report("run.wtape", ReplayMatch::sequence);
  report.accepted("0123456789");
  report.accepted("abcdefghij");  // 20 bytes accepted: the first 4 go
  const std::string text =
      report_of([&] { report.raise("title", 20, "Z", "Y", ms(1), 3); });
  EXPECT_NE(text.find("|456789abcdefghij|"), std::string::npos) << text;
  EXPECT_EQ(text.find("0123"), std::string::npos) << text;
  report.accepted(std::string(40, 'k'));  // one write longer than the context
  const std::string after = report_of([&] { report.raise("title", 60, "Z", "Y", 0, 3); });
  EXPECT_NE(after.find("|" + std::string(16, 'k') + "|"), std::string::npos) << after;
  EXPECT_EQ(after.find("abc"), std::string::npos) << after;
}

TEST(MismatchReport, NamesTheFileChannelOffsetTimeAndExchange) {
  MismatchReport report("run.wtape", ReplayMatch::sequence, "gps");
  try {
    report.raise("the client wrote other bytes", 7, "AB", "XY", 1'500'000'000, 4,
                 "  more said here\n");
    FAIL() << "raise returned";
  } catch (const ReplayMismatch& mismatch) {
    EXPECT_EQ(mismatch.tx_offset(), 7u);
    EXPECT_EQ(mismatch.session_time_ns(), 1'500'000'000u);
    EXPECT_EQ(mismatch.exchange(), 4);
    EXPECT_EQ(std::string(mismatch.what()),
              "replay mismatch in run.wtape: channel gps: the client wrote other bytes\n"
              "  at tx byte offset 7, session time 1.500000 s, exchange 4\n"
              "  before:   (none)\n"
              "  expected: 41 42  |AB|\n"
              "  actual:   58 59  |XY|\n"
              "  more said here\n");
  }
}

TEST(MismatchReport, SaysWhatAnEmptyExpectationMeans) {
  MismatchReport sequence("f", ReplayMatch::sequence);
  EXPECT_NE(report_of([&] { sequence.raise("t", 0, "", "Q", 0, -1); })
                .find("expected: (nothing: the recorded writes end here)"),
            std::string::npos);
  EXPECT_NE(report_of([&] { sequence.raise("t", 0, "", "Q", 0, 0, {}, true); })
                .find("expected: (an empty datagram)"),
            std::string::npos);
  const std::string no_exchange = report_of([&] { sequence.raise("t", 0, "", "Q", 0, -1); });
  EXPECT_NE(no_exchange.find("exchange -\n"), std::string::npos) << no_exchange;
  EXPECT_EQ(no_exchange.find("channel"), std::string::npos) << no_exchange;
}

TEST(MismatchReport, SessionSecondsHaveSixDecimals) {
  EXPECT_EQ(detail::session_seconds(0), "0.000000");
  EXPECT_EQ(detail::session_seconds(30'000'000), "0.030000");
  EXPECT_EQ(detail::session_seconds(12'345'678'901), "12.345679");
}

// --- wildcards of redacted bytes --------------------------------------------------------

TEST(Wildcards, CoverTheRangesARedactionNames) {
  Wildcards wildcards;
  EXPECT_TRUE(wildcards.empty());
  wildcards.add_event(R"({"offset":2,"length":3})");
  wildcards.add(10, 0);  // an empty range is none
  EXPECT_FALSE(wildcards.covers(1));
  EXPECT_TRUE(wildcards.covers(2));
  EXPECT_TRUE(wildcards.covers(4));
  EXPECT_FALSE(wildcards.covers(5));
  EXPECT_FALSE(wildcards.covers(10));
  wildcards.clear();
  EXPECT_TRUE(wildcards.empty());
}

TEST(Wildcards, APayloadThatNamesNoRangeAddsNone) {
  Wildcards wildcards;
  for (const char* payload : {"", "{}", "not json", R"({"offset":1})",
                              R"({"offset":-1,"length":2})", R"({"offset":1,"length":-2})"}) {
    wildcards.add_event(payload);
    EXPECT_TRUE(wildcards.empty()) << payload;
  }
}

TEST(Wildcards, ShiftedRangesMoveWithTheRecordInItsRequest) {
  Wildcards record;
  record.add(0, 2);
  Wildcards request;
  request.add(1, 1);
  request.append_shifted(record, 5);
  EXPECT_TRUE(request.covers(1));
  EXPECT_FALSE(request.covers(0));
  EXPECT_TRUE(request.covers(5));
  EXPECT_TRUE(request.covers(6));
  EXPECT_FALSE(request.covers(7));
}

TEST(Wildcards, AWildcardByteMatchesAnyByteInTheCommonPrefix) {
  EXPECT_EQ(detail::common_prefix("PING", "PINX"), 3u);
  EXPECT_EQ(detail::common_prefix("PI", "PING"), 2u);
  Wildcards none;
  EXPECT_EQ(detail::common_prefix("PASS=1234;", "PASS=9999;", none, 0), 5u);
  Wildcards secret;
  secret.add(5, 4);  // "1234" was scrubbed
  EXPECT_EQ(detail::common_prefix("PASS=1234;", "PASS=9999;", secret, 0), 10u);
  EXPECT_EQ(detail::common_prefix("PASS=1234;", "PASS=9999!", secret, 0), 9u);
  // From byte 5 of the record on: the wildcards are the record's own offsets.
  EXPECT_EQ(detail::common_prefix("1234;", "0000;", secret, 5), 5u);
  // From byte 6 on, three wildcard bytes (6, 7, 8), then "4" against "0".
  EXPECT_EQ(detail::common_prefix("1234;", "0000;", secret, 6), 3u);
}

// --- a recorded close: a loss, or the end -------------------------------------------

TEST(SessionGoesOn, OnlyBytesOrADeviceLossAfterACloseMakeItALoss) {
  EXPECT_FALSE(goes_on({}));
  EXPECT_FALSE(goes_on({event(1, RecordKind::open), {2, RecordKind::settings, "{}"}}));
  EXPECT_FALSE(goes_on({rx(1, ""), tx(2, "")}));  // empty records say nothing
  EXPECT_TRUE(goes_on({event(1, RecordKind::open), rx(2, "A")}));
  EXPECT_TRUE(goes_on({tx(1, "Q")}));
  EXPECT_TRUE(goes_on({event(1, RecordKind::device_lost)}));
}

// --- through a replay -------------------------------------------------------------------

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

// --- a request past the recorded exchanges --------------------------------------------

namespace {

// The mismatch a client raises by writing `extra` after every request of a
// two-exchange recording, under `keys`.
ReplayMismatch past_the_end(const std::string& keys, const std::string& extra = "EXTRA\n") {
  auto port = replay({tx(ms(1), "PING\n"), rx(ms(2), "PONG\n"), tx(ms(3), "TIME\n"),
                      rx(ms(4), "12:00\n")},
                     "timing=none,unused=ignore," + keys);
  port->write("PING\n");
  EXPECT_EQ(read_some(*port), "PONG\n");
  port->write("TIME\n");
  EXPECT_EQ(read_some(*port), "12:00\n");
  try {
    port->write(extra);
  } catch (const ReplayMismatch& mismatch) {
    return mismatch;
  }
  ADD_FAILURE() << keys << ": no mismatch";
  return ReplayMismatch("", 0, 0, -2);
}

}  // namespace

TEST(MismatchReport, ARequestPastTheRecordedExchangesSaysSoAndNamesTheirCount) {
  // The third request of a two-exchange recording is no exchange 1: it is
  // the next one, past the two the recording holds.
  for (const char* keys : {"match=sequence", "match=sequence,profile=lines", "match=request",
                           "match=request,profile=lines"}) {
    const ReplayMismatch mismatch = past_the_end(keys);
    const std::string report = mismatch.what();
    EXPECT_EQ(mismatch.exchange(), 2) << keys << ": " << report;
    EXPECT_NE(report.find("the client wrote more than the recording holds"), std::string::npos)
        << keys << ": " << report;
    EXPECT_NE(report.find("exchange 2, past the 2 recorded exchanges (0..1)\n"), std::string::npos)
        << keys << ": " << report;
    EXPECT_EQ(report.find("exchange 1"), std::string::npos) << keys << ": " << report;
  }
}

TEST(MismatchReport, ARequestPastOneRecordedExchangeSaysOne) {
  auto port = replay({tx(ms(1), "PING\n"), rx(ms(2), "PONG\n")}, "timing=none,unused=ignore");
  port->write("PING\n");
  EXPECT_EQ(read_some(*port), "PONG\n");
  try {
    port->write("PING\n");
    FAIL() << "no mismatch";
  } catch (const ReplayMismatch& mismatch) {
    EXPECT_NE(std::string(mismatch.what()).find("exchange 1, past the 1 recorded exchange (0)\n"),
              std::string::npos)
        << mismatch.what();
  }
}
