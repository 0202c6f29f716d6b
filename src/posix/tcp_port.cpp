// type=tcp: a TCP connection, made by connecting to host:port or, with
// listen=true, by waiting for one client on host:port.
#include <netinet/in.h>
#include <netinet/tcp.h>

#include <cerrno>
#include <chrono>
#include <cstdio>

#include "posix/transports.hpp"
#include "posix/socket_port.hpp"
#include "wiretape/errors.hpp"

namespace wiretape::detail {

namespace {

class TcpPort final : public SocketPort {
 public:
  TcpPort(sys::UniqueFd fd, std::string description)
      : SocketPort(std::move(fd), std::move(description)) {}
  ~TcpPort() override { close(); }
  std::string type() const override { return "tcp"; }
  PortCapabilities capabilities() const override { PortCapabilities c; c.output_pollable = true; return c; }
};

std::string seconds_text(Timeout timeout) {
  if (!timeout) return "forever";
  char text[32];
  std::snprintf(text, sizeof text, "%g s",
                std::chrono::duration<double>(*timeout).count());
  return text;
}

// Waits for `events` on `fd` until `deadline`; false on timeout.
bool wait_socket(int fd, short events, Deadline deadline,
                 const std::string& where) {
  for (;;) {
    pollfd p{fd, events, 0};
    const int ready = sys::poll(&p, 1, poll_timeout_ms(deadline));
    if (ready > 0) return true;
    if (ready < 0 && errno != EINTR) raise_os_error(errno, where, "poll");
    if (ready == 0 && deadline &&
        std::chrono::steady_clock::now() >= *deadline) {
      return false;
    }
  }
}

sys::UniqueFd make_socket(const addrinfo& info, const std::string& where) {
  sys::UniqueFd fd(sys::socket(info.ai_family, info.ai_socktype,
                               info.ai_protocol));
  if (!fd) raise_os_error(errno, where, "socket");
  make_nonblocking(fd.get(), where);
  return fd;
}

sys::UniqueFd connect_to(const std::string& host, int port, Timeout timeout,
                         const std::string& where) {
  const Deadline deadline = deadline_after(timeout);
  const AddrInfoList list = resolve(host, port, SOCK_STREAM, false, where);
  int last_error = ECONNREFUSED;
  for (const addrinfo* info = list.get(); info; info = info->ai_next) {
    sys::UniqueFd fd = make_socket(*info, where);
    int status;
    do {
      status = sys::connect(fd.get(), info->ai_addr, info->ai_addrlen);
    } while (status != 0 && errno == EINTR);
    if (status == 0) return fd;
    if (errno != EINPROGRESS) {
      last_error = errno;
      continue;
    }
    if (!wait_socket(fd.get(), POLLOUT, deadline, where)) {
      throw PortError(ETIMEDOUT, where + ": connect timed out after " +
                                     seconds_text(timeout));
    }
    int error = 0;
    socklen_t length = sizeof error;
    if (sys::getsockopt(fd.get(), SOL_SOCKET, SO_ERROR, &error, &length) != 0) {
      error = errno;
    }
    if (error == 0) return fd;
    last_error = error;
  }
  throw PortError(last_error, where + ": connect failed");
}

sys::UniqueFd accept_one(const std::string& host, int port, Timeout timeout,
                         const std::string& where, std::string& client) {
  const AddrInfoList list = resolve(host, port, SOCK_STREAM, true, where);
  const addrinfo& info = *list;
  sys::UniqueFd listener = make_socket(info, where);
  const int on = 1;
  sys::setsockopt(listener.get(), SOL_SOCKET, SO_REUSEADDR, &on, sizeof on);
  if (sys::bind(listener.get(), info.ai_addr, info.ai_addrlen) != 0) {
    raise_os_error(errno, where, "bind");
  }
  if (sys::listen(listener.get(), 1) != 0) {
    raise_os_error(errno, where, "listen");
  }
  const Deadline deadline = deadline_after(timeout);
  for (;;) {
    if (!wait_socket(listener.get(), POLLIN, deadline, where)) {
      throw PortError(ETIMEDOUT, where + ": no client connected within " +
                                     seconds_text(timeout));
    }
    sockaddr_storage peer{};
    socklen_t length = sizeof peer;
    sys::UniqueFd fd(sys::accept(listener.get(),
                                 reinterpret_cast<sockaddr*>(&peer), &length));
    if (fd) {
      client = address_text(reinterpret_cast<sockaddr*>(&peer), length);
      make_nonblocking(fd.get(), where);
      return fd;
    }
    if (errno != EINTR && errno != EAGAIN && errno != EWOULDBLOCK &&
        errno != ECONNABORTED) {
      raise_os_error(errno, where, "accept");
    }
  }
}

void set_nodelay(int fd) {
  const int on = 1;
  sys::setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &on, sizeof on);
}

}  // namespace

std::unique_ptr<Port> connect_tcp(const std::string& host, int port, Timeout connect_timeout,
                                  const std::string& where) {
  sys::UniqueFd fd = connect_to(host, port, connect_timeout, where);
  set_nodelay(fd.get());
  return std::make_unique<TcpPort>(std::move(fd), where);
}

std::unique_ptr<Port> open_tcp(Options& options) {
  const std::string host = options.take_string("host");
  const int port = static_cast<int>(options.take_int("port"));
  const bool listen = options.take_bool("listen");
  const bool nodelay = options.take_bool("nodelay");
  const Timeout timeout = options.take_timeout("timeout");
  options.finish("tcp");  // reject bad keys before connecting or listening

  const std::string endpoint = host + ":" + std::to_string(port);
  std::string description;
  sys::UniqueFd fd;
  if (listen) {
    std::string client;
    const std::string where = "tcp listen " + endpoint;
    fd = accept_one(host, port, timeout, where, client);
    description = where + " (client " + client + ")";
  } else {
    description = "tcp " + endpoint;
    fd = connect_to(host, port, timeout, description);
  }
  if (nodelay) set_nodelay(fd.get());
  return std::make_unique<TcpPort>(std::move(fd), std::move(description));
}

}  // namespace wiretape::detail
