#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <chrono>
#include <string>

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
