#include "posix/socket_port.hpp"

#include <arpa/inet.h>
#include <netinet/in.h>

#include <cerrno>

#include "posix/platform.hpp"
#include "wiretape/errors.hpp"

namespace wiretape::detail {

AddrInfoList resolve(const std::string& host, int port, int socket_type,
                     bool passive, const std::string& where) {
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = socket_type;
  hints.ai_flags = AI_NUMERICSERV | (passive ? AI_PASSIVE : 0);
  addrinfo* list = nullptr;
  const std::string service = std::to_string(port);
  const int status = ::getaddrinfo(host.empty() ? nullptr : host.c_str(),
                                   service.c_str(), &hints, &list);
  if (status == EAI_SYSTEM) {
    const int error = errno;  // before the message's allocations
    throw PortError(error, where + ": cannot resolve host '" + host + "'");
  }
  if (status != 0) {
    throw PortError(EHOSTUNREACH,
                    where + ": cannot resolve host '" + host + "': " + ::gai_strerror(status),
                    PortError::OwnExplanation{});
  }
  return AddrInfoList(list);
}

std::string address_text(const sockaddr* address, socklen_t) {
  char text[INET6_ADDRSTRLEN] = "?";
  if (address->sa_family == AF_INET) {
    const auto* in = reinterpret_cast<const sockaddr_in*>(address);
    ::inet_ntop(AF_INET, &in->sin_addr, text, sizeof text);
    return std::string(text) + ":" + std::to_string(ntohs(in->sin_port));
  }
  if (address->sa_family == AF_INET6) {
    const auto* in6 = reinterpret_cast<const sockaddr_in6*>(address);
    ::inet_ntop(AF_INET6, &in6->sin6_addr, text, sizeof text);
    return "[" + std::string(text) + "]:" + std::to_string(ntohs(in6->sin6_port));
  }
  return "?";
}

SocketPort::SocketPort(sys::UniqueFd fd, std::string description)
    : FdPort(std::move(fd), std::move(description)) {
  platform::prevent_sigpipe(this->fd());
}

ssize_t SocketPort::transfer_in(void* buffer, std::size_t size) {
  return sys::recv(fd(), buffer, size, 0);
}

ssize_t SocketPort::transfer_peek(void* buffer, std::size_t size) {
  return sys::recv(fd(), buffer, size, MSG_PEEK);
}

ssize_t SocketPort::transfer_out(const void* data, std::size_t size) {
  return sys::send(fd(), data, size, platform::no_sigpipe_send_flags());
}

void SocketPort::flush_output() { Call call(*this); }
void SocketPort::drain() { Call call(*this); }

void SocketPort::flush_input() {
  Call call(*this);
  char scratch[4096];
  for (;;) {
    const ssize_t n = sys::recv(fd(), scratch, sizeof scratch, 0);
    if (n > 0) continue;
    if (n < 0 && errno == EINTR) continue;
    // Nothing left (EAGAIN), end of file or an error: the next read reports
    // the latter two.
    return;
  }
}

}  // namespace wiretape::detail
