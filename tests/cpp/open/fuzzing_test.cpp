// include/wiretape/fuzzing.hpp: every plan over every built-in profile is a
// replay the engine plays to its end, serving what the plan's written
// session holds; a plan of length zero replays the recording unchanged; bad
// input is refused by name.
#include "wiretape/fuzzing.hpp"

#include <gtest/gtest.h>

#include <random>
#include <string>
#include <vector>

#include "support/profile_seeds.hpp"
#include "support/replay_support.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/profile.hpp"

namespace wiretape {
namespace {

using test::TempDir;
using test::replay_support::ms;
using test::replay_support::rx;
using test::replay_support::tx;
using test::replay_support::write_session;

// A session for `profile`: a request before each of its seed frames.
std::string profile_session(const TempDir& dir, const Profile& profile) {
  std::vector<Record> records;
  std::uint64_t t = 0;
  for (const std::string& frame : test::profile_seed_frames(profile)) {
    records.push_back(tx(ms(++t), "?\n"));
    records.push_back(rx(ms(++t), frame));
  }
  return write_session(dir, records);
}

// What a client writing the recorded requests gets until the replay ends.
std::string served(Port& port, int requests) {
  for (int i = 0; i < requests; ++i) port.write("?\n", 2);
  std::string got;
  char buffer[256];
  try {
    for (;;) got.append(buffer, port.read(buffer, sizeof buffer, std::chrono::seconds(5)));
  } catch (const PortClosed&) {
  }
  return got;
}

std::string rx_of(const std::string& path) {
  SessionReader reader(path);
  std::string all;
  for (Record record; reader.next(record);)
    if (record.kind == RecordKind::rx) all += record.data;
  return all;
}

TEST(FuzzedReplay, EmptyPlanReplaysEveryProfilesRecordingUnchanged) {
  for (const std::string& name : profile_names()) {
    SCOPED_TRACE(name);
    TempDir dir;
    const std::string path = profile_session(dir, *find_profile(name));
    const FuzzedReplay replay(path, name);
    EXPECT_EQ(replay.units(), 2u);
    auto port = replay.open("");
    EXPECT_EQ(served(*port, 2), rx_of(path));
    EXPECT_TRUE(replay.edits("").empty());
  }
}

// The property the fuzzers rely on, through the replay engine: any byte
// string, on any built-in profile, opens a replay that plays to its end and
// serves exactly what the plan's written session records.
TEST(FuzzedReplay, EveryPlanIsAReplayOfItsWrittenSession) {
  std::mt19937 random(2740);  // fixed seed: the same plans on every run
  for (const std::string& name : profile_names()) {
    SCOPED_TRACE(name);
    TempDir dir;
    const std::string path = profile_session(dir, *find_profile(name));
    const FuzzedReplay replay(path, name);
    for (int run = 0; run < 60; ++run) {
      std::string plan(random() % 40, '\0');
      for (char& byte : plan) byte = static_cast<char>(random());
      const std::string written = dir.file("plan.wtape");
      const std::vector<std::string> edits = replay.write(written, plan);
      EXPECT_EQ(edits, replay.edits(plan));
      EXPECT_EQ(SessionReader(written).header().edits, edits);
      auto port = replay.open(plan);
      EXPECT_EQ(served(*port, 2), rx_of(written)) << "plan of " << plan.size() << " bytes";
    }
  }
}

TEST(FuzzedReplay, WithoutAProfileThePlanActsOnRxRecords) {
  TempDir dir;
  const std::string path = write_session(dir, {tx(ms(1), "?\n"), rx(ms(2), "AB"), rx(ms(3), "CD")});
  const FuzzedReplay replay(path);
  EXPECT_EQ(replay.units(), 2u);
  const std::string drop_first("\x05\x00\x00\x00", 4);
  EXPECT_EQ(replay.edits(drop_first), std::vector<std::string>{"rx record 0 dropped"});
  auto port = replay.open(drop_first);
  EXPECT_EQ(served(*port, 1), "CD");
}

TEST(FuzzedReplay, BadInputIsRefusedByName) {
  TempDir dir;
  const std::string lines = write_session(dir, {tx(ms(1), "?\n"), rx(ms(2), "OK\n")});
  EXPECT_THROW(FuzzedReplay(lines, "no-such-profile"), OptionError);
  EXPECT_THROW(FuzzedReplay(lines, "", "no_such_key=1"), OptionError);
  EXPECT_THROW(FuzzedReplay(lines, "mavlink"), OptionError);  // no MAVLink frame in it
  EXPECT_THROW(FuzzedReplay(dir.file("missing.wtape")), PortError);  // cannot open
}

}  // namespace
}  // namespace wiretape
