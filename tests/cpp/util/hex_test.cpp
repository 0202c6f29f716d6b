// Bytes rendered as text (src/util/hex.cpp), as mismatch reports, error
// messages and the command-line tools show them.
#include <gtest/gtest.h>

#include <string>

#include "util/hex.hpp"

namespace wiretape::detail {
namespace {

TEST(HexAscii, EachByteInHexThenPrintableAsciiWithDotsForTheRest) {
  EXPECT_EQ(hex_ascii("VV\n"), "56 56 0a  |VV.|");
  EXPECT_EQ(hex_ascii(std::string("\x00\x7f\xff ~", 5)), "00 7f ff 20 7e  |... ~|");
  EXPECT_EQ(hex_ascii(""), "(none)");
}

TEST(EscapeBytes, KeepsPrintableAsciiAndEscapesEveryOtherByte) {
  EXPECT_EQ(escape_bytes("GET /\r\n\tok"), "GET /\\r\\n\\tok");
  EXPECT_EQ(escape_bytes("a\\b"), "a\\\\b");
  // ESC is escaped too, so no escape sequence reaches a terminal.
  EXPECT_EQ(escape_bytes(std::string("\x1b[2J\x00\xe9", 6)), "\\x1b[2J\\x00\\xe9");
  EXPECT_EQ(escape_bytes(""), "");
}

TEST(EscapeBytes, BytesBeyondTheLimitAreLeftOutAndCounted) {
  EXPECT_EQ(escape_bytes("abcdef", 4), "abcd... (+2 bytes)");
  EXPECT_EQ(escape_bytes("abcd", 4), "abcd");
  EXPECT_EQ(escape_bytes(std::string(100, 'x')), std::string(64, 'x') + "... (+36 bytes)");
}

TEST(AppendHexEscape, AppendsLowerCaseTwoDigitHex) {
  std::string out = "at ";
  append_hex_escape(out, 0x0a);
  append_hex_escape(out, 0xab);
  EXPECT_EQ(out, "at \\x0a\\xab");
}

}  // namespace
}  // namespace wiretape::detail
