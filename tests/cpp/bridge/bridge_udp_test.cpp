// The bridge's UDP client side from C++: a UDP device that answers each
// datagram with two, a client that sends datagrams of several sizes, and
// the recording: one record per datagram both ways, boundaries kept.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <string>
#include <thread>
#include <vector>

#include "wiretape/bridge.hpp"
#include "wiretape/errors.hpp"
#include "support/port_test_support.hpp"

namespace {

using namespace std::chrono_literals;
using wiretape::Bridge;
using wiretape::BridgeClientSide;
using wiretape::BridgeOptions;
using wiretape::RecordKind;

constexpr int kDeadlineMs = 10'000;

class UdpSocket {
 public:
  UdpSocket() : fd_(::socket(AF_INET, SOCK_DGRAM, 0)) {
    sockaddr_in local{};
    local.sin_family = AF_INET;
    local.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    ::bind(fd_, reinterpret_cast<sockaddr*>(&local), sizeof local);
  }
  ~UdpSocket() { ::close(fd_); }
  UdpSocket(const UdpSocket&) = delete;
  UdpSocket& operator=(const UdpSocket&) = delete;

  int port() const {
    sockaddr_in bound{};
    socklen_t length = sizeof bound;
    ::getsockname(fd_, reinterpret_cast<sockaddr*>(&bound), &length);
    return ntohs(bound.sin_port);
  }
  void send_to(const std::string& data, int port) const {
    sockaddr_in to{};
    to.sin_family = AF_INET;
    to.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    to.sin_port = htons(static_cast<std::uint16_t>(port));
    ASSERT_EQ(::sendto(fd_, data.data(), data.size(), 0, reinterpret_cast<sockaddr*>(&to),
                       sizeof to),
              static_cast<ssize_t>(data.size()));
  }
  // The next datagram into `data`; false when none came within `timeout_ms`.
  bool receive(std::string& data, sockaddr_in* from = nullptr, int timeout_ms = kDeadlineMs) const {
    pollfd entry{fd_, POLLIN, 0};
    if (::poll(&entry, 1, timeout_ms) <= 0) return false;
    std::vector<char> buffer(65536);
    sockaddr_in sender{};
    socklen_t length = sizeof sender;
    const ssize_t n = ::recvfrom(fd_, buffer.data(), buffer.size(), 0,
                                 reinterpret_cast<sockaddr*>(&sender), &length);
    if (n < 0) return false;
    data.assign(buffer.data(), static_cast<std::size_t>(n));
    if (from) *from = sender;
    return true;
  }
  int fd() const { return fd_; }

 private:
  int fd_;
};

std::vector<std::string> answers_to(const std::string& request) {
  return {"re:" + request, "#" + std::to_string(request.size())};
}

// Answers each datagram with answers_to(it), to its sender, until stopped.
class UdpDevice {
 public:
  UdpDevice() : thread_([this] { run(); }) {}
  ~UdpDevice() {
    stop_ = true;
    thread_.join();
  }
  std::string options() const {
    return "type=udp,host=127.0.0.1,port=" + std::to_string(socket_.port());
  }

 private:
  void run() {
    while (!stop_) {
      std::string request;
      sockaddr_in from{};
      if (!socket_.receive(request, &from, 20)) continue;
      for (const std::string& answer : answers_to(request)) {
        ::sendto(socket_.fd(), answer.data(), answer.size(), 0,
                 reinterpret_cast<sockaddr*>(&from), sizeof from);
      }
    }
  }

  UdpSocket socket_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

int port_of(const std::string& address) { return std::stoi(address.substr(address.rfind(':') + 1)); }

std::string temp_path(const std::string& name) {
  const char* dir = std::getenv("TMPDIR");
  return std::string(dir ? dir : "/tmp") + "/wiretape-bridge-udp-test-" +
         std::to_string(::getpid()) + "-" + name;
}

std::vector<std::string> payloads(const std::vector<wiretape::Record>& records, RecordKind kind) {
  std::vector<std::string> out;
  for (const auto& record : records) {
    if (record.kind == kind) out.push_back(record.data);
  }
  return out;
}

TEST(BridgeUdp, EachDatagramIsOneWriteOneRecordAndOneAnswerDatagram) {
  UdpDevice device;
  const std::string path = temp_path("boundaries.wtape");
  BridgeOptions options;
  options.device = device.options();
  options.client_side = BridgeClientSide::udp;
  options.output = path;
  options.quiet = true;
  std::vector<std::string> requests = {"a", std::string(9000, 'b'), "ccc"};
  std::vector<std::string> expected_answers;
  {
    Bridge bridge(options);
    bridge.start();
    const int port = port_of(bridge.listen_address());
    UdpSocket client;
    for (const std::string& request : requests) {
      client.send_to(request, port);
      for (const std::string& answer : answers_to(request)) {
        std::string got;
        ASSERT_TRUE(client.receive(got)) << "no answer to a " << request.size() << "-byte datagram";
        EXPECT_EQ(got, answer);
        expected_answers.push_back(answer);
      }
    }
    bridge.stop();
    ASSERT_TRUE(bridge.wait(10s));
    EXPECT_TRUE(bridge.result().ok()) << bridge.result().message;
    EXPECT_EQ(bridge.stats().datagrams_dropped, 0u);
    EXPECT_EQ(bridge.stats().clients_accepted, 1u);
  }
  const auto records = wiretape::test::load_records(path);
  EXPECT_EQ(payloads(records, RecordKind::tx), requests);
  EXPECT_EQ(payloads(records, RecordKind::rx), expected_answers);
  std::remove(path.c_str());
}

TEST(BridgeUdp, APeerIsCheckedAndNeedsTheUdpSide) {
  BridgeOptions options;
  options.device = "type=loopback";
  options.client_side = BridgeClientSide::tcp;
  options.udp_peer_host = "127.0.0.1";
  options.udp_peer_port = 9;
  try {
    Bridge bridge(options);
    FAIL() << "a peer without the udp side was accepted";
  } catch (const wiretape::OptionError& error) {
    EXPECT_EQ(error.key(), "peer");
  }
  options.client_side = BridgeClientSide::udp;
  options.udp_peer_port = 0;
  EXPECT_THROW(Bridge{options}, wiretape::OptionError);
  options.udp_peer_port = 70000;
  EXPECT_THROW(Bridge{options}, wiretape::OptionError);
  options.udp_peer_host.clear();
  options.listen_port = 70000;
  try {
    Bridge bridge(options);
    FAIL() << "udp port 70000 was accepted";
  } catch (const wiretape::OptionError& error) {
    EXPECT_EQ(error.key(), "udp");
  }
}

TEST(BridgeUdp, AnUnresolvablePeerFailsTheStartLeavingNothingRunning) {
  BridgeOptions options;
  options.device = "type=loopback";
  options.client_side = BridgeClientSide::udp;
  options.udp_peer_host = "no-such-host.invalid";
  options.udp_peer_port = 5000;
  options.quiet = true;
  Bridge bridge(options);
  EXPECT_THROW(bridge.start(), wiretape::PortError);
  EXPECT_FALSE(bridge.running());
}

}  // namespace
