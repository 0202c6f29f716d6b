// type=replay on sessions of several ports (DESIGN.md section 19): channel=,
// one clock per file, timing=causal across channels, reports and faults that
// name the channel.
#include <poll.h>

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cstdlib>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "replay/faults.hpp"
#include "replay/replay_port.hpp"
#include "support/port_test_support.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/options.hpp"
#include "wiretape/port.hpp"
#include "wiretape/session.hpp"

using namespace wiretape;
using namespace std::chrono_literals;
using wiretape::test::TempDir;

namespace {

constexpr std::uint64_t ms(std::uint64_t n) { return n * 1'000'000; }

struct ChannelRecord {
  std::uint16_t channel;
  std::uint64_t t_ns;
  RecordKind kind;
  std::string data;
};

Channel channel(std::uint16_t id, const std::string& name, const std::string& port_type) {
  Channel made;
  made.id = id;
  made.name = name;
  made.port_type = port_type;
  made.port_options = "type=" + port_type;
  return made;
}

std::string write_channels(const TempDir& dir, const std::vector<Channel>& channels,
                           const std::vector<ChannelRecord>& records) {
  const std::string path = dir.file("channels.wtape");
  SessionHeader header;
  header.channels = channels;
  header.port_type = channels.front().port_type;
  header.port_options = channels.front().port_options;
  SessionWriter writer(path, header);
  for (const ChannelRecord& record : records) {
    writer.write(record.kind, record.t_ns, record.data, record.channel);
  }
  writer.close();
  return path;
}

// A GPS on a serial line that talks on its own, and an RTK caster that
// answers a login, interleaved in time.
std::string gps_and_rtk(const TempDir& dir) {
  return write_channels(dir, {channel(0, "gps", "serial"), channel(1, "rtk", "tcp")},
                        {{0, ms(1), RecordKind::rx, "$GPGGA,1\n"},
                         {1, ms(2), RecordKind::tx, "LOGIN\n"},
                         {1, ms(3), RecordKind::rx, "ICY 200 OK\n"},
                         {0, ms(4), RecordKind::rx, "$GPGGA,2\n"}});
}

std::string read_text(Port& port, std::size_t size) {
  std::string text;
  while (text.size() < size) {
    std::string buffer(size - text.size(), '\0');
    const std::size_t n = port.read(buffer.data(), buffer.size(), test::kEventDeadline);
    if (n == 0) break;
    text += buffer.substr(0, n);
  }
  return text;
}

std::string open_error(const std::string& options, std::string* key = nullptr) {
  try {
    open_port(options);
  } catch (const OptionError& e) {
    if (key != nullptr) *key = e.key();
    return e.what();
  }
  return "(no error)";
}

bool under_thread_sanitizer() {
#if defined(__SANITIZE_THREAD__)
  return true;
#else
  return std::getenv("WIRETAPE_TSAN") != nullptr;
#endif
}

TEST(ReplayChannels, EachChannelReplaysItsOwnBytes) {
  TempDir dir;
  const std::string path = gps_and_rtk(dir);
  auto gps = open_port("type=replay,timing=none,file=" + path + ",channel=gps");
  auto rtk = open_port("type=replay,timing=none,file=" + path + ",channel=rtk");
  EXPECT_EQ(read_text(*gps, 18), "$GPGGA,1\n$GPGGA,2\n");
  rtk->write(std::string("LOGIN\n"));
  EXPECT_EQ(read_text(*rtk, 11), "ICY 200 OK\n");
  EXPECT_NE(gps->description().find("channel=gps"), std::string::npos) << gps->description();
}

TEST(ReplayChannels, ChannelIsRequiredOnAFileOfSeveral) {
  TempDir dir;
  const std::string path = gps_and_rtk(dir);
  std::string key;
  const std::string missing = open_error("type=replay,file=" + path, &key);
  EXPECT_EQ(key, "channel");
  EXPECT_NE(missing.find("required"), std::string::npos) << missing;
  EXPECT_NE(missing.find("gps, rtk"), std::string::npos) << missing;

  const std::string unknown = open_error("type=replay,file=" + path + ",channel=gsp", &key);
  EXPECT_EQ(key, "channel");
  EXPECT_NE(unknown.find("no channel 'gsp'"), std::string::npos) << unknown;
  EXPECT_NE(unknown.find("did you mean 'gps'?"), std::string::npos) << unknown;
  EXPECT_NE(unknown.find("gps, rtk"), std::string::npos) << unknown;
}

TEST(ReplayChannels, ChannelOnAFileOfOneUnnamedChannelIsRefused) {
  TempDir dir;
  const std::string path = dir.file("one.wtape");
  {
    SessionHeader header;
    header.port_type = "serial";
    SessionWriter writer(path, header);
    writer.write(RecordKind::rx, ms(1), "A");
  }
  std::string key;
  const std::string message = open_error("type=replay,file=" + path + ",channel=gps", &key);
  EXPECT_EQ(key, "channel");
  EXPECT_NE(message.find("none named"), std::string::npos) << message;
  // Without channel= it replays as ever.
  auto port = open_port("type=replay,timing=none,file=" + path);
  EXPECT_EQ(read_text(*port, 1), "A");
}

TEST(ReplayChannels, ChannelsOfOneFileShareOneClockFromTheFirstOpen) {
  TempDir dir;
  const std::string path =
      write_channels(dir, {channel(0, "a", "serial"), channel(1, "b", "serial")},
                     {{0, ms(300), RecordKind::rx, "A"}, {1, ms(300), RecordKind::rx, "B"}});
  const auto first_open = std::chrono::steady_clock::now();
  auto a = open_port("type=replay,timing=session,file=" + path + ",channel=a");
  // The second channel opens 200 ms later: its clock is still the first's.
  std::this_thread::sleep_for(200ms);
  auto b = open_port("type=replay,timing=session,file=" + path + ",channel=b");
  EXPECT_EQ(read_text(*b, 1), "B");
  const auto b_read = std::chrono::steady_clock::now() - first_open;
  EXPECT_GE(b_read, 300ms);
  // On its own clock it would come 300 ms after its own open, at 500 ms.
  if (!under_thread_sanitizer()) EXPECT_LT(b_read, 450ms);
  EXPECT_EQ(read_text(*a, 1), "A");
}

TEST(ReplayChannels, VirtualDevicesOfOneFileStartAtTheFirstClientSession) {
  TempDir dir;
  const std::string path =
      write_channels(dir, {channel(0, "a", "serial"), channel(1, "b", "serial")},
                     {{0, ms(300), RecordKind::rx, "A"}, {1, ms(300), RecordKind::rx, "B"}});
  // Bridges' replays: opened, then holding everything until a client comes.
  auto a = open_port("type=replay,timing=session,file=" + path + ",channel=a");
  auto b = open_port("type=replay,timing=session,file=" + path + ",channel=b");
  ASSERT_TRUE(detail::replay_await_client(*a));
  ASSERT_TRUE(detail::replay_await_client(*b));
  const auto first_client = std::chrono::steady_clock::now();
  detail::replay_begin_client_session(*a);
  std::this_thread::sleep_for(200ms);  // b's client comes later
  detail::replay_begin_client_session(*b);
  EXPECT_EQ(read_text(*b, 1), "B");
  const auto b_read = std::chrono::steady_clock::now() - first_client;
  EXPECT_GE(b_read, 300ms);
  if (!under_thread_sanitizer()) EXPECT_LT(b_read, 450ms);
  EXPECT_EQ(read_text(*a, 1), "A");
}

// The LiDAR: a start command on TCP, then the data stream on UDP.
std::string lidar(const TempDir& dir) {
  return write_channels(dir, {channel(0, "cmd", "tcp"), channel(1, "data", "udp")},
                        {{0, ms(100), RecordKind::tx, "START\n"},
                         {0, ms(101), RecordKind::rx, "OK\n"},
                         {1, ms(120), RecordKind::rx, "D1"},
                         {1, ms(130), RecordKind::rx, "D2"}});
}

TEST(ReplayChannels, CausalDataWaitsForTheStartCommandOnAnotherChannel) {
  TempDir dir;
  const std::string path = lidar(dir);
  auto cmd = open_port("type=replay,timing=causal,file=" + path + ",channel=cmd");
  auto data = open_port("type=replay,timing=causal,file=" + path + ",channel=data");
  std::atomic<bool> started{false};
  std::atomic<bool> early{false};
  std::string got;
  std::thread reader([&] {
    got = read_text(*data, 4);
    early = !started.load();
  });
  // Alone, D1 would be due 120 ms after the open: well past it, nothing.
  EXPECT_FALSE(data->wait_readable(400ms));
  started = true;
  cmd->write(std::string("START\n"));
  reader.join();
  EXPECT_EQ(got, "D1D2");
  EXPECT_FALSE(early.load());
  EXPECT_EQ(read_text(*cmd, 3), "OK\n");
}

TEST(ReplayChannels, TheOtherChannelsWriteRaisesThePollableHandle) {
  TempDir dir;
  const std::string path = lidar(dir);
  auto cmd = open_port("type=replay,timing=causal,file=" + path + ",channel=cmd");
  auto data = open_port("type=replay,timing=causal,file=" + path + ",channel=data");
  pollfd readable{data->native_handle(), POLLIN, 0};
  EXPECT_EQ(::poll(&readable, 1, 300), 0);
  cmd->write(std::string("START\n"));
  EXPECT_EQ(::poll(&readable, 1, 10'000), 1);
  EXPECT_EQ(read_text(*data, 4), "D1D2");
  EXPECT_EQ(read_text(*cmd, 3), "OK\n");
}

TEST(ReplayChannels, CausalAcrossChannelsIgnoresChannelsNotOpened) {
  TempDir dir;
  const std::string path = lidar(dir);
  auto data = open_port("type=replay,timing=causal,file=" + path + ",channel=data");
  EXPECT_EQ(read_text(*data, 4), "D1D2");
}

TEST(ReplayChannels, AClosedChannelNoLongerHoldsTheOthersBack) {
  TempDir dir;
  const std::string path = lidar(dir);
  auto cmd = open_port("type=replay,timing=causal,unused=ignore,file=" + path + ",channel=cmd");
  auto data = open_port("type=replay,timing=causal,file=" + path + ",channel=data");
  EXPECT_FALSE(data->wait_readable(200ms));
  cmd->close();
  EXPECT_EQ(read_text(*data, 4), "D1D2");
}

TEST(ReplayChannels, MismatchNamesTheChannel) {
  TempDir dir;
  const std::string path = gps_and_rtk(dir);
  auto rtk = open_port("type=replay,timing=none,unused=ignore,file=" + path + ",channel=rtk");
  try {
    rtk->write(std::string("LOGOUT\n"));
    FAIL() << "no mismatch";
  } catch (const ReplayMismatch& e) {
    EXPECT_NE(std::string(e.what()).find(": channel rtk: "), std::string::npos) << e.what();
  }
}

TEST(ReplayChannels, ARequestPastAChannelsExchangesNamesTheChannelsCount) {
  // Exchanges are numbered per channel: rtk's one exchange is its exchange 0.
  TempDir dir;
  const std::string path = gps_and_rtk(dir);
  auto rtk = open_port("type=replay,timing=none,unused=ignore,file=" + path + ",channel=rtk");
  rtk->write(std::string("LOGIN\n"));
  EXPECT_EQ(read_text(*rtk, 11), "ICY 200 OK\n");
  try {
    rtk->write(std::string("LOGIN\n"));
    FAIL() << "no mismatch";
  } catch (const ReplayMismatch& e) {
    const std::string report = e.what();
    EXPECT_NE(report.find(": channel rtk: the client wrote more than the recording holds"),
              std::string::npos) << report;
    EXPECT_NE(report.find("exchange 1, past the 1 recorded exchange (0)\n"), std::string::npos)
        << report;
    EXPECT_EQ(e.exchange(), 1);
  }
}

TEST(ReplayChannels, MismatchOfASingleChannelFileNamesNoChannel) {
  TempDir dir;
  const std::string path = dir.file("one.wtape");
  {
    SessionHeader header;
    header.port_type = "serial";
    SessionWriter writer(path, header);
    writer.write(RecordKind::tx, ms(1), "A");
  }
  auto port = open_port("type=replay,timing=none,unused=ignore,file=" + path);
  try {
    port->write(std::string("B"));
    FAIL() << "no mismatch";
  } catch (const ReplayMismatch& e) {
    EXPECT_EQ(std::string(e.what()).find("channel"), std::string::npos) << e.what();
  }
}

TEST(ReplayChannels, FaultsTakeAChannel) {
  const detail::FaultPlan plan =
      detail::parse_faults("drop@exchange:1@channel:gps;corrupt@exchange:2", 0);
  ASSERT_EQ(plan.faults.size(), 2u);
  EXPECT_EQ(plan.faults[0].channel, "gps");
  EXPECT_EQ(plan.faults[0].where_text, "exchange:1@channel:gps");
  EXPECT_EQ(plan.faults[1].channel, "");
  const std::vector<std::string> names = {"gps", "rtk"};
  EXPECT_EQ(detail::faults_for_channel(plan, "gps", names, "f.wtape").faults.size(), 2u);
  const detail::FaultPlan rtk = detail::faults_for_channel(plan, "rtk", names, "f.wtape");
  ASSERT_EQ(rtk.faults.size(), 1u);
  EXPECT_EQ(rtk.faults[0].kind_text, "corrupt");
  EXPECT_THROW(detail::parse_faults("drop@exchange:1@chanel:gps", 0), OptionError);
  EXPECT_THROW(detail::parse_faults("drop@exchange:1@channel:", 0), OptionError);
}

TEST(ReplayChannels, AFaultOfAnotherChannelIsNotInjectedHere) {
  TempDir dir;
  const std::string path = gps_and_rtk(dir);
  // Dropping the GPS's first sentence leaves the caster's answer alone.
  auto rtk = open_port("type=replay,timing=none,file=" + path +
                       ",channel=rtk,faults=drop@rx:0@channel:gps");
  rtk->write(std::string("LOGIN\n"));
  EXPECT_EQ(read_text(*rtk, 11), "ICY 200 OK\n");
  auto gps = open_port("type=replay,timing=none,unused=ignore,file=" + path +
                       ",channel=gps,faults=drop:9@rx:0@channel:gps");
  EXPECT_EQ(read_text(*gps, 9), "$GPGGA,2\n");
  std::string key;
  const std::string unknown = open_error(
      "type=replay,file=" + path + ",channel=gps,faults=drop@rx:0@channel:imu", &key);
  EXPECT_EQ(key, "faults");
  EXPECT_NE(unknown.find("imu"), std::string::npos) << unknown;
}

}  // namespace
