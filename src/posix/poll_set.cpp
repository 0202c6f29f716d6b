#include "posix/poll_set.hpp"

#include <cerrno>
#include <string>

#include "posix/syscalls.hpp"
#include "wiretape/errors.hpp"

namespace wiretape::detail {

void PollSet::wait(std::optional<std::chrono::milliseconds> timeout) {
  const int timeout_ms = timeout ? static_cast<int>(timeout->count()) : -1;
  for (auto& entry : fds_) entry.revents = 0;
  if (sys::poll(fds_.data(), fds_.size(), timeout_ms) >= 0) return;
  const int error = errno;
  for (auto& entry : fds_) entry.revents = 0;
  if (error == EINTR) return;
  throw PortError(error, std::string(owner_) + ": poll");
}

}  // namespace wiretape::detail
