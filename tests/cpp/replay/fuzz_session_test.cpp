// A plan applied to a recorded session (DESIGN.md section 27): the mutated
// rx served where it was recorded, among the client's tx; the result written
// as a plain .wtape with the plan's edits; the bad inputs refused by name.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "replay/fuzz_session.hpp"
#include "support/replay_support.hpp"
#include "wiretape/errors.hpp"

namespace wiretape::detail {
namespace {

using test::TempDir;
using test::replay_support::hello_session;
using test::replay_support::ms;
using test::replay_support::rx;
using test::replay_support::tx;
using test::replay_support::write_session;

std::string step(MutationKind kind, int record, int offset, int amount) {
  return {static_cast<char>(kind), static_cast<char>(record), static_cast<char>(offset), static_cast<char>(amount)};
}

std::string kinds_and_data(const std::vector<Record>& records) {
  std::string text;
  for (const Record& record : records) text += std::string(to_string(record.kind)) + ":" + record.data + "|";
  return text;
}

TEST(FuzzSession, EmptyPlanGivesTheRecordsAsRecorded) {
  TempDir dir;
  const auto recorded = hello_session();
  const FuzzRecording recording = read_fuzz_recording(write_session(dir, recorded), nullptr);
  EXPECT_EQ(recording.units.size(), 4u);  // four rx records
  const FuzzedRecords out = fuzz_records(recording, "");
  EXPECT_EQ(kinds_and_data(out.records), kinds_and_data(recorded));
  for (std::size_t i = 0; i < recorded.size(); ++i) EXPECT_EQ(out.records[i].t_ns, recorded[i].t_ns);
  EXPECT_TRUE(out.edits.empty());
}

// Each unit is served where its record was: after the same tx, so the
// client's requests still meet their answers.
TEST(FuzzSession, MutatedRxStaysAtItsPlaceAmongTheTx) {
  TempDir dir;
  const FuzzRecording recording = read_fuzz_recording(write_session(dir, hello_session()), nullptr);
  // rx record 1 (PONG) split, then rx record 0 (HELLO) duplicated
  const FuzzedRecords out =
      fuzz_records(recording, step(MutationKind::split, 1, 1, 0) + step(MutationKind::duplicate, 0, 0, 0));
  EXPECT_EQ(kinds_and_data(out.records),
            "rx:HELLO\n|rx:HELLO\n|tx:PING\n|rx:PO|rx:NG\n|tx:TIME\n|rx:12:00\n|rx:OK\n|");
  ASSERT_EQ(out.edits.size(), 2u);
  EXPECT_EQ(out.edits[0], "rx record 1 split across reads at byte 2, 10 ms apart");
}

// A reorder swaps what two places serve; the places keep their order.
TEST(FuzzSession, ReorderSwapsWhatTwoPlacesServe) {
  TempDir dir;
  const FuzzRecording recording = read_fuzz_recording(write_session(dir, hello_session()), nullptr);
  const FuzzedRecords out = fuzz_records(recording, step(MutationKind::reorder, 1, 0, 0));
  EXPECT_EQ(kinds_and_data(out.records), "rx:HELLO\n|tx:PING\n|rx:12:00\n|tx:TIME\n|rx:PONG\n|rx:OK\n|");
}

// A delayed record comes later, and so does everything after it: the
// session stays in time order.
TEST(FuzzSession, DelayMovesTheRecordAndWhatFollows) {
  TempDir dir;
  const auto recorded = hello_session();
  const FuzzRecording recording = read_fuzz_recording(write_session(dir, recorded), nullptr);
  const FuzzedRecords out = fuzz_records(recording, step(MutationKind::delay, 1, 0, 4));  // PONG, 50 ms
  ASSERT_EQ(out.records.size(), recorded.size());
  EXPECT_EQ(out.records[1].t_ns, recorded[1].t_ns);
  EXPECT_EQ(out.records[2].t_ns, recorded[2].t_ns + ms(50));
  EXPECT_EQ(out.records[5].t_ns, recorded[5].t_ns + ms(50));
  EXPECT_EQ(out.edits, std::vector<std::string>{"rx record 1 delayed by 50 ms"});
}

TEST(FuzzSession, WrittenSessionCarriesThePlansEdits) {
  TempDir dir;
  const FuzzRecording recording = read_fuzz_recording(write_session(dir, hello_session()), nullptr);
  const std::string plan = step(MutationKind::boundary, 1, 0, 5) + step(MutationKind::drop, 3, 0, 0);
  const std::string out = dir.file("finding.wtape");
  const std::vector<std::string> edits = write_fuzzed_session(recording, plan, out);
  ASSERT_EQ(edits.size(), 2u);
  EXPECT_EQ(edits[0], "rx record 1 byte 0: 0x50 → 0xff");
  EXPECT_EQ(edits[1], "rx record 3 dropped");
  SessionReader reader(out);
  EXPECT_EQ(reader.header().edits, edits);
  std::vector<Record> records;
  for (Record record; reader.next(record);) records.push_back(record);
  EXPECT_EQ(kinds_and_data(records), "rx:HELLO\n|tx:PING\n|rx:\xffONG\n|tx:TIME\n|rx:12:00\n|");
}

TEST(FuzzSession, WithAProfileThePlanActsOnFramesAtTheRecordTheyEndIn) {
  TempDir dir;
  // one NMEA sentence across two records, one whole in the third
  const auto profile = find_profile("nmea");
  const std::string first = profile->recompute_checksums(StreamDirection::rx, "$GPGGA,1,2*00\r\n");
  const std::string second = profile->recompute_checksums(StreamDirection::rx, "$GPRMC,3*00\r\n");
  const std::string path = write_session(
      dir, {rx(ms(1), first.substr(0, 5)), tx(ms(2), "poll\r\n"), rx(ms(3), first.substr(5)), rx(ms(4), second)});
  const FuzzRecording recording = read_fuzz_recording(path, profile);
  ASSERT_EQ(recording.units.size(), 2u);
  const FuzzedRecords out = fuzz_records(recording, "");
  EXPECT_EQ(kinds_and_data(out.records), "tx:poll\r\n|rx:" + first + "|rx:" + second + "|");
  const FuzzedRecords flipped = fuzz_records(recording, step(MutationKind::flip, 1, 3, 0));
  ASSERT_EQ(flipped.edits.size(), 1u);
  EXPECT_EQ(flipped.edits[0].rfind("rx frame 1 ", 0), 0u) << flipped.edits[0];
  EXPECT_EQ(profile->recompute_checksums(StreamDirection::rx, flipped.records[2].data), flipped.records[2].data);
}

TEST(FuzzSession, SessionWithoutDeviceBytesIsRefusedByName) {
  TempDir dir;
  const std::string path = write_session(dir, {tx(ms(1), "PING\n"), rx(ms(2), "")});
  try {
    read_fuzz_recording(path, nullptr);
    FAIL() << "no error";
  } catch (const SessionError& error) {
    EXPECT_NE(std::string(error.what()).find(path), std::string::npos) << error.what();
    EXPECT_NE(std::string(error.what()).find("no device bytes"), std::string::npos) << error.what();
  }
}

TEST(FuzzSession, ProfileThatDoesNotFitIsRefusedByName) {
  TempDir dir;
  const std::string path = write_session(dir, hello_session());  // lines, no Modbus frame in them
  try {
    read_fuzz_recording(path, find_profile("modbus-rtu"));
    FAIL() << "no error";
  } catch (const OptionError& error) {
    EXPECT_EQ(error.key(), "profile");
    EXPECT_NE(std::string(error.what()).find("'modbus-rtu' does not fit"), std::string::npos) << error.what();
  }
}

}  // namespace
}  // namespace wiretape::detail
