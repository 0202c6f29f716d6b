// The UDP endpoint: one socket bound where the driver sends its datagrams.
// Each datagram from the driver goes to the device as one write (so one tx
// record); each read from the device goes back as one datagram (one rx
// record), to the last sender or to a fixed peer. There are no connections:
// a client session starts with the first datagram of a sender (or at once
// when the peer is given), and a datagram from another address is a new
// client.
//
// Memory is bounded by a count of datagrams (and by buffer_limit bytes) in
// each direction. Datagrams from a client that floods faster than the
// device takes them are dropped when the queue to the device is full, and
// counted: UDP has no flow control to hold the client back, and a datagram
// left in the kernel is dropped there too, uncounted. A dropped datagram was
// never forwarded, so it is not recorded either: the recording holds exactly
// what the device saw.
//
// A fixed peer may not be listening yet (a driver started after the
// replay): the kernel answers "port unreachable", which the socket reports
// (IP_RECVERR) with the address it was sent to. A datagram the peer refused
// was not served. Until the peer has taken one, the first datagram is sent
// alone and kept: refused, it is sent again a little later, and nothing
// else is read from the device, so the peer gets the data from its start
// whenever it begins to listen (DESIGN.md section 23).
#include <netinet/in.h>
#include <sys/socket.h>
#ifdef __linux__
#include <linux/errqueue.h>
#endif

#include <array>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <deque>
#include <optional>
#include <string>

#include "bridge/endpoint.hpp"
#include "posix/platform.hpp"
#include "posix/socket_port.hpp"
#include "posix/syscalls.hpp"
#include "wiretape/errors.hpp"

namespace wiretape::detail::bridge {

namespace {

// The largest UDP payload (IPv4: 65535 less the IP and UDP headers).
constexpr std::size_t kMaxDatagram = 65507;
// At most this many datagrams wait in each direction.
constexpr std::size_t kMaxQueuedDatagrams = 1024;
// Datagrams read from the socket per round, so that a flood does not keep
// the loop from the device.
constexpr int kReadsPerRound = 256;
// How long a peer that refused a datagram is left before the next try.
constexpr std::chrono::milliseconds kPeerRetry{200};
// How long the first datagram to a peer waits for a refusal before it
// counts as taken (on this host the refusal comes back at once).
constexpr std::chrono::milliseconds kPeerVerdict{50};

struct Address {
  sockaddr_storage storage{};
  socklen_t length = 0;

  const sockaddr* get() const { return reinterpret_cast<const sockaddr*>(&storage); }
  bool operator==(const Address& other) const {
    return length == other.length && std::memcmp(&storage, &other.storage, length) == 0;
  }
  std::string text() const { return address_text(get(), length); }
  // The same host and port, whatever else the kernel filled in (an IPv6
  // flow label or scope in an error report).
  bool same_endpoint(const Address& other) const {
    if (storage.ss_family != other.storage.ss_family) return false;
    if (storage.ss_family == AF_INET) {
      const auto& a = reinterpret_cast<const sockaddr_in&>(storage);
      const auto& b = reinterpret_cast<const sockaddr_in&>(other.storage);
      return a.sin_port == b.sin_port && a.sin_addr.s_addr == b.sin_addr.s_addr;
    }
    if (storage.ss_family == AF_INET6) {
      const auto& a = reinterpret_cast<const sockaddr_in6&>(storage);
      const auto& b = reinterpret_cast<const sockaddr_in6&>(other.storage);
      return a.sin6_port == b.sin6_port &&
             std::memcmp(&a.sin6_addr, &b.sin6_addr, sizeof a.sin6_addr) == 0;
    }
    return *this == other;
  }
};

// Datagrams waiting, bounded in count and bytes.
class DatagramQueue {
 public:
  explicit DatagramQueue(std::size_t byte_limit) : byte_limit_(byte_limit) {}
  bool empty() const { return datagrams_.empty(); }
  bool full() const { return datagrams_.size() >= kMaxQueuedDatagrams || bytes_ >= byte_limit_; }
  const std::string& front() const { return datagrams_.front(); }
  void push(std::string datagram) {
    bytes_ += datagram.size();
    datagrams_.push_back(std::move(datagram));
  }
  void pop() {
    bytes_ -= datagrams_.front().size();
    datagrams_.pop_front();
  }
  // The front datagram, moved out of the queue rather than copied.
  std::string take() {
    std::string datagram = std::move(datagrams_.front());
    bytes_ -= datagram.size();
    datagrams_.pop_front();
    return datagram;
  }
  void clear() {
    datagrams_.clear();
    bytes_ = 0;
  }

 private:
  std::size_t byte_limit_;
  std::size_t bytes_ = 0;
  std::deque<std::string> datagrams_;
};

class UdpEndpoint final : public ClientEndpoint {
 public:
  UdpEndpoint(const BridgeOptions& options, DeviceSide& device, Status& status)
      : options_(options),
        device_(device),
        status_(status),
        to_device_(options.buffer_limit),
        to_client_(options.buffer_limit) {
    bind_socket();
    if (!options_.udp_peer_host.empty()) {
      const std::string where =
          "udp peer " + options_.udp_peer_host + ":" + std::to_string(options_.udp_peer_port);
      const AddrInfoList remote =
          resolve(options_.udp_peer_host, options_.udp_peer_port, SOCK_DGRAM, false, where);
      const addrinfo* chosen = remote.get();
      for (const addrinfo* info = remote.get(); info; info = info->ai_next) {
        if (info->ai_family == family_) {
          chosen = info;
          break;
        }
      }
      Address peer;
      std::memcpy(&peer.storage, chosen->ai_addr, chosen->ai_addrlen);
      peer.length = chosen->ai_addrlen;
      fixed_peer_ = true;
      watch_refusals();
      // With a peer the client session starts now: a device that streams
      // unprompted has someone to stream to (its first datagram is sent
      // again while the peer refuses it).
      start_client(peer);
    }
  }

  void add_to_poll(PollSet& poll_set) override {
    pass_to_device();
    slot_ = poll_set.add(socket_.get(), true, !to_client_.empty());
  }

  void handle_events(const PollSet& poll_set) override {
    const Readiness ready = poll_set.ready(slot_);
    // An error pending on the socket is polled as one: a read takes it, or
    // poll() would report it round after round.
    if (ready.readable || ready.hung_up) read_clients();
    if (fixed_peer_) take_refusals();
    if (!to_client_.empty()) send_to_client();
    pass_to_device();
  }

  Clock::time_point next_timer() const override {
    if (probe_sent_) return verdict_at_;
    if (holding_) return retry_at_;
    return Clock::time_point::max();
  }

  void run_timers(Clock::time_point now) override {
    if (probe_sent_ && now >= verdict_at_) {
      take_refusals();
      if (probe_sent_) peer_took_the_probe();
    }
    if (holding_ && now >= retry_at_) {
      holding_ = false;
      send_to_client();
    }
  }

  // Until a peer has taken a datagram, one is read from the device at a time.
  bool wants_device_data() const override {
    if (awaiting_peer()) return client_.has_value() && to_client_.empty();
    return client_.has_value() && !to_client_.full();
  }

  // One read of the device is one datagram to the client.
  bool keeps_datagram_boundaries() const override { return true; }

  void deliver_from_device(const char* data, std::size_t size) override {
    if (!client_) return;
    to_client_.push(std::string(data, size));
    send_to_client();
  }

  void device_lost() override {
    to_device_.clear();
  }

  bool has_clients() const override { return client_.has_value(); }

  bool served_device_data() const override { return served_device_data_; }

  std::string why_nothing_was_served() const override {
    if (!fixed_peer_ || peer_accepted_ || refused_ == 0) return "";
    return "the peer " + client_text_ + " refused every datagram sent to it (" +
           std::to_string(refused_) + " refused: nobody listened there)";
  }

  void shut_down() override {
    if (!awaiting_peer()) send_to_client();
    if (client_) {
      device_.client_disconnected(client_->text(), "closed: the bridge stopped");
    }
    if (dropped_ > 0) {
      status_.message("dropped " + std::to_string(dropped_) +
                      " datagrams a client sent faster than the device took them "
                      "(they were neither forwarded nor recorded)");
    }
    socket_.reset();
  }

 private:
  void bind_socket() {
    const std::string where =
        "udp " + options_.listen_host + ":" + std::to_string(options_.listen_port);
    const AddrInfoList local =
        resolve(options_.listen_host, options_.listen_port, SOCK_DGRAM, true, where);
    sys::UniqueFd fd(sys::socket(local->ai_family,
                                 local->ai_socktype | SOCK_NONBLOCK | SOCK_CLOEXEC,
                                 local->ai_protocol));
    if (!fd) raise_os_error(errno, where, "socket");
    if (sys::bind(fd.get(), local->ai_addr, local->ai_addrlen) != 0) {
      raise_os_error(errno, where, "bind");
    }
    family_ = local->ai_family;
    sockaddr_storage bound{};
    socklen_t length = sizeof bound;
    std::string address = options_.listen_host + ":" + std::to_string(options_.listen_port);
    if (sys::getsockname(fd.get(), reinterpret_cast<sockaddr*>(&bound), &length) == 0) {
      address = address_text(reinterpret_cast<sockaddr*>(&bound), length);
    }
    status_.set(&Status::listen_address, address);
    status_.message("receiving datagrams on udp " + address);
    socket_ = std::move(fd);
  }

  // Asks the socket to report the datagrams the peer refuses (Linux).
  void watch_refusals() {
#ifdef __linux__
    const int on = 1;
    if (family_ == AF_INET6) {
      sys::setsockopt(socket_.get(), SOL_IPV6, IPV6_RECVERR, &on, sizeof on);
    } else {
      sys::setsockopt(socket_.get(), SOL_IP, IP_RECVERR, &on, sizeof on);
    }
#endif
  }

  // Reads the socket's error queue: each entry is a datagram that did not
  // arrive, with the address it was sent to.
  void take_refusals() {
#ifdef __linux__
    for (;;) {
      Address to;
      std::array<char, 512> control{};
      char byte = 0;
      iovec vector{&byte, sizeof byte};
      msghdr message{};
      message.msg_name = &to.storage;
      message.msg_namelen = sizeof to.storage;
      message.msg_iov = &vector;
      message.msg_iovlen = 1;
      message.msg_control = control.data();
      message.msg_controllen = control.size();
      if (sys::recvmsg(socket_.get(), &message, MSG_ERRQUEUE | MSG_DONTWAIT) < 0) {
        if (errno == EINTR) continue;
        return;  // EAGAIN: none left
      }
      to.length = message.msg_namelen;
      int error = 0;
      for (cmsghdr* c = CMSG_FIRSTHDR(&message); c; c = CMSG_NXTHDR(&message, c)) {
        if ((c->cmsg_level == SOL_IP && c->cmsg_type == IP_RECVERR) ||
            (c->cmsg_level == SOL_IPV6 && c->cmsg_type == IPV6_RECVERR)) {
          sock_extended_err extended{};
          std::memcpy(&extended, CMSG_DATA(c), sizeof extended);
          error = static_cast<int>(extended.ee_errno);
        }
      }
      if (error != 0 && client_ && to.same_endpoint(*client_)) peer_refused(error);
    }
#endif
  }

  bool awaiting_peer() const { return fixed_peer_ && !peer_accepted_; }

  // No refusal came back for the first datagram: the peer took it, and the
  // rest follows.
  void peer_took_the_probe() {
    probe_sent_ = false;
    peer_accepted_ = true;
    served_device_data_ = true;
    if (!to_client_.empty()) to_client_.pop();
    if (refused_ > 0) {
      status_.message("the peer " + client_text_ +
                      " took a datagram: its client session starts there");
    }
    send_to_client();
  }

  void peer_refused(int error) {
    ++refused_;
    status_.update_stats([](BridgeStats& s) { ++s.datagrams_refused; });
    if (!refusal_reported_) {
      status_.message(system_error_message(
          "the peer " + client_text_ +
              (peer_accepted_ ? " refused a datagram (not served)"
                              : " refused a datagram (nobody listens there yet); the first "
                                "datagram is sent again every " +
                                    std::to_string(kPeerRetry.count()) + " ms until it is "
                                                                         "taken"),
          error));
      refusal_reported_ = true;
    }
    if (peer_accepted_) return;
    probe_sent_ = false;
    holding_ = true;
    retry_at_ = Clock::now() + kPeerRetry;
  }

  void start_client(const Address& peer) {
    if (client_) {
      device_.client_disconnected(client_->text(), "another sender took over");
      status_.message("client " + client_->text() + " replaced by " + peer.text());
      if (options_.restart) device_.restart();
    }
    client_ = peer;
    client_text_ = peer.text();
    device_.client_connected(peer.text(), "control");
    status_.message("client " + peer.text() +
                    (fixed_peer_ ? " (the peer)" : " connected (its first datagram)"));
  }

  void read_clients() {
    std::array<char, kMaxDatagram> buffer;
    for (int i = 0; i < kReadsPerRound; ++i) {
      Address from;
      from.length = sizeof from.storage;
      const ssize_t n = sys::recvfrom(socket_.get(), buffer.data(), buffer.size(), MSG_DONTWAIT,
                                      reinterpret_cast<sockaddr*>(&from.storage), &from.length);
      if (n < 0) {
        const int error = errno;
        if (error == EINTR) continue;
        // EAGAIN: all read. ECONNREFUSED and the like: an earlier datagram
        // to the client bounced (nobody listens there now); UDP goes on.
        return;
      }
      if (!fixed_peer_ && (!client_ || !(*client_ == from))) start_client(from);
      if (!device_.is_open()) continue;  // nobody to forward to: as a lost datagram
      if (to_device_.full()) {
        ++dropped_;
        status_.update_stats([](BridgeStats& s) { ++s.datagrams_dropped; });
        continue;
      }
      to_device_.push(std::string(buffer.data(), static_cast<std::size_t>(n)));
    }
  }

  // The device's queue takes one datagram at a time: a write of the queue
  // would join two datagrams into one.
  void pass_to_device() {
    while (!to_device_.empty() && device_.is_open() && !device_.has_data_for_device()) {
      const std::string datagram = to_device_.take();
      device_.send_datagram(datagram.data(), datagram.size());
    }
  }

  void send_to_client() {
    while (client_ && !to_client_.empty() && socket_ && !holding_ && !probe_sent_) {
      const std::string& datagram = to_client_.front();
      const ssize_t sent =
          sys::sendto(socket_.get(), datagram.data(), datagram.size(),
                      platform::no_sigpipe_send_flags() | MSG_DONTWAIT, client_->get(),
                      client_->length);
      if (sent < 0) {
        const int error = errno;
        if (error == EINTR) continue;
        if (error == EAGAIN || error == EWOULDBLOCK || error == ENOBUFS) return;
        // An earlier datagram bounced; this one was not sent.
        if (fixed_peer_ && error == ECONNREFUSED) {
          const std::uint64_t before = refused_;
          take_refusals();
          if (refused_ == before) peer_refused(error);
          if (awaiting_peer()) return;
          continue;
        }
        // Nobody listens at the client's address (yet): UDP drops it, so
        // do we.
        status_.message(system_error_message("a datagram to " + client_->text() +
                                             " was not sent", error));
      } else if (awaiting_peer()) {
        // Kept until the peer's verdict: refused, it is sent again.
        probe_sent_ = true;
        verdict_at_ = Clock::now() + kPeerVerdict;
        return;
      } else {
        served_device_data_ = true;
      }
      to_client_.pop();
    }
  }

  const BridgeOptions& options_;
  DeviceSide& device_;
  Status& status_;
  sys::UniqueFd socket_;
  int family_ = AF_INET;
  PollSet::Slot slot_ = PollSet::none;
  std::optional<Address> client_;
  std::string client_text_;
  bool fixed_peer_ = false;
  // A fixed peer: whether it has taken a datagram; whether the first one
  // (kept at the front of to_client_) was sent and awaits its verdict, and
  // when that verdict is due; refusals so far; the pause after one.
  bool peer_accepted_ = false;
  bool probe_sent_ = false;
  Clock::time_point verdict_at_{};
  std::uint64_t refused_ = 0;
  bool refusal_reported_ = false;
  bool holding_ = false;
  Clock::time_point retry_at_{};
  DatagramQueue to_device_;
  DatagramQueue to_client_;
  std::uint64_t dropped_ = 0;
  bool served_device_data_ = false;
};

}  // namespace

std::unique_ptr<ClientEndpoint> make_udp_endpoint(const BridgeOptions& options,
                                                  DeviceSide& device, Status& status) {
  return std::make_unique<UdpEndpoint>(options, device, status);
}

}  // namespace wiretape::detail::bridge
