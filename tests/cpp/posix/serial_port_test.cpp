// The serial port over a pseudo-terminal (openpty), with the OS-call seam
// watching what it programs: Linux forces 8N on a pty, so data bits and
// parity are checked on the termios handed to tcsetattr.
#include <fcntl.h>
#include <sys/ioctl.h>
#include <unistd.h>
#include <termios.h>

#include <gtest/gtest.h>

#include <chrono>
#include <functional>
#include <mutex>
#include <string>
#include <thread>
#include <tuple>
#include <vector>

#include "posix/platform.hpp"
#include "posix/termios_settings.hpp"
#include "support/port_test_support.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/port.hpp"

using namespace std::chrono_literals;
using wiretape::open_port;
using wiretape::test::PtyPair;
namespace sys = wiretape::detail::sys;

namespace {

// Records every termios the port hands to tcsetattr.
class TermiosWatch {
 public:
  TermiosWatch() {
    const auto real = sys::real().tcsetattr;
    seam_->tcsetattr = [this, real](int fd, int when, const termios* settings) {
      {
        std::lock_guard<std::mutex> lock(mutex_);
        programmed_.push_back(*settings);
      }
      return real(fd, when, settings);
    };
  }
  termios last() {
    std::lock_guard<std::mutex> lock(mutex_);
    EXPECT_FALSE(programmed_.empty());
    return programmed_.empty() ? termios{} : programmed_.back();
  }

 private:
  sys::ScopedOverride seam_;
  std::mutex mutex_;
  std::vector<termios> programmed_;
};

// The rate the pty really runs at, read from the master side.
unsigned device_baud(const PtyPair& pty) {
  unsigned baud = 0;
  EXPECT_EQ(wiretape::detail::platform::get_baud(pty.master, baud), 0);
  return baud;
}

std::string serial(const PtyPair& pty, const std::string& extra = "") {
  return "type=serial,device=" + pty.path + extra;
}

}  // namespace

TEST(Serial, SeveralBaudsWithTwoStopBitsAndEvenParity) {
  for (unsigned baud : {9600u, 57600u, 115200u, 230400u}) {
    SCOPED_TRACE(baud);
    PtyPair pty;
    TermiosWatch watch;
    auto port = open_port(serial(pty, ",baud=" + std::to_string(baud) +
                                          ",stopbits=2,parity=even"));
    const termios programmed = watch.last();
    EXPECT_EQ(cfgetospeed(&programmed), *wiretape::detail::standard_speed(baud));
    EXPECT_TRUE(programmed.c_cflag & CSTOPB);
    EXPECT_TRUE(programmed.c_cflag & PARENB);
    EXPECT_FALSE(programmed.c_cflag & PARODD);
    // flexiport parsed stopbits into databits: data bits stay 8.
    EXPECT_EQ(programmed.c_cflag & CSIZE, static_cast<tcflag_t>(CS8));
    EXPECT_EQ(device_baud(pty), baud);
    const auto settings = port->serial_settings();
    EXPECT_EQ(settings.baud, baud);
    EXPECT_EQ(settings.stop_bits, 2);
    EXPECT_EQ(settings.data_bits, 8);
    EXPECT_EQ(settings.parity, wiretape::Parity::even);
    EXPECT_NE(port->description().find(std::to_string(baud) + " 8E2"), std::string::npos)
        << port->description();
  }
}

// flexiport parsed `stopbits` into the data bits.
TEST(SerialFlexiportDefects, StopbitsAreNotParsedIntoDatabits) {
  for (const auto& [options, data_bits, stop_bits] :
       std::vector<std::tuple<std::string, tcflag_t, bool>>{
           {",stopbits=2", CS8, true},
           {",stopbits=1", CS8, false},
           {",databits=7,stopbits=2", CS7, true},
           {",stopbits=2,databits=6", CS6, true}}) {
    SCOPED_TRACE(options);
    PtyPair pty;
    TermiosWatch watch;
    auto port = open_port(serial(pty, options));
    const termios programmed = watch.last();
    EXPECT_EQ(programmed.c_cflag & CSIZE, data_bits);
    EXPECT_EQ((programmed.c_cflag & CSTOPB) != 0, stop_bits);
    EXPECT_EQ(port->serial_settings().stop_bits, stop_bits ? 2 : 1);
  }
}

TEST(Serial, DataBitsParityAndFlowReachTheTermios) {
  PtyPair pty;
  TermiosWatch watch;
  auto port = open_port(serial(pty, ",databits=7,parity=odd,flow=xonxoff"));
  termios programmed = watch.last();
  EXPECT_EQ(programmed.c_cflag & CSIZE, static_cast<tcflag_t>(CS7));
  EXPECT_TRUE(programmed.c_cflag & PARENB);
  EXPECT_TRUE(programmed.c_cflag & PARODD);
  EXPECT_TRUE(programmed.c_iflag & IXON);
  EXPECT_FALSE(programmed.c_cflag & CSTOPB);
  port.reset();

  PtyPair second;
  auto hardware = open_port(serial(second, ",hwflowctrl=1,parity=mark,databits=5"));
  programmed = watch.last();
  EXPECT_TRUE(programmed.c_cflag & CRTSCTS);
  EXPECT_TRUE(programmed.c_cflag & CMSPAR);
  EXPECT_TRUE(programmed.c_cflag & PARODD);
  EXPECT_EQ(programmed.c_cflag & CSIZE, static_cast<tcflag_t>(CS5));
  EXPECT_EQ(hardware->serial_settings().flow, wiretape::FlowControl::rtscts);
}

// flexiport's SetBaudRate programmed the previous rate.
TEST(SerialFlexiportDefects, SetBaudProgramsTheNewRate) {
  PtyPair pty;
  TermiosWatch watch;
  auto port = open_port(serial(pty, ",baud=9600,stopbits=2"));
  port->set_baud(115200);
  const termios programmed = watch.last();
  EXPECT_EQ(cfgetospeed(&programmed), static_cast<speed_t>(B115200));
  EXPECT_TRUE(programmed.c_cflag & CSTOPB) << "other settings are kept";
  EXPECT_EQ(device_baud(pty), 115200u);
  EXPECT_EQ(port->serial_settings().baud, 115200u);
  port->set_baud(19200);
  EXPECT_EQ(device_baud(pty), 19200u);
}

TEST(Serial, NonStandardRatesAreProgrammed) {
  PtyPair pty;
  auto port = open_port(serial(pty, ",baud=250000"));
  EXPECT_EQ(device_baud(pty), 250000u);
  port->set_baud(31250);  // MIDI
  EXPECT_EQ(device_baud(pty), 31250u);
}

// flexiport's serial port with the default timeout did not block.
TEST(SerialFlexiportDefects, DefaultTimeoutBlocksUntilDataComes) {
  PtyPair pty;
  wiretape::test::BlockedPollSignal signal;
  auto port = open_port(serial(pty));
  EXPECT_EQ(port->timeout(), wiretape::forever);
  std::thread device([&] {
    ASSERT_TRUE(signal.blocked.wait()) << "the read never blocked";
    pty.write_master("late");
  });
  EXPECT_EQ(port->read_exactly(4), "late");
  device.join();
}

TEST(Serial, ReadsWritesAndTimeouts) {
  PtyPair pty;
  auto port = open_port(serial(pty, ",timeout=0"));
  char byte;
  EXPECT_EQ(port->read(&byte, 1), 0u) << "timeout=0 polls";
  const auto start = std::chrono::steady_clock::now();
  EXPECT_EQ(port->read(&byte, 1, 50ms), 0u);
  EXPECT_GE(std::chrono::steady_clock::now() - start, 50ms);
  port->write_all("to device");
  EXPECT_EQ(pty.read_master(9), "to device");
  pty.write_master("abc");
  ASSERT_TRUE(port->wait_readable(5s));
  EXPECT_EQ(port->read_exactly(5, 100ms), "abc") << "partial on timeout";
  port->drain();
  port->flush_output();
  port->flush_input();
}

TEST(Serial, ModemLinesOnAPtyGiveAClearError) {
  PtyPair pty;
  auto port = open_port(serial(pty));
  for (auto call : std::vector<std::function<void()>>{
           [&] { port->set_dtr(true); }, [&] { port->set_rts(false); },
           [&] { port->cts(); }, [&] { port->dsr(); }, [&] { port->ri(); },
           [&] { port->cd(); }}) {
    try {
      call();
      ADD_FAILURE() << "expected PortError";
    } catch (const wiretape::PortError& error) {
      EXPECT_NE(std::string(error.what()).find("no modem lines"), std::string::npos)
          << error.what();
      EXPECT_NE(std::string(error.what()).find(pty.path), std::string::npos);
    }
  }
}

TEST(Serial, ModemLinesGoThroughTiocmgetAndTiocmset) {
  PtyPair pty;
  sys::ScopedOverride seam;
  int lines = TIOCM_CTS | TIOCM_CD;
  const auto real_ioctl = sys::real().ioctl;
  seam->ioctl = [&](int fd, unsigned long request, void* argument) {
    if (request == TIOCMGET) {
      *static_cast<int*>(argument) = lines;
      return 0;
    }
    if (request == TIOCMSET) {
      lines = *static_cast<int*>(argument);
      return 0;
    }
    return real_ioctl(fd, request, argument);
  };
  auto port = open_port(serial(pty));
  EXPECT_TRUE(port->cts());
  EXPECT_TRUE(port->cd());
  EXPECT_FALSE(port->dsr());
  EXPECT_FALSE(port->ri());
  port->set_dtr(true);
  EXPECT_TRUE(lines & TIOCM_DTR);
  port->set_rts(true);
  port->set_dtr(false);
  EXPECT_FALSE(lines & TIOCM_DTR);
  EXPECT_TRUE(lines & TIOCM_RTS);
}

TEST(Serial, SendBreakSetsAndClearsTheBreakCondition) {
  PtyPair pty;
  sys::ScopedOverride seam;
  std::vector<unsigned long> requests;
  const auto real_ioctl = sys::real().ioctl;
  seam->ioctl = [&](int fd, unsigned long request, void* argument) {
    if (request == TIOCSBRK || request == TIOCCBRK) {
      requests.push_back(request);
      return 0;
    }
    return real_ioctl(fd, request, argument);
  };
  auto port = open_port(serial(pty));
  port->send_break(1ms);
  EXPECT_EQ(requests, (std::vector<unsigned long>{TIOCSBRK, TIOCCBRK}));
}

TEST(Serial, InjectedEintrIsRetried) {
  PtyPair pty;
  sys::ScopedOverride seam;
  int interrupted_reads = 0;
  int interrupted_writes = 0;
  int interrupted_polls = 0;
  const auto real = sys::real();
  seam->read = [&](int fd, void* buffer, size_t size) -> ssize_t {
    if (interrupted_reads++ < 2) {
      errno = EINTR;
      return -1;
    }
    return real.read(fd, buffer, size);
  };
  seam->write = [&](int fd, const void* data, size_t size) -> ssize_t {
    if (interrupted_writes++ < 2) {
      errno = EINTR;
      return -1;
    }
    return real.write(fd, data, size);
  };
  seam->poll = [&](pollfd* fds, nfds_t count, int timeout) {
    if (interrupted_polls++ < 2) {
      errno = EINTR;
      return -1;
    }
    return real.poll(fds, count, timeout);
  };
  auto port = open_port(serial(pty, ",timeout=5"));
  interrupted_reads = interrupted_writes = interrupted_polls = 0;
  port->write_all("ok");
  EXPECT_EQ(pty.read_master(2), "ok");
  std::thread device([&] { pty.write_master("in"); });
  EXPECT_EQ(port->read_exactly(2), "in");
  device.join();
  EXPECT_GE(interrupted_reads, 2);
  EXPECT_GE(interrupted_writes, 2);
}

TEST(Serial, ShortWritesAreCompletedByWriteAll) {
  PtyPair pty;
  sys::ScopedOverride seam;
  const auto real_write = sys::real().write;
  std::vector<size_t> calls;
  seam->write = [&](int fd, const void* data, size_t size) {
    calls.push_back(size);
    return real_write(fd, data, std::min<size_t>(size, 3));
  };
  auto port = open_port(serial(pty, ",timeout=5"));
  calls.clear();
  EXPECT_EQ(port->write("abcdefgh"), 3u) << "write() returns what was accepted";
  EXPECT_EQ(port->write_all("ijklmnop"), 8u);
  // write() sent "abc" only; write_all() sent all of its data.
  EXPECT_EQ(pty.read_master(11), "abcijklmnop");
  EXPECT_GE(calls.size(), 4u);
}

TEST(Serial, WouldBlockWaitsForTheDeviceToAcceptMore) {
  PtyPair pty;
  sys::ScopedOverride seam;
  const auto real_write = sys::real().write;
  int refusals = 0;
  seam->write = [&](int fd, const void* data, size_t size) -> ssize_t {
    if (refusals++ < 1) {
      errno = EAGAIN;
      return -1;
    }
    return real_write(fd, data, size);
  };
  auto port = open_port(serial(pty, ",timeout=5"));
  refusals = 0;
  EXPECT_EQ(port->write_all("x"), 1u);
  EXPECT_EQ(pty.read_master(1), "x");
}

TEST(Serial, DisconnectsRaisePortClosed) {
  for (int error : {ENXIO, EIO, ECONNRESET}) {
    SCOPED_TRACE(error);
    PtyPair pty;
    sys::ScopedOverride seam;
    seam->read = [error](int, void*, size_t) -> ssize_t {
      errno = error;
      return -1;
    };
    auto port = open_port(serial(pty, ",timeout=1"));
    char byte;
    try {
      port->read(&byte, 1);
      ADD_FAILURE() << "expected PortClosed";
    } catch (const wiretape::PortClosed& closed) {
      EXPECT_EQ(closed.code().value(), error);
    }
  }
  {
    PtyPair pty;
    sys::ScopedOverride seam;
    seam->read = [](int, void*, size_t) -> ssize_t { return 0; };
    auto port = open_port(serial(pty, ",timeout=1"));
    char byte;
    EXPECT_THROW(port->read(&byte, 1), wiretape::PortClosed) << "end of file";
  }
}

TEST(Serial, OtherOsErrorsArePortErrors) {
  PtyPair pty;
  sys::ScopedOverride seam;
  seam->read = [](int, void*, size_t) -> ssize_t {
    errno = ENOMEM;
    return -1;
  };
  auto port = open_port(serial(pty, ",timeout=1"));
  char byte;
  try {
    port->read(&byte, 1);
    FAIL();
  } catch (const wiretape::PortClosed&) {
    FAIL() << "ENOMEM is not a disconnect";
  } catch (const wiretape::PortError& error) {
    EXPECT_EQ(error.code().value(), ENOMEM);
  }
}

TEST(Serial, DeviceHangupMidReadRaisesPortClosed) {
  PtyPair pty;
  auto port = open_port(serial(pty));
  wiretape::test::BlockedPollSignal signal;
  std::thread device([&] {
    ASSERT_TRUE(signal.blocked.wait());
    ::close(pty.master);  // the device goes away
    pty.master = -1;
  });
  char byte;
  EXPECT_THROW(port->read(&byte, 1), wiretape::PortClosed);
  device.join();
}

TEST(Serial, CloseFromAnotherThreadWakesABlockedWriteAndRead) {
  PtyPair pty;
  wiretape::test::BlockedPollSignal signal;
  auto port = open_port(serial(pty));
  std::thread closer([&] {
    ASSERT_TRUE(signal.blocked.wait());
    port->close();
  });
  char byte;
  EXPECT_THROW(port->read(&byte, 1), wiretape::PortClosed);
  closer.join();
  EXPECT_FALSE(port->is_open());
  EXPECT_THROW(port->write_all("x"), wiretape::PortClosed);
}

TEST(Serial, ExclusiveRefusesASecondOpener) {
  PtyPair pty;
  auto first = open_port(serial(pty));
  try {
    open_port(serial(pty));
    FAIL() << "expected PortError";
  } catch (const wiretape::PortError& error) {
    EXPECT_NE(std::string(error.what()).find(pty.path), std::string::npos)
        << error.what();
  }
  first.reset();
  PtyPair shared;
  auto a = open_port(serial(shared, ",exclusive=false"));
  EXPECT_NO_THROW(open_port(serial(shared, ",exclusive=false")));
}

TEST(Serial, MissingDeviceNamesThePath) {
  try {
    open_port("type=serial,device=/dev/does-not-exist-wiretape");
    FAIL();
  } catch (const wiretape::PortError& error) {
    EXPECT_EQ(error.code().value(), ENOENT);
    EXPECT_NE(std::string(error.what()).find("/dev/does-not-exist-wiretape"),
              std::string::npos);
  }
}

TEST(Serial, NotATerminalIsRefused) {
  wiretape::test::TempDir dir;
  const std::string file = dir.path + "/plain";
  ::close(::open(file.c_str(), O_CREAT | O_WRONLY, 0600));
  try {
    open_port("type=serial,device=" + file);
    FAIL();
  } catch (const wiretape::PortError& error) {
    EXPECT_NE(std::string(error.what()).find("not a terminal"), std::string::npos)
        << error.what();
  }
}

TEST(Serial, CloseFromAnotherThreadWakesABlockedWrite) {
  PtyPair pty;  // nobody reads the device side: the terminal fills up
  wiretape::test::BlockedPollSignal signal;
  auto port = open_port(serial(pty));
  std::thread closer([&] {
    ASSERT_TRUE(signal.blocked.wait());
    port->close();
  });
  const std::string block(1 << 20, 'w');
  EXPECT_THROW(port->write_all(block), wiretape::PortClosed);
  closer.join();
}

TEST(Serial, WriteTimesOutReturningWhatWasSent) {
  PtyPair pty;
  auto port = open_port(serial(pty, ",timeout=0.05"));
  const std::string block(1 << 20, 'w');
  const std::size_t sent = port->write_all(block);
  EXPECT_GT(sent, 0u);
  EXPECT_LT(sent, block.size());
}

TEST(Serial, PerCallWriteTimeoutOverridesThePortsForever) {
  PtyPair pty;
  auto port = open_port(serial(pty, ""));  // the port's own timeout: forever
  const std::string block(1 << 20, 'w');
  const std::size_t sent = port->write_all(block.data(), block.size(), std::chrono::milliseconds(50));
  EXPECT_GT(sent, 0u);
  EXPECT_LT(sent, block.size()) << "nobody reads the pty: its buffer must have filled";
  // Full now: a polling write takes nothing and returns at once.
  EXPECT_EQ(port->write(block.data(), block.size(), std::chrono::nanoseconds(0)), 0u);
  EXPECT_EQ(pty.read_master(3), "www");  // what was sent reached the device
}
