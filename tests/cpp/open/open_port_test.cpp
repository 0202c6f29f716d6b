// open_port(): the common keys, the type dispatch, and every key and alias of
// every transport type, good and bad.
#include <gtest/gtest.h>

#include <chrono>
#include <future>
#include <string>
#include <utility>
#include <vector>

#include "open/open_port.hpp"
#include "support/port_test_support.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/options.hpp"
#include "wiretape/port.hpp"

using namespace std::chrono_literals;
using wiretape::Access;
using wiretape::open_port;
using wiretape::OptionError;

namespace {

// Expects `options` to be refused with an OptionError naming `key`, and the
// message to contain `says`.
void expect_option_error(const std::string& options, const std::string& key,
                         const std::string& says = "") {
  SCOPED_TRACE(options);
  try {
    open_port(options);
    ADD_FAILURE() << "expected OptionError for " << options;
  } catch (const OptionError& error) {
    EXPECT_EQ(error.key(), key) << error.what();
    EXPECT_NE(std::string(error.what()).find(key), std::string::npos) << error.what();
    if (!says.empty()) {
      EXPECT_NE(std::string(error.what()).find(says), std::string::npos) << error.what();
    }
  } catch (const std::exception& error) {
    ADD_FAILURE() << "expected OptionError, got: " << error.what();
  }
}

}  // namespace

TEST(OpenPort, TypeIsRequiredAndChecked) {
  expect_option_error("timeout=1", "type", "missing option 'type'");
  expect_option_error("type=carrier-pigeon", "type", "serial");
  expect_option_error("", "type");
}

TEST(OpenPort, TimeoutKey) {
  EXPECT_EQ(open_port("type=loopback")->timeout(), wiretape::forever);
  EXPECT_EQ(open_port("type=loopback,timeout=-1")->timeout(), wiretape::forever);
  EXPECT_EQ(open_port("type=loopback,timeout=none")->timeout(), wiretape::forever);
  EXPECT_EQ(open_port("type=loopback,timeout=0")->timeout(), std::chrono::nanoseconds(0));
  EXPECT_EQ(open_port("type=loopback,timeout=0.25")->timeout(),
            std::chrono::nanoseconds(250ms));
  expect_option_error("type=loopback,timeout=soon", "timeout", "seconds");
  expect_option_error("type=loopback,timeout=-2", "timeout");
}

TEST(OpenPort, AccessKeyAndFlexiportBareSpellings) {
  EXPECT_EQ(open_port("type=loopback")->access(), Access::read_write);
  EXPECT_EQ(open_port("type=loopback,access=readonly")->access(), Access::read_only);
  EXPECT_EQ(open_port("type=loopback,access=writeonly")->access(), Access::write_only);
  EXPECT_EQ(open_port("type=loopback,access=readwrite")->access(), Access::read_write);
  EXPECT_EQ(open_port("type=loopback,readonly")->access(), Access::read_only);
  EXPECT_EQ(open_port("type=loopback,writeonly")->access(), Access::write_only);
  EXPECT_EQ(open_port("type=loopback,readwrite")->access(), Access::read_write);
  expect_option_error("type=loopback,access=sideways", "access", "readwrite, readonly, writeonly");
}

TEST(OpenPort, DebugAndRecordingKeysAreValidated) {
  EXPECT_NO_THROW(open_port("type=loopback,debug=0"));
  expect_option_error("type=loopback,debug=4", "debug", "0 to 3");
  expect_option_error("type=loopback,flush_ms=0", "flush_ms");
  expect_option_error("type=loopback,fsync=maybe", "fsync", "boolean");
  expect_option_error("type=loopback,log_errors=shout", "log_errors", "raise, warn");
  expect_option_error("type=loopback,log=", "log", "file name");
}

TEST(OpenPort, UnknownAndInapplicableKeysAreRefusedListingTheValidOnes) {
  expect_option_error("type=loopback,colour=blue", "colour", "unknown option");
  expect_option_error("type=loopback,baud=9600", "baud", "does not apply to type=loopback");
  expect_option_error("type=pty,device=/dev/ttyS0", "device", "does not apply to type=pty");
  expect_option_error("type=tcp,port=1,parity=even", "parity", "does not apply to type=tcp");
  expect_option_error("type=udp,listen", "listen", "valid keys for type=udp");
  expect_option_error("type=tcp,port=1,bogus=1", "bogus", "host");
}

// Every key of every type is in the key table: a replay key given to another
// type is "does not apply", never "unknown" (profile, faults, gap and meta_
// were missing from the old list of known keys), and a typo is answered with
// the nearest key of the type.
TEST(OpenPort, KeysOfEveryTypeAreKnownAndTyposGetTheNearestKey) {
  for (const char* replay_key : {"profile=scip", "faults=drop@exchange:0", "gap=10",
                                 "framing=fixed:4", "seed=1"}) {
    const std::string key = std::string(replay_key).substr(0, std::string(replay_key).find('='));
    expect_option_error(std::string("type=loopback,") + replay_key, key,
                        "does not apply to type=loopback");
  }
  expect_option_error("type=serial,device=/dev/null,bod=9600", "bod", "did you mean 'baud'?");
  expect_option_error("type=tcp,port=1,lisen", "lisen", "did you mean 'listen'?");
  expect_option_error("type=replay,file=x.wtape,at-end=closed", "at-end",
                      "did you mean 'at_end'?");
}

TEST(OpenPort, SerialKeys) {
  wiretape::test::PtyPair pty;
  const std::string device = "type=serial,device=" + pty.path;
  auto port = open_port(device +
                        ",baud=57600,databits=7,stopbits=2,parity=odd,"
                        "flow=xonxoff,exclusive=false,timeout=1");
  const auto settings = port->serial_settings();
  EXPECT_EQ(settings.baud, 57600u);
  EXPECT_EQ(settings.data_bits, 7);
  EXPECT_EQ(settings.stop_bits, 2);
  EXPECT_EQ(settings.parity, wiretape::Parity::odd);
  EXPECT_EQ(settings.flow, wiretape::FlowControl::xonxoff);
  port.reset();
  auto defaults = open_port(device)->serial_settings();
  EXPECT_EQ(defaults, wiretape::SerialSettings{});
  EXPECT_EQ(open_port(device + ",hwflowctrl=yes")->serial_settings().flow,
            wiretape::FlowControl::rtscts);
  EXPECT_EQ(open_port(device + ",hwflowctrl=no")->serial_settings().flow,
            wiretape::FlowControl::none);
  for (const char* parity : {"none", "even", "odd", "mark", "space"}) {
    EXPECT_NO_THROW(open_port(device + ",parity=" + parity)) << parity;
  }
}

TEST(OpenPort, SerialBadValues) {
  const std::string device = "type=serial,device=/dev/null";
  expect_option_error("type=serial", "device", "missing option 'device'");
  expect_option_error(device + ",baud=fast", "baud", "whole number");
  expect_option_error(device + ",baud=0", "baud");
  expect_option_error(device + ",databits=9", "databits", "5 to 8");
  expect_option_error(device + ",databits=4", "databits");
  expect_option_error(device + ",stopbits=3", "stopbits", "1 to 2");
  expect_option_error(device + ",parity=sometimes", "parity", "none, even, odd, mark, space");
  expect_option_error(device + ",flow=maybe", "flow", "none, rtscts, xonxoff");
  expect_option_error(device + ",hwflowctrl=maybe", "hwflowctrl", "boolean");
  expect_option_error(device + ",hwflowctrl=1,flow=none", "hwflowctrl", "only one");
  expect_option_error(device + ",exclusive=perhaps", "exclusive", "boolean");
}

TEST(OpenPort, TcpKeys) {
  const int number = wiretape::test::free_port();
  wiretape::test::Event listening;
  namespace sys = wiretape::detail::sys;
  sys::ScopedOverride seam;
  const auto real_listen = sys::real().listen;
  seam->listen = [&](int fd, int backlog) {
    const int status = real_listen(fd, backlog);
    listening.set();
    return status;
  };
  auto server = std::async(std::launch::async, [&] {
    return open_port("type=tcp,host=127.0.0.1,listen=true,nodelay=false,timeout=10,port=" +
                     std::to_string(number));
  });
  ASSERT_TRUE(listening.wait());
  auto client = open_port("type=tcp,ip=127.0.0.1,nodelay=yes,timeout=5,port=" +
                          std::to_string(number));
  auto accepted = server.get();
  client->write_all("k");
  EXPECT_EQ(accepted->read_exactly(1), "k");
}

TEST(OpenPort, TcpBadValues) {
  expect_option_error("type=tcp", "port", "missing option 'port'");
  expect_option_error("type=tcp,port=0", "port", "1 to 65535");
  expect_option_error("type=tcp,port=65536", "port");
  expect_option_error("type=tcp,port=http", "port", "whole number");
  expect_option_error("type=tcp,port=1,listen=maybe", "listen", "boolean");
  expect_option_error("type=tcp,port=1,nodelay=maybe", "nodelay", "boolean");
  expect_option_error("type=tcp,port=1,ip=127.0.0.1,host=127.0.0.1", "ip", "only one");
}

TEST(OpenPort, UdpKeysAndAliases) {
  const int a = wiretape::test::free_port(true);
  const int b = wiretape::test::free_port(true);
  auto first = open_port("type=udp,timeout=5,host=127.0.0.1,port=" + std::to_string(b) +
                         ",bind_host=127.0.0.1,bind_port=" + std::to_string(a));
  auto second = open_port("type=udp,timeout=5,dest_ip=127.0.0.1,dest_port=" +
                          std::to_string(a) + ",recv_ip=127.0.0.1,recv_port=" +
                          std::to_string(b));
  first->write_all("1");
  EXPECT_EQ(second->read_exactly(1), "1");
  second->write_all("2");
  EXPECT_EQ(first->read_exactly(1), "2");
}

TEST(OpenPort, UdpBadValues) {
  expect_option_error("type=udp,port=65536", "port");
  expect_option_error("type=udp,bind_port=-1", "bind_port");
  expect_option_error("type=udp,recv_port=70000", "bind_port");
  expect_option_error("type=udp,port=1,dest_port=1", "dest_port", "only one");
  expect_option_error("type=udp,bind_host=a,recv_ip=b", "recv_ip", "only one");
  expect_option_error("type=udp,bind_port=1,recv_port=2", "recv_port", "only one");
  expect_option_error("type=udp,host=1.2.3.4,dest_ip=1.2.3.4,port=1", "dest_ip", "only one");
  expect_option_error("type=udp,host=127.0.0.1", "port", "needs 'port'");
}

TEST(OpenPort, PtyAndLoopbackKeys) {
  wiretape::test::TempDir dir;
  auto pty = open_port("type=pty,link=" + dir.path + "/tty");
  EXPECT_NE(pty->description().find(dir.path + "/tty"), std::string::npos);
  EXPECT_EQ(open_port("type=loopback")->type(), "loopback");
  expect_option_error("type=pty,link=" + dir.path + "/x,baud=9600", "baud");
}

TEST(OpenPort, BadKeysAreRefusedBeforeTheDeviceIsTouched) {
  // A listening tcp port with a typo must not wait for a client first.
  const auto start = std::chrono::steady_clock::now();
  expect_option_error("type=tcp,listen,port=1,nodelai=1", "nodelai");
  EXPECT_LT(std::chrono::steady_clock::now() - start, 5s);
  wiretape::test::PtyPair pty;
  expect_option_error("type=serial,device=" + pty.path + ",bod=9600", "bod");
  // The device was not left locked by the refused open.
  EXPECT_NO_THROW(open_port("type=serial,device=" + pty.path));
}

TEST(OpenPort, ConflictingAccessModesAreRefused) {
  expect_option_error("type=loopback,readonly,writeonly", "writeonly", "access mode");
  expect_option_error("type=loopback,access=readwrite,readonly", "readonly", "access mode");
  EXPECT_EQ(open_port("type=loopback,readonly=false")->access(), Access::read_write);
  expect_option_error("type=loopback,colour=1", "colour", "readonly");
}

// speed= scales a replay's clock, and the waits of injected faults in every
// timing mode: with timing=none it is refused only when there is no such wait.
TEST(OpenPort, SpeedWithoutAClockScalesInjectedWaits) {
  const std::string replay = "type=replay,file=/nonexistent/s.wtape,timing=none,";
  for (const char* faults : {"delay:100@exchange:0", "stall:5@rx:1", "trickle@exchange:0",
                             "reconnect:5@exchange:0", "drop@exchange:0;delay:1@exchange:1"}) {
    const std::string options = replay + "speed=2,faults=" + faults;
    EXPECT_NO_THROW(wiretape::detail::check_replay_options(options)) << options;
    EXPECT_TRUE(wiretape::detail::replay_speed_applies(options)) << options;
  }
  EXPECT_FALSE(wiretape::detail::replay_speed_applies(replay + "faults=silence@exchange:0"));
  EXPECT_TRUE(wiretape::detail::replay_speed_applies("type=replay,file=x,timing=causal"));
}

// Keys that would do nothing alone are refused, naming what they need
// (the table in src/open/open_port.cpp), before anything is opened.
TEST(OpenPort, KeysThatNeedAnotherKeyNameIt) {
  for (const char* key : {"flush_ms=50", "fsync", "log_errors=warn", "meta_robot=r2"}) {
    const std::string name = std::string(key).substr(0, std::string(key).find('='));
    expect_option_error(std::string("type=loopback,") + key, name, "without log=FILE");
  }
  expect_option_error("type=seriallog,device=/dev/null", "file", "type=seriallog");
  expect_option_error("type=udplog,port=1", "file", "type=udplog");
  // Replay keys: checked before the session file is even looked for.
  const std::string replay = "type=replay,file=/nonexistent/s.wtape,";
  expect_option_error(replay + "repeat=last", "repeat", "match=request");
  expect_option_error(replay + "match=sequence,unmatched=silent", "unmatched", "match=request");
  expect_option_error(replay + "tolerance=5", "tolerance", "check=timing");
  expect_option_error(replay + "timing=none,speed=2", "speed", "timing=session");
  expect_option_error(replay + "timing=none,speed=2,faults=drop@exchange:0", "speed",
                      "scales nothing");
  expect_option_error(replay + "bogus=1", "bogus", "unknown option");
  // A key of another type is still "does not apply", not a dependency.
  expect_option_error("type=loopback,repeat=last", "repeat", "does not apply");
}
