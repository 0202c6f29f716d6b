// The bounds that keep a port server's memory and CPU independent of what
// clients do: queues that hold at most their limit, and a listener that
// rests instead of spinning when it cannot accept (out of descriptors).
#include <fcntl.h>
#include <poll.h>
#include <sys/socket.h>
#include <termios.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <string>
#include <thread>

#include "bridge/byte_queue.hpp"
#include "posix/syscalls.hpp"
#include "support/port_test_support.hpp"
#include "wiretape/bridge.hpp"

namespace sys = wiretape::detail::sys;
using wiretape::detail::bridge::ByteQueue;
using wiretape::detail::bridge::kChunk;

namespace {

std::size_t count_messages(const wiretape::Bridge& bridge, const std::string& part) {
  const auto messages = bridge.messages();
  return static_cast<std::size_t>(std::count_if(
      messages.begin(), messages.end(),
      [&](const std::string& m) { return m.find(part) != std::string::npos; }));
}

template <typename Condition>
bool wait_for(Condition condition) {
  const auto end = std::chrono::steady_clock::now() + wiretape::test::kEventDeadline;
  while (!condition()) {
    if (std::chrono::steady_clock::now() > end) return false;
    ::poll(nullptr, 0, 5);
  }
  return true;
}

}  // namespace

TEST(ByteQueue, HoldsAboutItsLimitNotTwice) {
  constexpr std::size_t limit = 1 << 20;
  ByteQueue queue(limit);
  const std::string chunk(kChunk / 4 + 123, 'x');
  while (!queue.full()) queue.append(chunk);
  // One append may overshoot; the memory follows the limit (a std::string
  // that doubles would hold 2 MiB here).
  EXPECT_LT(queue.size(), limit + chunk.size());
  EXPECT_LE(queue.capacity(), limit + chunk.size());
  EXPECT_EQ(queue.room(), 0u);
}

TEST(ByteQueue, ReusesTheConsumedFrontBeforeGrowing) {
  constexpr std::size_t limit = 256 * 1024;
  ByteQueue queue(limit);
  const std::string chunk(1000, 'y');
  // A queue that is written out as it fills, in steps that never empty it.
  for (int round = 0; round < 10'000; ++round) {
    while (queue.room() >= chunk.size()) queue.append(chunk);
    queue.consume(chunk.size() * 3 / 2);
  }
  EXPECT_LE(queue.capacity(), limit + chunk.size());
  EXPECT_EQ(std::string(queue.data(), 10), std::string(10, 'y'));
}

TEST(BridgeBounds, OutOfDescriptorsTheListenerRestsAndResumes) {
  std::atomic<bool> out_of_descriptors{true};
  std::atomic<int> failed_accepts{0};
  sys::ScopedOverride seam;
  seam->accept4 = [&](int fd, sockaddr* address, socklen_t* length, int flags) {
    if (out_of_descriptors.load()) {
      ++failed_accepts;
      errno = EMFILE;
      return -1;
    }
    return sys::real().accept4(fd, address, length, flags);
  };

  wiretape::BridgeOptions options;
  options.device = "type=loopback";
  options.client_side = wiretape::BridgeClientSide::tcp;
  options.shared = true;
  options.quiet = true;
  wiretape::Bridge bridge(options);
  bridge.start();
  const int client = wiretape::test::connect_tcp(bridge.listen_address());
  ASSERT_GE(client, 0);
  ASSERT_TRUE(wait_for([&] { return count_messages(bridge, "cannot accept clients") > 0; }));

  // A spinning loop retries accept() thousands of times a second; a resting
  // one a few times (the rest doubles from 50 ms to 1 s).
  const int before = failed_accepts.load();
  ::poll(nullptr, 0, 500);  // the measurement window
  EXPECT_LT(failed_accepts.load() - before, 20);
  EXPECT_EQ(count_messages(bridge, "cannot accept clients"), 1u);

  // Descriptors free again: the waiting client is accepted and served.
  out_of_descriptors.store(false);
  const std::string message = "served after the shortage\n";
  ASSERT_EQ(::write(client, message.data(), message.size()),
            static_cast<ssize_t>(message.size()));
  EXPECT_EQ(wiretape::test::read_count(client, message.size()), message);
  EXPECT_EQ(count_messages(bridge, "accepting clients again"), 1u);
  ::close(client);
  bridge.stop();
  ASSERT_TRUE(bridge.wait(std::chrono::seconds(10)));
  EXPECT_EQ(bridge.result().stats.clients_accepted, 1u);
}

TEST(BridgeBounds, ARefusedClientThatSpokeFirstReadsTheRefusalNotAReset) {
  // The second connection is accepted only after its client has sent
  // something: closing a socket with unread input resets the connection,
  // and the reset would discard the refusal message.
  std::atomic<bool> hold_accepts{false};
  wiretape::test::Event release;
  sys::ScopedOverride seam;
  seam->accept4 = [&](int fd, sockaddr* address, socklen_t* length, int flags) {
    if (hold_accepts.load()) release.wait();
    return sys::real().accept4(fd, address, length, flags);
  };

  wiretape::BridgeOptions options;
  options.device = "type=loopback";
  options.client_side = wiretape::BridgeClientSide::tcp;
  options.quiet = true;
  wiretape::Bridge bridge(options);
  bridge.start();
  const int control = wiretape::test::connect_tcp(bridge.listen_address());
  ASSERT_GE(control, 0);
  ASSERT_TRUE(wait_for([&] { return bridge.stats().clients_accepted == 1; }));

  hold_accepts.store(true);
  const int refused = wiretape::test::connect_tcp(bridge.listen_address());
  ASSERT_GE(refused, 0);
  const std::string greeting = "a driver talks first\n";
  ASSERT_EQ(::write(refused, greeting.data(), greeting.size()),
            static_cast<ssize_t>(greeting.size()));
  release.set();

  std::string received;
  int error = 0;
  for (;;) {
    ASSERT_TRUE(wiretape::test::fd_readable(refused, wiretape::test::kEventDeadline));
    char buffer[512];
    const ssize_t n = ::read(refused, buffer, sizeof buffer);
    if (n < 0) error = errno;
    if (n <= 0) break;
    received.append(buffer, static_cast<std::size_t>(n));
  }
  EXPECT_EQ(error, 0) << "the refused client saw its connection reset";
  EXPECT_NE(received.find("in use by another client"), std::string::npos) << received;
  ::close(refused);
  ::close(control);
  bridge.stop();
  ASSERT_TRUE(bridge.wait(std::chrono::seconds(10)));
  EXPECT_EQ(bridge.result().stats.clients_refused, 1u);
}

// Data is written from the reader's buffer while nothing waits before it,
// and only the rest is queued: a terminal or a connection that takes a
// little at a time, or nothing (EAGAIN), while the other side keeps sending
// and the queue fills, gets every byte once and in order.
namespace {

std::string numbered_bytes(std::size_t size) {
  std::string payload;
  payload.reserve(size);
  for (std::size_t i = 0; i < size; ++i) payload.push_back(static_cast<char>(i % 251));
  return payload;
}

// Every third call takes nothing (EAGAIN), the others at most 700 bytes.
template <typename Call>
ssize_t short_or_refused(std::atomic<int>& calls, std::size_t size, Call call) {
  if (++calls % 3 == 0) {
    errno = EAGAIN;
    return -1;
  }
  return call(std::min<std::size_t>(size, 700));
}

// Each write of more than a few bytes to a terminal (the relay's data, not
// its 1-byte wake-ups) is short or refused.
void make_terminal_writes_short(sys::ScopedOverride& seam, std::atomic<int>& short_writes) {
  seam->write = [&short_writes](int fd, const void* data, size_t size) -> ssize_t {
    if (size <= 64 || !::isatty(fd)) return sys::real().write(fd, data, size);
    return short_or_refused(short_writes, size,
                            [&](std::size_t n) { return sys::real().write(fd, data, n); });
  };
}

void make_raw(int fd) {
  termios settings{};
  ASSERT_EQ(::tcgetattr(fd, &settings), 0);
  ::cfmakeraw(&settings);
  ASSERT_EQ(::tcsetattr(fd, TCSANOW, &settings), 0);
}

// A bridge of the pty pair's terminal with the smallest queue: it fills at once.
wiretape::BridgeOptions smallest_queue_options(const wiretape::test::PtyPair& device,
                                               wiretape::BridgeClientSide client_side) {
  wiretape::BridgeOptions options;
  options.device = "type=serial,device=" + device.path;
  options.client_side = client_side;
  options.buffer_limit = kChunk;
  options.quiet = true;
  return options;
}

// What the device sends in the batching tests: several times the queue.
constexpr std::size_t kDevicePayloadSize = 512 * 1024;

// kDevicePayloadSize numbered bytes written at the device's master arrive at
// `reader` (the bridge's `reader_name`) whole and in order.
void expect_device_bytes_arrive_whole(wiretape::test::PtyPair& device, int reader,
                                      const char* reader_name) {
  const std::string payload = numbered_bytes(kDevicePayloadSize);
  std::thread feeder([&] { device.write_master(payload); });
  const std::string received = wiretape::test::read_count(reader, payload.size());
  feeder.join();
  EXPECT_EQ(received.size(), payload.size());
  EXPECT_TRUE(received == payload) << "the " << reader_name << "'s bytes differ from the device's";
}

void expect_clean_stop(wiretape::Bridge& bridge) {
  bridge.stop();
  ASSERT_TRUE(bridge.wait(std::chrono::seconds(10)));
  EXPECT_TRUE(bridge.result().ok()) << bridge.result().message;
}

}  // namespace

TEST(BridgeBatching, ShortAndRefusedWritesToTheTerminalLoseNoDeviceByte) {
  std::atomic<int> short_writes{0};
  sys::ScopedOverride seam;
  make_terminal_writes_short(seam, short_writes);
  wiretape::test::PtyPair device;
  make_raw(device.terminal);
  wiretape::Bridge bridge(smallest_queue_options(device, wiretape::BridgeClientSide::pty));
  bridge.start();
  const int terminal = ::open(bridge.pty_path().c_str(), O_RDWR | O_NOCTTY | O_CLOEXEC);
  ASSERT_GE(terminal, 0);
  make_raw(terminal);
  expect_device_bytes_arrive_whole(device, terminal, "terminal");
  EXPECT_GT(short_writes.load(), 100);
  ::close(terminal);
  expect_clean_stop(bridge);
}

TEST(BridgeBatching, ShortAndRefusedWritesToTheDeviceLoseNoClientByte) {
  std::atomic<int> short_writes{0};
  sys::ScopedOverride seam;
  make_terminal_writes_short(seam, short_writes);
  wiretape::test::PtyPair device;
  make_raw(device.terminal);
  wiretape::Bridge bridge(smallest_queue_options(device, wiretape::BridgeClientSide::tcp));
  bridge.start();
  const int client = wiretape::test::connect_tcp(bridge.listen_address());
  ASSERT_GE(client, 0);
  const std::string payload = numbered_bytes(256 * 1024);
  std::thread sender([&] {
    std::size_t sent = 0;
    while (sent < payload.size()) {
      const ssize_t n = ::send(client, payload.data() + sent, payload.size() - sent, MSG_NOSIGNAL);
      if (n <= 0) return;
      sent += static_cast<std::size_t>(n);
    }
  });
  const std::string received = device.read_master(payload.size());
  sender.join();
  EXPECT_EQ(received.size(), payload.size());
  EXPECT_TRUE(received == payload) << "the device's bytes differ from the client's";
  EXPECT_GT(short_writes.load(), 100);
  ::close(client);
  expect_clean_stop(bridge);
}

TEST(BridgeBatching, ShortAndRefusedSendsToAClientLoseNoDeviceByte) {
  std::atomic<int> short_sends{0};
  sys::ScopedOverride seam;
  seam->send = [&short_sends](int fd, const void* data, size_t size, int flags) -> ssize_t {
    return short_or_refused(short_sends, size,
                            [&](std::size_t n) { return sys::real().send(fd, data, n, flags); });
  };
  wiretape::test::PtyPair device;
  make_raw(device.terminal);
  wiretape::Bridge bridge(smallest_queue_options(device, wiretape::BridgeClientSide::tcp));
  bridge.start();
  const int client = wiretape::test::connect_tcp(bridge.listen_address());
  ASSERT_GE(client, 0);
  expect_device_bytes_arrive_whole(device, client, "client");
  ::close(client);
  expect_clean_stop(bridge);
}

// The device is read once per wake-up: reads that come back short or with
// EAGAIN although poll() said readable lose nothing and keep the order.
TEST(BridgeBatching, ShortAndEmptyReadsOfTheDeviceLoseNoByte) {
  std::atomic<int> odd_reads{0};
  sys::ScopedOverride seam;
  seam->read = [&odd_reads](int fd, void* buffer, size_t size) -> ssize_t {
    if (size <= 64 || !::isatty(fd)) return sys::real().read(fd, buffer, size);
    return short_or_refused(odd_reads, size,
                            [&](std::size_t n) { return sys::real().read(fd, buffer, n); });
  };
  wiretape::test::PtyPair device;
  make_raw(device.terminal);
  wiretape::Bridge bridge(smallest_queue_options(device, wiretape::BridgeClientSide::tcp));
  bridge.start();
  const int client = wiretape::test::connect_tcp(bridge.listen_address());
  ASSERT_GE(client, 0);
  expect_device_bytes_arrive_whole(device, client, "client");
  EXPECT_GT(odd_reads.load(), 100);
  ::close(client);
  expect_clean_stop(bridge);
  EXPECT_EQ(bridge.result().stats.bytes_from_device, kDevicePayloadSize);
}
