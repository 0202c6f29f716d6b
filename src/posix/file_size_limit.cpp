#include "posix/file_size_limit.hpp"

#include <pthread.h>
#include <signal.h>
#include <sys/resource.h>

#include <cerrno>
#include <ctime>

namespace wiretape::detail {

namespace {

sigset_t file_size_signal() {
  sigset_t set;
  sigemptyset(&set);
  sigaddset(&set, SIGXFSZ);
  return set;
}

}  // namespace

FileSizeSignalBlocked::FileSizeSignalBlocked() {
  const sigset_t set = file_size_signal();
  sigset_t previous;
  sigemptyset(&previous);
  if (pthread_sigmask(SIG_BLOCK, &set, &previous) == 0) {
    was_blocked_ = sigismember(&previous, SIGXFSZ) == 1;
  } else {
    was_blocked_ = true;  // nothing was changed, nothing to restore
  }
}

FileSizeSignalBlocked::~FileSizeSignalBlocked() {
  if (was_blocked_) return;
  const int saved_errno = errno;
  const sigset_t set = file_size_signal();
  sigset_t pending;
  sigemptyset(&pending);
  if (sigpending(&pending) == 0 && sigismember(&pending, SIGXFSZ) == 1) {
    const timespec now{};
    while (sigtimedwait(&set, nullptr, &now) < 0 && errno == EINTR) {
    }
  }
  pthread_sigmask(SIG_UNBLOCK, &set, nullptr);
  errno = saved_errno;
}

std::optional<std::uint64_t> file_size_limit() {
  rlimit limit{};
  if (getrlimit(RLIMIT_FSIZE, &limit) != 0 || limit.rlim_cur == RLIM_INFINITY) {
    return std::nullopt;
  }
  return static_cast<std::uint64_t>(limit.rlim_cur);
}

}  // namespace wiretape::detail
