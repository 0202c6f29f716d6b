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

#include <atomic>
#include <cstddef>
#include <string>
#include <vector>

#include "posix/syscalls.hpp"
#include "wiretape/session.hpp"

namespace wiretape::test {

// Replaces poll() in the OS-call seam with one that sets `blocked` the first
// time a call waits without a timeout (-1): proof that a read is blocked.
class BlockedPollSignal {
 public:
  BlockedPollSignal();
  Event blocked;

 private:
  detail::sys::ScopedOverride override_;
};

// A pseudo-terminal pair made with openpty(); the terminal side's path is
// what a serial port opens.
struct PtyPair {
  PtyPair();
  ~PtyPair();
  PtyPair(const PtyPair&) = delete;
  PtyPair& operator=(const PtyPair&) = delete;
  int master = -1;
  int terminal = -1;
  std::string path;
  // Writes all of `data` to the master side.
  void write_master(const std::string& data) const;
  // Reads from the master side until `count` bytes came or 5 s passed.
  std::string read_master(std::size_t count) const;
};

// A whole file's bytes; "" if it cannot be read.
std::string read_file(const std::string& path);
// Replaces the file's content with `bytes`.
void write_file(const std::string& path, const std::string& bytes);

// A TCP connection to "HOST:PORT" made with libc directly, so that a test's
// fakes in the OS-call seam touch only the code under test; -1 if refused.
int connect_tcp(const std::string& address);
// Reads `fd` until `count` bytes came or kEventDeadline passed.
std::string read_count(int fd, std::size_t count);

// Every record of a session file; throws its SessionError when it is damaged.
std::vector<Record> load_records(const std::string& path);

// Whether this process holds a descriptor open on `path` (Linux: /proc).
bool holds_fd_on(const std::string& path);

// A fresh directory under /tmp, removed with its content at destruction.
struct TempDir {
  TempDir();
  ~TempDir();
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  std::string file(const std::string& name) const { return path + "/" + name; }
  std::string path;
};

}  // namespace wiretape::test
