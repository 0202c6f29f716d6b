// A self-pipe that wakes a poll() loop from another thread: the loop polls
// fd() for reading, another thread calls wake().
#pragma once

#include "posix/syscalls.hpp"

namespace wiretape::detail {

class WakePipe {
 public:
  // Throws PortError naming `owner` when the system has no pipe to give.
  explicit WakePipe(const char* owner);

  // Readable once wake() was called, until drain().
  int fd() const noexcept { return read_end_.get(); }
  // Thread-safe and never blocks: a full pipe already wakes the loop.
  void wake() noexcept;
  // Takes back every wake-up so far.
  void drain() noexcept;

 private:
  sys::UniqueFd read_end_;
  sys::UniqueFd write_end_;
};

}  // namespace wiretape::detail
