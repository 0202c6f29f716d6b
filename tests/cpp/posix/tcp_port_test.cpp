#include <netinet/in.h>
#include <netinet/tcp.h>
#include <sys/socket.h>

#include <gtest/gtest.h>

#include <chrono>
#include <future>
#include <string>
#include <thread>

#include "support/port_test_support.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/port.hpp"

using namespace std::chrono_literals;
using wiretape::open_port;
using wiretape::Port;
namespace sys = wiretape::detail::sys;

namespace {

// A listening port and a connected port in one process: the listener is
// opened on a thread; the client connects once listen() was called.
struct TcpPair {
  std::unique_ptr<Port> server;
  std::unique_ptr<Port> client;
};

TcpPair connect_pair(const std::string& server_extra = "",
                     const std::string& client_extra = "") {
  const int number = wiretape::test::free_port();
  wiretape::test::Event listening;
  sys::ScopedOverride seam;
  const auto real_listen = sys::real().listen;
  seam->listen = [&](int fd, int backlog) {
    const int status = real_listen(fd, backlog);
    listening.set();
    return status;
  };
  auto server = std::async(std::launch::async, [&] {
    return open_port("type=tcp,listen,timeout=10,port=" +
                     std::to_string(number) + server_extra);
  });
  EXPECT_TRUE(listening.wait());
  TcpPair pair;
  pair.client = open_port("type=tcp,host=127.0.0.1,timeout=5,port=" +
                          std::to_string(number) + client_extra);
  pair.server = server.get();
  return pair;
}

}  // namespace

TEST(Tcp, ListenAndConnectInOneProcessCarryDataBothWays) {
  auto pair = connect_pair();
  EXPECT_EQ(pair.client->type(), "tcp");
  EXPECT_NE(pair.server->description().find("listen"), std::string::npos);
  EXPECT_NE(pair.server->description().find("client 127.0.0.1:"), std::string::npos)
      << pair.server->description();
  pair.client->write_all("ping\n");
  EXPECT_EQ(pair.server->read_line(), "ping\n");
  pair.server->write_all("pong\n");
  EXPECT_EQ(pair.client->read_line(), "pong\n");
}

TEST(Tcp, NodelayIsOnByDefaultAndCanBeTurnedOff) {
  auto pair = connect_pair("", ",nodelay=false");
  int value = -1;
  socklen_t length = sizeof value;
  ASSERT_EQ(::getsockopt(pair.server->native_handle(), IPPROTO_TCP, TCP_NODELAY,
                         &value, &length), 0);
  EXPECT_NE(value, 0);
  ASSERT_EQ(::getsockopt(pair.client->native_handle(), IPPROTO_TCP, TCP_NODELAY,
                         &value, &length), 0);
  EXPECT_EQ(value, 0);
}

TEST(Tcp, ReadTimeoutsAndPartialCompoundReads) {
  auto pair = connect_pair();
  char byte;
  EXPECT_EQ(pair.client->read(&byte, 1, 0s), 0u);
  const auto start = std::chrono::steady_clock::now();
  EXPECT_EQ(pair.client->read(&byte, 1, 50ms), 0u);
  EXPECT_GE(std::chrono::steady_clock::now() - start, 50ms);
  pair.server->write_all("part");
  ASSERT_TRUE(pair.client->wait_readable(5s));
  EXPECT_EQ(pair.client->read_exactly(100, 100ms), "part");
  pair.server->write_all("no delimiter");
  EXPECT_EQ(pair.client->read_until("\r\n", Port::unlimited, 100ms), "no delimiter");
}

TEST(Tcp, AvailableAndFlushInput) {
  auto pair = connect_pair();
  pair.server->write_all("12345");
  ASSERT_TRUE(pair.client->wait_readable(5s));
  // All five bytes were sent in one segment over loopback.
  const auto deadline = std::chrono::steady_clock::now() + 5s;
  while (pair.client->available() < 5 && std::chrono::steady_clock::now() < deadline) {
    pair.client->wait_readable(100ms);
  }
  EXPECT_EQ(pair.client->available(), 5u);
  pair.client->flush_input();
  EXPECT_EQ(pair.client->available(), 0u);
}

TEST(Tcp, PeerClosingMidReadRaisesPortClosed) {
  auto pair = connect_pair();
  wiretape::test::BlockedPollSignal signal;
  std::thread closer([&] {
    ASSERT_TRUE(signal.blocked.wait());
    pair.server->close();
  });
  char byte;
  pair.client->set_timeout(wiretape::forever);
  EXPECT_THROW(pair.client->read(&byte, 1), wiretape::PortClosed);
  closer.join();
  // And stays so.
  EXPECT_THROW(pair.client->read(&byte, 1), wiretape::PortClosed);
}

TEST(Tcp, PeerResetRaisesPortClosed) {
  auto pair = connect_pair();
  // SO_LINGER 0 makes close() send a reset.
  linger abort_on_close{1, 0};
  ASSERT_EQ(::setsockopt(pair.server->native_handle(), SOL_SOCKET, SO_LINGER,
                         &abort_on_close, sizeof abort_on_close), 0);
  pair.server->close();
  char byte;
  EXPECT_THROW(pair.client->read(&byte, 1, 5s), wiretape::PortClosed);
}

TEST(Tcp, WritingToAClosedPeerRaisesPortClosedNotSigpipe) {
  auto pair = connect_pair();
  linger abort_on_close{1, 0};
  ::setsockopt(pair.server->native_handle(), SOL_SOCKET, SO_LINGER,
               &abort_on_close, sizeof abort_on_close);
  pair.server->close();
  EXPECT_THROW(
      {
        for (int i = 0; i < 100; ++i) pair.client->write_all(std::string(4096, 'x'));
      },
      wiretape::PortClosed);
}

TEST(Tcp, CloseFromAnotherThreadWakesABlockedRead) {
  auto pair = connect_pair();
  wiretape::test::BlockedPollSignal signal;
  pair.client->set_timeout(wiretape::forever);
  std::thread closer([&] {
    ASSERT_TRUE(signal.blocked.wait());
    pair.client->close();
  });
  char byte;
  EXPECT_THROW(pair.client->read(&byte, 1), wiretape::PortClosed);
  closer.join();
}

TEST(Tcp, ListenTimesOutWithoutAClient) {
  const int number = wiretape::test::free_port();
  try {
    open_port("type=tcp,listen=true,timeout=0.05,port=" + std::to_string(number));
    FAIL() << "expected PortError";
  } catch (const wiretape::PortClosed&) {
    FAIL() << "a listen timeout is not a disconnect";
  } catch (const wiretape::PortError& error) {
    EXPECT_EQ(error.code().value(), ETIMEDOUT);
    EXPECT_NE(std::string(error.what()).find(std::to_string(number)), std::string::npos);
  }
}

TEST(Tcp, ConnectionRefusedNamesTheEndpoint) {
  const int number = wiretape::test::free_port();
  try {
    open_port("type=tcp,timeout=5,port=" + std::to_string(number));
    FAIL() << "expected PortError";
  } catch (const wiretape::PortError& error) {
    EXPECT_EQ(error.code().value(), ECONNREFUSED);
    EXPECT_NE(std::string(error.what()).find("127.0.0.1:" + std::to_string(number)),
              std::string::npos) << error.what();
  }
}

TEST(Tcp, FlexiportIpAliasIsAccepted) {
  const int number = wiretape::test::free_port();
  try {
    open_port("type=tcp,ip=127.0.0.1,timeout=5,port=" + std::to_string(number));
  } catch (const wiretape::OptionError& error) {
    FAIL() << error.what();
  } catch (const wiretape::PortError&) {
    // Nobody listens: refused, which is fine; the option was accepted.
  }
  EXPECT_THROW(open_port("type=tcp,ip=127.0.0.1,host=localhost,port=1"),
               wiretape::OptionError);
}

// A socket can be looked at without consuming (MSG_PEEK): read_until takes
// one system call per chunk the peer sent, not one per byte, and consumes
// nothing past the delimiter.
TEST(Tcp, ReadUntilTakesAFewSystemCallsPerLineNotOnePerByte) {
  auto pair = connect_pair();
  const std::string line = std::string(999, 'x') + "\n";
  pair.server->write_all(line + "next");
  const auto deadline = std::chrono::steady_clock::now() + 5s;
  while (pair.client->available() < line.size() + 4 &&
         std::chrono::steady_clock::now() < deadline) {
    pair.client->wait_readable(100ms);
  }
  int receives = 0;
  {
    sys::ScopedOverride seam;
    const auto real_recv = sys::real().recv;
    seam->recv = [&](int fd, void* buffer, size_t size, int flags) {
      ++receives;
      return real_recv(fd, buffer, size, flags);
    };
    EXPECT_EQ(pair.client->read_until("\n", Port::unlimited, 5s), line);
  }
  EXPECT_LE(receives, 4);
  EXPECT_EQ(pair.client->available(), 4u);
  EXPECT_EQ(pair.client->read_exactly(4, 5s), "next");
}

TEST(Tcp, ReadUntilFindsADelimiterSplitAcrossSegments) {
  auto pair = connect_pair();
  pair.server->write_all("abc\r");
  ASSERT_TRUE(pair.client->wait_readable(5s));
  std::thread sender([&] { pair.server->write_all("\nrest"); });
  EXPECT_EQ(pair.client->read_until("\r\n", Port::unlimited, 5s), "abc\r\n");
  sender.join();
  EXPECT_EQ(pair.client->read_exactly(4, 5s), "rest");
}
