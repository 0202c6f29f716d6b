// Fixtures shared by the benchmark programs: synthetic sessions, loopback TCP
// peers (a sink and an echo server) and process figures (peak RSS).
#pragma once

#include <arpa/inet.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <string>
#include <system_error>
#include <thread>
#include <vector>

#include "wiretape/session.hpp"

namespace wiretape::bench {

using Clock = std::chrono::steady_clock;

inline double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

// Peak resident set size of this program so far, in MiB. VmHWM belongs to
// the address space, which execve() replaced; getrusage's ru_maxrss would
// carry over the peak of the process that started us.
inline double peak_rss_mib() {
  if (std::FILE* status = std::fopen("/proc/self/status", "r")) {
    char line[256];
    long kib = -1;
    while (std::fgets(line, sizeof line, status)) {
      if (std::sscanf(line, "VmHWM: %ld kB", &kib) == 1) break;
    }
    std::fclose(status);
    if (kib >= 0) return static_cast<double>(kib) / 1024.0;
  }
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return static_cast<double>(usage.ru_maxrss) / 1024.0;  // KiB, Linux
}

// A session of `total_bytes` of device output cut into rx records of
// `record_bytes` each, 1 µs apart, with no writes: what timing=none replay
// throughput is measured on.
inline void write_rx_session(const std::string& path, std::uint64_t total_bytes,
                             std::size_t record_bytes = 4096) {
  SessionHeader header;
  header.port_type = "serial";
  header.port_options = "type=serial,device=/dev/bench";
  header.user_metadata["purpose"] = "benchmark";
  SessionWriter writer(path, header);
  std::string payload(record_bytes, '\0');
  for (std::size_t i = 0; i < payload.size(); ++i) {
    payload[i] = static_cast<char>('A' + i % 26);
  }
  writer.write(RecordKind::open, 0, "{}");
  std::uint64_t written = 0;
  std::uint64_t t_ns = 1000;
  while (written < total_bytes) {
    const auto size = static_cast<std::size_t>(
        std::min<std::uint64_t>(record_bytes, total_bytes - written));
    writer.write(RecordKind::rx, t_ns, std::string_view(payload.data(), size));
    written += size;
    t_ns += 1000;
  }
  writer.close();
}

// A listening socket on 127.0.0.1 with an ephemeral port, accepting one
// client; the derived servers run on a thread.
class LoopbackServer {
 public:
  LoopbackServer() {
    listener_ = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (listener_ < 0) throw std::system_error(errno, std::generic_category(), "socket");
    sockaddr_in address{};
    address.sin_family = AF_INET;
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (::bind(listener_, reinterpret_cast<sockaddr*>(&address), sizeof address) != 0 ||
        ::listen(listener_, 4) != 0) {
      throw std::system_error(errno, std::generic_category(), "bind/listen");
    }
    socklen_t length = sizeof address;
    ::getsockname(listener_, reinterpret_cast<sockaddr*>(&address), &length);
    port_ = ntohs(address.sin_port);
  }
  virtual ~LoopbackServer() {
    // Wakes an accept() still waiting when the client never came.
    ::shutdown(listener_, SHUT_RDWR);
    if (thread_.joinable()) thread_.join();
    ::close(listener_);
  }
  LoopbackServer(const LoopbackServer&) = delete;
  LoopbackServer& operator=(const LoopbackServer&) = delete;

  int port() const { return port_; }
  std::string client_options() const {
    return "type=tcp,host=127.0.0.1,port=" + std::to_string(port_) + ",timeout=30";
  }

 protected:
  // Accepts one client and runs `serve(fd)` on a thread.
  template <typename Serve>
  void start(Serve serve) {
    thread_ = std::thread([this, serve] {
      const int client = ::accept4(listener_, nullptr, nullptr, SOCK_CLOEXEC);
      if (client < 0) return;
      const int one = 1;
      ::setsockopt(client, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
      serve(client);
      ::close(client);
    });
  }

 private:
  int listener_ = -1;
  int port_ = 0;
  std::thread thread_;
};

// Reads and discards until the client closes; counts the bytes.
class TcpSink : public LoopbackServer {
 public:
  TcpSink() {
    start([this](int fd) {
      std::vector<char> buffer(1 << 20);
      for (;;) {
        const ssize_t got = ::read(fd, buffer.data(), buffer.size());
        if (got > 0) {
          received_ += static_cast<std::uint64_t>(got);
        } else if (got == 0 || errno != EINTR) {
          break;
        }
      }
    });
  }
  ~TcpSink() override = default;
  std::uint64_t received() const { return received_; }

 private:
  std::atomic<std::uint64_t> received_{0};
};

// Sends back whatever arrives, until the client closes.
class TcpEcho : public LoopbackServer {
 public:
  TcpEcho() {
    start([](int fd) {
      std::vector<char> buffer(65536);
      for (;;) {
        const ssize_t got = ::read(fd, buffer.data(), buffer.size());
        if (got <= 0) {
          if (got < 0 && errno == EINTR) continue;
          break;
        }
        ssize_t sent = 0;
        while (sent < got) {
          const ssize_t n = ::write(fd, buffer.data() + sent, static_cast<std::size_t>(got - sent));
          if (n < 0) {
            if (errno == EINTR) continue;
            return;
          }
          sent += n;
        }
      }
    });
  }
  ~TcpEcho() override = default;
};

// A positive integer from the command line, or an error naming `what`.
inline std::uint64_t parse_count(const char* text, const char* what) {
  char* end = nullptr;
  const unsigned long long value = std::strtoull(text, &end, 10);
  if (end == text || *end != '\0' || value == 0) {
    throw std::invalid_argument(std::string(what) + ": expected a positive integer, got '" + text + "'");
  }
  return value;
}

inline double percentile(std::vector<double> values, double fraction) {
  if (values.empty()) return 0.0;
  std::sort(values.begin(), values.end());
  const auto index = static_cast<std::size_t>(fraction * static_cast<double>(values.size() - 1) + 0.5);
  return values[std::min(index, values.size() - 1)];
}

}  // namespace wiretape::bench
