#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <chrono>
#include <string>

#include "posix/syscalls.hpp"
#include "posix/transports.hpp"
#include "support/port_test_support.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/port.hpp"

using namespace std::chrono_literals;
using wiretape::open_port;

namespace {

std::string endpoint_options(int bind_port, int destination_port) {
  return "type=udp,timeout=5,bind_host=127.0.0.1,bind_port=" +
         std::to_string(bind_port) + ",host=127.0.0.1,port=" +
         std::to_string(destination_port);
}

}  // namespace

TEST(Udp, DatagramsFlowBothWays) {
  const int a_port = wiretape::test::free_port(true);
  const int b_port = wiretape::test::free_port(true);
  auto a = open_port(endpoint_options(a_port, b_port));
  auto b = open_port(endpoint_options(b_port, a_port));
  EXPECT_EQ(a->type(), "udp");
  EXPECT_NE(a->description().find("127.0.0.1:" + std::to_string(a_port)),
            std::string::npos) << a->description();
  a->write_all("from a");
  char buffer[64];
  std::size_t n = b->read(buffer, sizeof buffer);
  EXPECT_EQ(std::string(buffer, n), "from a");
  b->write_all("from b");
  n = a->read(buffer, sizeof buffer);
  EXPECT_EQ(std::string(buffer, n), "from b");
}

TEST(Udp, EachReadReturnsOneDatagramAndAShortReadTruncatesIt) {
  const int a_port = wiretape::test::free_port(true);
  const int b_port = wiretape::test::free_port(true);
  auto a = open_port(endpoint_options(a_port, b_port));
  auto b = open_port(endpoint_options(b_port, a_port));
  a->write_all("0123456789");
  a->write_all("second");
  char buffer[64];
  ASSERT_EQ(b->read(buffer, 4), 4u);
  EXPECT_EQ(std::string(buffer, 4), "0123");
  // The rest of the first datagram is gone, as with recv().
  const std::size_t n = b->read(buffer, sizeof buffer);
  EXPECT_EQ(std::string(buffer, n), "second");
  EXPECT_EQ(b->read(buffer, sizeof buffer, 20ms), 0u) << "nothing more: timeout";
}

TEST(Udp, FlexiportAliasesAndReplyToLastSender) {
  const int a_port = wiretape::test::free_port(true);
  const int b_port = wiretape::test::free_port(true);
  auto a = open_port("type=udp,timeout=5,recv_ip=127.0.0.1,recv_port=" +
                     std::to_string(a_port) + ",dest_ip=127.0.0.1,dest_port=" +
                     std::to_string(b_port));
  // No destination: b answers whoever spoke last.
  auto b = open_port("type=udp,timeout=5,bind_host=127.0.0.1,bind_port=" +
                     std::to_string(b_port));
  EXPECT_THROW(b->write_all("nobody to send to"), wiretape::PortError);
  a->write_all("question");
  EXPECT_EQ(b->read_exactly(8), "question");
  b->write_all("answer");
  EXPECT_EQ(a->read_exactly(6), "answer");
}

TEST(Udp, PollingAndNativeHandle) {
  const int a_port = wiretape::test::free_port(true);
  const int b_port = wiretape::test::free_port(true);
  auto a = open_port(endpoint_options(a_port, b_port));
  auto b = open_port(endpoint_options(b_port, a_port));
  char byte;
  EXPECT_EQ(b->read(&byte, 1, 0s), 0u);
  EXPECT_FALSE(wiretape::test::fd_readable(b->native_handle(), 0ms));
  a->write_all("xyz");
  EXPECT_TRUE(wiretape::test::fd_readable(b->native_handle(), 5000ms));
  EXPECT_EQ(b->available(), 3u);
  b->flush_input();
  EXPECT_EQ(b->available(), 0u);
}

TEST(Udp, HostWithoutPortIsAnOptionError) {
  try {
    open_port("type=udp,host=127.0.0.1");
    FAIL() << "expected OptionError";
  } catch (const wiretape::OptionError& error) {
    EXPECT_EQ(error.key(), "port");
  }
  EXPECT_THROW(open_port("type=udp,port=70000"), wiretape::OptionError);
  EXPECT_THROW(open_port("type=udp,dest_port=1,port=2"), wiretape::OptionError);
}

// read_until peeks at each datagram and reads it through the delimiter: a
// line sent in several datagrams comes back whole, an empty datagram is
// passed over, and the rest of a datagram after the delimiter is dropped, as
// a short read drops it.
TEST(Udp, ReadUntilGathersALineFromDatagrams) {
  const int a_port = wiretape::test::free_port(true);
  const int b_port = wiretape::test::free_port(true);
  auto a = open_port(endpoint_options(a_port, b_port));
  auto b = open_port(endpoint_options(b_port, a_port));
  a->write_all("ab");
  {  // an empty datagram (Port::write sends nothing for 0 bytes)
    const int fd = ::socket(AF_INET, SOCK_DGRAM, 0);
    ASSERT_GE(fd, 0);
    sockaddr_in to{};
    to.sin_family = AF_INET;
    to.sin_port = htons(static_cast<std::uint16_t>(b_port));
    to.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    EXPECT_EQ(::sendto(fd, "", 0, 0, reinterpret_cast<const sockaddr*>(&to), sizeof to), 0);
    ::close(fd);
  }
  a->write_all("c\nrest of it");
  a->write_all("next\n");
  EXPECT_EQ(b->read_until("\n", wiretape::Port::unlimited, 5s), "abc\n");
  EXPECT_EQ(b->read_until("\n", wiretape::Port::unlimited, 5s), "next\n");
}

namespace {

// A plain socket bound to 127.0.0.1 (port 0: any), closed at the end.
struct PlainUdp {
  int fd = ::socket(AF_INET, SOCK_DGRAM, 0);
  sockaddr_in address{};
  PlainUdp() {
    address.sin_family = AF_INET;
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    ::bind(fd, reinterpret_cast<sockaddr*>(&address), sizeof address);
    socklen_t length = sizeof address;
    ::getsockname(fd, reinterpret_cast<sockaddr*>(&address), &length);
  }
  ~PlainUdp() { ::close(fd); }
  int port() const { return ntohs(address.sin_port); }
  void send_to(const sockaddr_in& to, const std::string& data) const {
    ::sendto(fd, data.data(), data.size(), 0, reinterpret_cast<const sockaddr*>(&to), sizeof to);
  }
  // One datagram, and who sent it.
  std::string receive(sockaddr_in& from) const {
    char buffer[256];
    socklen_t length = sizeof from;
    const ssize_t n = ::recvfrom(fd, buffer, sizeof buffer, 0,
                                 reinterpret_cast<sockaddr*>(&from), &length);
    return n < 0 ? std::string("<error>") : std::string(buffer, static_cast<std::size_t>(n));
  }
};

}  // namespace

// A port with a destination reads the destination's datagrams alone (the
// record proxy's device side, DESIGN.md section 23): the socket is
// connected, and a datagram that reached it from anyone else (queued
// before the connect) is dropped and counted. The seam leaves the socket
// unconnected here, so the stranger's datagram does reach it.
TEST(Udp, ADatagramFromAnotherSenderThanTheDestinationIsDroppedAndCounted) {
  wiretape::detail::sys::ScopedOverride seam;
  bool connected = false;
  seam->connect = [&connected](int, const sockaddr*, socklen_t) {
    connected = true;
    return 0;
  };
  PlainUdp device;
  PlainUdp stranger;
  auto port = open_port("type=udp,timeout=5,host=127.0.0.1,port=" +
                        std::to_string(device.port()));
  EXPECT_TRUE(connected) << "a port with a destination connects its socket";
  port->write_all("ping");
  sockaddr_in proxy{};
  ASSERT_EQ(device.receive(proxy), "ping");
  stranger.send_to(proxy, "not the device");
  device.send_to(proxy, "pong");
  char buffer[64];
  const std::size_t n = port->read(buffer, sizeof buffer);
  EXPECT_EQ(std::string(buffer, n), "pong");
  auto* datagrams = dynamic_cast<wiretape::detail::DatagramPort*>(port.get());
  ASSERT_NE(datagrams, nullptr);
  EXPECT_EQ(datagrams->datagrams_from_others(), 1u);
}

// Port::read cannot return an empty datagram (0 bytes is a timeout): a
// DatagramPort receives and sends them.
TEST(Udp, EmptyDatagramsGoBothWaysThroughADatagramPort) {
  PlainUdp device;
  auto port = open_port("type=udp,timeout=5,host=127.0.0.1,port=" +
                        std::to_string(device.port()));
  auto* datagrams = dynamic_cast<wiretape::detail::DatagramPort*>(port.get());
  ASSERT_NE(datagrams, nullptr);
  EXPECT_FALSE(datagrams->receive_datagram(nullptr, 0).has_value()) << "none waits yet";
  ASSERT_TRUE(datagrams->send_empty_datagram());
  sockaddr_in proxy{};
  EXPECT_EQ(device.receive(proxy), "");
  device.send_to(proxy, "");
  ASSERT_TRUE(port->wait_readable(5s));
  char buffer[16];
  const std::optional<std::size_t> n = datagrams->receive_datagram(buffer, sizeof buffer);
  ASSERT_TRUE(n.has_value());
  EXPECT_EQ(*n, 0u);
}
