// The checksums built-in and declared profiles check and recompute.
#pragma once

#include <cstdint>
#include <string_view>

namespace wiretape::detail {

// CRC-16/MODBUS: reflected 0xA001, init 0xFFFF; sent low byte first.
std::uint16_t crc16_modbus(std::string_view bytes);
// CRC-16/CCITT-FALSE: 0x1021, init 0xFFFF, not reflected; sent high byte first.
std::uint16_t crc16_ccitt(std::string_view bytes);
// CRC-16/MCRF4XX (MAVLink's X.25): reflected 0x8408, init 0xFFFF.
std::uint16_t crc16_x25(std::string_view bytes, std::uint16_t crc = 0xFFFF);
// CRC-32 (zlib's).
std::uint32_t crc32_zlib(std::string_view bytes);
std::uint8_t sum8(std::string_view bytes);
std::uint8_t xor8(std::string_view bytes);

}  // namespace wiretape::detail
