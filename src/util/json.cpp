// The JSON reader and writer of util/json.hpp.
#include "util/json.hpp"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "util/hex.hpp"

namespace wiretape::detail::json {

namespace {

// The length of the UTF-8 sequence of a non-ASCII character at `pos`, or 0
// when RFC 3629 does not allow it there: a stray continuation byte, a
// truncated sequence, an overlong form, a surrogate, a code point above
// U+10FFFF.
std::size_t utf8_sequence_length(std::string_view text, std::size_t pos) {
  const auto byte = [&](std::size_t at) { return static_cast<unsigned char>(text[at]); };
  const unsigned char lead = byte(pos);
  std::size_t length = 0;
  unsigned char low = 0x80, high = 0xBF;  // the range of the second byte
  if (lead >= 0xC2 && lead <= 0xDF) {
    length = 2;
  } else if (lead >= 0xE0 && lead <= 0xEF) {
    length = 3;
    if (lead == 0xE0) low = 0xA0;   // overlong
    if (lead == 0xED) high = 0x9F;  // surrogates
  } else if (lead >= 0xF0 && lead <= 0xF4) {
    length = 4;
    if (lead == 0xF0) low = 0x90;   // overlong
    if (lead == 0xF4) high = 0x8F;  // above U+10FFFF
  } else {
    return 0;
  }
  if (text.size() - pos < length) return 0;
  for (std::size_t i = 1; i < length; ++i) {
    const unsigned char next = byte(pos + i);
    if (next < (i == 1 ? low : 0x80) || next > (i == 1 ? high : 0xBF)) return 0;
  }
  return length;
}

class Parser {
 public:
  explicit Parser(std::string_view text) : text_(text) {}

  Value parse_document() {
    skip_space();
    Value value = parse_value(0);
    skip_space();
    if (pos_ != text_.size()) fail("unexpected text after the JSON value");
    return value;
  }

 private:
  [[noreturn]] void fail(const std::string& what) const {
    throw ParseError("JSON: " + what + " at byte " + std::to_string(pos_), pos_);
  }

  void skip_space() {
    while (pos_ < text_.size() &&
           (text_[pos_] == ' ' || text_[pos_] == '\t' || text_[pos_] == '\n' ||
            text_[pos_] == '\r')) {
      ++pos_;
    }
  }

  bool consume_word(std::string_view word) {
    if (text_.substr(pos_, word.size()) == word) {
      pos_ += word.size();
      return true;
    }
    return false;
  }

  // `depth`: how many arrays and objects enclose this value.
  Value parse_value(int depth) {
    if (pos_ >= text_.size()) fail("unexpected end of text");
    Value value;
    const char c = text_[pos_];
    if ((c == '{' || c == '[') && depth >= max_nesting_depth) {
      fail("arrays and objects nested deeper than " + std::to_string(max_nesting_depth) +
           " levels");
    }
    if (c == '{') {
      value.type = Value::Type::object;
      ++pos_;
      skip_space();
      if (pos_ < text_.size() && text_[pos_] == '}') {
        ++pos_;
        return value;
      }
      for (;;) {
        skip_space();
        if (pos_ >= text_.size() || text_[pos_] != '"') fail("expected a key string");
        std::string key = parse_string();
        skip_space();
        if (pos_ >= text_.size() || text_[pos_] != ':') fail("expected ':'");
        ++pos_;
        skip_space();
        value.members.emplace_back(std::move(key), parse_value(depth + 1));
        skip_space();
        if (pos_ < text_.size() && text_[pos_] == ',') {
          ++pos_;
          continue;
        }
        if (pos_ < text_.size() && text_[pos_] == '}') {
          ++pos_;
          return value;
        }
        fail("expected ',' or '}'");
      }
    }
    if (c == '[') {
      value.type = Value::Type::array;
      ++pos_;
      skip_space();
      if (pos_ < text_.size() && text_[pos_] == ']') {
        ++pos_;
        return value;
      }
      for (;;) {
        skip_space();
        value.items.push_back(parse_value(depth + 1));
        skip_space();
        if (pos_ < text_.size() && text_[pos_] == ',') {
          ++pos_;
          continue;
        }
        if (pos_ < text_.size() && text_[pos_] == ']') {
          ++pos_;
          return value;
        }
        fail("expected ',' or ']'");
      }
    }
    if (c == '"') {
      value.type = Value::Type::string;
      value.text = parse_string();
      return value;
    }
    if (consume_word("true")) {
      value.type = Value::Type::boolean;
      value.boolean = true;
      return value;
    }
    if (consume_word("false")) {
      value.type = Value::Type::boolean;
      return value;
    }
    if (consume_word("null")) return value;
    if (c == '-' || (c >= '0' && c <= '9')) return parse_number();
    // The character is shown escaped unless printable: the message may reach
    // a terminal, and the text is whatever a file held.
    std::string shown;
    const auto byte = static_cast<unsigned char>(c);
    if (byte >= 0x20 && byte < 0x7f) {
      shown = std::string("'") + c + "'";
    } else {
      append_hex_escape(shown, byte);
    }
    fail(std::string("unexpected character ") + shown);
  }

  Value parse_number() {
    const std::size_t start = pos_;
    auto digits = [&] {
      const std::size_t from = pos_;
      while (pos_ < text_.size() && text_[pos_] >= '0' && text_[pos_] <= '9') ++pos_;
      return pos_ > from;
    };
    if (text_[pos_] == '-') ++pos_;
    if (!digits()) fail("bad number");
    if (pos_ < text_.size() && text_[pos_] == '.') {
      ++pos_;
      if (!digits()) fail("bad number");
    }
    if (pos_ < text_.size() && (text_[pos_] == 'e' || text_[pos_] == 'E')) {
      ++pos_;
      if (pos_ < text_.size() && (text_[pos_] == '+' || text_[pos_] == '-')) ++pos_;
      if (!digits()) fail("bad number");
    }
    Value value;
    value.type = Value::Type::number;
    value.text = std::string(text_.substr(start, pos_ - start));
    value.number = std::strtod(value.text.c_str(), nullptr);
    return value;
  }

  unsigned parse_hex4() {
    if (text_.size() - pos_ < 4) fail("truncated \\u escape");
    unsigned code = 0;
    for (int i = 0; i < 4; ++i) {
      const char h = text_[pos_++];
      code <<= 4;
      if (h >= '0' && h <= '9') code |= static_cast<unsigned>(h - '0');
      else if (h >= 'a' && h <= 'f') code |= static_cast<unsigned>(h - 'a' + 10);
      else if (h >= 'A' && h <= 'F') code |= static_cast<unsigned>(h - 'A' + 10);
      else fail("bad \\u escape");
    }
    return code;
  }

  static void append_utf8(std::string& out, unsigned code) {
    if (code < 0x80) {
      out.push_back(static_cast<char>(code));
    } else if (code < 0x800) {
      out.push_back(static_cast<char>(0xC0 | (code >> 6)));
      out.push_back(static_cast<char>(0x80 | (code & 0x3F)));
    } else if (code < 0x10000) {
      out.push_back(static_cast<char>(0xE0 | (code >> 12)));
      out.push_back(static_cast<char>(0x80 | ((code >> 6) & 0x3F)));
      out.push_back(static_cast<char>(0x80 | (code & 0x3F)));
    } else {
      out.push_back(static_cast<char>(0xF0 | (code >> 18)));
      out.push_back(static_cast<char>(0x80 | ((code >> 12) & 0x3F)));
      out.push_back(static_cast<char>(0x80 | ((code >> 6) & 0x3F)));
      out.push_back(static_cast<char>(0x80 | (code & 0x3F)));
    }
  }

  // Copies one UTF-8 encoded character starting at pos_ (a byte of 0x80 or
  // more).
  void append_utf8_sequence(std::string& out) {
    const std::size_t length = utf8_sequence_length(text_, pos_);
    if (length == 0) fail("invalid UTF-8 in a string");
    out.append(text_.substr(pos_, length));
    pos_ += length;
  }

  std::string parse_string() {
    ++pos_;  // opening quote
    std::string out;
    for (;;) {
      if (pos_ >= text_.size()) fail("unterminated string");
      const char c = text_[pos_++];
      if (c == '"') return out;
      if (static_cast<unsigned char>(c) < 0x20) {
        --pos_;
        fail("control character in string");
      }
      if (static_cast<unsigned char>(c) >= 0x80) {
        --pos_;
        append_utf8_sequence(out);
        continue;
      }
      if (c != '\\') {
        out.push_back(c);
        continue;
      }
      if (pos_ >= text_.size()) fail("unterminated escape");
      const char e = text_[pos_++];
      switch (e) {
        case '"': out.push_back('"'); break;
        case '\\': out.push_back('\\'); break;
        case '/': out.push_back('/'); break;
        case 'b': out.push_back('\b'); break;
        case 'f': out.push_back('\f'); break;
        case 'n': out.push_back('\n'); break;
        case 'r': out.push_back('\r'); break;
        case 't': out.push_back('\t'); break;
        case 'u': {
          const std::size_t escape_start = pos_ - 2;
          unsigned code = parse_hex4();
          if (code >= 0xD800 && code < 0xDC00 && text_.substr(pos_, 2) == "\\u") {
            pos_ += 2;
            const unsigned low = parse_hex4();
            if (low >= 0xDC00 && low < 0xE000) {
              code = 0x10000 + ((code - 0xD800) << 10) + (low - 0xDC00);
            } else {
              pos_ = escape_start;
              fail("bad surrogate pair");
            }
          }
          // A lone surrogate has no UTF-8 form: encoded anyway it would make
          // the string invalid UTF-8 for every reader after this one.
          if (code >= 0xD800 && code < 0xE000) {
            pos_ = escape_start;
            fail("a \\u escape of a lone surrogate (not valid Unicode)");
          }
          append_utf8(out, code);
          break;
        }
        default:
          --pos_;
          fail("bad escape");
      }
    }
  }

  std::string_view text_;
  std::size_t pos_ = 0;
};

void serialize_into(std::string& out, const Value& value) {
  switch (value.type) {
    case Value::Type::null: out += "null"; break;
    case Value::Type::boolean: out += value.boolean ? "true" : "false"; break;
    case Value::Type::number: out += value.text.empty() ? "0" : value.text; break;
    case Value::Type::string: append_string(out, value.text); break;
    case Value::Type::array: {
      out.push_back('[');
      bool first = true;
      for (const Value& item : value.items) {
        if (!first) out.push_back(',');
        first = false;
        serialize_into(out, item);
      }
      out.push_back(']');
      break;
    }
    case Value::Type::object: {
      out.push_back('{');
      bool first = true;
      for (const auto& [key, member] : value.members) {
        if (!first) out.push_back(',');
        first = false;
        append_string(out, key);
        out.push_back(':');
        serialize_into(out, member);
      }
      out.push_back('}');
      break;
    }
  }
}

}  // namespace

const Value* Value::find(std::string_view key) const {
  for (const auto& [name, member] : members) {
    if (name == key) return &member;
  }
  return nullptr;
}

std::optional<std::string> Value::string_member(std::string_view key) const {
  const Value* member = find(key);
  if (member == nullptr || !member->is_string()) return std::nullopt;
  return member->text;
}

Value parse(std::string_view text) { return Parser(text).parse_document(); }

std::optional<std::size_t> invalid_utf8_offset(std::string_view text) {
  std::size_t pos = 0;
  while (pos < text.size()) {
    if (static_cast<unsigned char>(text[pos]) < 0x80) {
      ++pos;
      continue;
    }
    const std::size_t length = utf8_sequence_length(text, pos);
    if (length == 0) return pos;
    pos += length;
  }
  return std::nullopt;
}

void append_string(std::string& out, std::string_view value) {
  out.push_back('"');
  for (const char c : value) {
    switch (c) {
      case '"': out += "\\\""; break;
      case '\\': out += "\\\\"; break;
      case '\n': out += "\\n"; break;
      case '\r': out += "\\r"; break;
      case '\t': out += "\\t"; break;
      default:
        if (static_cast<unsigned char>(c) < 0x20) {
          char escape[8];
          std::snprintf(escape, sizeof escape, "\\u%04x",
                        static_cast<unsigned>(static_cast<unsigned char>(c)));
          out += escape;
        } else {
          out.push_back(c);
        }
    }
  }
  out.push_back('"');
}

std::string quote(std::string_view value) {
  std::string out;
  append_string(out, value);
  return out;
}

std::string serialize(const Value& value) {
  std::string out;
  serialize_into(out, value);
  return out;
}

void ObjectWriter::key(std::string_view name) {
  if (text_.size() > 1) text_.push_back(',');
  append_string(text_, name);
  text_.push_back(':');
}

ObjectWriter& ObjectWriter::add(std::string_view name, std::string_view value) {
  key(name);
  append_string(text_, value);
  return *this;
}

ObjectWriter& ObjectWriter::add(std::string_view name, bool value) {
  key(name);
  text_ += value ? "true" : "false";
  return *this;
}

ObjectWriter& ObjectWriter::add(std::string_view name, std::int64_t value) {
  key(name);
  text_ += std::to_string(value);
  return *this;
}

ObjectWriter& ObjectWriter::add(std::string_view name, std::uint64_t value) {
  key(name);
  text_ += std::to_string(value);
  return *this;
}

ObjectWriter& ObjectWriter::add_raw(std::string_view name, std::string_view json) {
  key(name);
  text_ += json;
  return *this;
}

ObjectWriter& ObjectWriter::add(std::string_view name,
                                const std::map<std::string, std::string>& object) {
  key(name);
  text_.push_back('{');
  bool first = true;
  for (const auto& [k, v] : object) {
    if (!first) text_.push_back(',');
    first = false;
    append_string(text_, k);
    text_.push_back(':');
    append_string(text_, v);
  }
  text_.push_back('}');
  return *this;
}

}  // namespace wiretape::detail::json
