// Sessions of several ports (format 1.2 channels): the header's channel list
// round trip, what a reader of one channel and of every channel returns, and
// the names and lists a writer and a reader refuse.
#include <gtest/gtest.h>

#include <fstream>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "session/format.hpp"
#include "session/header.hpp"
#include "session/reader.hpp"
#include "support/port_test_support.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/session.hpp"

using namespace wiretape;
using wiretape::test::TempDir;

namespace {

Channel channel(std::uint16_t id, std::string name, std::string type) {
  Channel c;
  c.id = id;
  c.name = std::move(name);
  c.port_type = type;
  c.port_options = "type=" + type;
  c.capture = Capture::wire;
  return c;
}

SessionHeader two_channel_header() {
  SessionHeader header;
  header.channels = {channel(0, "cmd", "tcp"), channel(1, "data", "udp")};
  header.channels[0].device_address = "192.0.2.10:2111";
  DeviceIdentity identity;
  identity.vendor_id = "0403";
  identity.product_id = "6001";
  header.channels[1].device_identity = identity;
  return header;
}

// A file of two channels whose records interleave: cmd tx, data rx, cmd rx, data rx.
std::string write_two_channels(const TempDir& dir) {
  const std::string path = dir.file("two.wtape");
  SessionWriter writer(path, two_channel_header());
  writer.write(RecordKind::tx, 10, "START\n", 0);
  writer.write(RecordKind::rx, 20, "d1", 1);
  writer.write(RecordKind::rx, 30, "OK\n", 0);
  writer.write(RecordKind::rx, 40, "d2", 1);
  writer.close();
  return path;
}

std::vector<Record> read_all(const std::string& path, std::optional<std::uint16_t> channel) {
  SessionReader reader(path, channel);
  std::vector<Record> records;
  Record record;
  while (reader.next(record)) records.push_back(record);
  EXPECT_FALSE(reader.damage().has_value());
  return records;
}

std::string with_header_json(const std::string& json) {
  std::string file(detail::session_magic, sizeof detail::session_magic);
  const auto put16 = [&](std::uint16_t v) {
    file.push_back(static_cast<char>(v & 0xff));
    file.push_back(static_cast<char>(v >> 8));
  };
  const auto put32 = [&](std::uint32_t v) {
    for (int i = 0; i < 4; ++i) file.push_back(static_cast<char>((v >> (8 * i)) & 0xff));
  };
  put16(1);
  put16(2);
  put32(static_cast<std::uint32_t>(json.size()));
  file += json;
  put32(crc32c(file.data(), file.size()));
  return file;
}

}  // namespace

TEST(Channels, RoundTripThroughTheHeader) {
  TempDir dir;
  const std::string path = write_two_channels(dir);
  SessionReader reader(path);
  const SessionHeader& header = reader.header();
  EXPECT_EQ(header.version_minor, 3);
  ASSERT_EQ(header.channels.size(), 2u);
  EXPECT_EQ(header.channels, two_channel_header().channels);
  // The port members are channel 0's: what a reader of format 1.1 replays.
  EXPECT_EQ(header.port_type, "tcp");
  EXPECT_EQ(header.port_options, "type=tcp");
  EXPECT_EQ(header.device_address, "192.0.2.10:2111");
  EXPECT_EQ(header.capture, Capture::wire);
  EXPECT_FALSE(header.device_identity.has_value());
  EXPECT_EQ(header.to_json(), header.metadata_json) << "what was read writes the same bytes";
  ASSERT_TRUE(header.find_channel("data"));
  EXPECT_EQ(header.find_channel("data")->id, 1);
  EXPECT_FALSE(header.find_channel("nope"));
  EXPECT_EQ(header.channel_list(), header.channels);
}

TEST(Channels, EveryChannelInRecordedOrderOrOneChannelAlone) {
  TempDir dir;
  const std::string path = write_two_channels(dir);
  const auto all = read_all(path, std::nullopt);
  ASSERT_EQ(all.size(), 4u);
  const std::vector<std::uint16_t> channels = {all[0].channel, all[1].channel, all[2].channel,
                                               all[3].channel};
  EXPECT_EQ(channels, (std::vector<std::uint16_t>{0, 1, 0, 1}));
  const auto data = read_all(path, 1);
  ASSERT_EQ(data.size(), 2u);
  EXPECT_EQ(data[0].data, "d1");
  EXPECT_EQ(data[1].data, "d2");
  EXPECT_EQ(data[1].channel, 1);
  const auto cmd = read_all(path, 0);
  ASSERT_EQ(cmd.size(), 2u);
  EXPECT_EQ(cmd[0].data, "START\n");
  EXPECT_EQ(cmd[1].t_ns, 30u);
  EXPECT_TRUE(read_all(path, 7).empty()) << "a channel the file does not have has no records";
}

TEST(Channels, ASessionOfOnePortIsOneUnnamedChannel) {
  TempDir dir;
  SessionHeader header;
  header.port_type = "serial";
  header.port_options = "type=serial,device=/dev/ttyUSB0";
  {
    SessionWriter writer(dir.file("one.wtape"), header);
    writer.write(RecordKind::rx, 5, "x");
  }
  SessionReader reader(dir.file("one.wtape"));
  EXPECT_TRUE(reader.header().channels.empty());
  EXPECT_EQ(reader.header().metadata_json.find("channels"), std::string::npos)
      << "a session of one port writes no channel list (a 1.1 reader's bytes)";
  const auto list = reader.header().channel_list();
  ASSERT_EQ(list.size(), 1u);
  EXPECT_EQ(list[0].id, 0);
  EXPECT_EQ(list[0].name, "");
  EXPECT_EQ(list[0].port_type, "serial");
  EXPECT_EQ(list[0].port_options, header.port_options);
}

TEST(Channels, RecordsOfAChannelTheHeaderDoesNotListAreSkipped) {
  TempDir dir;
  {
    SessionWriter writer(dir.file("stray.wtape"), two_channel_header());
    writer.write(RecordKind::rx, 1, "a", 0);
    writer.write(RecordKind::rx, 2, "newer writer's", 2);
    writer.write(RecordKind::rx, 3, "b", 1);
  }
  const auto all = read_all(dir.file("stray.wtape"), std::nullopt);
  ASSERT_EQ(all.size(), 2u);
  EXPECT_EQ(all[0].data, "a");
  EXPECT_EQ(all[1].data, "b");
}

TEST(Channels, TheReaderTellsOfTheRecordsItSkipsForAnUnlistedChannel) {
  TempDir dir;
  const std::string path = dir.file("stray.wtape");
  {
    SessionWriter writer(path, two_channel_header());
    writer.write(RecordKind::rx, 1, "a", 0);
    writer.write(RecordKind::rx, 2, "newer writer's", 2);
    writer.write(RecordKind::rx, 3, "b", 1);
  }
  std::vector<detail::UnlistedRecord> skipped;
  SessionHeader header;
  auto source = detail::open_session_source(
      path, header, detail::Streams::refused, std::nullopt,
      [&skipped](const detail::UnlistedRecord& record) { skipped.push_back(record); });
  Record record;
  int returned = 0;
  while (source->next(record)) ++returned;
  EXPECT_EQ(returned, 2);
  ASSERT_EQ(skipped.size(), 1u);
  EXPECT_EQ(skipped[0].channel, 2);
  // Its offset is where its record header begins: the channel id is there.
  std::ifstream file(path, std::ios::binary);
  file.seekg(static_cast<std::streamoff>(skipped[0].offset) + 6);
  unsigned char id[2] = {};
  file.read(reinterpret_cast<char*>(id), 2);
  EXPECT_EQ(id[0] | (id[1] << 8), 2);
}

TEST(Channels, NamesThatCannotNameAChannel) {
  EXPECT_FALSE(channel_name_problem("gps"));
  EXPECT_FALSE(channel_name_problem("_rtk-2"));
  EXPECT_FALSE(channel_name_problem(std::string(64, 'a')));
  const auto problem = [](std::string_view name) {
    const auto why = channel_name_problem(name);
    return why ? *why : std::string("(accepted)");
  };
  EXPECT_NE(problem("").find("empty"), std::string::npos);
  EXPECT_NE(problem(std::string(65, 'a')).find("longer than 64"), std::string::npos);
  EXPECT_NE(problem("2gps").find("does not start"), std::string::npos);
  EXPECT_NE(problem("-x").find("does not start"), std::string::npos);
  EXPECT_NE(problem("gps.1").find("other than"), std::string::npos);
  EXPECT_NE(problem("a b").find("other than"), std::string::npos);
  // Option keys would make `--device type=tcp,...` ambiguous.
  for (const char* key : {"type", "device", "file", "baud", "log", "host", "port", "timing"}) {
    EXPECT_NE(problem(key).find("option key"), std::string::npos) << key;
  }
}

TEST(Channels, AWriterRefusesAListAReaderWouldRefuse) {
  TempDir dir;
  const auto refused = [&](SessionHeader header, const std::string& why) {
    try {
      SessionWriter writer(dir.file("bad.wtape"), header);
      ADD_FAILURE() << "accepted: " << why;
    } catch (const OptionError& e) {
      EXPECT_NE(std::string(e.what()).find(why), std::string::npos) << e.what();
      EXPECT_EQ(e.key(), "channels");
    }
  };
  SessionHeader twice = two_channel_header();
  twice.channels[1].name = "cmd";
  refused(twice, "two channels are named \"cmd\"");
  SessionHeader out_of_order = two_channel_header();
  out_of_order.channels[1].id = 5;
  refused(out_of_order, "has id 5");
  SessionHeader bad_name = two_channel_header();
  bad_name.channels[0].name = "baud";
  refused(bad_name, "option key");
  SessionHeader unnamed = two_channel_header();
  unnamed.channels[1].name = "";
  refused(unnamed, "empty");
}

TEST(Channels, AReaderRefusesChannelsItCannotAttributeRecordsTo) {
  TempDir dir;
  const std::string base =
      R"({"port_options":"","port_type":"","start_utc":"","wiretape_version":"0","host":"","capture":"client","metadata":{},"channels":)";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"{}", "not an array"},
      {"[]", "is empty"},
      {R"([{"id":1,"name":"a"}])", "has no id 0"},
      {R"([{"id":0}])", "has no name"},
      {R"([{"id":0,"name":"a"},{"id":1,"name":"a"}])", "two channels are named"},
      {R"([{"id":0,"name":"type"}])", "option key"},
      {R"([{"id":0,"name":"a","capture":"radio"}])", "unknown capture"},
      {R"([3])", "not an object"},
  };
  for (const auto& [channels, why] : cases) {
    const std::string path = dir.file("bad.wtape");
    std::ofstream(path, std::ios::binary | std::ios::trunc) << with_header_json(base + channels + "}");
    try {
      SessionReader reader(path);
      ADD_FAILURE() << "read: " << channels;
    } catch (const SessionError& e) {
      EXPECT_NE(std::string(e.what()).find(why), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("channels"), std::string::npos) << e.what();
    }
  }
}
