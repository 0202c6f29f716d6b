// src/replay/recorded_events.cpp: what a recorded settings, modem_lines or
// break event says, whether the client's call matches it, and how a
// mismatch report names both.
#include <gtest/gtest.h>

#include <optional>
#include <string>

#include "replay/recorded_events.hpp"
#include "session/record_kinds.hpp"
#include "wiretape/session.hpp"

using namespace wiretape;
using wiretape::detail::ClientEvent;
using wiretape::detail::event_matches;
using wiretape::detail::event_mismatch_lines;
using wiretape::detail::event_text;
using wiretape::detail::recorded_event_text;
using wiretape::detail::recorded_fields;

namespace {

Record event(RecordKind kind, std::string payload) { return {1'000, kind, std::move(payload)}; }

const Record kRecordedSettings =
    event(RecordKind::settings,
          R"({"baud":115200,"databits":8,"stopbits":1,"parity":"none","flow":"none",)"
          R"("applied":true,"source":"client's terminal settings"})");

}  // namespace

TEST(RecordedEvents, TheProxysNoteIsNotAMember) {
  const auto fields = recorded_fields(event(RecordKind::modem_lines, R"({"dtr":false,"applied":true})"));
  EXPECT_EQ(fields.size(), 1u);
  EXPECT_EQ(fields.at("dtr"), "false");
  EXPECT_TRUE(recorded_fields(event(RecordKind::settings, "not json")).empty());
}

TEST(RecordedEvents, EventsInWords) {
  EXPECT_EQ(event_text(RecordKind::modem_lines, {{"dtr", "false"}, {"rts", "true"}}),
            "DTR low, RTS high");
  EXPECT_EQ(event_text(RecordKind::line_break, {{"duration_ms", "250"}}), "a break");
  EXPECT_EQ(event_text(RecordKind::settings, {{"baud", "9600"}}), R"(settings {"baud":9600})");
  // Who made the recorded change is not what it was.
  EXPECT_EQ(recorded_event_text(kRecordedSettings),
            R"(settings {"baud":115200,"databits":8,"flow":"none","parity":"none","stopbits":1})");
}

TEST(RecordedEvents, OnlyTheMembersBothNameAreCompared) {
  EXPECT_TRUE(event_matches(kRecordedSettings, {RecordKind::settings, {{"baud", "115200"}}}, true));
  EXPECT_FALSE(event_matches(kRecordedSettings, {RecordKind::settings, {{"baud", "9600"}}}, true));
  EXPECT_FALSE(event_matches(kRecordedSettings, {RecordKind::modem_lines, {{"dtr", "false"}}}, true));
}

TEST(RecordedEvents, ALineChangeMatchesOnlyTheSameLines) {
  const Record dtr_low = event(RecordKind::modem_lines, R"({"dtr":false,"applied":true})");
  EXPECT_TRUE(event_matches(dtr_low, {RecordKind::modem_lines, {{"dtr", "false"}}}, true));
  EXPECT_FALSE(event_matches(dtr_low, {RecordKind::modem_lines, {{"dtr", "true"}}}, true));
  EXPECT_FALSE(event_matches(dtr_low, {RecordKind::modem_lines, {{"rts", "false"}}}, true));
  EXPECT_FALSE(event_matches(dtr_low, {RecordKind::line_break, {{"duration_ms", "250"}}}, true));
}

TEST(RecordedEvents, ABreaksLengthIsComparedOnlyWhenAsked) {
  const Record pause = event(RecordKind::line_break, R"({"duration_ms":250})");
  const ClientEvent shorter{RecordKind::line_break, {{"duration_ms", "100"}}};
  EXPECT_TRUE(event_matches(pause, shorter, /*compare_break_length=*/false));
  EXPECT_FALSE(event_matches(pause, shorter, /*compare_break_length=*/true));
}

TEST(RecordedEvents, TheReportNamesTheExpectedAndTheActualEvent) {
  const Record dtr_low = event(RecordKind::modem_lines, R"({"dtr":false})");
  EXPECT_EQ(event_mismatch_lines(dtr_low, ClientEvent{RecordKind::line_break, {}}),
            "  expected line change: DTR low\n"
            "  actual line change:   a break\n");
  EXPECT_EQ(event_mismatch_lines(std::nullopt, ClientEvent{RecordKind::modem_lines, {{"dtr", "true"}}}),
            "  expected line change: (none)\n"
            "  actual line change:   DTR high\n");
  // Settings are events, not line changes.
  EXPECT_EQ(event_mismatch_lines(kRecordedSettings, ClientEvent{RecordKind::modem_lines, {{"dtr", "false"}}}),
            "  expected event: settings {\"baud\":115200,\"databits\":8,\"flow\":\"none\","
            "\"parity\":\"none\",\"stopbits\":1}\n"
            "  actual event:   DTR low\n");
}
