// CRC32C (Castagnoli), the checksum of every header and record of a .wtape
// file: a portable table path and a hardware path that must agree with it.
// wiretape::crc32c (include/wiretape/session.hpp) picks the faster one.
#pragma once

#include <cstddef>
#include <cstdint>

namespace wiretape::detail {

// CRC32C by slicing-by-8 tables: the portable path, and the reference the
// hardware path must agree with.
std::uint32_t crc32c_table(const void* data, std::size_t size, std::uint32_t crc = 0);
// Whether this CPU has CRC32C instructions this build can use.
bool crc32c_hardware_available();
// CRC32C by the CPU's instructions (falls back to the tables when
// crc32c_hardware_available() is false). wiretape::crc32c picks this when it
// can.
std::uint32_t crc32c_hardware(const void* data, std::size_t size, std::uint32_t crc = 0);
// Whether this CPU can fold long buffers by carry-less multiplication
// (x86-64 with AVX-512 VPCLMULQDQ).
bool crc32c_folding_available();
// CRC32C by folding (buffers of 256 bytes and more; shorter ones and the
// tail by crc32c_hardware); falls back to crc32c_hardware when
// crc32c_folding_available() is false. wiretape::crc32c picks this when it
// can.
std::uint32_t crc32c_folded(const void* data, std::size_t size, std::uint32_t crc = 0);

}  // namespace wiretape::detail
