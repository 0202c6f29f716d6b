// A small JSON writer and reader for session-file header metadata and event
// payloads. Not a general-purpose library: numbers are kept as their text
// (and as a double), objects keep their keys in file order, and nesting is
// bounded so that hostile input cannot exhaust the stack.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace wiretape::detail::json {

// The deepest nesting of arrays and objects parse() accepts (the outermost
// object is level 1): deep enough for any metadata a person writes, shallow
// enough that hostile input cannot exhaust the stack of this parser or of the
// readers the JSON is handed to (Python's json module recurses too).
// docs/session-format.md states it.
inline constexpr int max_nesting_depth = 64;

// A parse error; offset() is the byte offset in the text.
class ParseError : public std::runtime_error {
 public:
  ParseError(const std::string& what, std::size_t offset)
      : std::runtime_error(what), offset_(offset) {}
  std::size_t offset() const noexcept { return offset_; }

 private:
  std::size_t offset_;
};

struct Value {
  enum class Type { null, boolean, number, string, array, object };
  Type type = Type::null;
  bool boolean = false;
  double number = 0;
  std::string text;  // the string, or a number's text as written
  std::vector<Value> items;
  std::vector<std::pair<std::string, Value>> members;

  bool is_object() const { return type == Type::object; }
  bool is_string() const { return type == Type::string; }
  // The member named `key`, or nullptr.
  const Value* find(std::string_view key) const;
  // The member `key` if it is a string, else std::nullopt.
  std::optional<std::string> string_member(std::string_view key) const;
};

// Parses one JSON value that must fill `text` (whitespace around allowed).
// Strings must be valid UTF-8, raw or escaped (no lone surrogates), so that
// every string it returns is valid UTF-8; nesting is bounded by
// max_nesting_depth. Throws ParseError with the byte offset of the problem.
Value parse(std::string_view text);

// The offset of the first byte of `text` that is not valid UTF-8 (RFC 3629),
// or std::nullopt when all of it is: what writers check before they put text
// into JSON that parse() must read back.
std::optional<std::size_t> invalid_utf8_offset(std::string_view text);

// Writes `value` as a JSON string literal (with quotes).
void append_string(std::string& out, std::string_view value);
std::string quote(std::string_view value);
// Compact JSON text of `value`.
std::string serialize(const Value& value);

// Builds a JSON object in a fixed key order, for deterministic output.
class ObjectWriter {
 public:
  ObjectWriter& add(std::string_view key, std::string_view value);
  ObjectWriter& add(std::string_view key, const char* value) {
    return add(key, std::string_view(value));
  }
  ObjectWriter& add(std::string_view key, bool value);
  ObjectWriter& add(std::string_view key, std::int64_t value);
  ObjectWriter& add(std::string_view key, std::uint64_t value);
  ObjectWriter& add(std::string_view key, int value) {
    return add(key, static_cast<std::int64_t>(value));
  }
  ObjectWriter& add(std::string_view key, unsigned value) {
    return add(key, static_cast<std::uint64_t>(value));
  }
  // `json` is inserted as is (an already serialized value).
  ObjectWriter& add_raw(std::string_view key, std::string_view json);
  ObjectWriter& add(std::string_view key,
                    const std::map<std::string, std::string>& object);
  std::string str() const { return text_ + "}"; }

 private:
  void key(std::string_view name);
  std::string text_ = "{";
};

}  // namespace wiretape::detail::json
