// The bounds that keep a port server's memory and CPU independent of what
// clients do: queues that hold at most their limit, and a listener that
// rests instead of spinning when it cannot accept (out of descriptors).
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <string>

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
