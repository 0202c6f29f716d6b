// Bytes rendered as text, for mismatch reports, error messages and the
// command-line tools (bound to Python as _core.hex_ascii and
// _core.escape_bytes, so that both languages print bytes the same way).
#pragma once

#include <cstddef>
#include <string>
#include <string_view>

namespace wiretape::detail {

// "56 56 0a  |VV.|": each byte in hex, then the bytes as ASCII with '.' for
// anything not printable; "(none)" for no bytes. Callers cut long input
// (reports show 16 bytes of context).
std::string hex_ascii(std::string_view bytes);

// The bytes as one line of terminal-safe text: printable ASCII kept, a
// backslash doubled, \n \r \t for those controls and \xNN for every other
// byte (ESC included, so no escape sequence reaches the terminal). Bytes
// beyond `limit` are left out and counted: "... (+N bytes)".
std::string escape_bytes(std::string_view bytes, std::size_t limit = 64);

// Appends "\xNN" (lower-case hex) for one byte.
void append_hex_escape(std::string& out, unsigned char byte);

}  // namespace wiretape::detail
