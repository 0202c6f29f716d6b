// The bounds that keep a port server's memory independent of what clients
// do: queues that hold at most their limit.

#include <gtest/gtest.h>

#include <string>

#include "bridge/byte_queue.hpp"

using wiretape::detail::bridge::ByteQueue;
using wiretape::detail::bridge::kChunk;

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
