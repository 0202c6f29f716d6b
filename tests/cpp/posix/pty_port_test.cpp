#include <fcntl.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/stat.h>
#include <termios.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <chrono>
#include <string>
#include <thread>

#include "posix/syscalls.hpp"
#include "support/port_test_support.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/port.hpp"

using namespace std::chrono_literals;
using wiretape::open_port;
using wiretape::test::TempDir;

namespace {

// The client side: a program opening the terminal as its serial device.
int open_client(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDWR | O_NOCTTY);
  if (fd < 0) ADD_FAILURE() << "cannot open " << path;
  return fd;
}

void write_fd(int fd, const std::string& data) {
  ASSERT_EQ(::write(fd, data.data(), data.size()),
            static_cast<ssize_t>(data.size()));
}

std::string read_fd(int fd, std::size_t count) {
  std::string out;
  while (out.size() < count) {
    if (!wiretape::test::fd_readable(fd, 5000ms)) break;
    char buffer[256];
    const ssize_t n = ::read(fd, buffer, std::min(sizeof buffer, count - out.size()));
    if (n <= 0) break;
    out.append(buffer, static_cast<std::size_t>(n));
  }
  return out;
}

// What a client programs on its terminal: raw, `speed` both ways, one or
// two stop bits.
void program_client(int client, speed_t speed, bool two_stop_bits) {
  termios settings{};
  ASSERT_EQ(::tcgetattr(client, &settings), 0);
  ::cfmakeraw(&settings);
  ::cfsetispeed(&settings, speed);
  ::cfsetospeed(&settings, speed);
  if (two_stop_bits) {
    settings.c_cflag |= CSTOPB;
  } else {
    settings.c_cflag &= ~static_cast<tcflag_t>(CSTOPB);
  }
  ASSERT_EQ(::tcsetattr(client, TCSANOW, &settings), 0);
}

}  // namespace

TEST(Pty, DataFlowsBothWaysThroughTheLink) {
  TempDir dir;
  const std::string link = dir.path + "/device";
  auto port = open_port("type=pty,timeout=5,link=" + link);
  EXPECT_EQ(port->type(), "pty");
  EXPECT_NE(port->description().find("/dev/pts/"), std::string::npos)
      << port->description();
  EXPECT_NE(port->description().find(link), std::string::npos);

  const int client = open_client(link);
  write_fd(client, "hello\r\n");  // raw mode: no translation
  EXPECT_EQ(port->read_exactly(7), "hello\r\n");
  port->write_all("world\n");
  EXPECT_EQ(read_fd(client, 6), "world\n");
  ::close(client);
}

TEST(Pty, LinkIsRemovedOnClose) {
  TempDir dir;
  const std::string link = dir.path + "/device";
  auto port = open_port("type=pty,link=" + link);
  struct stat info {};
  ASSERT_EQ(::lstat(link.c_str(), &info), 0);
  EXPECT_TRUE(S_ISLNK(info.st_mode));
  port->close();
  EXPECT_NE(::lstat(link.c_str(), &info), 0);
  EXPECT_FALSE(port->is_open());
  EXPECT_EQ(port->native_handle(), -1);
}

TEST(Pty, LinkOverARegularFileIsRefused) {
  TempDir dir;
  const std::string file = dir.path + "/taken";
  ::close(::open(file.c_str(), O_CREAT | O_WRONLY, 0600));
  try {
    open_port("type=pty,link=" + file);
    FAIL() << "expected PortError";
  } catch (const wiretape::PortError& error) {
    EXPECT_NE(std::string(error.what()).find(file), std::string::npos);
  }
}

TEST(Pty, ClientReopeningContinuesTheSession) {
  TempDir dir;
  const std::string link = dir.path + "/device";
  auto port = open_port("type=pty,timeout=5,link=" + link);
  int client = open_client(link);
  write_fd(client, "one");
  EXPECT_EQ(port->read_exactly(3), "one");
  ::close(client);

  // The device side sees no hang-up: a read times out quietly.
  char byte;
  EXPECT_EQ(port->read(&byte, 1, 20ms), 0u);
  client = open_client(link);
  write_fd(client, "two");
  EXPECT_EQ(port->read_exactly(3), "two");
  port->write_all("back");
  EXPECT_EQ(read_fd(client, 4), "back");
  ::close(client);
}

TEST(Pty, SerialSettingsReportWhatTheClientProgrammed) {
  TempDir dir;
  const std::string link = dir.path + "/device";
  auto port = open_port("type=pty,link=" + link);
  const int client = open_client(link);
  program_client(client, B115200, true);
  auto seen = port->serial_settings();
  EXPECT_EQ(seen.baud, 115200u);
  EXPECT_EQ(seen.stop_bits, 2);

  program_client(client, B19200, false);
  seen = port->serial_settings();
  EXPECT_EQ(seen.baud, 19200u);
  EXPECT_EQ(seen.stop_bits, 1);
  ::close(client);
}

// The bridge reads the client's settings before every read of its bytes:
// one system call each time (TCGETS2 on Linux), not tcgetattr() and then a
// second call for a custom rate.
TEST(Pty, SerialSettingsAreReadInOneSystemCall) {
  TempDir dir;
  const std::string link = dir.path + "/device";
  auto port = open_port("type=pty,link=" + link);
  const int client = open_client(link);
  program_client(client, B57600, true);

  namespace sys = wiretape::detail::sys;
  int ioctls = 0;
  int tcgetattrs = 0;
  wiretape::SerialSettings seen;
  {
    sys::ScopedOverride seam;
    seam->ioctl = [&](int fd, unsigned long request, void* argument) {
      ++ioctls;
      return sys::real().ioctl(fd, request, argument);
    };
    seam->tcgetattr = [&](int fd, termios* out) {
      ++tcgetattrs;
      return sys::real().tcgetattr(fd, out);
    };
    seen = port->serial_settings();
  }
#if defined(__linux__)
  EXPECT_EQ(ioctls + tcgetattrs, 1);
#endif
  EXPECT_EQ(seen.baud, 57600u);
  EXPECT_EQ(seen.stop_bits, 2);
  ::close(client);
}

// A read with timeout 0 that finds nothing answers at once: one read(), no
// poll() after it (the bridge makes such a read every time it empties a
// terminal).
TEST(Pty, AReadWithTimeoutZeroThatFindsNothingMakesNoPoll) {
  TempDir dir;
  const std::string link = dir.path + "/device";
  auto port = open_port("type=pty,timeout=0,link=" + link);
  const int client = open_client(link);
  namespace sys = wiretape::detail::sys;
  int polls = 0;
  int reads = 0;
  char byte;
  {
    sys::ScopedOverride seam;
    seam->poll = [&](pollfd* fds, nfds_t count, int timeout_ms) {
      ++polls;
      return sys::real().poll(fds, count, timeout_ms);
    };
    seam->read = [&](int fd, void* out, size_t size) {
      ++reads;
      return sys::real().read(fd, out, size);
    };
    EXPECT_EQ(port->read(&byte, 1), 0u);
  }
  EXPECT_EQ(polls, 0);
  EXPECT_EQ(reads, 1);
  // A timeout still waits (a poll), and data still arrives.
  write_fd(client, "x");
  EXPECT_EQ(port->read(&byte, 1, 5s), 1u);
  EXPECT_EQ(byte, 'x');
  ::close(client);
}

TEST(Pty, ModemLinesGiveAClearError) {
  auto port = open_port("type=pty");
  try {
    port->set_dtr(true);
    FAIL() << "expected PortError";
  } catch (const wiretape::PortError& error) {
    EXPECT_NE(std::string(error.what()).find("no modem lines"), std::string::npos)
        << error.what();
  }
  EXPECT_THROW(port->cts(), wiretape::PortError);
}

TEST(Pty, TimeoutsPollAndExpireAndCompoundReadsReturnPartialData) {
  TempDir dir;
  const std::string link = dir.path + "/device";
  auto port = open_port("type=pty,timeout=0,link=" + link);
  char byte;
  EXPECT_EQ(port->read(&byte, 1), 0u) << "timeout=0 polls";
  const auto start = std::chrono::steady_clock::now();
  EXPECT_EQ(port->read(&byte, 1, 50ms), 0u);
  EXPECT_GE(std::chrono::steady_clock::now() - start, 50ms);

  const int client = open_client(link);
  write_fd(client, "abc");
  ASSERT_TRUE(port->wait_readable(5s));
  EXPECT_EQ(port->read_exactly(10, 100ms), "abc");
  EXPECT_FALSE(port->wait_readable(0s));
  ::close(client);
}

TEST(Pty, NativeHandlePollsReadableWithData) {
  TempDir dir;
  const std::string link = dir.path + "/device";
  auto port = open_port("type=pty,link=" + link);
  EXPECT_FALSE(wiretape::test::fd_readable(port->native_handle(), 0ms));
  const int client = open_client(link);
  write_fd(client, "x");
  EXPECT_TRUE(wiretape::test::fd_readable(port->native_handle(), 5000ms));
  EXPECT_EQ(port->available(), 1u);
  ::close(client);
}

TEST(Pty, CloseFromAnotherThreadWakesABlockedRead) {
  wiretape::test::BlockedPollSignal signal;
  auto port = open_port("type=pty");  // blocks forever by default
  std::thread closer([&] {
    ASSERT_TRUE(signal.blocked.wait());
    port->close();
  });
  char byte;
  EXPECT_THROW(port->read(&byte, 1), wiretape::PortClosed);
  closer.join();
}

TEST(Pty, FlushInputDropsUnreadDataAndDrainReturns) {
  TempDir dir;
  const std::string link = dir.path + "/device";
  auto port = open_port("type=pty,timeout=5,link=" + link);
  const int client = open_client(link);
  write_fd(client, "stale");
  ASSERT_TRUE(port->wait_readable(5s));
  port->flush_input();
  EXPECT_EQ(port->available(), 0u);
  char byte;
  EXPECT_EQ(port->read(&byte, 1, 0s), 0u);
  port->write_all("x");
  port->drain();
  port->flush_output();
  write_fd(client, "fresh");
  EXPECT_EQ(port->read_exactly(5), "fresh");
  ::close(client);
}

TEST(Pty, BaudAndModemControlAreNotTheDeviceSidesToSet) {
  auto port = open_port("type=pty");
  try {
    port->set_baud(9600);
    FAIL();
  } catch (const wiretape::PortError& error) {
    EXPECT_EQ(error.code().value(), ENOTSUP);
  }
}
