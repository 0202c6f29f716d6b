// The record-kind table (src/session/record_kinds.cpp): names both ways,
// every kind once with its meaning and payload fields, the payload check's
// messages, and every event the library's writers record against it.
#include <unistd.h>

#include <gtest/gtest.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>

#include <atomic>
#include <chrono>
#include <memory>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "ports/ports.hpp"
#include "session/record_kinds.hpp"
#include "support/port_test_support.hpp"
#include "wiretape/bridge.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/port.hpp"
#include "wiretape/session.hpp"

using namespace wiretape;

using wiretape::test::TempDir;

TEST(RecordKinds, NamesRoundTrip) {
  for (int value = 0; value < 256; ++value) {
    const auto kind = static_cast<RecordKind>(value);
    const std::string_view name = to_string(kind);
    if (name == "unknown") continue;
    EXPECT_EQ(record_kind_from_string(name), kind) << name;
  }
  EXPECT_EQ(to_string(RecordKind::line_break), "break");
  EXPECT_FALSE(record_kind_from_string("nonsense"));
}

TEST(RecordKindTable, CoversEveryNamedKindOnceInCodeOrder) {
  std::set<std::string_view> names;
  int previous_code = -1;
  for (const detail::RecordKindSpec& spec : detail::record_kinds()) {
    EXPECT_GT(static_cast<int>(spec.code()), previous_code) << spec.name;
    previous_code = spec.code();
    EXPECT_TRUE(names.insert(spec.name).second) << spec.name;
    EXPECT_EQ(to_string(spec.kind), spec.name);
    EXPECT_FALSE(spec.meaning.empty()) << spec.name;
    EXPECT_EQ(spec.is_event, spec.kind != RecordKind::rx && spec.kind != RecordKind::tx)
        << spec.name;
    if (!spec.is_event) EXPECT_EQ(spec.field_count, 0u) << spec.name;
    std::set<std::string_view> fields;
    for (const detail::EventFieldSpec& field : spec) {
      EXPECT_TRUE(fields.insert(field.name).second) << spec.name << "." << field.name;
      EXPECT_FALSE(field.meaning.empty()) << spec.name << "." << field.name;
    }
  }
  std::size_t named = 0;
  for (int code = 0; code < 256; ++code) {
    if (detail::find_record_kind(static_cast<RecordKind>(code)) != nullptr) ++named;
  }
  EXPECT_EQ(named, names.size());
  EXPECT_EQ(names.size(), 16u);
}

TEST(RecordKindTable, PayloadCheckNamesTheProblem) {
  using detail::event_payload_problem;
  EXPECT_FALSE(event_payload_problem(RecordKind::close, ""));
  EXPECT_FALSE(event_payload_problem(RecordKind::line_break, R"({"duration_ms":250})"));
  EXPECT_EQ(event_payload_problem(RecordKind::line_break, "{}"),
            "break payload lacks \"duration_ms\"");
  EXPECT_EQ(event_payload_problem(RecordKind::line_break, R"({"duration_ms":2.5})"),
            "break payload member \"duration_ms\" is not a integer: 2.5");
  EXPECT_EQ(event_payload_problem(RecordKind::modem_lines, R"({"dcd":true})"),
            "modem_lines payload member \"dcd\" is not in the table");
  EXPECT_EQ(event_payload_problem(RecordKind::drain, "[]"), "drain payload is not a JSON object");
  EXPECT_TRUE(event_payload_problem(RecordKind::rx, "{}"));
}

namespace {

// A serial device that takes every line setting and can be made to go away.
class FakeSerialDevice final : public Port {
 public:
  std::atomic<bool> gone{false};

  std::size_t available() override { return 0; }
  void flush_input() override {}
  void flush_output() override {}
  void drain() override {}
  void close() override { open_ = false; }
  bool is_open() const override { return open_; }
  std::string description() const override { return "fake serial @ 9600 8N1"; }
  std::string type() const override { return "serial"; }
  int native_handle() const override { return -1; }
  void set_baud(unsigned baud) override { settings_.baud = baud; }
  void configure(const SerialSettings& settings) override { settings_ = settings; }
  SerialSettings serial_settings() const override { return settings_; }
  void set_dtr(bool) override {}
  void set_rts(bool) override {}
  void send_break(std::chrono::milliseconds) override {}

 protected:
  std::size_t read_some(void*, std::size_t, Deadline) override {
    if (gone) throw PortClosed("fake serial: the device went away", ENXIO);
    return 0;
  }
  std::size_t write_some(const void*, std::size_t size, Deadline) override { return size; }
  bool wait_readable_until(Deadline) override { return gone; }

 private:
  bool open_ = true;
  SerialSettings settings_;
};

std::vector<Record> events_of(const std::string& path) {
  SessionReader reader(path);
  std::vector<Record> events;
  Record record;
  while (reader.next(record)) {
    const detail::RecordKindSpec* spec = detail::find_record_kind(record.kind);
    if (spec != nullptr && spec->is_event) events.push_back(record);
  }
  EXPECT_FALSE(reader.damage());
  return events;
}

int connect_tcp(const std::string& address) {
  const std::size_t colon = address.rfind(':');
  sockaddr_in peer{};
  peer.sin_family = AF_INET;
  peer.sin_port = htons(static_cast<std::uint16_t>(std::stoi(address.substr(colon + 1))));
  ::inet_pton(AF_INET, address.substr(0, colon).c_str(), &peer.sin_addr);
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  if (fd >= 0 && ::connect(fd, reinterpret_cast<const sockaddr*>(&peer), sizeof peer) != 0) {
    ::close(fd);
    return -1;
  }
  return fd;
}

}  // namespace

// Every event payload the library's writers produce follows the table: the
// recording port with each event it records, and the proxy with a client.
TEST(RecordKindTable, EveryEventTheWritersRecordFollowsTheSchema) {
  TempDir dir;
  std::vector<Record> events;

  const std::string recorded = dir.file("port.wtape");
  {
    auto device = std::make_unique<FakeSerialDevice>();
    FakeSerialDevice& fake = *device;
    detail::RecordingConfig config;
    config.path = recorded;
    config.port_type = "serial";
    auto port = detail::record_port(std::move(device), config);
    port->set_baud(115200);
    SerialSettings settings;
    settings.baud = 57600;
    settings.data_bits = 7;
    settings.stop_bits = 2;
    settings.parity = Parity::even;
    settings.flow = FlowControl::rtscts;
    port->configure(settings);
    port->set_dtr(true);
    port->set_rts(false);
    port->send_break(std::chrono::milliseconds(250));
    port->flush_input();
    port->flush_output();
    port->drain();
    port->write("ping");
    fake.gone = true;
    char byte = 0;
    EXPECT_THROW(port->read(&byte, 1), PortClosed);
    port->close();
  }
  for (Record& event : events_of(recorded)) events.push_back(std::move(event));

  const std::string proxied = dir.file("proxy.wtape");
  {
    BridgeOptions options;
    options.device = "type=loopback";
    options.client_side = BridgeClientSide::tcp;
    options.output = proxied;
    options.quiet = true;
    Bridge bridge(options);
    bridge.start();
    const int client = connect_tcp(bridge.listen_address());
    ASSERT_GE(client, 0);
    ASSERT_EQ(::write(client, "hi", 2), 2);
    char echo[2] = {};
    std::size_t got = 0;
    while (got < sizeof echo) {
      const ssize_t n = ::read(client, echo + got, sizeof echo - got);
      ASSERT_GT(n, 0);
      got += static_cast<std::size_t>(n);
    }
    ::close(client);
    bridge.stop();
    ASSERT_TRUE(bridge.wait(std::chrono::seconds(30)));
  }
  for (Record& event : events_of(proxied)) events.push_back(std::move(event));

  std::set<RecordKind> seen;
  for (const Record& event : events) {
    seen.insert(event.kind);
    const auto problem = detail::event_payload_problem(event.kind, event.data);
    EXPECT_FALSE(problem) << *problem << " in " << event.data;
  }
  // Written elsewhere: redaction by `wiretape edit` in Python
  // (tests/python/tools/test_edit.py checks its payloads against this table);
  // fault by fault injection, which the format reserves it for; capture_gap
  // by `wiretape convert --from pcap --allow-gaps` in Python
  // (tests/python/tools/test_pcap_import.py).
  const std::set<RecordKind> written_elsewhere = {RecordKind::redaction, RecordKind::fault,
                                                  RecordKind::capture_gap};
  for (const detail::RecordKindSpec& spec : detail::record_kinds()) {
    if (spec.is_event && written_elsewhere.count(spec.kind) == 0) {
      EXPECT_TRUE(seen.count(spec.kind)) << "no " << spec.name << " recorded";
    }
  }
}
