// The .wtape byte layout (docs/session-format.md): magic, versions, the sizes
// of the fixed parts, and the little/big-endian helpers the reader, the
// writer and the flexiport importer share.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

namespace wiretape::detail {

// "\x89WTAPE\r\n": the high byte catches 7-bit transfers, CR LF catches
// newline translation.
inline constexpr char session_magic[8] = {'\x89', 'W', 'T', 'A', 'P', 'E', '\r', '\n'};
inline constexpr std::uint16_t session_version_major = 1;
// 1.3: the per-channel index at the end of a file of several channels.
inline constexpr std::uint16_t session_version_minor = 3;
// magic, major, minor, JSON length
inline constexpr std::size_t file_header_fixed_size = 16;
// A header larger than this is corrupt, whatever the file holds.
inline constexpr std::uint32_t max_header_json = 16u << 20;
// length, kind, flags, channel, t_ns
inline constexpr std::size_t record_header_size = 16;
inline constexpr std::size_t crc_size = 4;
// The largest t_ns a reader accepts: the last nanosecond of the 32-bit
// seconds of flexiport's logs (about 136 years), so that every session can be
// exported to them, and far from overflowing the signed 64-bit nanosecond
// clocks of replay (std::chrono) or, added to the session's start, the
// unsigned ones of pcapng and MCAP.
inline constexpr std::uint64_t max_record_t_ns = 4'294'967'295'999'999'999ull;

inline void put_u16le(char* out, std::uint16_t v) {
  out[0] = static_cast<char>(v & 0xFF);
  out[1] = static_cast<char>(v >> 8);
}
inline void put_u32le(char* out, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) out[i] = static_cast<char>((v >> (8 * i)) & 0xFF);
}
inline void put_u64le(char* out, std::uint64_t v) {
  for (int i = 0; i < 8; ++i) out[i] = static_cast<char>((v >> (8 * i)) & 0xFF);
}
inline std::uint16_t get_u16le(const char* in) {
  const auto* b = reinterpret_cast<const unsigned char*>(in);
  return static_cast<std::uint16_t>(b[0] | (b[1] << 8));
}
inline std::uint32_t get_u32le(const char* in) {
  const auto* b = reinterpret_cast<const unsigned char*>(in);
  return static_cast<std::uint32_t>(b[0]) | (static_cast<std::uint32_t>(b[1]) << 8) |
         (static_cast<std::uint32_t>(b[2]) << 16) | (static_cast<std::uint32_t>(b[3]) << 24);
}
inline std::uint64_t get_u64le(const char* in) {
  return static_cast<std::uint64_t>(get_u32le(in)) |
         (static_cast<std::uint64_t>(get_u32le(in + 4)) << 32);
}
inline std::uint32_t get_u32be(const char* in) {
  const auto* b = reinterpret_cast<const unsigned char*>(in);
  return (static_cast<std::uint32_t>(b[0]) << 24) | (static_cast<std::uint32_t>(b[1]) << 16) |
         (static_cast<std::uint32_t>(b[2]) << 8) | static_cast<std::uint32_t>(b[3]);
}
inline void put_u32be(char* out, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) out[i] = static_cast<char>((v >> (24 - 8 * i)) & 0xFF);
}

// Unsigned LEB128: 7 bits a byte, low bits first, the high bit set on every
// byte but the last (the index's spans, the records inside a chunk).
inline void put_varint(std::string& out, std::uint64_t v) {
  while (v >= 0x80) {
    out.push_back(static_cast<char>((v & 0x7F) | 0x80));
    v >>= 7;
  }
  out.push_back(static_cast<char>(v));
}
// Reads a varint at `at` of `in`, advancing `at`; false when `in` ends
// inside it or it is longer than a 64-bit value can be.
inline bool get_varint(std::string_view in, std::size_t& at, std::uint64_t& v) {
  v = 0;
  for (int shift = 0; shift < 64; shift += 7) {
    if (at >= in.size()) return false;
    const auto byte = static_cast<unsigned char>(in[at++]);
    if (shift == 63 && byte > 1) return false;
    v |= static_cast<std::uint64_t>(byte & 0x7F) << shift;
    if ((byte & 0x80) == 0) return true;
  }
  return false;
}

}  // namespace wiretape::detail
