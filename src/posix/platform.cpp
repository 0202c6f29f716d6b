// Non-POSIX calls, one system at a time. Linux is complete; other systems get
// the portable fallbacks.
#include "posix/platform.hpp"

#include <cerrno>
#include <climits>
#include <cstdint>
#include <cstdlib>
#include <mutex>

#if defined(__linux__)
// <asm/termbits.h> declares its own struct termios, so this file must not
// include <termios.h> (nor the seam header that does).
#include <asm/ioctls.h>
#include <asm/termbits.h>
#include <sys/inotify.h>
#include <sys/prctl.h>
#include <sys/socket.h>
#include <unistd.h>

namespace wiretape::detail::sys {
int ioctl_through_seam(int fd, unsigned long request, void* argument);
ssize_t read_through_seam(int fd, void* out, size_t size);
}
#else
#include <stdlib.h>
#include <sys/socket.h>
#endif

namespace wiretape::detail::platform {

#if defined(__linux__)

int set_custom_baud(int fd, unsigned baud) {
  struct termios2 settings {};
  if (sys::ioctl_through_seam(fd, TCGETS2, &settings) != 0) return errno;
  settings.c_cflag &= ~static_cast<tcflag_t>(CBAUD);
  settings.c_cflag |= BOTHER;
  settings.c_cflag &= ~static_cast<tcflag_t>(CBAUD << IBSHIFT);
  settings.c_cflag |= BOTHER << IBSHIFT;
  settings.c_ispeed = baud;
  settings.c_ospeed = baud;
  if (sys::ioctl_through_seam(fd, TCSETS2, &settings) != 0) return errno;
  return 0;
}

int get_baud(int fd, unsigned& baud) {
  struct termios2 settings {};
  if (sys::ioctl_through_seam(fd, TCGETS2, &settings) != 0) return errno;
  baud = settings.c_ospeed;
  return 0;
}

int get_line_flags(int fd, LineFlags& out) {
  struct termios2 settings {};
  if (sys::ioctl_through_seam(fd, TCGETS2, &settings) != 0) return errno;
  out.cflag = settings.c_cflag;
  out.iflag = settings.c_iflag;
  out.baud = settings.c_ospeed;
  return 0;
}

std::string terminal_path(int master_fd) {
  char name[256];
  const int err = ::ptsname_r(master_fd, name, sizeof name);
  if (err != 0) {
    errno = err;
    return {};
  }
  return name;
}

int no_sigpipe_send_flags() { return MSG_NOSIGNAL; }
void prevent_sigpipe(int) {}

void precise_timers_for_this_thread() {
  // Best effort: on failure the thread keeps the default slack, which only
  // makes its wake-ups later, never wrong.
  ::prctl(PR_SET_TIMERSLACK, 1UL, 0UL, 0UL, 0UL);
}

int watch_opens_and_closes(const std::string& path) {
  const int fd = ::inotify_init1(IN_NONBLOCK | IN_CLOEXEC);
  if (fd < 0) return -1;
  if (::inotify_add_watch(fd, path.c_str(), IN_OPEN | IN_ACCESS | IN_MODIFY | IN_CLOSE) < 0) {
    const int error = errno;
    ::close(fd);
    errno = error;
    return -1;
  }
  return fd;
}

bool watch_reads(int watch_fd, const std::string& path, bool reads) {
  // The same inode's watch, given a new mask.
  const std::uint32_t mask = IN_OPEN | IN_MODIFY | IN_CLOSE | (reads ? IN_ACCESS : 0u);
  return ::inotify_add_watch(watch_fd, path.c_str(), mask) >= 0;
}

std::vector<TerminalEvent> read_opens_and_closes(int watch_fd) {
  std::vector<TerminalEvent> events;
  alignas(inotify_event) char buffer[4096];
  for (;;) {
    const ssize_t n = sys::read_through_seam(watch_fd, buffer, sizeof buffer);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return events;
    for (ssize_t at = 0; at + static_cast<ssize_t>(sizeof(inotify_event)) <= n;) {
      const auto* event = reinterpret_cast<const inotify_event*>(buffer + at);
      // One event carries one of these; in this order should it carry more.
      if (event->mask & IN_OPEN) events.push_back(TerminalEvent::opened);
      if (event->mask & IN_ACCESS) events.push_back(TerminalEvent::read);
      if (event->mask & IN_MODIFY) events.push_back(TerminalEvent::wrote);
      if (event->mask & IN_CLOSE) events.push_back(TerminalEvent::closed);
      at += static_cast<ssize_t>(sizeof(inotify_event) + event->len);
    }
    // A read takes every queued event that fits: room left for the largest
    // means the queue was empty, and another read would only find EAGAIN
    // (a system call per message the client writes).
    if (static_cast<std::size_t>(n) + sizeof(inotify_event) + NAME_MAX + 1 <= sizeof buffer) {
      return events;
    }
  }
}

#else

int set_custom_baud(int, unsigned) { return ENOTSUP; }
int get_baud(int, unsigned&) { return ENOTSUP; }
int get_line_flags(int, LineFlags&) { return ENOTSUP; }

std::string terminal_path(int master_fd) {
  // ptsname() returns a static buffer.
  static std::mutex guard;
  std::lock_guard<std::mutex> lock(guard);
  const char* name = ::ptsname(master_fd);
  return name ? std::string(name) : std::string();
}

int no_sigpipe_send_flags() { return 0; }
void prevent_sigpipe(int socket_fd) {
#if defined(SO_NOSIGPIPE)
  int on = 1;
  ::setsockopt(socket_fd, SOL_SOCKET, SO_NOSIGPIPE, &on, sizeof on);
#else
  (void)socket_fd;
#endif
}

void precise_timers_for_this_thread() {}

int watch_opens_and_closes(const std::string&) {
  errno = ENOTSUP;
  return -1;
}

bool watch_reads(int, const std::string&, bool) { return false; }

std::vector<TerminalEvent> read_opens_and_closes(int) { return {}; }

#endif

}  // namespace wiretape::detail::platform
