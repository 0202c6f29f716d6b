// A TCP listener and the connections it accepts, non-blocking, for an event
// loop that polls their descriptors (the bridge's TCP client side).
#pragma once

#include <chrono>
#include <cstddef>
#include <optional>
#include <string>

#include "posix/syscalls.hpp"

namespace wiretape::detail {

// The outcome of one non-blocking transfer on a connection.
struct Transfer {
  enum class Status {
    done,         // `bytes` moved (at least one)
    would_block,  // nothing now; poll again
    closed,       // the peer closed the connection (receive only)
    failed,       // `error` says why
  };
  Status status = Status::done;
  std::size_t bytes = 0;
  int error = 0;
};

class Connection {
 public:
  Connection(sys::UniqueFd fd, std::string peer)
      : fd_(std::move(fd)), peer_(std::move(peer)) {}

  int fd() const noexcept { return fd_.get(); }
  // "HOST:PORT" ("[v6]:PORT") of the other end.
  const std::string& peer() const noexcept { return peer_; }
  Transfer receive(void* buffer, std::size_t size);
  Transfer send(const void* data, std::size_t size);
  // Sends FIN: the peer reads what was sent, then the end.
  void shutdown_sending() { sys::shutdown(fd_.get(), SHUT_WR); }
  void close() { fd_.reset(); }

 private:
  sys::UniqueFd fd_;
  std::string peer_;
};

class Listener {
 public:
  // Listens on `host` ("" for every address) and `port` (0: a free one),
  // with room for `backlog` connections not yet accepted (the kernel caps
  // it at net.core.somaxconn). Throws PortError naming "listen HOST:PORT"
  // and the step that failed.
  Listener(const std::string& host, int port, int backlog);

  int fd() const noexcept { return fd_.get(); }
  // Where clients connect, with the port the system picked: "HOST:PORT".
  const std::string& address() const noexcept { return address_; }
  using Clock = std::chrono::steady_clock;

  // The next waiting connection, or nothing when none waits (or accepting
  // failed; see resting()).
  std::optional<Connection> accept();

  // Out of descriptors or memory (EMFILE, ENFILE, ENOBUFS, ENOMEM) the
  // waiting connection stays queued and the listener stays readable: polled
  // again at once it would wake the loop for nothing, endlessly. So after
  // such a failure (or any the listener cannot place) it rests: until
  // resume_at() it must be left out of poll(); accept() is tried again after
  // that, the rest doubling from kFirstRest to kLongestRest while the
  // failure lasts.
  static constexpr std::chrono::milliseconds kFirstRest{50};
  static constexpr std::chrono::milliseconds kLongestRest{1000};
  bool resting(Clock::time_point now) const { return rest_error_ != 0 && now < resume_at_; }
  // When the rest ends (Clock::time_point::max() when there is none).
  Clock::time_point resume_at() const {
    return rest_error_ != 0 ? resume_at_ : Clock::time_point::max();
  }
  // The errno of the failure that began the current rest; 0 once a
  // connection was accepted again.
  int rest_error() const noexcept { return rest_error_; }

 private:
  void rest(int error);

  sys::UniqueFd fd_;
  std::string address_;
  int rest_error_ = 0;
  std::chrono::milliseconds rest_{0};
  Clock::time_point resume_at_{};
};

}  // namespace wiretape::detail
