// The OS-call seam itself: overrides apply to the ports and are undone.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <string>

#include "posix/syscalls.hpp"
#include "support/port_test_support.hpp"
#include "wiretape/bridge.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/port.hpp"
#include "wiretape/recorder.hpp"
#include "wiretape/session.hpp"

namespace sys = wiretape::detail::sys;

TEST(SyscallSeam, OverridesNestAndAreRestored) {
  int outer_calls = 0;
  int inner_calls = 0;
  {
    sys::ScopedOverride outer;
    outer->pipe = [&](int fds[2]) {
      ++outer_calls;
      return sys::real().pipe(fds);
    };
    {
      sys::ScopedOverride inner;
      inner->pipe = [&](int fds[2]) {
        ++inner_calls;
        errno = EMFILE;
        return -1;
      };
      EXPECT_THROW(wiretape::open_port("type=loopback"), wiretape::PortError);
      EXPECT_EQ(inner_calls, 1);
    }
    EXPECT_NO_THROW(wiretape::open_port("type=loopback"));
    EXPECT_EQ(outer_calls, 1);
  }
  EXPECT_NO_THROW(wiretape::open_port("type=loopback"));
  EXPECT_EQ(outer_calls, 1);
  EXPECT_EQ(inner_calls, 1);
}

TEST(SyscallSeam, EveryTransportGoesThroughIt) {
  // Failing socket() and posix_openpt() in the seam makes tcp, udp and pty
  // fail to open: none of them calls libc around the seam.
  sys::ScopedOverride seam;
  seam->socket = [](int, int, int) {
    errno = EACCES;
    return -1;
  };
  seam->posix_openpt = [](int) {
    errno = EAGAIN;
    return -1;
  };
  seam->open = [](const char*, int, mode_t) {
    errno = ENOENT;
    return -1;
  };
  EXPECT_THROW(wiretape::open_port("type=tcp,port=9"), wiretape::PortError);
  EXPECT_THROW(wiretape::open_port("type=udp"), wiretape::PortError);
  EXPECT_THROW(wiretape::open_port("type=pty"), wiretape::PortError);
  wiretape::test::PtyPair pty;
  EXPECT_THROW(wiretape::open_port("type=serial,device=" + pty.path),
               wiretape::PortError);
}

TEST(SyscallSeam, ErrorsNameThePortAndTheOperation) {
  wiretape::test::PtyPair pty;
  sys::ScopedOverride seam;
  seam->tcsetattr = [](int, int, const termios*) {
    errno = EPERM;
    return -1;
  };
  try {
    wiretape::open_port("type=serial,device=" + pty.path);
    FAIL();
  } catch (const wiretape::PortError& error) {
    const std::string what = error.what();
    EXPECT_NE(what.find(pty.path), std::string::npos) << what;
    EXPECT_NE(what.find("tcsetattr"), std::string::npos) << what;
    EXPECT_EQ(error.code().value(), EPERM);
  }
}

TEST(SyscallSeam, TheBridgeCarriesOnThroughInterruptedPollAndAccept) {
  std::atomic<int> polls{0};
  std::atomic<int> interrupted_polls{0};
  std::atomic<int> interrupted_accepts{0};
  sys::ScopedOverride seam;
  // Every other poll() and the first try of every accept() are interrupted
  // by a signal, as a process with signal handlers sees them.
  seam->poll = [&](pollfd* fds, nfds_t count, int timeout_ms) {
    if (polls++ % 2 == 0) {
      ++interrupted_polls;
      errno = EINTR;
      return -1;
    }
    return sys::real().poll(fds, count, timeout_ms);
  };
  bool accept_interrupted = false;
  seam->accept4 = [&](int fd, sockaddr* address, socklen_t* length, int flags) {
    accept_interrupted = !accept_interrupted;
    if (accept_interrupted) {
      ++interrupted_accepts;
      errno = EINTR;
      return -1;
    }
    return sys::real().accept4(fd, address, length, flags);
  };

  wiretape::BridgeOptions options;
  options.device = "type=loopback";
  options.client_side = wiretape::BridgeClientSide::tcp;
  options.quiet = true;
  wiretape::Bridge bridge(options);
  bridge.start();
  const int client = wiretape::test::connect_tcp(bridge.listen_address());
  ASSERT_GE(client, 0);
  const std::string message = "through every interruption\n";
  ASSERT_EQ(::write(client, message.data(), message.size()),
            static_cast<ssize_t>(message.size()));
  EXPECT_EQ(wiretape::test::read_count(client, message.size()), message);
  ::close(client);
  bridge.stop();
  ASSERT_TRUE(bridge.wait(std::chrono::seconds(10)));
  EXPECT_EQ(bridge.result().outcome, wiretape::BridgeOutcome::stopped);
  EXPECT_EQ(bridge.result().stats.clients_accepted, 1u);
  EXPECT_GT(interrupted_polls.load(), 0);
  EXPECT_GT(interrupted_accepts.load(), 0);
}

// The pty bridge's line channel (the `--as` shim's socket) makes its socket
// through the seam: a refused socket fails the start, naming the channel's
// path and the call.
TEST(SyscallSeam, ALineChannelThatCannotMakeItsSocketFailsTheStartNamingIt) {
  wiretape::test::TempDir dir;
  const std::string path = dir.file("lines.sock");
  sys::ScopedOverride seam;
  seam->socket = [](int domain, int type, int protocol) {
    if (domain == AF_UNIX) {
      errno = EMFILE;
      return -1;
    }
    return sys::real().socket(domain, type, protocol);
  };
  wiretape::BridgeOptions options;
  options.device = "type=loopback";
  options.line_channel = path;
  options.quiet = true;
  wiretape::Bridge bridge(options);
  try {
    bridge.start();
    FAIL() << "the bridge started without its line channel";
  } catch (const wiretape::PortError& error) {
    const std::string what = error.what();
    EXPECT_NE(what.find("line channel " + path), std::string::npos) << what;
    EXPECT_NE(what.find("socket"), std::string::npos) << what;
    EXPECT_EQ(error.code().value(), EMFILE);
  }
  EXPECT_EQ(bridge.result().outcome, wiretape::BridgeOutcome::failed);
}

// A recorder's header rewrite (add_channel) writes through the seam: a full
// disk is a PortError naming the file and the channel, and the channel is
// not added.
TEST(SyscallSeam, AHeaderRewriteThatCannotWriteNamesTheFileAndTheChannel) {
  wiretape::test::TempDir dir;
  const std::string path = dir.file("channels.wtape");
  wiretape::Recorder recorder(path, wiretape::SessionHeader::starting_now(),
                              wiretape::FlushPolicy{}, 4096);
  {
    sys::ScopedOverride seam;
    seam->pwrite = [](int, const void*, size_t, off_t) -> ssize_t {
      errno = ENOSPC;
      return -1;
    };
    wiretape::Channel channel;
    channel.name = "gps";
    try {
      recorder.add_channel(channel);
      FAIL() << "the channel was added without its header";
    } catch (const wiretape::PortError& error) {
      const std::string what = error.what();
      EXPECT_NE(what.find(path), std::string::npos) << what;
      EXPECT_NE(what.find("\"gps\""), std::string::npos) << what;
      EXPECT_EQ(error.code().value(), ENOSPC);
    }
  }
  EXPECT_TRUE(recorder.header().channels.empty());
  recorder.close();
}
