// Measures one relay between a device and its client (wiretape record
// --pty/--listen/--udp, socat ...) against which the same relay by socat is
// compared. The relay is a separate process started from the command line
// after `--`, in which {device} becomes the device's path, {device_port} the
// device's UDP port, {port} a free port for the relay's client side and
// {link} a path for the relay's own pty. Feeding, reading and timing run on
// native threads of this program, so the figures are the relay's and the
// kernel's, not an interpreter's.
//
//   wiretape_relay_bench tcp|pty BYTES MESSAGES WORKDIR -- COMMAND...
//
// The device is a pseudo-terminal held here. Prints {"bytes_per_s",
// "cpu_s_per_MB" (the relay process's CPU time, all threads, from
// /proc/PID/task/*/schedstat, while the device sent BYTES to the client),
// "one_way_p50_us", "one_way_p99_us" (MESSAGES 64-byte messages, one at a
// time, alternately device to client and client to device, each from its
// write to the read of its last byte; "to_client_p50_us" and
// "to_device_p50_us" each direction alone; "message_cpu_us", the relay's
// CPU time a message), ...}.
//
//   wiretape_relay_bench udp DATAGRAMS_PER_S MILLISECONDS WORKDIR -- COMMAND...
//
// The device is a UDP socket here (with a deep receive queue); the client
// sends 1,200-byte datagrams to the relay, paced at DATAGRAMS_PER_S for
// MILLISECONDS. Prints {"offered", "sent", "received", "lost", "loss_pct",
// "send_rate", "cpu_s", ...}: lost = offered - received at the device.
//
// Errors go to stderr with exit status 1.
#include <arpa/inet.h>
#include <dirent.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <pty.h>
#include <signal.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/uio.h>
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
constexpr std::size_t kDatagram = 1200;
// How long a relay may take to become ready: 15 s, or
// WIRETAPE_RELAY_BENCH_READY_S seconds for a relay run under valgrind, where
// Python's start-up alone takes that long (bench/instruction_counts.py).
std::chrono::seconds ready_deadline_length() {
  const char* given = std::getenv("WIRETAPE_RELAY_BENCH_READY_S");
  return std::chrono::seconds(given && *given ? wb::parse_count(given, "WIRETAPE_RELAY_BENCH_READY_S") : 15);
}
const std::chrono::seconds kReadyDeadline = ready_deadline_length();
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

sockaddr_in loopback(int port) {
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  address.sin_port = htons(static_cast<std::uint16_t>(port));
  return address;
}

// A port of `type` free on 127.0.0.1 a moment ago, for the relay to bind.
int free_port(int type) {
  Fd probe(::socket(AF_INET, type, 0));
  sockaddr_in address = loopback(0);
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

  pid_t pid() const { return pid_; }

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
    const auto deadline = Clock::now() + std::max<std::chrono::seconds>(std::chrono::seconds(10), kReadyDeadline);
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

// CPU time (user + system, all threads) the process `pid` has used so far,
// from /proc/PID/stat in clock ticks (10 ms); negative when it cannot be read.
double cpu_seconds_in_ticks(pid_t pid) {
  std::FILE* file = std::fopen(("/proc/" + std::to_string(pid) + "/stat").c_str(), "r");
  if (!file) return -1.0;
  char text[4096] = {};
  const std::size_t n = std::fread(text, 1, sizeof text - 1, file);
  std::fclose(file);
  text[n] = '\0';
  // Fields after the command name, which is in parentheses and may hold spaces:
  // 3 state ... 14 utime 15 stime (clock ticks).
  const char* rest = std::strrchr(text, ')');
  if (!rest) return -1.0;
  unsigned long long utime = 0, stime = 0;
  if (std::sscanf(rest + 1, " %*c %*d %*d %*d %*d %*d %*u %*u %*u %*u %*u %llu %llu", &utime, &stime) != 2) {
    return -1.0;
  }
  return static_cast<double>(utime + stime) / static_cast<double>(::sysconf(_SC_CLK_TCK));
}

// The same to the nanosecond: the run time of each of its threads, from
// /proc/PID/task/TID/schedstat (a thread that ended meanwhile is missed: the
// relays keep theirs while they run). Falls back to the ticks.
double cpu_seconds(pid_t pid) {
  const std::string tasks = "/proc/" + std::to_string(pid) + "/task";
  DIR* folder = ::opendir(tasks.c_str());
  if (!folder) return cpu_seconds_in_ticks(pid);
  unsigned long long total_ns = 0;
  bool any = false;
  while (const dirent* entry = ::readdir(folder)) {
    if (entry->d_name[0] == '.') continue;
    std::FILE* file = std::fopen((tasks + "/" + entry->d_name + "/schedstat").c_str(), "r");
    if (!file) continue;
    unsigned long long run_ns = 0;
    if (std::fscanf(file, "%llu", &run_ns) == 1) {
      total_ns += run_ns;
      any = true;
    }
    std::fclose(file);
  }
  ::closedir(folder);
  return any ? static_cast<double>(total_ns) / 1e9 : cpu_seconds_in_ticks(pid);
}

// One message's one-way time: written on `from`, its last byte read on `to`.
double one_way_us(int from, int to, const std::string& message) {
  char answer[kMessage];
  const auto begin = Clock::now();
  write_all(from, message.data(), message.size());
  read_exactly(to, answer, message.size(), Clock::now() + std::chrono::seconds(10));
  return std::chrono::duration<double, std::micro>(Clock::now() - begin).count();
}

// pty and tcp: throughput from the device to the client (and the relay's CPU
// time meanwhile), then one-way latency of `messages` 64-byte messages, one
// at a time, alternating direction.
int run_stream(const std::string& kind, std::uint64_t bytes, std::uint64_t messages, const std::string& workdir,
               std::vector<std::string> command) {
  int master_fd = -1, device_fd = -1;
  char device_name[256] = {};
  if (::openpty(&master_fd, &device_fd, device_name, nullptr, nullptr) != 0) fail("openpty");
  Fd master(master_fd), device(device_fd);  // held open so the device never hangs up
  make_raw(device.get());
  const int port = kind == "tcp" ? free_port(SOCK_STREAM) : 0;
  const std::string link = workdir + "/relay-bench-" + std::to_string(::getpid()) + ".pty";
  ::unlink(link.c_str());
  for (auto& word : command) {
    word = substitute(word, "{device}", device_name);
    word = substitute(word, "{port}", std::to_string(port));
    word = substitute(word, "{link}", link);
  }
  Relay relay(command, workdir + "/relay-bench-" + std::to_string(::getpid()) + ".log");
  Fd client = connect_client(kind, port, link, relay);

  // A first message both ways: the relay has its client and its device.
  const std::string message(kMessage, 'p');
  one_way_us(master.get(), client.get(), message);
  one_way_us(client.get(), master.get(), message);

  // Throughput: the device sends `bytes`, the client reads them all.
  std::vector<char> received(kChunk);
  const double cpu_before = cpu_seconds(relay.pid());
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
  const double cpu = cpu_seconds(relay.pid()) - cpu_before;
  feeder.join();

  // One-way latency, each message alone in the relay: device to client, then
  // client to device, and so on.
  std::vector<double> latencies_us;
  std::vector<double> to_client_us;
  std::vector<double> to_device_us;
  latencies_us.reserve(messages);
  const double message_cpu_before = cpu_seconds(relay.pid());
  for (std::uint64_t i = 0; i < messages; ++i) {
    const double us = i % 2 == 0 ? one_way_us(master.get(), client.get(), message)
                                 : one_way_us(client.get(), master.get(), message);
    latencies_us.push_back(us);
    (i % 2 == 0 ? to_client_us : to_device_us).push_back(us);
  }
  const double message_cpu_us =
      messages > 0 ? (cpu_seconds(relay.pid()) - message_cpu_before) * 1e6 / static_cast<double>(messages)
                   : 0.0;
  client.reset();
  relay.stop();
  ::unlink(link.c_str());
  std::printf("{\"bytes\": %llu, \"seconds\": %.6f, \"bytes_per_s\": %.1f, \"cpu_s\": %.3f, "
              "\"cpu_s_per_MB\": %.6f, \"messages\": %llu, \"one_way_p50_us\": %.2f, \"one_way_p99_us\": %.2f, "
              "\"to_client_p50_us\": %.2f, \"to_device_p50_us\": %.2f, \"message_cpu_us\": %.2f}\n",
              static_cast<unsigned long long>(bytes), seconds, static_cast<double>(bytes) / seconds, cpu,
              cpu / (static_cast<double>(bytes) / 1e6), static_cast<unsigned long long>(messages),
              wb::percentile(latencies_us, 0.5), wb::percentile(latencies_us, 0.99),
              wb::percentile(to_client_us, 0.5), wb::percentile(to_device_us, 0.5), message_cpu_us);
  return 0;
}

// udp: the client sends `rate` datagrams of kDatagram bytes a second for
// `milliseconds` to the relay, which forwards them to a device socket here;
// what the device received, and so what was lost on the way.
int run_udp(std::uint64_t rate, std::uint64_t milliseconds, const std::string& workdir,
            std::vector<std::string> command) {
  Fd device(::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0));
  // A deep queue at the device, so that what is lost is lost in the relay.
  const int deep = 64 << 20;
  if (::setsockopt(device.get(), SOL_SOCKET, SO_RCVBUFFORCE, &deep, sizeof deep) != 0) {
    ::setsockopt(device.get(), SOL_SOCKET, SO_RCVBUF, &deep, sizeof deep);
  }
  sockaddr_in device_address = loopback(0);
  if (::bind(device.get(), reinterpret_cast<sockaddr*>(&device_address), sizeof device_address) != 0) fail("bind");
  socklen_t length = sizeof device_address;
  ::getsockname(device.get(), reinterpret_cast<sockaddr*>(&device_address), &length);
  const int port = free_port(SOCK_DGRAM);
  for (auto& word : command) {
    word = substitute(word, "{device_port}", std::to_string(ntohs(device_address.sin_port)));
    word = substitute(word, "{port}", std::to_string(port));
  }

  std::atomic<bool> stopping{false};
  std::atomic<bool> warmed{false};
  std::atomic<std::uint64_t> received{0};
  std::thread sink([&] {
    std::vector<char> buffer(65536);
    while (!stopping.load()) {
      if (!wait_ready(device.get(), POLLIN, Clock::now() + std::chrono::milliseconds(50))) continue;
      const ssize_t n = ::recv(device.get(), buffer.data(), buffer.size(), MSG_DONTWAIT);
      if (n <= 0) continue;
      if (buffer[0] == 'W') {
        warmed = true;
      } else if (n == static_cast<ssize_t>(kDatagram)) {
        received.fetch_add(1);
      }
    }
  });
  struct JoinSink {
    std::atomic<bool>& stopping;
    std::thread& sink;
    ~JoinSink() {
      stopping = true;
      sink.join();
    }
  } join_sink{stopping, sink};

  Relay relay(command, workdir + "/relay-bench-" + std::to_string(::getpid()) + ".log");
  Fd client(::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0));
  sockaddr_in relay_address = loopback(port);
  if (::connect(client.get(), reinterpret_cast<sockaddr*>(&relay_address), sizeof relay_address) != 0) {
    fail("connect");
  }
  // Warm-up: a datagram every 20 ms until one reaches the device.
  const auto ready_deadline = Clock::now() + kReadyDeadline;
  while (!warmed.load()) {
    if (!relay.running()) {
      errno = 0;
      fail("the relay exited before it was ready:\n" + relay.log());
    }
    if (Clock::now() > ready_deadline) {
      errno = 0;
      fail("no datagram reached the device through the relay in " + std::to_string(kReadyDeadline.count()) +
           " s:\n" + relay.log());
    }
    ::send(client.get(), "W", 1, 0);
    std::this_thread::sleep_for(std::chrono::milliseconds(20));  // polling another process's readiness
  }

  // The flood, paced by the clock: by time t, rate * t datagrams are sent.
  const std::uint64_t total = rate * milliseconds / 1000;
  constexpr std::size_t kBatch = 32;
  std::vector<std::string> payloads(kBatch, std::string(kDatagram, 'F'));
  std::vector<iovec> vectors(kBatch);
  std::vector<mmsghdr> headers(kBatch);
  for (std::size_t i = 0; i < kBatch; ++i) {
    vectors[i] = {payloads[i].data(), kDatagram};
    headers[i] = {};
    headers[i].msg_hdr.msg_iov = &vectors[i];
    headers[i].msg_hdr.msg_iovlen = 1;
  }
  const double cpu_before = cpu_seconds(relay.pid());
  std::uint64_t sent = 0, refused = 0;
  const auto start = Clock::now();
  while (sent + refused < total) {
    const double elapsed = wb::seconds_since(start);
    const auto due = std::min<std::uint64_t>(total, static_cast<std::uint64_t>(elapsed * static_cast<double>(rate)));
    if (sent + refused >= due) {
      std::this_thread::sleep_for(std::chrono::microseconds(100));  // pacing the sender
      continue;
    }
    const auto batch = static_cast<unsigned>(std::min<std::uint64_t>(kBatch, due - sent - refused));
    const int n = ::sendmmsg(client.get(), headers.data(), batch, 0);
    if (n > 0) {
      sent += static_cast<std::uint64_t>(n);
    } else if (errno == ENOBUFS || errno == EAGAIN || errno == ECONNREFUSED) {
      refused += 1;  // the relay's socket is gone or full: lost all the same
    } else if (errno != EINTR) {
      fail("sendmmsg");
    }
  }
  const double seconds = wb::seconds_since(start);
  // Drained: nothing more arrives for 500 ms.
  std::uint64_t seen = received.load();
  for (auto quiet_since = Clock::now(); Clock::now() - quiet_since < std::chrono::milliseconds(500);) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));  // waiting for the relay to drain
    if (received.load() != seen) {
      seen = received.load();
      quiet_since = Clock::now();
    }
  }
  const double cpu = cpu_seconds(relay.pid()) - cpu_before;
  relay.stop();
  const std::uint64_t got = received.load();
  const std::uint64_t offered = sent + refused;
  std::printf("{\"datagram_bytes\": %zu, \"offered\": %llu, \"sent\": %llu, \"received\": %llu, \"lost\": %llu, "
              "\"loss_pct\": %.4f, \"seconds\": %.6f, \"send_rate\": %.1f, \"cpu_s\": %.3f}\n",
              kDatagram, static_cast<unsigned long long>(offered), static_cast<unsigned long long>(sent),
              static_cast<unsigned long long>(got), static_cast<unsigned long long>(offered - got),
              100.0 * static_cast<double>(offered - got) / static_cast<double>(offered), seconds,
              static_cast<double>(offered) / seconds, cpu);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  const std::string kind = argc > 1 ? argv[1] : "";
  if (argc < 7 || std::string(argv[5]) != "--" || (kind != "tcp" && kind != "pty" && kind != "udp")) {
    std::cerr << "usage: wiretape_relay_bench tcp|pty BYTES MESSAGES WORKDIR -- COMMAND...\n"
                 "       wiretape_relay_bench udp DATAGRAMS_PER_S MILLISECONDS WORKDIR -- COMMAND...\n";
    return 2;
  }
  ::signal(SIGPIPE, SIG_IGN);
  try {
    std::vector<std::string> command(argv + 6, argv + argc);
    if (kind == "udp") {
      return run_udp(wb::parse_count(argv[2], "DATAGRAMS_PER_S"), wb::parse_count(argv[3], "MILLISECONDS"), argv[4],
                     std::move(command));
    }
    return run_stream(kind, wb::parse_count(argv[2], "BYTES"), wb::parse_count(argv[3], "MESSAGES"), argv[4],
                      std::move(command));
  } catch (const std::exception& error) {
    std::cerr << "wiretape_relay_bench: " << error.what() << "\n";
    return 1;
  }
}
