// What tcp and udp ports share: send/recv instead of read/write, address
// resolution and printing.
#pragma once

#include <netdb.h>
#include <sys/socket.h>

#include <memory>
#include <string>

#include "posix/fd_port.hpp"

namespace wiretape::detail {

struct AddrInfoDeleter {
  void operator()(addrinfo* list) const { ::freeaddrinfo(list); }
};
using AddrInfoList = std::unique_ptr<addrinfo, AddrInfoDeleter>;

// getaddrinfo() for `host`:`port`; throws PortError naming `where` when the
// name does not resolve.
AddrInfoList resolve(const std::string& host, int port, int socket_type,
                     bool passive, const std::string& where);

// "127.0.0.1:5000" / "[::1]:5000".
std::string address_text(const sockaddr* address, socklen_t length);

class SocketPort : public FdPort {
 public:
  // A socket has no unsent output to drop or wait for that the application
  // can reach portably; these return at once.
  void flush_output() override;
  void drain() override;
  // Discards what the socket has received so far.
  void flush_input() override;

 protected:
  SocketPort(sys::UniqueFd fd, std::string description);
  ssize_t transfer_in(void* buffer, std::size_t size) override;
  ssize_t transfer_out(const void* data, std::size_t size) override;
  ssize_t transfer_peek(void* buffer, std::size_t size) override;
};

}  // namespace wiretape::detail
