#include "posix/listener.hpp"

#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>

#include <algorithm>
#include <cerrno>
#include <memory>

#include "posix/platform.hpp"
#include "posix/socket_port.hpp"
#include "wiretape/errors.hpp"

namespace wiretape::detail {

namespace {

[[noreturn]] void raise_errno(const std::string& what) {
  const int error = errno;
  throw PortError(error, what);
}

Transfer failed_or_would_block(int error) {
  Transfer transfer;
  if (error == EAGAIN || error == EWOULDBLOCK || error == EINTR) {
    transfer.status = Transfer::Status::would_block;
  } else {
    transfer.status = Transfer::Status::failed;
    transfer.error = error;
  }
  return transfer;
}

// Failures of one waiting connection (it is gone from the queue), not of
// the listener; Linux reports pending network errors this way too.
bool connection_failed_on_its_own(int error) {
  switch (error) {
    case EINTR:
    case ECONNABORTED:
    case EPROTO:
    case ENETDOWN:
    case ENETUNREACH:
    case EHOSTDOWN:
    case EHOSTUNREACH:
    case ENOPROTOOPT:
    case EOPNOTSUPP:
      return true;
    default:
      return false;
  }
}

}  // namespace

Transfer Connection::receive(void* buffer, std::size_t size) {
  const ssize_t got = sys::recv(fd_.get(), buffer, size, 0);
  if (got < 0) return failed_or_would_block(errno);
  Transfer transfer;
  if (got == 0) {
    transfer.status = Transfer::Status::closed;
    return transfer;
  }
  transfer.bytes = static_cast<std::size_t>(got);
  return transfer;
}

Transfer Connection::send(const void* data, std::size_t size) {
  const ssize_t sent = sys::send(fd_.get(), data, size,
                                 platform::no_sigpipe_send_flags() | MSG_DONTWAIT);
  if (sent < 0) return failed_or_would_block(errno);
  Transfer transfer;
  transfer.bytes = static_cast<std::size_t>(sent);
  return transfer;
}

Listener::Listener(const std::string& host, int port, int backlog) {
  const std::string where = "listen " + host + ":" + std::to_string(port);
  const AddrInfoList list = resolve(host, port, SOCK_STREAM, /*passive=*/true, where);
  const addrinfo* found = list.get();
  sys::UniqueFd fd(sys::socket(found->ai_family,
                               found->ai_socktype | SOCK_NONBLOCK | SOCK_CLOEXEC,
                               found->ai_protocol));
  if (!fd) raise_errno(where + ": socket");
  const int on = 1;
  sys::setsockopt(fd.get(), SOL_SOCKET, SO_REUSEADDR, &on, sizeof on);
  if (sys::bind(fd.get(), found->ai_addr, found->ai_addrlen) != 0) raise_errno(where + ": bind");
  if (sys::listen(fd.get(), backlog) != 0) raise_errno(where + ": listen");
  sockaddr_storage bound{};
  socklen_t length = sizeof bound;
  sys::getsockname(fd.get(), reinterpret_cast<sockaddr*>(&bound), &length);
  address_ = address_text(reinterpret_cast<sockaddr*>(&bound), length);
  fd_ = std::move(fd);
}

std::optional<Connection> Listener::accept() {
  for (;;) {
    sockaddr_storage peer{};
    socklen_t length = sizeof peer;
    sys::UniqueFd fd(sys::accept4(fd_.get(), reinterpret_cast<sockaddr*>(&peer), &length,
                                  SOCK_NONBLOCK | SOCK_CLOEXEC));
    if (!fd) {
      const int error = errno;
      if (error == EAGAIN || error == EWOULDBLOCK) return std::nullopt;  // none waits
      if (connection_failed_on_its_own(error)) continue;
      // Out of descriptors or memory, or a failure we cannot place: the
      // connection may still be queued.
      rest(error);
      return std::nullopt;
    }
    rest_error_ = 0;
    rest_ = std::chrono::milliseconds(0);
    platform::prevent_sigpipe(fd.get());
    const int on = 1;
    sys::setsockopt(fd.get(), IPPROTO_TCP, TCP_NODELAY, &on, sizeof on);
    return Connection(std::move(fd), address_text(reinterpret_cast<sockaddr*>(&peer), length));
  }
}

void Listener::rest(int error) {
  rest_error_ = error;
  rest_ = std::clamp(rest_ * 2, std::chrono::milliseconds(kFirstRest),
                     std::chrono::milliseconds(kLongestRest));
  resume_at_ = Clock::now() + rest_;
}

}  // namespace wiretape::detail
