#include "posix/wake_pipe.hpp"

#include <fcntl.h>

#include <cerrno>
#include <string>

#include "wiretape/errors.hpp"

namespace wiretape::detail {

WakePipe::WakePipe(const char* owner) {
  int fds[2];
  if (sys::pipe2(fds, O_NONBLOCK | O_CLOEXEC) != 0) {
    const int error = errno;
    throw PortError(error, std::string(owner) + ": creating the wake-up pipe");
  }
  read_end_.reset(fds[0]);
  write_end_.reset(fds[1]);
}

void WakePipe::wake() noexcept {
  const char byte = 1;
  while (sys::write(write_end_.get(), &byte, 1) < 0 && errno == EINTR) {
  }
}

void WakePipe::drain() noexcept {
  char scratch[64];
  for (;;) {
    const ssize_t n = sys::read(read_end_.get(), scratch, sizeof scratch);
    if (n > 0) continue;
    if (n < 0 && errno == EINTR) continue;
    return;
  }
}

}  // namespace wiretape::detail
