// type=udp: datagrams. Each read returns at most one datagram (truncated to
// the buffer, as recv does); each write sends one datagram to host:port, or,
// when no destination is given, to whoever sent the last datagram received.
//
// With host:port the socket is connected to it (connect(2)): the device is
// the only sender whose datagrams are read, as a UDP proxy's device side
// must be (DESIGN.md section 23). The kernel drops datagrams from other
// senders to a connected socket (the sender gets "port unreachable");
// those that arrived between bind and connect are dropped here, and
// counted.
#include <netinet/in.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <mutex>

#include "posix/transports.hpp"
#include "posix/platform.hpp"
#include "posix/socket_port.hpp"
#include "wiretape/errors.hpp"

namespace wiretape::detail {

namespace {

bool same_address(const sockaddr_storage& a, const sockaddr_storage& b) {
  if (a.ss_family != b.ss_family) return false;
  if (a.ss_family == AF_INET) {
    const auto& x = reinterpret_cast<const sockaddr_in&>(a);
    const auto& y = reinterpret_cast<const sockaddr_in&>(b);
    return x.sin_port == y.sin_port && x.sin_addr.s_addr == y.sin_addr.s_addr;
  }
  if (a.ss_family == AF_INET6) {
    const auto& x = reinterpret_cast<const sockaddr_in6&>(a);
    const auto& y = reinterpret_cast<const sockaddr_in6&>(b);
    return x.sin6_port == y.sin6_port &&
           std::memcmp(&x.sin6_addr, &y.sin6_addr, sizeof x.sin6_addr) == 0;
  }
  return false;
}

class UdpPort final : public SocketPort, public DatagramPort {
 public:
  UdpPort(sys::UniqueFd fd, std::string description,
          std::optional<sockaddr_storage> destination, socklen_t length)
      : SocketPort(std::move(fd), std::move(description)),
        fixed_destination_(destination.has_value()),
        destination_(destination),
        destination_length_(length) {}
  ~UdpPort() override { close(); }
  std::string type() const override { return "udp"; }
  PortCapabilities capabilities() const override { PortCapabilities c; c.datagrams = c.output_pollable = true; return c; }
  std::uint64_t datagrams_from_others() const override { return from_others_.load(); }

  std::optional<std::size_t> receive_datagram(void* buffer, std::size_t size) override {
    Call call(*this);
    for (;;) {
      const ssize_t n = receive_one(buffer, size, MSG_DONTWAIT);
      if (n >= 0) return static_cast<std::size_t>(n);
      if (errno == EINTR) continue;
      if (errno == EAGAIN || errno == EWOULDBLOCK) return std::nullopt;
      fail(errno, "read");
    }
  }

  int take_error() override {
    int error = 0;
    socklen_t length = sizeof error;
    if (sys::getsockopt(fd(), SOL_SOCKET, SO_ERROR, &error, &length) != 0) return 0;
    return error;
  }

  bool send_empty_datagram() override {
    Call call(*this);
    char nothing = 0;
    for (;;) {
      if (transfer_out(&nothing, 0) == 0) return true;
      if (errno == EINTR) continue;
      if (errno == EAGAIN || errno == EWOULDBLOCK || errno == ENOBUFS) return false;
      fail(errno, "write");
    }
  }

 protected:
  bool zero_read_is_end_of_file() const override { return false; }

  ssize_t transfer_in(void* buffer, std::size_t size) override {
    return receive_one(buffer, size, 0);
  }

  ssize_t transfer_out(const void* data, std::size_t size) override {
    sockaddr_storage to{};
    socklen_t length = 0;
    {
      std::lock_guard<std::mutex> lock(peer_mutex_);
      if (!destination_) {
        errno = EDESTADDRREQ;
        return -1;
      }
      to = *destination_;
      length = destination_length_;
    }
    for (;;) {
      const ssize_t n = sys::sendto(fd(), data, size, platform::no_sigpipe_send_flags(),
                                    reinterpret_cast<const sockaddr*>(&to), length);
      // A connected socket reports an earlier datagram's bounce on this
      // send; this one has not gone yet.
      if (n < 0 && errno == ECONNREFUSED && fixed_destination_) continue;
      return n;
    }
  }

 private:
  // One recvfrom: a datagram from the destination (or, without one, from
  // anyone, who becomes the destination); -1 with errno EAGAIN for one
  // dropped.
  ssize_t receive_one(void* buffer, std::size_t size, int flags) {
    sockaddr_storage from{};
    socklen_t length = sizeof from;
    const ssize_t n = sys::recvfrom(fd(), buffer, size, flags,
                                    reinterpret_cast<sockaddr*>(&from), &length);
    if (n < 0 && errno == ECONNREFUSED) {
      // An earlier datagram to the device bounced (nobody listened there
      // then). Reading takes the error; the device may be up by now, and a
      // datagram is as lost as it would be unconnected.
      errno = EAGAIN;
      return -1;
    }
    if (n >= 0 && fixed_destination_ && !same_address(from, *destination_)) {
      // Not the device: neither read, nor recorded, nor forwarded.
      ++from_others_;
      errno = EAGAIN;
      return -1;
    }
    if (n >= 0 && !fixed_destination_) {
      std::lock_guard<std::mutex> lock(peer_mutex_);
      destination_ = from;
      destination_length_ = length;
    }
    return n;
  }

  // host/port given: every datagram goes there; otherwise to the last sender.
  const bool fixed_destination_;
  std::mutex peer_mutex_;
  std::optional<sockaddr_storage> destination_;
  socklen_t destination_length_;
  std::atomic<std::uint64_t> from_others_{0};
};

}  // namespace

std::unique_ptr<Port> open_udp(Options& options) {
  const std::string host = options.take_string("host");
  const int port = static_cast<int>(options.take_int("port"));
  const std::string bind_host = options.take_string("bind_host");
  const int bind_port = static_cast<int>(options.take_int("bind_port"));
  if (port == 0 && options.has("host")) {
    throw OptionError("port", "option 'host' for type=udp needs 'port' (the "
                              "destination port, 1 to 65535)");
  }

  options.finish("udp");

  const std::string where = "udp " + bind_host + ":" + std::to_string(bind_port);
  const AddrInfoList local = resolve(bind_host, bind_port, SOCK_DGRAM, true, where);
  sys::UniqueFd fd(sys::socket(local->ai_family, local->ai_socktype,
                               local->ai_protocol));
  if (!fd) raise_os_error(errno, where, "socket");
  const int on = 1;
  sys::setsockopt(fd.get(), SOL_SOCKET, SO_REUSEADDR, &on, sizeof on);
  if (sys::bind(fd.get(), local->ai_addr, local->ai_addrlen) != 0) {
    raise_os_error(errno, where, "bind");
  }
  sockaddr_storage bound{};
  socklen_t bound_length = sizeof bound;
  std::string description = "udp ";
  if (sys::getsockname(fd.get(), reinterpret_cast<sockaddr*>(&bound),
                       &bound_length) == 0) {
    description += address_text(reinterpret_cast<sockaddr*>(&bound), bound_length);
  } else {
    description += bind_host + ":" + std::to_string(bind_port);
  }

  std::optional<sockaddr_storage> destination;
  socklen_t destination_length = 0;
  if (port != 0) {
    const AddrInfoList remote = resolve(host, port, SOCK_DGRAM, false, where);
    // Prefer the family of the bound socket.
    const addrinfo* chosen = remote.get();
    for (const addrinfo* info = remote.get(); info; info = info->ai_next) {
      if (info->ai_family == local->ai_family) {
        chosen = info;
        break;
      }
    }
    sockaddr_storage to{};
    std::memcpy(&to, chosen->ai_addr, chosen->ai_addrlen);
    destination = to;
    destination_length = chosen->ai_addrlen;
    if (sys::connect(fd.get(), chosen->ai_addr, chosen->ai_addrlen) != 0) {
      raise_os_error(errno, where, "connect to " + address_text(chosen->ai_addr,
                                                                chosen->ai_addrlen));
    }
    description += " -> " + address_text(chosen->ai_addr, chosen->ai_addrlen);
  } else {
    description += " (replies to the last sender)";
  }
  return std::make_unique<UdpPort>(std::move(fd), std::move(description),
                                   destination, destination_length);
}

}  // namespace wiretape::detail
