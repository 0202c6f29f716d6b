// Measures one relay between a serial device and its clients (wiretape
// serve, wiretape record --pty, socat ...): throughput from the device to the
// client and the round-trip time of a 64-byte message through the relay to a
// device that echoes. The device is a pseudo-terminal held here; the relay is
// a separate process started from the command line after `--`, in which
// {device} becomes the device's path, {port} a free TCP port and {link} a
// path for the relay's own pty. Feeding, reading and echoing run on native
// threads of this program, so the figures are the relay's and the kernel's,
// not an interpreter's.
//
//   wiretape_relay_bench tcp|pty BYTES ROUNDTRIPS WORKDIR -- COMMAND...
//
// prints {"bytes_per_s": ..., "rtt_median_us": ..., "rtt_p90_us": ...}.
// Errors go to stderr with exit status 1.
#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <pty.h>
#include <signal.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <termios.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "bench_support.hpp"

extern char** environ;

namespace {

namespace wb = wiretape::bench;
using wb::Clock;

constexpr std::size_t kChunk = 64 * 1024;
constexpr std::size_t kMessage = 64;
constexpr auto kReadyDeadline = std::chrono::seconds(15);
constexpr auto kTransferDeadline = std::chrono::seconds(120);

[[noreturn]] void fail(const std::string& what) {
  throw std::runtime_error(what + (errno ? std::string(": ") + std::strerror(errno) : std::string()));
}

class Fd {
 public:
  Fd() = default;
  explicit Fd(int fd) : fd_(fd) {}
  Fd(Fd&& other) noexcept : fd_(other.release()) {}
  Fd& operator=(Fd&& other) noexcept {
    reset(other.release());
    return *this;
  }
  ~Fd() { reset(); }
  int get() const { return fd_; }
  int release() { return std::exchange(fd_, -1); }
  void reset(int fd = -1) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = fd;
  }

 private:
  int fd_ = -1;
};

void make_raw(int fd) {
  termios settings{};
  if (::tcgetattr(fd, &settings) != 0) fail("tcgetattr");
  ::cfmakeraw(&settings);
  if (::tcsetattr(fd, TCSANOW, &settings) != 0) fail("tcsetattr");
}

// Waits until `fd` is ready for `events` or the deadline passes.
bool wait_ready(int fd, short events, Clock::time_point deadline) {
  for (;;) {
    const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now());
    if (left.count() <= 0) return false;
    pollfd entry{fd, events, 0};
    const int ready = ::poll(&entry, 1, static_cast<int>(left.count()));
    if (ready > 0) return true;
    if (ready < 0 && errno != EINTR) fail("poll");
  }
}

void write_all(int fd, const char* data, std::size_t size) {
  while (size > 0) {
    const ssize_t n = ::write(fd, data, size);
    if (n < 0) {
      if (errno == EINTR) continue;
      if (errno == EAGAIN) {
        if (!wait_ready(fd, POLLOUT, Clock::now() + kTransferDeadline)) fail("write: the relay stopped taking data");
        continue;
      }
      fail("write");
    }
    data += n;
    size -= static_cast<std::size_t>(n);
  }
}

void read_exactly(int fd, char* data, std::size_t size, Clock::time_point deadline) {
  std::size_t got = 0;
  while (got < size) {
    if (!wait_ready(fd, POLLIN, deadline)) {
      errno = 0;
      fail("the relay delivered " + std::to_string(got) + " of " + std::to_string(size) + " bytes in time");
    }
    const ssize_t n = ::read(fd, data + got, size - got);
    if (n == 0) {
      errno = 0;
      fail("the relay closed after " + std::to_string(got) + " of " + std::to_string(size) + " bytes");
    }
    if (n < 0) {
      if (errno == EINTR || errno == EAGAIN) continue;
      fail("read");
    }
    got += static_cast<std::size_t>(n);
  }
}

int free_tcp_port() {
  Fd probe(::socket(AF_INET, SOCK_STREAM, 0));
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (::bind(probe.get(), reinterpret_cast<sockaddr*>(&address), sizeof address) != 0) fail("bind");
  socklen_t length = sizeof address;
  ::getsockname(probe.get(), reinterpret_cast<sockaddr*>(&address), &length);
  return ntohs(address.sin_port);
}

Fd try_connect(int port) {
  Fd fd(::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0));
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  address.sin_port = htons(static_cast<std::uint16_t>(port));
  if (::connect(fd.get(), reinterpret_cast<sockaddr*>(&address), sizeof address) != 0) return Fd();
  const int one = 1;
  ::setsockopt(fd.get(), IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
  return fd;
}

std::string substitute(std::string text, const std::string& key, const std::string& value) {
  for (std::size_t at = text.find(key); at != std::string::npos; at = text.find(key, at + value.size())) {
    text.replace(at, key.size(), value);
  }
  return text;
}

// The relay process: started with its output in WORKDIR/relay.log, stopped
// with SIGINT (as a user would) and reaped.
class Relay {
 public:
  Relay(const std::vector<std::string>& command, const std::string& log_path) : log_path_(log_path) {
    std::vector<char*> argv;
    for (const auto& word : command) argv.push_back(const_cast<char*>(word.c_str()));
    argv.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, 1, log_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_adddup2(&actions, 1, 2);
    const int status = ::posix_spawnp(&pid_, argv[0], &actions, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&actions);
    if (status != 0) {
      errno = status;
      fail("cannot start " + command[0]);
    }
  }
  ~Relay() { stop(); }

  bool running() {
    if (pid_ <= 0) return false;
    int status = 0;
    if (::waitpid(pid_, &status, WNOHANG) == pid_) {
      pid_ = -1;
      return false;
    }
    return true;
  }

  std::string log() const {
    std::string text;
    if (std::FILE* file = std::fopen(log_path_.c_str(), "r")) {
      char buffer[4096];
      std::size_t n = 0;
      while ((n = std::fread(buffer, 1, sizeof buffer, file)) > 0) text.append(buffer, n);
      std::fclose(file);
    }
    return text;
  }

  void stop() {
    if (pid_ <= 0) return;
    ::kill(pid_, SIGINT);
    const auto deadline = Clock::now() + std::chrono::seconds(10);
    int status = 0;
    while (::waitpid(pid_, &status, WNOHANG) == 0) {
      if (Clock::now() > deadline) {
        ::kill(pid_, SIGKILL);
        ::waitpid(pid_, &status, 0);
        break;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(5));  // reaping another process
    }
    pid_ = -1;
  }

 private:
  pid_t pid_ = -1;
  std::string log_path_;
};

// Connects to the relay's client side once it is ready.
Fd connect_client(const std::string& kind, int port, const std::string& link, Relay& relay) {
  const auto deadline = Clock::now() + kReadyDeadline;
  while (Clock::now() < deadline) {
    if (!relay.running()) {
      errno = 0;
      fail("the relay exited before it was ready:\n" + relay.log());
    }
    if (kind == "tcp") {
      Fd fd = try_connect(port);
      if (fd.get() >= 0) return fd;
    } else {
      struct stat info {};
      if (::stat(link.c_str(), &info) == 0) {
        Fd fd(::open(link.c_str(), O_RDWR | O_NOCTTY | O_CLOEXEC));
        if (fd.get() < 0) fail("open " + link);
        make_raw(fd.get());
        return fd;
      }
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(10));  // polling another process's readiness
  }
  errno = 0;
  fail("the relay was not ready after 15 s:\n" + relay.log());
}

int run(const std::string& kind, std::uint64_t bytes, std::uint64_t roundtrips, const std::string& workdir,
        std::vector<std::string> command) {
  int master_fd = -1, device_fd = -1;
  char device_name[256] = {};
  if (::openpty(&master_fd, &device_fd, device_name, nullptr, nullptr) != 0) fail("openpty");
  Fd master(master_fd), device(device_fd);  // held open so the device never hangs up
  make_raw(device.get());
  const int port = kind == "tcp" ? free_tcp_port() : 0;
  const std::string link = workdir + "/relay-bench-" + std::to_string(::getpid()) + ".pty";
  ::unlink(link.c_str());
  for (auto& word : command) {
    word = substitute(word, "{device}", device_name);
    word = substitute(word, "{port}", std::to_string(port));
    word = substitute(word, "{link}", link);
  }
  Relay relay(command, workdir + "/relay-bench-" + std::to_string(::getpid()) + ".log");
  Fd client = connect_client(kind, port, link, relay);

  // Throughput: the device sends `bytes`, the client reads them all.
  std::vector<char> received(kChunk);
  const auto start = Clock::now();
  std::thread feeder([&] {
    std::vector<char> block(kChunk);
    for (std::size_t i = 0; i < block.size(); ++i) block[i] = static_cast<char>(i);
    std::uint64_t sent = 0;
    try {
      while (sent < bytes) {
        const std::size_t n = static_cast<std::size_t>(std::min<std::uint64_t>(kChunk, bytes - sent));
        write_all(master.get(), block.data(), n);
        sent += n;
      }
    } catch (const std::exception&) {
      // The reader reports the shortfall.
    }
  });
  std::uint64_t got = 0;
  const auto transfer_deadline = start + kTransferDeadline;
  try {
    while (got < bytes) {
      const std::size_t want = static_cast<std::size_t>(std::min<std::uint64_t>(kChunk, bytes - got));
      if (!wait_ready(client.get(), POLLIN, transfer_deadline)) {
        errno = 0;
        fail("the relay delivered " + std::to_string(got) + " of " + std::to_string(bytes) + " bytes in 120 s");
      }
      const ssize_t n = ::read(client.get(), received.data(), want);
      if (n == 0) {
        errno = 0;
        fail("the relay closed after " + std::to_string(got) + " bytes");
      }
      if (n < 0) {
        if (errno == EINTR || errno == EAGAIN) continue;
        fail("read from the relay");
      }
      got += static_cast<std::uint64_t>(n);
    }
  } catch (...) {
    relay.stop();  // unblocks the feeder
    master.reset();
    feeder.join();
    throw;
  }
  const double seconds = wb::seconds_since(start);
  feeder.join();

  // Round trips: the device echoes what it is sent.
  std::atomic<bool> stopping{false};
  std::thread echo([&] {
    std::vector<char> buffer(kChunk);
    while (!stopping.load()) {
      if (!wait_ready(master.get(), POLLIN, Clock::now() + std::chrono::milliseconds(100))) continue;
      const ssize_t n = ::read(master.get(), buffer.data(), buffer.size());
      if (n <= 0) {
        if (n < 0 && (errno == EINTR || errno == EAGAIN)) continue;
        return;
      }
      try {
        write_all(master.get(), buffer.data(), static_cast<std::size_t>(n));
      } catch (const std::exception&) {
        return;
      }
    }
  });
  std::vector<double> rtts_us;
  rtts_us.reserve(roundtrips);
  const std::string message(kMessage, 'p');
  char answer[kMessage];
  try {
    for (std::uint64_t i = 0; i < roundtrips; ++i) {
      const auto begin = Clock::now();
      write_all(client.get(), message.data(), message.size());
      read_exactly(client.get(), answer, sizeof answer, Clock::now() + std::chrono::seconds(10));
      rtts_us.push_back(std::chrono::duration<double, std::micro>(Clock::now() - begin).count());
    }
  } catch (...) {
    stopping = true;
    echo.join();
    throw;
  }
  stopping = true;
  echo.join();
  client.reset();
  relay.stop();
  ::unlink(link.c_str());
  std::printf("{\"bytes\": %llu, \"seconds\": %.6f, \"bytes_per_s\": %.1f, \"roundtrips\": %llu, "
              "\"rtt_median_us\": %.2f, \"rtt_p90_us\": %.2f}\n",
              static_cast<unsigned long long>(bytes), seconds, static_cast<double>(bytes) / seconds,
              static_cast<unsigned long long>(roundtrips), wb::percentile(rtts_us, 0.5),
              wb::percentile(rtts_us, 0.9));
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 7 || std::string(argv[5]) != "--" ||
      (std::string(argv[1]) != "tcp" && std::string(argv[1]) != "pty")) {
    std::cerr << "usage: wiretape_relay_bench tcp|pty BYTES ROUNDTRIPS WORKDIR -- COMMAND...\n";
    return 2;
  }
  ::signal(SIGPIPE, SIG_IGN);
  try {
    return run(argv[1], wb::parse_count(argv[2], "BYTES"), wb::parse_count(argv[3], "ROUNDTRIPS"), argv[4],
               std::vector<std::string>(argv + 6, argv + argc));
  } catch (const std::exception& error) {
    std::cerr << "wiretape_relay_bench: " << error.what() << "\n";
    return 1;
  }
}
