// Bridges recording into channels of one Recorder (DESIGN §19): the proxy
// side of sessions of several ports.
#include <unistd.h>

#include <gtest/gtest.h>

#include <chrono>
#include <memory>
#include <string>
#include <thread>

#include "support/port_test_support.hpp"
#include "wiretape/bridge.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/recorder.hpp"
#include "wiretape/session.hpp"

namespace {

using namespace std::chrono_literals;
using namespace wiretape;

constexpr auto kDeadline = 10s;

void write_all(int fd, const std::string& data) {
  std::size_t done = 0;
  while (done < data.size()) {
    const ssize_t n = ::write(fd, data.data() + done, data.size() - done);
    ASSERT_GT(n, 0);
    done += static_cast<std::size_t>(n);
  }
}

BridgeOptions recording_bridge(std::shared_ptr<Recorder> recorder, const std::string& channel,
                               const std::string& device) {
  BridgeOptions options;
  options.device = device;
  options.client_side = BridgeClientSide::tcp;
  options.recorder = std::move(recorder);
  options.channel = channel;
  options.quiet = true;
  return options;
}

// One exchange through `bridge`: what is sent comes back (a loopback device).
void echo_through(const Bridge& bridge, const std::string& data) {
  const int client = wiretape::test::connect_tcp(bridge.listen_address());
  ASSERT_GE(client, 0);
  write_all(client, data);
  EXPECT_EQ(wiretape::test::read_count(client, data.size()), data);
  ::close(client);
}

TEST(BridgeRecorder, TwoBridgesRecordTheirChannelsOfOneFileInTimeOrder) {
  wiretape::test::TempDir dir;
  const std::string path = dir.file("two.wtape");
  auto recorder = std::make_shared<Recorder>(path);
  Bridge gps(recording_bridge(recorder, "gps", "type=loopback"));
  Bridge rtk(recording_bridge(recorder, "rtk", "type=loopback,timeout=1"));
  gps.start();
  rtk.start();
  echo_through(gps, "$GPGGA,1\r\n");
  echo_through(rtk, "RTCM-1");
  echo_through(gps, "$GPGGA,2\r\n");
  for (Bridge* bridge : {&gps, &rtk}) {
    bridge->stop();
    ASSERT_TRUE(bridge->wait(kDeadline));
    EXPECT_TRUE(bridge->result().ok()) << bridge->result().message;
  }
  recorder->close();

  SessionReader reader(path);
  const SessionHeader& header = reader.header();
  ASSERT_EQ(header.channels.size(), 2u);
  const auto gps_channel = header.find_channel("gps");
  const auto rtk_channel = header.find_channel("rtk");
  ASSERT_TRUE(gps_channel && rtk_channel);
  EXPECT_EQ(gps_channel->capture, Capture::wire);
  EXPECT_EQ(gps_channel->port_options, "type=loopback");
  EXPECT_EQ(gps_channel->port_type, "loopback");
  EXPECT_EQ(rtk_channel->port_options, "type=loopback,timeout=1");

  const auto records = wiretape::test::load_records(path);
  std::string gps_tx, rtk_tx, order;
  std::uint64_t last_t = 0;
  int opens = 0, closes = 0;
  for (const Record& record : records) {
    EXPECT_GE(record.t_ns, last_t) << "one clock, records in time order";
    last_t = record.t_ns;
    if (record.kind == RecordKind::open) ++opens;
    if (record.kind == RecordKind::close) ++closes;
    if (record.kind != RecordKind::tx) continue;
    if (record.channel == gps_channel->id) gps_tx += record.data;
    if (record.channel == rtk_channel->id) rtk_tx += record.data;
    if (order.empty() || order.back() != static_cast<char>('0' + record.channel)) {
      order += static_cast<char>('0' + record.channel);
    }
  }
  EXPECT_EQ(gps_tx, "$GPGGA,1\r\n$GPGGA,2\r\n");
  EXPECT_EQ(rtk_tx, "RTCM-1");
  EXPECT_EQ(order, "010");
  EXPECT_EQ(opens, 2);
  EXPECT_EQ(closes, 2);
}

TEST(BridgeRecorder, OptionsAreCheckedNamingTheKey) {
  wiretape::test::TempDir dir;
  auto recorder = std::make_shared<Recorder>(dir.file("opts.wtape"));
  auto expect_key = [](BridgeOptions options, const std::string& key) {
    try {
      Bridge bridge(std::move(options));
      FAIL() << "accepted";
    } catch (const OptionError& e) {
      EXPECT_EQ(e.key(), key) << e.what();
    }
  };
  BridgeOptions both = recording_bridge(recorder, "gps", "type=loopback");
  both.output = dir.file("own.wtape");
  expect_key(both, "output");
  expect_key(recording_bridge(recorder, "", "type=loopback"), "channel");
  expect_key(recording_bridge(recorder, "not a name", "type=loopback"), "channel");
  expect_key(recording_bridge(nullptr, "gps", "type=loopback"), "channel");
  BridgeOptions with_metadata = recording_bridge(recorder, "gps", "type=loopback");
  with_metadata.metadata = {{"robot", "r2"}};
  expect_key(with_metadata, "metadata");
}

TEST(BridgeRecorder, AChannelNameTakenTwiceFailsTheSecondBridgeAtStart) {
  wiretape::test::TempDir dir;
  auto recorder = std::make_shared<Recorder>(dir.file("dup.wtape"));
  Bridge first(recording_bridge(recorder, "gps", "type=loopback"));
  first.start();
  Bridge second(recording_bridge(recorder, "gps", "type=loopback"));
  EXPECT_THROW(second.start(), OptionError);
  first.stop();
  ASSERT_TRUE(first.wait(kDeadline));
  EXPECT_TRUE(first.result().ok()) << first.result().message;
}

TEST(BridgeRecorder, ANetworkDeviceChannelHoldsTheDeviceAddress) {
  wiretape::test::TempDir dir;
  const std::string path = dir.file("net.wtape");
  // The device: a loopback behind another bridge's TCP listener.
  BridgeOptions device_options;
  device_options.device = "type=loopback";
  device_options.client_side = BridgeClientSide::tcp;
  device_options.quiet = true;
  Bridge device(device_options);
  device.start();
  const std::string address = device.listen_address();
  const std::string port = address.substr(address.rfind(':') + 1);

  auto recorder = std::make_shared<Recorder>(path);
  Bridge proxy(recording_bridge(recorder, "net", "type=tcp,host=127.0.0.1,port=" + port));
  proxy.start();
  echo_through(proxy, "ping");
  proxy.stop();
  ASSERT_TRUE(proxy.wait(kDeadline));
  EXPECT_TRUE(proxy.result().ok()) << proxy.result().message;
  device.stop();
  ASSERT_TRUE(device.wait(kDeadline));
  recorder->close();

  SessionReader reader(path);
  const auto channel = reader.header().find_channel("net");
  ASSERT_TRUE(channel);
  EXPECT_EQ(channel->device_address, "127.0.0.1:" + port);
  EXPECT_EQ(channel->port_type, "tcp");
}

}  // namespace
