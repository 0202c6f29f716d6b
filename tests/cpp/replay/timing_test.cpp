// src/replay/timing.cpp: when a recorded thing is due on the replay clock
// (timing=none, session, causal; speed; the origin of a client session) and
// the check=timing window around it, first on ReplayTimeline itself with
// times the test chooses, then through a replay.
#include <gtest/gtest.h>

#include <chrono>
#include <optional>
#include <string>

#include "replay/replay_config.hpp"
#include "replay/timing.hpp"
#include "support/replay_support.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/port.hpp"

using namespace wiretape;
using namespace std::chrono_literals;
using namespace wiretape::test::replay_support;
using wiretape::detail::ReplayTime;
using wiretape::detail::ReplayTimeline;

namespace {

// A fixed open time: the timeline reads no clock, so any time point will do.
const ReplayTime kOpen = ReplayTime(std::chrono::seconds(1000));

ReplayTimeline timeline(const std::string& keys, std::uint64_t origin_ns = 0) {
  return ReplayTimeline(config_from(keys), kOpen, origin_ns);
}

ReplayTimeline::Anchor anchor(ReplayTime finished, std::uint64_t recorded_t_ns) {
  return ReplayTimeline::Anchor{finished, recorded_t_ns};
}

}  // namespace

// --- the due-time formula ------------------------------------------------------------

TEST(ReplayTimelineDue, TimingNoneIsDueAtTheOpenWhateverTheRecordedTime) {
  const ReplayTimeline none = timeline("timing=none");
  EXPECT_EQ(none.due(0, std::nullopt), kOpen);
  EXPECT_EQ(none.due(ms(5000), std::nullopt), kOpen);
  EXPECT_EQ(none.due(ms(5000), anchor(kOpen + 3s, ms(1))), kOpen);
}

TEST(ReplayTimelineDue, SessionTimingIsTheOpenPlusTheRecordedTimeOverSpeed) {
  EXPECT_EQ(timeline("timing=session").due(ms(250), std::nullopt), kOpen + 250ms);
  EXPECT_EQ(timeline("timing=session,speed=4").due(ms(400), std::nullopt), kOpen + 100ms);
  EXPECT_EQ(timeline("timing=session,speed=0.5").due(ms(10), std::nullopt), kOpen + 20ms);
  // An anchor changes nothing under timing=session: time alone decides.
  EXPECT_EQ(timeline("timing=session").due(ms(250), anchor(kOpen + 10s, ms(100))),
            kOpen + 250ms);
}

TEST(ReplayTimelineDue, SessionTimingCountsFromTheOrigin) {
  // A later client session of a virtual device starts at its recorded
  // client_connect: that time is the open time.
  const ReplayTimeline later = timeline("timing=session", ms(1000));
  EXPECT_EQ(later.due(ms(1000), std::nullopt), kOpen);
  EXPECT_EQ(later.due(ms(1300), std::nullopt), kOpen + 300ms);
  // Recorded before the origin (the session before's tail): due at once.
  EXPECT_EQ(later.due(ms(200), std::nullopt), kOpen);
}

TEST(ReplayTimelineDue, CausalTimingIsTheAnchorsFinishPlusTheRecordedGap) {
  const ReplayTimeline causal = timeline("timing=causal");
  const ReplayTime wrote = kOpen + 7s;  // the client was slow to ask
  EXPECT_EQ(causal.due(ms(160), anchor(wrote, ms(100))), wrote + 60ms);
  const ReplayTimeline faster = timeline("timing=causal,speed=3");
  EXPECT_EQ(faster.due(ms(160), anchor(wrote, ms(100))), wrote + 20ms);
}

TEST(ReplayTimelineDue, CausalTimingWithoutAnAnchorIsSessionTiming) {
  EXPECT_EQ(timeline("timing=causal").due(ms(40), std::nullopt), kOpen + 40ms);
  EXPECT_EQ(timeline("timing=causal,speed=2", ms(20)).due(ms(40), std::nullopt),
            kOpen + 10ms);
}

// A clock's granularity can stamp a record before the write it follows.
TEST(ReplayTimelineDue, ARecordStampedBeforeItsAnchorIsDueAtTheAnchor) {
  const ReplayTime wrote = kOpen + 1s;
  EXPECT_EQ(timeline("timing=causal").due(ms(99), anchor(wrote, ms(100))), wrote);
}

TEST(ReplayTimelineDue, SpeedRoundsToTheNearestNanosecond) {
  // 1 ns / 3 = 0.33 ns rounds to 0; 2 ns / 3 = 0.67 ns rounds to 1.
  const ReplayTimeline third = timeline("timing=session,speed=3");
  EXPECT_EQ(third.due(1, std::nullopt), kOpen);
  EXPECT_EQ(third.due(2, std::nullopt), kOpen + 1ns);
}

// --- the check=timing window -----------------------------------------------------------

TEST(ReplayTimelineCheck, WithoutCheckTimingNothingIsEverAMiss) {
  for (const char* keys : {"timing=session,check=data", "timing=causal,check=off"}) {
    const ReplayTimeline unchecked = timeline(keys);
    EXPECT_EQ(unchecked.check(kOpen, kOpen - 1h), std::nullopt) << keys;
    EXPECT_EQ(unchecked.check(kOpen, kOpen + 1h), std::nullopt) << keys;
  }
}

TEST(ReplayTimelineCheck, TheWindowIsDuePlusOrMinusToleranceEdgesIncluded) {
  const ReplayTimeline checked = timeline("timing=session,check=timing,tolerance=50");
  const ReplayTime due = kOpen + 1s;
  EXPECT_EQ(checked.check(due, due), std::nullopt);
  EXPECT_EQ(checked.check(due, due - 50ms), std::nullopt);
  EXPECT_EQ(checked.check(due, due + 50ms), std::nullopt);
  const auto early = checked.check(due, due - 50ms - 1ns);
  ASSERT_TRUE(early.has_value());
  EXPECT_TRUE(early->early);
  const auto late = checked.check(due, due + 50ms + 1ns);
  ASSERT_TRUE(late.has_value());
  EXPECT_FALSE(late->early);
}

TEST(ReplayTimelineCheck, AMissSaysHowEarlyOrLateTheToleranceAndTheTiming) {
  const ReplayTimeline session = timeline("timing=session,check=timing,tolerance=20");
  const auto early = session.check(kOpen + 1s, kOpen + 1s - 125ms);
  ASSERT_TRUE(early.has_value());
  EXPECT_EQ(early->title, "the client wrote too early");
  EXPECT_EQ(early->detail,
            "  the write came 125.000 ms early (tolerance 20.000 ms, timing=session)\n");
  const ReplayTimeline causal = timeline("timing=causal,check=timing,tolerance=0.5");
  const auto late = causal.check(kOpen, kOpen + 2500us);
  ASSERT_TRUE(late.has_value());
  EXPECT_EQ(late->title, "the client wrote too late");
  EXPECT_EQ(late->detail,
            "  the write came 2.500 ms late (tolerance 0.500 ms, timing=causal)\n");
}

TEST(ReplayTimelineCheck, AWriteIsCheckedAgainstTheWriteBeforeItUnderCausalTiming) {
  const ReplayTimeline causal = timeline("timing=causal,check=timing,tolerance=10");
  const ReplayTime previous = kOpen + 5s;
  // Recorded 100 ms after the previous write: due 100 ms after the client's.
  EXPECT_EQ(causal.check_write(ms(300), previous, ms(200), previous + 100ms), std::nullopt);
  const auto late = causal.check_write(ms(300), previous, ms(200), previous + 150ms);
  ASSERT_TRUE(late.has_value());
  EXPECT_FALSE(late->early);
  // The first write has nothing before it: measured from the open.
  EXPECT_EQ(causal.check_write(ms(30), std::nullopt, 0, kOpen + 30ms), std::nullopt);
  EXPECT_TRUE(causal.check_write(ms(30), std::nullopt, 0, kOpen + 5s).has_value());
}

// --- through a replay ------------------------------------------------------------------

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

TEST(ReplayTiming, CausalSpeedScalesTheGaps) {
  auto port = replay({tx(0, "Q"), rx(ms(2000), "A")}, "timing=causal,speed=20");
  const auto asked = std::chrono::steady_clock::now();
  port->write("Q");
  EXPECT_EQ(read_some(*port, 10, 5s), "A");  // 100 ms, not 2 s
  EXPECT_GE(std::chrono::steady_clock::now() - asked, 90ms);
}
