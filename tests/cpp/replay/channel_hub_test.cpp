// src/replay/channel_hub.cpp: what the replays of one session file's
// channels share in a process (DESIGN.md section 19): one hub per file
// (found by device and inode), one clock, and under timing=causal the gate
// that holds a channel's rx until the client has written, on every other
// channel, the tx recorded before it. Driven directly, with times the test
// chooses; tests/cpp/replay/replay_channels_test.cpp replays through it.
#include <unistd.h>

#include <gtest/gtest.h>

#include <chrono>
#include <memory>
#include <string>
#include <vector>

#include "replay/channel_hub.hpp"
#include "support/port_test_support.hpp"

using namespace wiretape;
using namespace std::chrono_literals;
using wiretape::detail::ChannelHub;
using wiretape::detail::ChannelMember;
using wiretape::detail::ReplayTime;
using wiretape::test::TempDir;

namespace {

constexpr std::uint64_t ms(std::uint64_t n) { return n * 1'000'000; }

const ReplayTime kStart = ReplayTime(std::chrono::seconds(100));

std::string made_file(const TempDir& dir, const std::string& name) {
  const std::string path = dir.file(name);
  test::write_file(path, "session");
  return path;
}

// A hub of a file of its own, for the order across channels.
std::shared_ptr<ChannelHub> fresh_hub(const TempDir& dir) {
  return ChannelHub::of_file(made_file(dir, "channels.wtape"));
}

}  // namespace

// --- one hub per file -------------------------------------------------------------------

TEST(ChannelHub, OneFileHasOneHubWhateverItsName) {
  TempDir dir;
  const std::string path = made_file(dir, "run.wtape");
  const std::string link = dir.file("link.wtape");
  ASSERT_EQ(::link(path.c_str(), link.c_str()), 0);
  const std::string symlink = dir.file("symlink.wtape");
  ASSERT_EQ(::symlink(path.c_str(), symlink.c_str()), 0);
  const auto hub = ChannelHub::of_file(path);
  EXPECT_EQ(ChannelHub::of_file(path), hub);
  EXPECT_EQ(ChannelHub::of_file(link), hub);
  EXPECT_EQ(ChannelHub::of_file(symlink), hub);
  EXPECT_NE(ChannelHub::of_file(made_file(dir, "other.wtape")), hub);
}

TEST(ChannelHub, AHubLivesWhileAReplayHoldsIt) {
  TempDir dir;
  const std::string path = made_file(dir, "run.wtape");
  {
    const auto first = ChannelHub::of_file(path);
    EXPECT_EQ(first->open_time(kStart), kStart);
  }
  // Nobody held the first: the next replay of the file starts a clock anew.
  const auto second = ChannelHub::of_file(path);
  EXPECT_EQ(second->open_time(kStart + 5s), kStart + 5s);
}

TEST(ChannelHub, AFileThatCannotBeFoundGetsAHubSharedWithNobody) {
  const auto one = ChannelHub::of_file("/nonexistent/run.wtape");
  const auto two = ChannelHub::of_file("/nonexistent/run.wtape");
  ASSERT_NE(one, nullptr);
  EXPECT_NE(one, two);
}

// --- one clock ---------------------------------------------------------------------------

TEST(ChannelHub, TheClockIsTheFirstCallsTimeForEveryCallAfter) {
  TempDir dir;
  const auto hub = fresh_hub(dir);
  EXPECT_EQ(hub->open_time(kStart), kStart);
  EXPECT_EQ(hub->open_time(kStart + 3s), kStart);
  // The first client session's clock is its own, also set once.
  EXPECT_EQ(hub->first_client_time(kStart + 1s), kStart + 1s);
  EXPECT_EQ(hub->first_client_time(kStart + 9s), kStart + 1s);
  EXPECT_EQ(hub->open_time(kStart + 9s), kStart);
}

// --- the order across channels ------------------------------------------------------------

// The RTK channel's login (5 bytes, recorded at 10 ms) and its second
// request (3 more bytes, at 30 ms) gate the GPS channel's rx recorded after
// them.
TEST(ChannelMember, RxWaitsForTheOtherChannelsTxRecordedBeforeIt) {
  TempDir dir;
  const auto hub = fresh_hub(dir);
  const auto gps = hub->join(0, {});
  const auto rtk = hub->join(1, {{5, ms(10)}, {8, ms(30)}});
  EXPECT_TRUE(gps->gate(ms(5)).open);
  EXPECT_FALSE(gps->gate(ms(5)).anchor.has_value());
  // Recorded at the same time as the login: not after it.
  EXPECT_TRUE(gps->gate(ms(10)).open);
  EXPECT_FALSE(gps->gate(ms(20)).open);
  rtk->wrote(4, kStart + 1s);
  EXPECT_FALSE(gps->gate(ms(20)).open);  // 4 of the login's 5 bytes
  rtk->wrote(1, kStart + 2s);
  const ChannelMember::Gate after_login = gps->gate(ms(20));
  EXPECT_TRUE(after_login.open);
  ASSERT_TRUE(after_login.anchor.has_value());
  EXPECT_EQ(after_login.anchor->finished, kStart + 2s);
  EXPECT_EQ(after_login.anchor->recorded_t_ns, ms(10));
  EXPECT_FALSE(gps->gate(ms(40)).open);
  rtk->wrote(3, kStart + 4s);
  const ChannelMember::Gate after_both = gps->gate(ms(40));
  EXPECT_TRUE(after_both.open);
  EXPECT_EQ(after_both.anchor->finished, kStart + 4s);
  EXPECT_EQ(after_both.anchor->recorded_t_ns, ms(30));
  // A channel's own tx never gates it: its strategy orders those.
  EXPECT_TRUE(rtk->gate(ms(40)).open);
}

// One write that covers both requests covers them at one time.
TEST(ChannelMember, OneWriteCoversEveryRequestItCompletes) {
  TempDir dir;
  const auto hub = fresh_hub(dir);
  const auto gps = hub->join(0, {});
  const auto rtk = hub->join(1, {{5, ms(10)}, {8, ms(30)}});
  rtk->wrote(8, kStart + 1s);
  EXPECT_EQ(gps->gate(ms(20)).anchor->finished, kStart + 1s);
  EXPECT_EQ(gps->gate(ms(40)).anchor->finished, kStart + 1s);
}

TEST(ChannelMember, TheAnchorIsTheLatestOfTheOtherChannelsWrites) {
  TempDir dir;
  const auto hub = fresh_hub(dir);
  const auto gps = hub->join(0, {});
  const auto rtk = hub->join(1, {{2, ms(10)}});
  const auto imu = hub->join(2, {{2, ms(20)}});
  imu->wrote(2, kStart + 1s);  // recorded later, written first
  EXPECT_FALSE(gps->gate(ms(30)).open);
  rtk->wrote(2, kStart + 3s);
  const ChannelMember::Gate gate = gps->gate(ms(30));
  ASSERT_TRUE(gate.open);
  EXPECT_EQ(gate.anchor->finished, kStart + 3s);
  EXPECT_EQ(gate.anchor->recorded_t_ns, ms(10));
}

// Two replays of one channel are two clients of one device, not an order.
TEST(ChannelMember, ReplaysOfTheSameChannelDoNotGateEachOther) {
  TempDir dir;
  const auto hub = fresh_hub(dir);
  const auto first = hub->join(1, {});
  const auto second = hub->join(1, {{5, ms(10)}});
  EXPECT_TRUE(first->gate(ms(50)).open);
}

TEST(ChannelMember, AClosedReplayNoLongerHoldsTheOthersBack) {
  TempDir dir;
  const auto hub = fresh_hub(dir);
  const auto gps = hub->join(0, {});
  auto rtk = hub->join(1, {{5, ms(10)}});
  EXPECT_FALSE(gps->gate(ms(20)).open);
  rtk->leave();
  EXPECT_TRUE(gps->gate(ms(20)).open);
  rtk->leave();  // twice is once
  {
    const auto imu = hub->join(2, {{5, ms(10)}});
    EXPECT_FALSE(gps->gate(ms(20)).open);
  }
  EXPECT_TRUE(gps->gate(ms(20)).open) << "a member destroyed has left";
}

// The others' replays are woken when a write covers a request, and only then.
TEST(ChannelMember, AWriteThatCoversARequestWakesTheOtherChannels) {
  TempDir dir;
  const auto hub = fresh_hub(dir);
  const auto gps = hub->join(0, {});
  const auto rtk = hub->join(1, {{5, ms(10)}, {8, ms(30)}});
  int gps_woken = 0;
  int rtk_woken = 0;
  gps->set_waker([&] { ++gps_woken; });
  rtk->set_waker([&] { ++rtk_woken; });
  rtk->wrote(0, kStart);
  rtk->wrote(3, kStart);
  EXPECT_EQ(gps_woken, 0) << "nothing newly covered";
  rtk->wrote(2, kStart);
  EXPECT_EQ(gps_woken, 1);
  EXPECT_EQ(rtk_woken, 0) << "a writer is not woken by its own write";
  gps->set_waker(nullptr);
  rtk->wrote(3, kStart);
  EXPECT_EQ(gps_woken, 1);
}

TEST(ChannelMember, AMemberThatLeftIsNeverWokenAfter) {
  TempDir dir;
  const auto hub = fresh_hub(dir);
  const auto gps = hub->join(0, {});
  const auto rtk = hub->join(1, {{1, ms(10)}});
  int woken = 0;
  gps->set_waker([&] { ++woken; });
  gps->leave();
  rtk->wrote(1, kStart);
  EXPECT_EQ(woken, 0);
}
