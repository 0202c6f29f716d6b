#include "replay/profiles/checksums.hpp"

namespace wiretape::detail {

std::uint16_t crc16_modbus(std::string_view bytes) {
  std::uint16_t crc = 0xFFFF;
  for (unsigned char byte : bytes) {
    crc ^= byte;
    for (int bit = 0; bit < 8; ++bit) {
      crc = (crc & 1) ? static_cast<std::uint16_t>((crc >> 1) ^ 0xA001)
                      : static_cast<std::uint16_t>(crc >> 1);
    }
  }
  return crc;
}

std::uint16_t crc16_ccitt(std::string_view bytes) {
  std::uint16_t crc = 0xFFFF;
  for (unsigned char byte : bytes) {
    crc ^= static_cast<std::uint16_t>(byte << 8);
    for (int bit = 0; bit < 8; ++bit) {
      crc = (crc & 0x8000) ? static_cast<std::uint16_t>((crc << 1) ^ 0x1021)
                           : static_cast<std::uint16_t>(crc << 1);
    }
  }
  return crc;
}

std::uint16_t crc16_x25(std::string_view bytes, std::uint16_t crc) {
  for (unsigned char byte : bytes) {
    std::uint8_t tmp = static_cast<std::uint8_t>(byte ^ (crc & 0xFF));
    tmp = static_cast<std::uint8_t>(tmp ^ (tmp << 4));
    crc = static_cast<std::uint16_t>((crc >> 8) ^ (tmp << 8) ^ (tmp << 3) ^ (tmp >> 4));
  }
  return crc;
}

std::uint32_t crc32_zlib(std::string_view bytes) {
  std::uint32_t crc = 0xFFFFFFFFu;
  for (unsigned char byte : bytes) {
    crc ^= byte;
    for (int bit = 0; bit < 8; ++bit) crc = (crc & 1) ? (crc >> 1) ^ 0xEDB88320u : crc >> 1;
  }
  return ~crc;
}

std::uint8_t sum8(std::string_view bytes) {
  std::uint8_t sum = 0;
  for (unsigned char byte : bytes) sum = static_cast<std::uint8_t>(sum + byte);
  return sum;
}

std::uint8_t xor8(std::string_view bytes) {
  std::uint8_t sum = 0;
  for (unsigned char byte : bytes) sum ^= byte;
  return sum;
}

}  // namespace wiretape::detail
