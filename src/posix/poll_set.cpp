#include "posix/poll_set.hpp"

#include <cerrno>
#include <string>

#include "posix/syscalls.hpp"
#include "wiretape/errors.hpp"

namespace wiretape::detail {

PollSet::Slot PollSet::add(int fd, bool want_read, bool want_write) {
  short events = 0;
  if (want_read) events |= POLLIN;
  if (want_write) events |= POLLOUT;
  fds_.push_back({fd, events, 0});
  return fds_.size() - 1;
}

void PollSet::wait(std::optional<std::chrono::milliseconds> timeout) {
  const int timeout_ms = timeout ? static_cast<int>(timeout->count()) : -1;
  for (auto& entry : fds_) entry.revents = 0;
  if (sys::poll(fds_.data(), fds_.size(), timeout_ms) >= 0) return;
  const int error = errno;
  for (auto& entry : fds_) entry.revents = 0;
  if (error == EINTR) return;
  throw PortError(error, std::string(owner_) + ": poll");
}

Readiness PollSet::ready(Slot slot) const {
  Readiness readiness;
  if (slot >= fds_.size()) return readiness;
  const short revents = fds_[slot].revents;
  readiness.readable = (revents & POLLIN) != 0;
  readiness.writable = (revents & POLLOUT) != 0;
  readiness.hung_up = (revents & (POLLHUP | POLLERR)) != 0;
  return readiness;
}

}  // namespace wiretape::detail
