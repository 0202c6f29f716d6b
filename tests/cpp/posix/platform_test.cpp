// The terminal watch (platform.hpp): a pty client's opens, writes and
// closes come in the order they happened, so that the bridge can tell the
// client sessions of a close and an immediate reopen apart (DESIGN.md
// section 12).
#include <fcntl.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "posix/platform.hpp"
#include "posix/syscalls.hpp"
#include "support/port_test_support.hpp"

namespace {

namespace platform = wiretape::detail::platform;
using platform::TerminalEvent;

TEST(TerminalWatch, ReportsACloseAndReopenBeforeTheWriteAfterThem) {
  wiretape::test::PtyPair pty;
  wiretape::detail::sys::UniqueFd watch(platform::watch_opens_and_closes(pty.path));
  ASSERT_TRUE(watch) << "inotify";
  ASSERT_TRUE(platform::watch_reads(watch.get(), pty.path, false));
  const int first = ::open(pty.path.c_str(), O_RDWR | O_NOCTTY | O_CLOEXEC);
  ASSERT_GE(first, 0);
  ::close(first);
  const int second = ::open(pty.path.c_str(), O_RDWR | O_NOCTTY | O_CLOEXEC);
  ASSERT_GE(second, 0);
  ASSERT_EQ(::write(second, "PING\n", 5), 5);
  ::close(second);
  EXPECT_EQ(platform::read_opens_and_closes(watch.get()),
            (std::vector<TerminalEvent>{TerminalEvent::opened, TerminalEvent::closed,
                                        TerminalEvent::opened, TerminalEvent::wrote,
                                        TerminalEvent::closed}));
  EXPECT_EQ(pty.read_master(5), "PING\n");
}

}  // namespace
