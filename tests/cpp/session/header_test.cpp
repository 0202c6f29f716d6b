// One SessionHeader for reading and writing (header round trip through the
// writer and the reader) and event_payload, the one maker of event payloads,
// checked against the record-kind table.
#include <gtest/gtest.h>

#include <cstdint>
#include <stdexcept>
#include <string>

#include "session/header.hpp"
#include "session/record_kinds.hpp"
#include "support/port_test_support.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/session.hpp"
#include "wiretape/version.hpp"

using namespace wiretape;
using wiretape::test::TempDir;

namespace {

SessionHeader full_header() {
  SessionHeader header;
  header.port_options = "type=tcp,host=10.0.0.5,port=502";
  header.port_type = "tcp";
  header.start_utc = "2026-01-02T03:04:05.000006Z";
  header.wiretape_version = "9.9.9";
  header.host = "bench";
  header.capture = Capture::wire;
  header.source_format = "pcap";
  header.source_files = {"plc.pcapng"};
  header.source_details = {{"stream", "tcp:0"}};
  header.device_address = "10.0.0.5:502";
  header.edits = {"cut 2e..5e", "dropped meta note"};
  header.user_metadata = {{"robot", "r2"}, {"note", "a \"quoted\" word"}};
  DeviceIdentity& identity = header.device_identity.emplace();
  identity.kernel_name = "ttyACM0";
  identity.subsystem = "usb";
  identity.vendor_id = "2341";
  identity.product_id = "0043";
  identity.serial_number = "85736323838351F0B1C1";
  identity.product = "Arduino Uno";
  identity.by_id = "/dev/serial/by-id/usb-Arduino_Uno_85736323838351F0B1C1-if00";
  return header;
}

// Every member but those a writer sets itself (format version, stored JSON).
void expect_same_members(const SessionHeader& a, const SessionHeader& b) {
  EXPECT_EQ(a.port_options, b.port_options);
  EXPECT_EQ(a.port_type, b.port_type);
  EXPECT_EQ(a.start_utc, b.start_utc);
  EXPECT_EQ(a.wiretape_version, b.wiretape_version);
  EXPECT_EQ(a.host, b.host);
  EXPECT_EQ(a.capture, b.capture);
  EXPECT_EQ(a.source_format, b.source_format);
  EXPECT_EQ(a.source_files, b.source_files);
  EXPECT_EQ(a.source_details, b.source_details);
  EXPECT_EQ(a.device_address, b.device_address);
  EXPECT_EQ(a.edits, b.edits);
  EXPECT_EQ(a.user_metadata, b.user_metadata);
  EXPECT_EQ(a.device_identity, b.device_identity);
}

}  // namespace

TEST(SessionHeader, RoundTripsThroughTheWriterAndTheReader) {
  TempDir dir;
  const SessionHeader written = full_header();
  {
    SessionWriter writer(dir.file("h.wtape"), written);
    expect_same_members(writer.header(), written);
    EXPECT_EQ(writer.header().metadata_json, written.to_json());
    writer.close();
  }
  SessionReader reader(dir.file("h.wtape"));
  expect_same_members(reader.header(), written);
  EXPECT_EQ(reader.header().metadata_json, written.to_json());
  // What was read writes the same header again, byte for byte.
  EXPECT_EQ(reader.header().to_json(), written.to_json());
}

TEST(SessionHeader, WritesWhatItIsGivenAndInventsNothing) {
  TempDir dir;
  { SessionWriter writer(dir.file("plain.wtape"), SessionHeader{}); }
  SessionReader reader(dir.file("plain.wtape"));
  EXPECT_EQ(reader.header().start_utc, "");  // not known
  EXPECT_EQ(reader.header().host, "");
  EXPECT_EQ(reader.header().wiretape_version, wiretape::version);
  EXPECT_EQ(reader.header().source_format, "wiretape");
  EXPECT_EQ(reader.header().metadata_json.find("\"source\""), std::string::npos)
      << "a session recorded by wiretape names no source";
}

TEST(SessionHeader, StartingNowIsTheMachinesTimeAndName) {
  const SessionHeader header = SessionHeader::starting_now();
  EXPECT_EQ(detail::start_utc_problem(header.start_utc), std::nullopt);
  EXPECT_FALSE(header.start_utc.empty());
  EXPECT_EQ(header.host, detail::host_name());
}

TEST(SessionHeader, ToJsonRefusesWhatAReaderWouldRefuse) {
  SessionHeader header;
  header.start_utc = "yesterday";
  try {
    (void)header.to_json();
    FAIL();
  } catch (const OptionError& e) {
    EXPECT_EQ(e.key(), "start_utc");
  }
  header.start_utc.clear();
  header.source_details = {{"files", "x"}};
  EXPECT_THROW((void)header.to_json(), OptionError);
}

TEST(EventPayload, IsWrittenInTheTablesOrderWithTheTablesTypes) {
  EXPECT_EQ(detail::event_payload(RecordKind::fault, {{"where", std::string("exchange:3")},
                                                      {"kind", std::string("corrupt")}}),
            R"({"kind":"corrupt","where":"exchange:3"})");
  EXPECT_EQ(detail::event_payload(RecordKind::settings,
                                  {{"applied", false}, {"baud", std::int64_t{9600}}}),
            R"({"baud":9600,"applied":false})");
  EXPECT_EQ(detail::event_payload(RecordKind::close, {}), "{}");
  // What it makes, the reader's check accepts.
  const std::string payload = detail::event_payload(
      RecordKind::redaction, {{"offset", std::int64_t{2}}, {"length", std::int64_t{4}}});
  EXPECT_EQ(detail::event_payload_problem(RecordKind::redaction, payload), std::nullopt);
}

namespace {

std::string refusal(RecordKind kind, const detail::EventMembers& members) {
  try {
    detail::event_payload(kind, members);
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "accepted";
}

}  // namespace

TEST(EventPayload, RefusesWhatTheTableDoesNotSayNamingKindAndMember) {
  EXPECT_EQ(refusal(RecordKind::fault, {{"kind", std::string("drop")}}),
            "fault event: required member \"where\" is missing");
  EXPECT_EQ(refusal(RecordKind::settings, {{"baud", std::string("fast")}}),
            "settings event: member \"baud\" must be an integer, not a string");
  EXPECT_EQ(refusal(RecordKind::settings, {{"baud", std::int64_t{1}}, {"speed", true}}),
            "settings event: unknown member \"speed\" (its members: baud, databits, "
            "stopbits, parity, flow, applied, source)");
  EXPECT_EQ(refusal(RecordKind::line_break,
                    {{"duration_ms", std::int64_t{1}}, {"duration_ms", std::int64_t{2}}}),
            "break event: member \"duration_ms\" given twice");
  EXPECT_EQ(refusal(RecordKind::rx, {}), "rx is a direction, not an event: its payload is bytes");
}

// Format 1.2's device_identity: written only when known, only its known
// members; read back; of another shape, ignored as provenance is.
TEST(SessionHeader, DeviceIdentityIsAnObjectOfTheMembersKnown) {
  const SessionHeader header = full_header();
  const std::string json = header.to_json();
  EXPECT_NE(json.find("\"device_identity\":{\"kernel_name\":\"ttyACM0\",\"subsystem\":\"usb\","
                      "\"vendor_id\":\"2341\""),
            std::string::npos)
      << json;
  EXPECT_EQ(json.find("\"manufacturer\""), std::string::npos) << "not known, not written";
  EXPECT_EQ(SessionHeader{}.to_json().find("device_identity"), std::string::npos);

  SessionHeader read;
  detail::parse_header_json(R"({"device_identity":"ttyACM0","capture":"wire"})", "f", 16, read);
  EXPECT_FALSE(read.device_identity.has_value());
  detail::parse_header_json(R"({"device_identity":{"vendor_id":"0403","future":"x","product":7}})",
                            "f", 16, read);
  ASSERT_TRUE(read.device_identity.has_value());
  EXPECT_EQ(read.device_identity->vendor_id, "0403");
  EXPECT_EQ(read.device_identity->product, "");

  SessionHeader bad;
  bad.device_identity.emplace().product = std::string("Uno\xff", 4);
  try {
    (void)bad.to_json();
    FAIL();
  } catch (const OptionError& e) {
    EXPECT_EQ(e.key(), "device_identity.product");
  }
}

TEST(SessionHeader, ClearingTheDeviceSerialClearsItsPartOfTheByIdName) {
  DeviceIdentity identity = *full_header().device_identity;
  detail::clear_device_serial(identity);
  EXPECT_EQ(identity.serial_number, "");
  EXPECT_EQ(identity.by_id, "/dev/serial/by-id/usb-Arduino_Uno_redacted-if00");
  EXPECT_EQ(identity.vendor_id, "2341");
}

TEST(StartUtc, ParsesToEpochNanoseconds) {
  EXPECT_EQ(detail::start_utc_epoch_ns(""), std::nullopt);  // not known
  EXPECT_EQ(detail::start_utc_epoch_ns("1970-01-01T00:00:00Z"), 0);
  EXPECT_EQ(detail::start_utc_epoch_ns("2026-11-23T10:00:00.123456Z"),
            1795428000LL * 1'000'000'000 + 123'456'000);
  EXPECT_EQ(detail::start_utc_epoch_ns("2000-02-29T23:59:59.000000001Z"),
            951868799LL * 1'000'000'000 + 1);
  // A leap second is the next minute's first.
  EXPECT_EQ(detail::start_utc_epoch_ns("2016-12-31T23:59:60Z"), 1483228800LL * 1'000'000'000);
  EXPECT_THROW(detail::start_utc_epoch_ns("2026-11-23 10:00:00Z"), OptionError);
  EXPECT_THROW(detail::start_utc_epoch_ns("1969-12-31T23:59:59Z"), OptionError);
}

TEST(StartUtc, FormatsWhatItParses) {
  EXPECT_EQ(detail::format_start_utc(0), "1970-01-01T00:00:00.000000000Z");
  EXPECT_EQ(detail::format_start_utc(1795428000LL * 1'000'000'000 + 123'456'789),
            "2026-11-23T10:00:00.123456789Z");
  EXPECT_EQ(detail::format_start_utc(951868799LL * 1'000'000'000),
            "2000-02-29T23:59:59.000000000Z");
  EXPECT_EQ(detail::format_start_utc(-1), std::nullopt);
  EXPECT_EQ(detail::format_start_utc(INT64_MAX), std::nullopt);  // in 2262
  const std::int64_t last = 9'214'646'399LL * 1'000'000'000;     // 2261-12-31T23:59:59
  ASSERT_TRUE(detail::format_start_utc(last).has_value());
  EXPECT_EQ(detail::start_utc_epoch_ns(*detail::format_start_utc(last)), last);
}

// An attached recording (DESIGN §26): its member reads back, and warnings
// found while recording are written into the header in place.
TEST(SessionHeader, AttachedRoundTripsAndItsWarningsAreRewrittenInPlace) {
  TempDir dir;
  SessionHeader header = full_header();
  AttachedProgram& attached = header.attached.emplace();
  attached.pid = 4242;
  attached.command = "driver";
  attached.utc = "2026-01-02T03:04:05.000006Z";
  attached.descriptors = {3, 7};
  attached.device = "/dev/ttyUSB0";
  EXPECT_NE(header.to_json().find("\"attached\":{\"pid\":4242,\"command\":\"driver\""),
            std::string::npos)
      << header.to_json();
  {
    SessionWriter writer(dir.file("a.wtape"), header, FlushPolicy{}, 4096);
    writer.write(RecordKind::rx, 5, "x");
    SessionHeader updated = writer.header();
    updated.attached->warnings = {"the program used splice"};
    writer.rewrite_header(updated);
    writer.write(RecordKind::tx, 6, "y");
    writer.close();
  }
  SessionReader reader(dir.file("a.wtape"));
  ASSERT_TRUE(reader.header().attached.has_value());
  attached.warnings = {"the program used splice"};
  EXPECT_EQ(*reader.header().attached, attached);
  expect_same_members(reader.header(), header);
  Record record;
  ASSERT_TRUE(reader.next(record));
  EXPECT_EQ(record.data, "x");
  ASSERT_TRUE(reader.next(record));
  EXPECT_EQ(record.data, "y");
  // A header without room for the rewrite says so; the file stays readable.
  SessionWriter tight(dir.file("tight.wtape"), SessionHeader{});
  SessionHeader grown = tight.header();
  grown.attached = attached;
  EXPECT_THROW(tight.rewrite_header(grown), SessionError);
}
