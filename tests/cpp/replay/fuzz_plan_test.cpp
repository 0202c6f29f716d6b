// Fuzzing plans over rx records (DESIGN.md section 27): any byte string is a
// plan, an empty plan changes nothing, each step kind does what it says and
// says it in words.
#include <gtest/gtest.h>

#include <random>
#include <string>
#include <vector>

#include "replay/fuzz_plan.hpp"
#include "support/profile_seeds.hpp"
#include "wiretape/profile.hpp"

namespace wiretape::detail {
namespace {

using test::profile_seed_frames;

std::vector<RxRecord> recording() { return {{"AB\x04", 0}, {"hello", 0}, {"xyz", 0}}; }

std::string step(MutationKind kind, int record, int offset, int amount) {
  return {static_cast<char>(kind), static_cast<char>(record), static_cast<char>(offset), static_cast<char>(amount)};
}

TEST(FuzzPlan, EmptyPlanLeavesTheRecordingUnchanged) {
  const MutatedRx out = apply_plan(recording(), "");
  ASSERT_EQ(out.records.size(), 3u);
  EXPECT_EQ(out.records[0].bytes, "AB\x04");
  EXPECT_EQ(out.records[1].bytes, "hello");
  EXPECT_EQ(out.records[2].bytes, "xyz");
  EXPECT_TRUE(out.edits.empty());
}

TEST(FuzzPlan, TrailingPartialStepIsIgnored) {
  EXPECT_EQ(decode_plan("\x01\x02\x03").size(), 0u);
  EXPECT_EQ(decode_plan(std::string("\x01\x02\x03\x04\x05", 5)).size(), 1u);
}

TEST(FuzzPlan, BoundaryStepSetsTheByteAndSaysSo) {
  const MutatedRx out = apply_plan(recording(), step(MutationKind::boundary, 0, 2, 5));
  EXPECT_EQ(out.records[0].bytes, "AB\xff");
  ASSERT_EQ(out.edits.size(), 1u);
  EXPECT_EQ(out.edits[0], "rx record 0 byte 2: 0x04 → 0xff");
}

TEST(FuzzPlan, SplitDropAndTruncateReshapeRecords) {
  const MutatedRx out = apply_plan(recording(), step(MutationKind::split, 1, 1, 0) +
                                                    step(MutationKind::drop, 0, 0, 0) +
                                                    step(MutationKind::truncate, 2, 1, 0));
  ASSERT_EQ(out.records.size(), 3u);
  EXPECT_EQ(out.records[0].bytes, "he");
  EXPECT_EQ(out.records[1].bytes, "llo");
  EXPECT_EQ(out.records[2].bytes, "x");
  EXPECT_EQ(out.edits[0], "rx record 1 split across reads at byte 2, 10 ms apart");
  EXPECT_EQ(out.edits[1], "rx record 0 dropped");
  EXPECT_EQ(out.edits[2], "rx record 2 truncated: 3 → 1 bytes");
}

TEST(FuzzPlan, DelayReorderDuplicateAndExtend) {
  const MutatedRx out = apply_plan(recording(), step(MutationKind::delay, 2, 0, 4) +
                                                    step(MutationKind::reorder, 0, 0, 0) +
                                                    step(MutationKind::duplicate, 0, 0, 0) +
                                                    step(MutationKind::extend, 3, 1, 'Z'));
  ASSERT_EQ(out.records.size(), 4u);
  EXPECT_EQ(out.records[3].delay_ms, 50u);  // the delay moves with its record
  EXPECT_EQ(out.records[0].bytes, "hello");
  EXPECT_EQ(out.records[1].bytes, "hello");
  EXPECT_EQ(out.records[2].bytes, "AB\x04");
  EXPECT_EQ(out.records[3].bytes, "xyzZZ");
  EXPECT_EQ(out.edits.size(), 4u);
}

// The property the fuzzer relies on: every byte string is a valid plan, it
// decodes and applies without error, and each edit line names what changed.
TEST(FuzzPlan, RandomPlansAlwaysApply) {
  std::mt19937 random(40);  // fixed seed: the same plans on every run
  for (int run = 0; run < 2000; ++run) {
    std::string plan(random() % 64, '\0');
    for (char& byte : plan) byte = static_cast<char>(random());
    const MutatedRx out = apply_plan(recording(), plan);
    EXPECT_LE(out.edits.size(), plan.size() / kPlanStepBytes);
    for (const std::string& edit : out.edits) EXPECT_EQ(edit.rfind("rx record ", 0), 0u) << edit;
  }
}

TEST(FuzzPlan, StepsOnAnEmptyRecordingChangeNothing) {
  const MutatedRx out = apply_plan({}, step(MutationKind::extend, 0, 0, 1) + step(MutationKind::drop, 0, 0, 0));
  EXPECT_TRUE(out.records.empty());
  EXPECT_TRUE(out.edits.empty());
}

std::vector<RxRecord> seed_for(const Profile& profile) {
  std::vector<RxRecord> records;
  for (std::string& frame : profile_seed_frames(profile)) records.push_back({std::move(frame), 0});
  return records;
}

std::string joined(const std::vector<RxRecord>& records) {
  std::string all;
  for (const RxRecord& record : records) all += record.bytes;
  return all;
}

TEST(FuzzPlanProfile, EmptyPlanServesEveryProfilesRecordingUnchanged) {
  for (const std::string& name : profile_names()) {
    SCOPED_TRACE(name);
    const auto profile = find_profile(name);
    const std::vector<RxRecord> seed = seed_for(*profile);
    const MutatedRx out = apply_plan(*profile, seed, "");
    EXPECT_EQ(joined(out.records), joined(seed));
    EXPECT_EQ(out.records.size(), seed.size());  // one record a frame
    EXPECT_TRUE(out.edits.empty());
  }
}

// Byte steps (flip, boundary) over random plans and every built-in profile:
// each frame served still carries a correct checksum, so it reaches the
// driver's parser, and each change names the frame.
TEST(FuzzPlanProfile, ChangedFramesKeepCorrectChecksums) {
  std::mt19937 random(27);  // fixed seed: the same plans on every run
  for (const std::string& name : profile_names()) {
    SCOPED_TRACE(name);
    const auto profile = find_profile(name);
    const std::vector<RxRecord> seed = seed_for(*profile);
    for (const RxRecord& frame : seed)
      ASSERT_EQ(profile->recompute_checksums(StreamDirection::rx, frame.bytes), frame.bytes) << "seed not valid";
    for (int run = 0; run < 300; ++run) {
      std::string plan(4 * (1 + random() % 6), '\0');
      for (char& byte : plan) byte = static_cast<char>(random());
      for (std::size_t at = 0; at < plan.size(); at += kPlanStepBytes)
        plan[at] = static_cast<char>(random() % 2);  // flip or boundary
      const MutatedRx out = apply_plan(*profile, seed, plan);
      for (const RxRecord& frame : out.records)
        EXPECT_EQ(profile->recompute_checksums(StreamDirection::rx, frame.bytes), frame.bytes);
      for (const std::string& edit : out.edits) EXPECT_EQ(edit.rfind("rx frame ", 0), 0u) << edit;
    }
  }
}

TEST(FuzzPlanProfile, ModbusRtuBoundaryRecomputesTheCrc) {
  const auto profile = find_profile("modbus-rtu");
  const std::vector<RxRecord> seed = seed_for(*profile);
  // boundary 0xff on byte 3 (the first register's high byte) of frame 0
  const MutatedRx out = apply_plan(*profile, seed, step(MutationKind::boundary, 0, 3, 5));
  ASSERT_EQ(out.edits.size(), 1u);
  EXPECT_NE(out.records[0].bytes, seed[0].bytes);
  EXPECT_EQ(out.records[0].bytes.substr(0, 4), std::string("\x01\x03\x04\xff", 4));
  EXPECT_NE(out.records[0].bytes.substr(7), seed[0].bytes.substr(7));  // a new CRC
  EXPECT_EQ(profile->recompute_checksums(StreamDirection::rx, out.records[0].bytes), out.records[0].bytes);
  EXPECT_EQ(out.edits[0].rfind("rx frame 0 ", 0), 0u) << out.edits[0];
}

}  // namespace
}  // namespace wiretape::detail
