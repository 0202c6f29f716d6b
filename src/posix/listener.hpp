// A TCP listener and the connections it accepts, non-blocking, for an event
// loop that polls their descriptors (the bridge's TCP client side).
#pragma once

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
  void close() { fd_.reset(); }

 private:
  sys::UniqueFd fd_;
  std::string peer_;
};

class Listener {
 public:
  // Listens on `host` ("" for every address) and `port` (0: a free one).
  // Throws PortError naming "listen HOST:PORT" and the step that failed.
  Listener(const std::string& host, int port);

  int fd() const noexcept { return fd_.get(); }
  // Where clients connect, with the port the system picked: "HOST:PORT".
  const std::string& address() const noexcept { return address_; }
  // The next waiting connection, or nothing when none waits (or accepting
  // failed in a way the next poll retries).
  std::optional<Connection> accept();

 private:
  sys::UniqueFd fd_;
  std::string address_;
};

}  // namespace wiretape::detail
