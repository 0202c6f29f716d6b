// The OS-call seam itself: overrides apply to the ports and are undone.
#include <gtest/gtest.h>

#include <cerrno>
#include <string>

#include "posix/syscalls.hpp"
#include "support/port_test_support.hpp"
#include "wiretape/errors.hpp"
#include "wiretape/port.hpp"

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
