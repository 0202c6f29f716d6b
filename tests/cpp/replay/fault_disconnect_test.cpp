// The device goes away while a read or a write is blocked, on every
// transport: the blocked call wakes and raises PortClosed (never hangs, never
// crashes, never SIGPIPE), and a recording port records the loss.
#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <chrono>
#include <functional>
#include <future>
#include <string>
#include <thread>

#include "support/port_test_support.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/port.hpp"
#include "wiretape/session.hpp"

using namespace std::chrono_literals;
using wiretape::open_port;
using wiretape::test::BlockedPollSignal;
using wiretape::test::kEventDeadline;

namespace {

enum class Outcome { returned, port_closed, port_error, other_exception };

struct CallResult {
  Outcome outcome = Outcome::returned;
  std::string what;
};

std::string describe(const CallResult& result) {
  switch (result.outcome) {
    case Outcome::returned: return "returned normally";
    case Outcome::port_closed: return "PortClosed: " + result.what;
    case Outcome::port_error: return "PortError (not PortClosed): " + result.what;
    case Outcome::other_exception: return "unexpected exception: " + result.what;
  }
  return "?";
}

// Runs a port call on its own thread and reports how it ended.
std::future<CallResult> in_background(std::function<void()> call) {
  return std::async(std::launch::async, [call] {
    CallResult result;
    try {
      call();
    } catch (const wiretape::PortClosed& e) {
      result = {Outcome::port_closed, e.what()};
    } catch (const wiretape::PortError& e) {
      result = {Outcome::port_error, e.what()};
    } catch (const std::exception& e) {
      result = {Outcome::other_exception, e.what()};
    }
    return result;
  });
}

// Waits for the background call; a call still blocked after the deadline is
// the hang this test exists to catch.
CallResult finished(std::future<CallResult>& call) {
  if (call.wait_for(kEventDeadline) != std::future_status::ready) {
    ADD_FAILURE() << "the blocked call did not wake within " << kEventDeadline.count() << " s";
    std::abort();  // the thread is stuck in the port: nothing safe is left to do
  }
  return call.get();
}

// Big enough to fill any kernel buffer between the port and a device that
// does not read.
const std::string kFlood(64 * 1024 * 1024, 'w');

// A TCP "device": listens on 127.0.0.1; accept() gives the connection.
struct TcpDevice {
  TcpDevice() {
    listener = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    EXPECT_EQ(::bind(listener, reinterpret_cast<sockaddr*>(&address), sizeof address), 0);
    EXPECT_EQ(::listen(listener, 1), 0);
    socklen_t length = sizeof address;
    ::getsockname(listener, reinterpret_cast<sockaddr*>(&address), &length);
    port = ntohs(address.sin_port);
  }
  ~TcpDevice() {
    if (connection >= 0) ::close(connection);
    ::close(listener);
  }
  void accept() { connection = ::accept(listener, nullptr, nullptr); }
  // Closing with unread data in the receive queue sends a reset.
  void disconnect() {
    ::close(connection);
    connection = -1;
  }
  std::string options() const { return "type=tcp,host=127.0.0.1,port=" + std::to_string(port); }
  int listener = -1;
  int connection = -1;
  int port = 0;
};

}  // namespace

// --- serial (the device is the far side of a pseudo-terminal) -----------------

TEST(FaultDisconnect, SerialDeviceVanishingMidReadRaisesPortClosed) {
  wiretape::test::PtyPair device;
  auto port = open_port("type=serial,device=" + device.path);
  BlockedPollSignal blocked;
  auto call = in_background([&] {
    char byte;
    port->read(&byte, 1);
  });
  ASSERT_TRUE(blocked.blocked.wait()) << "the read never blocked";
  ::close(device.master);  // the adapter is unplugged
  device.master = -1;
  const CallResult result = finished(call);
  EXPECT_EQ(result.outcome, Outcome::port_closed) << describe(result);
}

TEST(FaultDisconnect, SerialDeviceVanishingMidWriteRaisesPortClosed) {
  wiretape::test::PtyPair device;
  auto port = open_port("type=serial,device=" + device.path);
  BlockedPollSignal blocked;
  auto call = in_background([&] { port->write_all(kFlood); });
  ASSERT_TRUE(blocked.blocked.wait()) << "the write never blocked";
  ::close(device.master);
  device.master = -1;
  const CallResult result = finished(call);
  EXPECT_EQ(result.outcome, Outcome::port_closed) << describe(result);
}

// --- tcp, both as the connecting side and as the listening side ------------------

TEST(FaultDisconnect, TcpDeviceClosingMidReadRaisesPortClosed) {
  TcpDevice device;
  auto port = open_port(device.options());
  device.accept();
  BlockedPollSignal blocked;
  auto call = in_background([&] { port->read_exactly(100); });
  ASSERT_TRUE(blocked.blocked.wait());
  device.disconnect();
  const CallResult result = finished(call);
  EXPECT_EQ(result.outcome, Outcome::port_closed) << describe(result);
}

TEST(FaultDisconnect, TcpDeviceResettingMidWriteRaisesPortClosedNotSigpipe) {
  TcpDevice device;
  auto port = open_port(device.options());
  device.accept();
  BlockedPollSignal blocked;
  auto call = in_background([&] { port->write_all(kFlood); });
  ASSERT_TRUE(blocked.blocked.wait()) << "the write never blocked";
  device.disconnect();  // unread data queued: the kernel sends a reset
  const CallResult result = finished(call);
  EXPECT_EQ(result.outcome, Outcome::port_closed) << describe(result);
}

TEST(FaultDisconnect, TcpListeningPortsClientLeavingMidReadRaisesPortClosed) {
  const int port_number = wiretape::test::free_port();
  auto accepted = std::async(std::launch::async, [&] {
    return open_port("type=tcp,listen,timeout=10,host=127.0.0.1,port=" + std::to_string(port_number));
  });
  int client = -1;
  const auto deadline = std::chrono::steady_clock::now() + kEventDeadline;
  while (client < 0 && std::chrono::steady_clock::now() < deadline) {
    client = ::socket(AF_INET, SOCK_STREAM, 0);
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    address.sin_port = htons(static_cast<std::uint16_t>(port_number));
    if (::connect(client, reinterpret_cast<sockaddr*>(&address), sizeof address) != 0) {
      ::close(client);
      client = -1;
      std::this_thread::yield();  // the listener is not up yet: try again
    }
  }
  ASSERT_GE(client, 0) << "could not connect to the listening port";
  auto port = accepted.get();
  port->set_timeout(wiretape::forever);
  BlockedPollSignal blocked;
  auto call = in_background([&] { port->read_line(); });
  ASSERT_TRUE(blocked.blocked.wait());
  ::close(client);
  const CallResult result = finished(call);
  EXPECT_EQ(result.outcome, Outcome::port_closed) << describe(result);
}

// --- udp: no connection to lose; a vanished peer must not hang or crash ------------

TEST(FaultDisconnect, UdpPeerVanishingNeitherHangsNorCrashes) {
  const int peer_port = wiretape::test::free_port(true);
  auto port = open_port("type=udp,host=127.0.0.1,timeout=0.2,port=" + std::to_string(peer_port));
  // Nobody listens on peer_port: the kernel answers with port unreachable.
  for (int i = 0; i < 3; ++i) {
    try {
      port->write_all("ping");
      char buffer[16];
      EXPECT_EQ(port->read(buffer, sizeof buffer), 0u) << "nothing can have answered";
    } catch (const wiretape::PortError& e) {
      // A refused datagram may surface as an OS error: allowed, if it says so.
      EXPECT_NE(std::string(e.what()).find("udp"), std::string::npos) << e.what();
    }
  }
  EXPECT_TRUE(port->is_open());
}

// --- pty: wiretape is the device; the client hanging up is not the end ----------

TEST(FaultDisconnect, PtyClientHangingUpMidReadLeavesTheReadWaitingForTheNextClient) {
  wiretape::test::TempDir dir;
  const std::string link = dir.path + "/device";
  auto port = open_port("type=pty,link=" + link);
  int client = ::open(link.c_str(), O_RDWR | O_NOCTTY);
  ASSERT_GE(client, 0);
  BlockedPollSignal blocked;
  auto call = in_background([&] {
    if (port->read_exactly(3) != "abc") throw std::runtime_error("wrong bytes after reconnect");
  });
  ASSERT_TRUE(blocked.blocked.wait());
  ::close(client);  // the driver exits...
  client = ::open(link.c_str(), O_RDWR | O_NOCTTY);  // ...and starts again
  ASSERT_GE(client, 0);
  ASSERT_EQ(::write(client, "abc", 3), 3);
  const CallResult result = finished(call);
  EXPECT_EQ(result.outcome, Outcome::returned) << describe(result);
  ::close(client);
}

TEST(FaultDisconnect, PtyCloseFromAnotherThreadMidWriteRaisesPortClosed) {
  wiretape::test::TempDir dir;
  auto port = open_port("type=pty,link=" + dir.path + "/device");
  const int client = ::open((dir.path + "/device").c_str(), O_RDWR | O_NOCTTY);
  ASSERT_GE(client, 0);  // a client that never reads: the write must block
  BlockedPollSignal blocked;
  auto call = in_background([&] { port->write_all(kFlood); });
  ASSERT_TRUE(blocked.blocked.wait()) << "the write never blocked";
  port->close();
  const CallResult result = finished(call);
  EXPECT_EQ(result.outcome, Outcome::port_closed) << describe(result);
  ::close(client);
}

// --- loopback ----------------------------------------------------------------------

TEST(FaultDisconnect, LoopbackClosedMidReadRaisesPortClosed) {
  auto port = open_port("type=loopback");
  auto call = in_background([&] { port->read_until("\n"); });
  // The loopback port waits on a condition variable, not poll(), so there is
  // no seam to see it block; whether close() comes before the read blocks or
  // while it does, the read must end in PortClosed.
  port->close();
  const CallResult result = finished(call);
  EXPECT_EQ(result.outcome, Outcome::port_closed) << describe(result);
}

// --- recorded: the loss is in the file, and the file verifies -----------------

TEST(FaultDisconnect, RecordedTcpDeviceLossIsRecordedAndTheFileVerifies) {
  wiretape::test::TempDir dir;
  const std::string path = dir.path + "/lost.wtape";
  TcpDevice device;
  auto port = open_port(device.options() + ",log=" + path);
  device.accept();
  ASSERT_EQ(::write(device.connection, "hello\n", 6), 6);
  EXPECT_EQ(port->read_line(), "hello\n");
  BlockedPollSignal blocked;
  auto call = in_background([&] { port->read_line(); });
  ASSERT_TRUE(blocked.blocked.wait());
  device.disconnect();
  const CallResult result = finished(call);
  EXPECT_EQ(result.outcome, Outcome::port_closed) << describe(result);
  port->close();

  wiretape::SessionReader reader(path);
  wiretape::Record record;
  std::string rx;
  bool lost = false;
  while (reader.next(record)) {
    if (record.kind == wiretape::RecordKind::rx) rx += record.data;
    if (record.kind == wiretape::RecordKind::device_lost) lost = true;
  }
  EXPECT_FALSE(reader.damage()) << reader.damage()->what();
  EXPECT_EQ(rx, "hello\n");
  EXPECT_TRUE(lost) << "no device_lost record in " << path;

  // Replayed, the loss comes back at the same point: a blocked read after
  // the recorded bytes raises PortClosed.
  auto replay = open_port("type=replay,timing=none,file=" + path);
  EXPECT_EQ(replay->read_line(), "hello\n");
  auto replayed = in_background([&] { replay->read_line(); });
  const CallResult replayed_result = finished(replayed);
  EXPECT_EQ(replayed_result.outcome, Outcome::port_closed) << describe(replayed_result);
}
