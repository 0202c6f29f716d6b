// The descriptors an event loop waits on, and what poll() said of each.
#pragma once

#include <poll.h>

#include <chrono>
#include <cstddef>
#include <limits>
#include <optional>
#include <vector>

namespace wiretape::detail {

// What poll() saw on one descriptor.
struct Readiness {
  bool readable = false;
  bool writable = false;
  bool hung_up = false;  // hang-up or error: a read will tell which
  bool any() const { return readable || writable || hung_up; }
};

class PollSet {
 public:
  using Slot = std::size_t;
  static constexpr Slot none = std::numeric_limits<Slot>::max();

  // `owner` names the loop in errors ("bridge").
  explicit PollSet(const char* owner) : owner_(owner) {}

  void clear() { fds_.clear(); }
  // Adds `fd` for this round; returns its slot for ready(). (Inline, as
  // ready(): the bridge calls both several times for each read it relays.)
  Slot add(int fd, bool want_read, bool want_write) {
    short events = 0;
    if (want_read) events |= POLLIN;
    if (want_write) events |= POLLOUT;
    fds_.push_back({fd, events, 0});
    return fds_.size() - 1;
  }
  // Waits through the system-call seam until something is ready or
  // `timeout` passed (nullopt: no limit). An interrupted wait (EINTR) returns
  // with nothing ready; other failures raise PortError.
  void wait(std::optional<std::chrono::milliseconds> timeout);
  // What the last wait() saw on `slot` (nothing for PollSet::none).
  Readiness ready(Slot slot) const {
    Readiness readiness;
    if (slot >= fds_.size()) return readiness;
    const short revents = fds_[slot].revents;
    readiness.readable = (revents & POLLIN) != 0;
    readiness.writable = (revents & POLLOUT) != 0;
    readiness.hung_up = (revents & (POLLHUP | POLLERR)) != 0;
    return readiness;
  }

 private:
  const char* owner_;
  std::vector<pollfd> fds_;
};

}  // namespace wiretape::detail
