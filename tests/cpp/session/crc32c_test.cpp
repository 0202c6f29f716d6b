// The CRC32C instruction and folding paths must agree with the table path
// bit for bit: session files written by one are read by the others.
#include <gtest/gtest.h>

#include <cstdint>
#include <random>
#include <vector>

#include "session/crc32c.hpp"
#include "wiretape/session.hpp"

namespace {

using wiretape::detail::crc32c_folded;
using wiretape::detail::crc32c_folding_available;
using wiretape::detail::crc32c_hardware;
using wiretape::detail::crc32c_hardware_available;
using wiretape::detail::crc32c_table;

std::vector<unsigned char> random_bytes(std::size_t size, std::uint32_t seed) {
  std::mt19937 generator(seed);
  std::vector<unsigned char> bytes(size);
  for (auto& byte : bytes) byte = static_cast<unsigned char>(generator());
  return bytes;
}

TEST(Crc32c, BothPathsGiveTheCheckValue) {
  EXPECT_EQ(crc32c_table("123456789", 9), 0xE3069283u);
  EXPECT_EQ(crc32c_hardware("123456789", 9), 0xE3069283u);
  EXPECT_EQ(crc32c_folded("123456789", 9), 0xE3069283u);
  EXPECT_EQ(wiretape::crc32c("123456789", 9), 0xE3069283u);
}

TEST(Crc32c, HardwarePathMatchesTablesForEveryShortLengthAndAlignment) {
  if (!crc32c_hardware_available()) {
    GTEST_SKIP() << "no CRC32C instructions on this CPU or build: only the table path runs";
  }
  const auto bytes = random_bytes(300 + 16, 1);
  for (std::size_t start = 0; start < 16; ++start) {
    for (std::size_t length = 0; length <= 300; ++length) {
      for (std::uint32_t initial : {0u, 0xFFFFFFFFu, 0x12345678u}) {
        ASSERT_EQ(crc32c_hardware(bytes.data() + start, length, initial),
                  crc32c_table(bytes.data() + start, length, initial))
            << "start " << start << " length " << length << " initial " << initial;
      }
    }
  }
}

TEST(Crc32c, HardwarePathMatchesTablesAcrossTheBlockLengths) {
  if (!crc32c_hardware_available()) {
    GTEST_SKIP() << "no CRC32C instructions on this CPU or build: only the table path runs";
  }
  // Every length through three middle blocks, three short ones and the
  // stride loop after them, from aligned and unaligned starts.
  const std::size_t longest = 3 * 1024 + 3 * 256 + 40;
  const auto bytes = random_bytes(longest + 8, 6);
  for (std::size_t start : {0u, 3u}) {
    for (std::size_t length = 0; length <= longest; ++length) {
      ASSERT_EQ(crc32c_hardware(bytes.data() + start, length, 0x9E3779B9u),
                crc32c_table(bytes.data() + start, length, 0x9E3779B9u))
          << "start " << start << " length " << length;
    }
  }
}

TEST(Crc32c, HardwarePathMatchesTablesOnLargeRandomBuffers) {
  if (!crc32c_hardware_available()) {
    GTEST_SKIP() << "no CRC32C instructions on this CPU or build: only the table path runs";
  }
  std::mt19937 generator(2);
  // Sizes around the three-block boundaries of both block lengths.
  const std::vector<std::size_t> sizes = {767,   768,   769,   1000,  3071, 3072, 3073, 4095,
                                          3 * 8192 - 1,
                                          3 * 8192, 3 * 8192 + 1, 3 * 8192 + 768 + 7,
                                          65536, 1 << 20, 1000003};
  for (std::size_t size : sizes) {
    const auto bytes = random_bytes(size + 8, static_cast<std::uint32_t>(size));
    const std::size_t start = generator() % 8;
    const std::uint32_t initial = generator();
    ASSERT_EQ(crc32c_hardware(bytes.data() + start, size, initial),
              crc32c_table(bytes.data() + start, size, initial))
        << "size " << size << " start " << start;
  }
}

TEST(Crc32c, FoldingPathMatchesTablesForEveryLengthAndAlignment) {
  if (!crc32c_folding_available()) {
    GTEST_SKIP() << "no AVX-512 VPCLMULQDQ on this CPU or build: the instruction path runs";
  }
  // Every length through the 256-byte start, the 64- and 16-byte steps and
  // the tail, up to a few rounds of the 256-byte loop.
  const auto bytes = random_bytes(1100 + 64, 4);
  for (std::size_t start : {0u, 1u, 3u, 8u, 15u, 33u, 63u}) {
    for (std::size_t length = 0; length <= 1100; ++length) {
      for (std::uint32_t initial : {0u, 0xFFFFFFFFu, 0x12345678u}) {
        ASSERT_EQ(crc32c_folded(bytes.data() + start, length, initial),
                  crc32c_table(bytes.data() + start, length, initial))
            << "start " << start << " length " << length << " initial " << initial;
      }
    }
  }
}

TEST(Crc32c, FoldingPathMatchesTablesOnLargeRandomBuffers) {
  if (!crc32c_folding_available()) {
    GTEST_SKIP() << "no AVX-512 VPCLMULQDQ on this CPU or build: the instruction path runs";
  }
  std::mt19937 generator(5);
  const std::vector<std::size_t> sizes = {4096, 4112, 65536, 65536 + 255, 1 << 20, 1000003};
  for (std::size_t size : sizes) {
    const auto bytes = random_bytes(size + 64, static_cast<std::uint32_t>(size) + 1);
    const std::size_t start = generator() % 64;
    const std::uint32_t initial = generator();
    ASSERT_EQ(crc32c_folded(bytes.data() + start, size, initial),
              crc32c_table(bytes.data() + start, size, initial))
        << "size " << size << " start " << start;
  }
}

TEST(Crc32c, ChainingAcrossCallsMatchesOneCall) {
  const auto bytes = random_bytes(100000, 3);
  const std::uint32_t whole = crc32c_table(bytes.data(), bytes.size());
  for (std::size_t split : {0u, 1u, 7u, 8u, 769u, 24576u, 50001u, 100000u}) {
    const std::uint32_t head = wiretape::crc32c(bytes.data(), split);
    EXPECT_EQ(wiretape::crc32c(bytes.data() + split, bytes.size() - split, head), whole)
        << "split at " << split;
  }
}

}  // namespace
