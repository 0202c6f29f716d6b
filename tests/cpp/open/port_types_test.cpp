// The port-type registry (src/open/port_types.cpp): it and the key table
// name the same types, its capabilities are what the opened ports say, and
// what replay learns of a recorded type it learns from the registry (a new
// datagram transport is one registration, never a `port_type == "udp"`).
#include <gtest/gtest.h>

#include <algorithm>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include "open/port_types.hpp"
#include "posix/transports.hpp"
#include "replay/exchanges.hpp"
#include "replay/replay_port.hpp"
#include "support/port_test_support.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/options.hpp"
#include "wiretape/port.hpp"
#include "wiretape/session.hpp"

using namespace wiretape;
using namespace wiretape::detail;

namespace {

std::vector<std::string> names_of(const std::vector<std::string_view>& views) {
  return {views.begin(), views.end()};
}

std::vector<std::string> registered_names() {
  std::vector<std::string> names;
  for (const PortType& type : registered_port_types()) names.emplace_back(type.name);
  return names;
}

const OptionKey& type_key() {
  for (const OptionKey& key : option_keys()) {
    if (key.name == "type") return key;
  }
  throw std::logic_error("the key table has no 'type' row");
}

}  // namespace

TEST(PortTypes, TheKeyTableAndTheRegistryNameTheSameTypesInTheSameOrder) {
  EXPECT_EQ(names_of(port_types()), registered_names());
}

TEST(PortTypes, TypeAcceptsExactlyTheRegisteredTypesAndTheirAliases) {
  std::vector<std::string> expected = registered_names();
  for (const PortTypeAlias& alias : port_type_aliases()) {
    expected.emplace_back(alias.name);
    EXPECT_NE(find_port_type(alias.type), nullptr)
        << alias.name << " stands for " << alias.type << ", which is not registered";
    EXPECT_EQ(find_port_type(alias.name), nullptr) << alias.name << " is both";
  }
  EXPECT_EQ(names_of(type_key().choices), expected);
}

TEST(PortTypes, EveryTypeAKeyIsWrittenForIsRegisteredOrRecordsIntoAFile) {
  std::set<std::string> named;
  for (const OptionKey& key : option_keys()) {
    for (std::string_view type : key.port_types) {
      named.emplace(type);
      const PortTypeAlias* alias = find_port_type_alias(type);
      EXPECT_TRUE(find_port_type(type) != nullptr || (alias && alias->records_into_file))
          << "key '" << key.name << "' is written for type '" << type
          << "', which the registry does not open";
    }
  }
  // The other way: every registered type has the common keys, and the
  // logging spellings have their file= (log= by flexiport's name).
  for (const std::string& type : registered_names()) EXPECT_EQ(named.count(type), 1u) << type;
  for (const PortTypeAlias& alias : port_type_aliases()) {
    if (alias.records_into_file) EXPECT_EQ(named.count(std::string(alias.name)), 1u);
  }
}

TEST(PortTypes, CapabilitiesAreWhatTheOpenedPortsSay) {
  test::TempDir dir;
  const std::vector<std::pair<std::string, std::string>> openable = {
      {"udp", "type=udp,bind_host=127.0.0.1"},
      {"loopback", "type=loopback"},
      {"pty", "type=pty,link=" + dir.file("pty")},
  };
  for (const auto& [name, options] : openable) {
    SCOPED_TRACE(name);
    const PortType* type = find_port_type(name);
    ASSERT_NE(type, nullptr);
    const std::unique_ptr<Port> port = open_port(options);
    EXPECT_EQ(type->capabilities.datagrams, port->capabilities().datagrams);
    EXPECT_EQ(type->capabilities.modem_lines, port->capabilities().modem_lines);
  }
  EXPECT_EQ(datagram_port_types(), std::vector<std::string>{"udp"});
}

// One concept, "a serial line": the registry's capability and the types the
// key table gives the line settings (what Python's has_line_settings reads).
TEST(PortTypes, TheSerialLinesAreTheTypesTheLineSettingsApplyTo) {
  for (const PortType& type : registered_port_types()) {
    SCOPED_TRACE(std::string(type.name));
    EXPECT_EQ(type.capabilities.modem_lines, find_option_key("baud", type.name) != nullptr);
  }
}

TEST(PortTypes, AnUnknownTypeIsRefusedListingTheRegisteredOnes) {
  try {
    open_port("type=carrier-pigeon");
    FAIL() << "opened a type nobody registered";
  } catch (const OptionError& error) {
    EXPECT_EQ(error.key(), "type");
    for (const std::string& name : registered_names()) {
      EXPECT_NE(std::string(error.what()).find(name), std::string::npos) << error.what();
    }
  }
  try {
    open_port("timeout=1");
    FAIL() << "opened a port of no type";
  } catch (const OptionError& error) {
    EXPECT_NE(std::string(error.what()).find(registered_port_type_names()), std::string::npos)
        << error.what();
  }
}

// A session recorded from a port of type "carrier", a datagram transport
// that replay and the segmentation have never heard of: two tx datagrams,
// then the device's answer to the second.
class RecordedDatagramType : public ::testing::Test {
 protected:
  void SetUp() override {
    path_ = dir_.file("carrier.wtape");
    SessionHeader header = SessionHeader::starting_now();
    header.port_type = "carrier";
    header.port_options = "type=carrier";
    SessionWriter writer(path_, header);
    writer.write(RecordKind::tx, 1, "a");
    writer.write(RecordKind::tx, 2, "b");
    writer.write(RecordKind::rx, 3, "c");
    writer.close();
  }
  test::TempDir dir_;
  std::string path_;
};

TEST_F(RecordedDatagramType, ReplaysDatagramsWhenTheTypesPassedDownSaySo) {
  Options options = Options::parse("file=" + path_ + ",timing=none");
  options.set_port_type("replay");
  const std::unique_ptr<Port> datagrams = open_replay(options, {"carrier"});
  EXPECT_NE(dynamic_cast<DatagramPort*>(datagrams.get()), nullptr);

  Options again = Options::parse("file=" + path_ + ",timing=none");
  again.set_port_type("replay");
  const std::unique_ptr<Port> stream = open_replay(again, datagram_port_types());
  EXPECT_EQ(dynamic_cast<DatagramPort*>(stream.get()), nullptr);
}

TEST_F(RecordedDatagramType, IsSegmentedByDatagramWhenTheTypesPassedDownSaySo) {
  // Datagrams: "a" alone, then "b" answered by "c". A byte stream: one
  // request "ab", answered by "c".
  EXPECT_EQ(segment_session_file(path_, "", {"carrier"}).exchanges.size(), 2u);
  EXPECT_EQ(segment_session_file(path_, "", datagram_port_types()).exchanges.size(), 1u);
}
