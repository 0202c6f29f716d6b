// Every port type answers Port::capabilities() with what it can do, and a
// recording port answers for the port it wraps.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <string>

#include "support/port_test_support.hpp"
#include "wiretape/port.hpp"

namespace {

using wiretape::PortCapabilities;

std::string describe(const PortCapabilities& c) {
  std::string text;
  const auto flag = [&](const char* name, bool on) {
    if (on) text += std::string(text.empty() ? "" : " ") + name;
  };
  flag("serial_settings", c.serial_settings);
  flag("terminal_settings", c.terminal_settings);
  flag("modem_lines", c.modem_lines);
  flag("send_break", c.send_break);
  flag("datagrams", c.datagrams);
  flag("output_pollable", c.output_pollable);
  flag("played_recording", c.played_recording);
  return text.empty() ? "none" : text;
}

std::string capabilities_of(const std::string& options) {
  return describe(wiretape::open_port(options)->capabilities());
}

// A listening TCP socket on 127.0.0.1; returns its port.
int listen_on_loopback(int& fd) {
  fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t length = sizeof address;
  if (::bind(fd, reinterpret_cast<sockaddr*>(&address), length) != 0 || ::listen(fd, 1) != 0 ||
      ::getsockname(fd, reinterpret_cast<sockaddr*>(&address), &length) != 0) {
    return -1;
  }
  return ntohs(address.sin_port);
}

TEST(PortCapabilities, TheDefaultPromisesNothing) {
  EXPECT_EQ(describe(PortCapabilities{}), "none");
}

TEST(PortCapabilities, Loopback) { EXPECT_EQ(capabilities_of("type=loopback"), "none"); }

TEST(PortCapabilities, Pty) {
  EXPECT_EQ(capabilities_of("type=pty"), "terminal_settings output_pollable");
}

TEST(PortCapabilities, SerialOnAPty) {
  wiretape::test::PtyPair pty;
  EXPECT_EQ(capabilities_of("type=serial,device=" + pty.path),
            "serial_settings modem_lines send_break output_pollable");
}

TEST(PortCapabilities, Tcp) {
  int listener = -1;
  const int port = listen_on_loopback(listener);
  ASSERT_GT(port, 0);
  EXPECT_EQ(capabilities_of("type=tcp,host=127.0.0.1,port=" + std::to_string(port)),
            "output_pollable");
  ::close(listener);
}

TEST(PortCapabilities, Udp) {
  EXPECT_EQ(capabilities_of("type=udp,port=" + std::to_string(wiretape::test::free_port(true))),
            "datagrams output_pollable");
}

TEST(PortCapabilities, ReplayEmulatesASerialLine) {
  wiretape::test::TempDir dir;
  const std::string file = dir.path + "/session.wtape";
  wiretape::open_port("type=loopback,log=" + file)->close();
  EXPECT_EQ(capabilities_of("type=replay,file=" + file),
            "serial_settings modem_lines send_break played_recording");
}

TEST(PortCapabilities, ARecordingPortAnswersForThePortItWraps) {
  wiretape::test::TempDir dir;
  wiretape::test::PtyPair pty;
  EXPECT_EQ(capabilities_of("type=serial,device=" + pty.path + ",log=" + dir.path + "/s.wtape"),
            "serial_settings modem_lines send_break output_pollable");
  EXPECT_EQ(capabilities_of("type=loopback,log=" + dir.path + "/l.wtape"), "none");
}

}  // namespace
