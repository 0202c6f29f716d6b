// Fuzzing plans over rx records (DESIGN.md section 27): any byte string is a
// plan, an empty plan changes nothing, each step kind does what it says and
// says it in words.
#include <gtest/gtest.h>

#include <random>
#include <string>
#include <vector>

#include "replay/fuzz_plan.hpp"

namespace wiretape::detail {
namespace {

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
  EXPECT_EQ(out.edits[0], "rx record 1 split across reads at byte 2");
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

}  // namespace
}  // namespace wiretape::detail
