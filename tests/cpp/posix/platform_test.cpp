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

// The bridge reads the watch each time the client writes: one read() when
// it holds a few events, not a second one to find it empty; and a watch
// holding more events than one read takes still gives them all.
TEST(TerminalWatch, ReadsItsEventsInOneCallAndAllOfManyInMore) {
  wiretape::test::PtyPair pty;
  wiretape::detail::sys::UniqueFd watch(platform::watch_opens_and_closes(pty.path));
  ASSERT_TRUE(watch) << "inotify";
  ASSERT_TRUE(platform::watch_reads(watch.get(), pty.path, false));
  namespace sys = wiretape::detail::sys;
  int reads = 0;
  sys::ScopedOverride seam;
  seam->read = [&](int fd, void* out, size_t size) {
    if (fd == watch.get()) ++reads;
    return sys::real().read(fd, out, size);
  };
  const int client = ::open(pty.path.c_str(), O_RDWR | O_NOCTTY | O_CLOEXEC);
  ASSERT_GE(client, 0);
  ASSERT_EQ(::write(client, "A", 1), 1);
  EXPECT_EQ(platform::read_opens_and_closes(watch.get()),
            (std::vector<TerminalEvent>{TerminalEvent::opened, TerminalEvent::wrote}));
  EXPECT_EQ(reads, 1);

  // 400 opens and closes: 800 events of 16 bytes, more than one read takes.
  for (int i = 0; i < 400; ++i) ::close(::open(pty.path.c_str(), O_RDWR | O_NOCTTY | O_CLOEXEC));
  reads = 0;
  const std::vector<TerminalEvent> events = platform::read_opens_and_closes(watch.get());
  ASSERT_EQ(events.size(), 800u);
  EXPECT_EQ(events.front(), TerminalEvent::opened);
  EXPECT_EQ(events.back(), TerminalEvent::closed);
  EXPECT_GT(reads, 1);
  ::close(client);
  EXPECT_EQ(pty.read_master(1), "A");
}

}  // namespace
