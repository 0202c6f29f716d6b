#include "util/hex.hpp"

namespace wiretape::detail {

namespace {

constexpr char kDigits[] = "0123456789abcdef";

bool printable_ascii(unsigned char byte) { return byte >= 0x20 && byte < 0x7f; }

}  // namespace

std::string hex_ascii(std::string_view bytes) {
  if (bytes.empty()) return "(none)";
  std::string hex;
  std::string ascii;
  hex.reserve(bytes.size() * 3);
  ascii.reserve(bytes.size());
  for (unsigned char byte : bytes) {
    if (!hex.empty()) hex.push_back(' ');
    hex.push_back(kDigits[byte >> 4]);
    hex.push_back(kDigits[byte & 0xf]);
    ascii.push_back(printable_ascii(byte) ? static_cast<char>(byte) : '.');
  }
  return hex + "  |" + ascii + "|";
}

void append_hex_escape(std::string& out, unsigned char byte) {
  out += "\\x";
  out.push_back(kDigits[byte >> 4]);
  out.push_back(kDigits[byte & 0xf]);
}

std::string escape_bytes(std::string_view bytes, std::size_t limit) {
  const std::string_view shown = bytes.substr(0, limit);
  std::string out;
  out.reserve(shown.size());
  for (unsigned char byte : shown) {
    switch (byte) {
      case '\n': out += "\\n"; break;
      case '\r': out += "\\r"; break;
      case '\t': out += "\\t"; break;
      case '\\': out += "\\\\"; break;
      default:
        if (printable_ascii(byte)) {
          out.push_back(static_cast<char>(byte));
        } else {
          append_hex_escape(out, byte);
        }
    }
  }
  if (bytes.size() > shown.size()) {
    out += "... (+" + std::to_string(bytes.size() - shown.size()) + " bytes)";
  }
  return out;
}

}  // namespace wiretape::detail
