// The constructors of the port types that are operating-system transports.
// open_port() (src/open/open_port.cpp, through the registry in
// src/open/port_types.cpp) calls them once the common keys have been taken;
// each reads the keys of its type through the key table.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include "wiretape/options.hpp"
#include "wiretape/port.hpp"

namespace wiretape::detail {

std::unique_ptr<Port> open_serial(Options& options);
std::unique_ptr<Port> open_tcp(Options& options);
std::unique_ptr<Port> open_udp(Options& options);
std::unique_ptr<Port> open_pty(Options& options);
std::unique_ptr<Port> open_rfc2217(Options& options);

// A TCP connection to host:port as type=tcp makes it (TCP_NODELAY set),
// for the transports that speak a protocol over one (type=rfc2217); errors
// name `where`.
std::unique_ptr<Port> connect_tcp(const std::string& host, int port, Timeout connect_timeout,
                                  const std::string& where);

// What a datagram transport (type=udp) offers beyond Port, whose reads and
// writes cannot carry an empty datagram (a read of 0 bytes is a timeout).
// A zero-length datagram is a datagram like any other (DESIGN.md
// section 23).
class DatagramPort {
 public:
  virtual ~DatagramPort() = default;
  // The next datagram, if one waits now: its size (0 for an empty one,
  // truncated to `size` as recv does); nothing when none waits.
  virtual std::optional<std::size_t> receive_datagram(void* buffer, std::size_t size) = 0;
  // Sends an empty datagram; false when it could not go now.
  virtual bool send_empty_datagram() = 0;
  // How many datagrams another sender than the destination sent, dropped
  // (0 without a destination).
  virtual std::uint64_t datagrams_from_others() const = 0;
  // Takes the error a bounced datagram left on the socket (poll() shows it
  // as POLLERR, not a hang-up: UDP goes on); its errno, 0 for none.
  virtual int take_error() = 0;
};

}  // namespace wiretape::detail
