// Sessions of several ports (DESIGN §19): SessionWriter's header room and
// add_channel(), and the Recorder that hands out ports recording into one
// file on one clock.
#include <gtest/gtest.h>

#include <sys/stat.h>

#include <atomic>
#include <fstream>
#include <iterator>
#include <string>
#include <thread>
#include <vector>

#include "support/port_test_support.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/port.hpp"
#include "wiretape/recorder.hpp"
#include "wiretape/session.hpp"

using namespace wiretape;
using wiretape::test::TempDir;

namespace {

std::string file_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

std::vector<Record> records_of(const std::string& path) {
  SessionReader reader(path);
  std::vector<Record> records;
  Record record;
  while (reader.next(record)) records.push_back(record);
  EXPECT_FALSE(reader.damage()) << reader.damage()->what();
  return records;
}

SessionHeader fixed_header() {
  SessionHeader header;
  header.start_utc = "2026-11-23T10:00:00Z";
  header.host = "bench";
  header.port_options = "type=loopback";
  header.port_type = "loopback";
  return header;
}

Channel named(const std::string& name, const std::string& options = "type=loopback") {
  Channel channel;
  channel.name = name;
  channel.port_options = options;
  channel.port_type = "loopback";
  channel.capture = Capture::wire;
  return channel;
}

// --- SessionWriter: header room, add_channel ------------------------------------------

TEST(SessionWriterHeaderRoom, NoRoomWritesTheHeaderExactlyAsLongAsItsJson) {
  TempDir dir;
  const std::string path = dir.file("exact.wtape");
  SessionWriter writer(path, fixed_header(), FlushPolicy{}, 0);
  writer.close();
  const std::string json = writer.header().metadata_json;
  const std::string bytes = file_bytes(path);
  // magic, version, length, JSON, CRC: not one byte more.
  ASSERT_EQ(bytes.size(), 16 + json.size() + 4);
  EXPECT_EQ(bytes.substr(16, json.size()), json);
}

TEST(SessionWriterHeaderRoom, RoomIsSpacesThatReadersAccept) {
  TempDir dir;
  const std::string path = dir.file("room.wtape");
  {
    SessionWriter writer(path, fixed_header(), FlushPolicy{}, 1000);
    writer.write(RecordKind::rx, 5, "abc");
    writer.close();
    const std::string json = writer.header().metadata_json;
    const std::string bytes = file_bytes(path);
    ASSERT_EQ(bytes.size(), 16 + json.size() + 1000 + 4 + 16 + 3 + 4);
    EXPECT_EQ(bytes.substr(16 + json.size(), 1000), std::string(1000, ' '));
  }
  SessionReader reader(path);
  EXPECT_EQ(reader.header().port_options, "type=loopback");
  EXPECT_EQ(reader.header().host, "bench");
  const auto records = records_of(path);
  ASSERT_EQ(records.size(), 1u);
  EXPECT_EQ(records[0].data, "abc");
}

TEST(SessionWriterHeaderRoom, AddChannelRewritesTheHeaderInPlace) {
  TempDir dir;
  const std::string path = dir.file("channels.wtape");
  SessionWriter writer(path, fixed_header(), FlushPolicy{}, 4096);
  writer.write(RecordKind::open, 0, "{}");
  EXPECT_EQ(writer.add_channel(named("gps", "type=serial,device=/dev/ttyUSB0")), 0);
  writer.write(RecordKind::rx, 10, "$GPGGA", 0);
  EXPECT_EQ(writer.add_channel(named("rtk", "type=tcp,host=caster,port=2101")), 1);
  writer.write(RecordKind::tx, 20, "GET /", 1);
  const auto size_before_close = file_bytes(path).size();
  writer.close();
  EXPECT_GE(file_bytes(path).size(), size_before_close);  // nothing was inserted

  SessionReader reader(path);
  const SessionHeader& header = reader.header();
  ASSERT_EQ(header.channels.size(), 2u);
  EXPECT_EQ(header.channels[0].name, "gps");
  EXPECT_EQ(header.channels[1].name, "rtk");
  EXPECT_EQ(header.channels[1].id, 1);
  EXPECT_EQ(header.channels[1].port_options, "type=tcp,host=caster,port=2101");
  // The top-level members are channel 0's: what a 1.1 reader sees.
  EXPECT_EQ(header.port_options, "type=serial,device=/dev/ttyUSB0");
  EXPECT_EQ(header.capture, Capture::wire);
  const auto records = records_of(path);
  ASSERT_EQ(records.size(), 3u);
  EXPECT_EQ(records[1].channel, 0);
  EXPECT_EQ(records[2].channel, 1);
  EXPECT_EQ(records[2].data, "GET /");
}

TEST(SessionWriterHeaderRoom, AChannelThatDoesNotFitSaysHowManyFit) {
  TempDir dir;
  const std::string path = dir.file("full.wtape");
  SessionHeader header = fixed_header();
  const std::size_t one_channel =
      [&] {
        SessionHeader with = header;
        with.channels.push_back(named("gps"));
        return with.to_json().size() - header.to_json().size();
      }();
  SessionWriter writer(path, header, FlushPolicy{}, one_channel + 10);
  writer.add_channel(named("gps"));
  try {
    writer.add_channel(named("rtk"));
    FAIL() << "a channel beyond the header room was added";
  } catch (const SessionError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("no room for channel \"rtk\""), std::string::npos) << what;
    EXPECT_NE(what.find("fit 1 channel"), std::string::npos) << what;
  }
  writer.write(RecordKind::rx, 1, "x", 0);
  writer.close();
  // The file is as it was before the refused channel.
  SessionReader reader(path);
  ASSERT_EQ(reader.header().channels.size(), 1u);
  EXPECT_EQ(records_of(path).size(), 1u);
}

TEST(SessionWriterHeaderRoom, BadAndDuplicateNamesAreRefusedNamingName) {
  TempDir dir;
  SessionWriter writer(dir.file("names.wtape"), fixed_header(), FlushPolicy{}, 4096);
  writer.add_channel(named("gps"));
  for (const char* bad : {"gps", "", "9lives", "type"}) {
    try {
      writer.add_channel(named(bad));
      FAIL() << "channel name \"" << bad << "\" was accepted";
    } catch (const OptionError& e) {
      EXPECT_EQ(e.key(), "name") << e.what();
    }
  }
}

TEST(SessionWriterHeaderRoom, AddChannelIsSafeWithConcurrentWrites) {
  TempDir dir;
  const std::string path = dir.file("race.wtape");
  SessionWriter writer(path, fixed_header(), FlushPolicy{std::chrono::milliseconds(0)},
                       Recorder::default_header_room);
  writer.add_channel(named("c0"));
  std::atomic<bool> stop{false};
  std::thread writing([&] {
    std::uint64_t t = 0;
    while (!stop.load()) writer.write(RecordKind::rx, ++t, "data", 0);
  });
  for (int i = 1; i < 40; ++i) writer.add_channel(named("c" + std::to_string(i)));
  stop = true;
  writing.join();
  writer.close();
  SessionReader reader(path);
  EXPECT_EQ(reader.header().channels.size(), 40u);
  EXPECT_EQ(records_of(path).size(), writer.records_written());
}

// --- Recorder ----------------------------------------------------------------------------

TEST(Recorder, PortsRecordIntoTheirOwnChannelsOnOneClock) {
  TempDir dir;
  const std::string path = dir.file("run.wtape");
  {
    Recorder recorder(path);
    auto gps = recorder.open_port("name=gps,type=loopback");
    auto rtk = recorder.open_port("type=loopback,name=rtk,timeout=1");
    gps->write("$GPGGA\r\n");
    EXPECT_EQ(gps->read_exactly(8), "$GPGGA\r\n");
    rtk->write("GET /RTCM");
    EXPECT_EQ(rtk->read_exactly(9), "GET /RTCM");
    gps->write("$GPRMC\r\n");
    EXPECT_EQ(gps->read_exactly(8), "$GPRMC\r\n");
    gps->close();
    rtk->close();
  }
  SessionReader reader(path);
  const SessionHeader& header = reader.header();
  ASSERT_EQ(header.channels.size(), 2u);
  EXPECT_EQ(header.channels[0].name, "gps");
  EXPECT_EQ(header.channels[0].port_options, "type=loopback");
  EXPECT_EQ(header.channels[0].port_type, "loopback");
  EXPECT_EQ(header.channels[0].capture, Capture::client);
  EXPECT_EQ(header.channels[1].name, "rtk");
  EXPECT_EQ(header.channels[1].port_options, "type=loopback,timeout=1");

  const auto records = records_of(path);
  std::string gps_tx, rtk_tx, order;
  std::uint64_t last_t = 0;
  for (const Record& record : records) {
    EXPECT_GE(record.t_ns, last_t) << "records are in the one clock's order";
    last_t = record.t_ns;
    if (record.kind == RecordKind::tx) {
      (record.channel == 0 ? gps_tx : rtk_tx) += record.data;
      order += std::to_string(record.channel);
    }
  }
  EXPECT_EQ(gps_tx, "$GPGGA\r\n$GPRMC\r\n");
  EXPECT_EQ(rtk_tx, "GET /RTCM");
  EXPECT_EQ(order, "010");
  ASSERT_FALSE(records.empty());
  EXPECT_EQ(records.front().kind, RecordKind::open);
  EXPECT_EQ(records.front().t_ns, 0u);  // time 0: the first channel's open
}

TEST(Recorder, PortOptionsAreCheckedNamingTheKey) {
  TempDir dir;
  const std::string path = dir.file("bad.wtape");
  Recorder recorder(path);
  auto expect_refused = [&](const std::string& options, const std::string& key,
                            const std::string& says) {
    try {
      recorder.open_port(options);
      FAIL() << options << " was accepted";
    } catch (const OptionError& e) {
      EXPECT_EQ(e.key(), key) << e.what();
      EXPECT_NE(std::string(e.what()).find(says), std::string::npos) << e.what();
    }
  };
  expect_refused("type=loopback", "name", "name=NAME");
  expect_refused("name=9x,type=loopback", "name", "9x");
  expect_refused("name=file,type=loopback", "name", "file");
  expect_refused("name=gps,type=loopback,log=" + dir.file("other.wtape"), "log", "records into");
  expect_refused("name=gps,type=seriallog,device=/dev/null,file=" + dir.file("other.wtape"),
                 "type", "type=serial");
  auto gps = recorder.open_port("name=gps,type=loopback");
  expect_refused("name=gps,type=loopback", "name", "already has a channel named \"gps\"");
  // A port that fails to open takes no channel: its name stays free.
  EXPECT_THROW(recorder.open_port("name=rtk,type=nosuchtype"), OptionError);
  auto rtk = recorder.open_port("name=rtk,type=loopback");
  recorder.close();
  SessionReader reader(path);
  ASSERT_EQ(reader.header().channels.size(), 2u);
  EXPECT_EQ(reader.header().channels[1].name, "rtk");
  struct stat st {};
  EXPECT_NE(::stat(dir.file("other.wtape").c_str(), &st), 0) << "log= made a file";
}

TEST(Recorder, PortsKeepTheFileOpenAfterTheRecorderIsGone) {
  TempDir dir;
  const std::string path = dir.file("alive.wtape");
  std::unique_ptr<Port> port;
  {
    Recorder recorder(path);
    port = recorder.open_port("name=only,type=loopback");
  }
  port->write("late");
  EXPECT_EQ(port->read_exactly(4), "late");
  port.reset();  // the last owner: the file is closed, with everything
  std::string tx;
  bool closed = false;
  for (const Record& record : records_of(path)) {
    if (record.kind == RecordKind::tx) tx += record.data;
    if (record.kind == RecordKind::close) closed = true;
  }
  EXPECT_EQ(tx, "late");
  EXPECT_TRUE(closed);
}

TEST(Recorder, PortsGoOnAfterRecorderCloseWithoutRecording) {
  TempDir dir;
  const std::string path = dir.file("closed.wtape");
  Recorder recorder(path);
  auto port = recorder.open_port("name=gps,type=loopback");
  port->write("before");
  EXPECT_EQ(port->read_exactly(6), "before");
  recorder.close();
  port->write("after");  // neither throws nor records
  EXPECT_EQ(port->read_exactly(5), "after");
  port->close();
  std::string tx;
  for (const Record& record : records_of(path)) {
    if (record.kind == RecordKind::tx) tx += record.data;
  }
  EXPECT_EQ(tx, "before");
}

TEST(Recorder, AddChannelGivesTheProxyAChannelOnTheSameClock) {
  TempDir dir;
  const std::string path = dir.file("proxy.wtape");
  Recorder recorder(path);
  auto port = recorder.open_port("name=cmd,type=loopback");
  RecordingChannel data = recorder.add_channel(named("data"));
  EXPECT_EQ(data.id(), 1);
  EXPECT_EQ(data.name(), "data");
  const std::uint64_t t = data.now_ns();
  EXPECT_GT(t, 0u);
  data.write(RecordKind::rx, t, "scan");
  EXPECT_THROW(recorder.add_channel(named("data")), OptionError);
  port->close();
  recorder.close();
  SessionReader reader(path);
  ASSERT_EQ(reader.header().channels.size(), 2u);
  EXPECT_EQ(reader.header().channels[1].capture, Capture::wire);
  bool found = false;
  for (const Record& record : records_of(path)) {
    if (record.channel == 1 && record.kind == RecordKind::rx) {
      found = true;
      EXPECT_EQ(record.data, "scan");
      EXPECT_EQ(record.t_ns, t);
    }
  }
  EXPECT_TRUE(found);
}

// Several proxies on several threads: a record stamped as it enters the file
// cannot land behind a later one of another channel (a thread taken off the
// CPU between reading the clock and appending would do that).
TEST(Recorder, WriteNowKeepsEveryChannelInTimeOrderAcrossThreads) {
  TempDir dir;
  const std::string path = dir.file("threads.wtape");
  constexpr int kChannels = 4;
  constexpr int kRecordsEach = 20000;
  {
    Recorder recorder(path);
    std::vector<RecordingChannel> channels;
    for (int i = 0; i < kChannels; ++i) {
      channels.push_back(recorder.add_channel(named("c" + std::to_string(i))));
    }
    std::vector<std::thread> writers;
    for (RecordingChannel& channel : channels) {
      writers.emplace_back([&channel] {
        for (int n = 0; n < kRecordsEach; ++n) channel.write_now(RecordKind::rx, "x");
      });
    }
    for (std::thread& writer : writers) writer.join();
    recorder.close();
  }
  std::uint64_t last_t = 0;
  std::vector<int> per_channel(kChannels, 0);
  for (const Record& record : records_of(path)) {
    ASSERT_GE(record.t_ns, last_t) << "record of channel " << record.channel;
    last_t = record.t_ns;
    ASSERT_LT(record.channel, kChannels);
    ++per_channel[record.channel];
  }
  for (int count : per_channel) EXPECT_EQ(count, kRecordsEach);
}

TEST(Recorder, ALogPortIsAFileOfOneUnnamedChannel) {
  TempDir dir;
  const std::string path = dir.file("single.wtape");
  {
    auto port = open_port("type=loopback,log=" + path);
    port->write("hi");
    EXPECT_EQ(port->read_exactly(2), "hi");
  }
  SessionReader reader(path);
  EXPECT_TRUE(reader.header().channels.empty());
  EXPECT_EQ(reader.header().metadata_json.find("\"channels\""), std::string::npos);
  ASSERT_EQ(reader.header().channel_list().size(), 1u);
  EXPECT_EQ(reader.header().channel_list()[0].name, "");
  const auto records = records_of(path);
  ASSERT_FALSE(records.empty());
  EXPECT_EQ(records.front().kind, RecordKind::open);
  EXPECT_EQ(records.front().t_ns, 0u);
  for (const Record& record : records) EXPECT_EQ(record.channel, 0);
}

}  // namespace
