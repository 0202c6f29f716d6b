// Helpers shared by the transport tests.
#pragma once

#include <poll.h>

#include <chrono>
#include <condition_variable>
#include <mutex>

namespace wiretape::test {

// Generous, for events that should happen at once on an idle machine.
inline constexpr std::chrono::seconds kEventDeadline{10};

// Polls `fd` for readability; true if readable within `timeout`.
bool fd_readable(int fd, std::chrono::milliseconds timeout);

// A one-shot event one thread sets and another waits on.
class Event {
 public:
  void set();
  // True if set within `timeout`.
  bool wait(std::chrono::milliseconds timeout = kEventDeadline);

 private:
  std::mutex mutex_;
  std::condition_variable changed_;
  bool set_ = false;
};

// A TCP/UDP port number on 127.0.0.1 that was free a moment ago.
int free_port(bool udp = false);

}  // namespace wiretape::test
