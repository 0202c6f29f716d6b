// Option strings: `type=serial,device=/dev/ttyUSB0,baud=115200,timeout=1`.
//
// Syntax (flexiport's): `key=value` pairs separated by commas, spaces, tabs or
// newlines; a bare `key` means `key=1`; a value containing separators is
// written in double quotes, with `\"` and `\\` inside. Keys are consumed by
// the typed take_* accessors; finish() then rejects whatever was not consumed,
// naming the key and listing the keys that are valid for the port type.
#pragma once

#include <cstdint>
#include <initializer_list>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "wiretape/timeout.hpp"

namespace wiretape {

class Options {
 public:
  struct Entry {
    std::string key;
    std::string value;
  };

  Options() = default;
  // Throws OptionError on bad syntax (unterminated quote, empty key, duplicate
  // key, a NUL byte), naming the key or the position in the text. Linear in
  // the length of the text.
  static Options parse(std::string_view text);

  const std::vector<Entry>& entries() const noexcept { return entries_; }
  bool has(std::string_view key) const;
  // The raw value, without consuming it.
  std::optional<std::string> peek(std::string_view key) const;
  // Throws OptionError when `value` holds a NUL byte.
  void set(std::string_view key, std::string value);
  void erase(std::string_view key);

  // Treats `alias` as another spelling of `canonical` (flexiport names);
  // giving both is an error.
  void alias(std::string_view alias, std::string_view canonical);

  // Typed accessors: each declares `key` valid for this port type and consumes
  // it; a bad value throws OptionError naming the key and what is valid.
  std::optional<std::string> take(std::string_view key);
  std::string take_string(std::string_view key, std::string fallback);
  std::string take_required(std::string_view key);
  bool take_bool(std::string_view key, bool fallback);
  std::int64_t take_int(std::string_view key, std::int64_t fallback,
                        std::int64_t min, std::int64_t max);
  double take_double(std::string_view key, double fallback, double min,
                     double max);
  std::string take_choice(std::string_view key, std::string fallback,
                          std::initializer_list<std::string_view> choices);
  // Seconds as a float; `-1` or `none` means forever.
  Timeout take_timeout(std::string_view key, Timeout fallback);
  // Every `PREFIX*` key, with the prefix removed (meta_KEY=VALUE).
  std::map<std::string, std::string> take_prefixed(std::string_view prefix);

  // Throws OptionError for the first key never consumed: unknown keys and
  // keys that do not apply to `type` get different messages, both listing the
  // valid keys.
  void finish(std::string_view type) const;

  // Canonical text: parse(to_string()) gives back the same entries.
  std::string to_string() const;

 private:
  const Entry* find(std::string_view key) const;
  void add(std::string key, std::string value);
  void reindex();
  std::vector<Entry> entries_;
  // key -> its position in entries_, so that parsing and taking n keys stays
  // linear instead of scanning every entry per key.
  std::unordered_map<std::string, std::size_t> index_;
  std::set<std::string, std::less<>> consumed_;
  std::vector<std::string> declared_;
};

// A value as it is written in an option string: as is when it needs no
// quotes, else in double quotes with `"` and `\` escaped
// (`log="/home/me/My Runs/a.wtape"`). Quoted: the empty value and values
// holding a separator (comma, space, tab, CR, LF), `=`, `"` or `\`.
// Options::parse gives the value back.
std::string quote_option_value(std::string_view value);

// The option string that a device setting (the CLI's --device, a URL's
// device=, WIRETAPE_DEVICE) stands for: a bare path, with no `=`, means
// `type=serial,device=PATH` (quoted as needed); anything else is an option
// string, returned as given. Surrounding white space is ignored. Throws
// OptionError (key "device") when the setting is empty.
std::string device_options(std::string_view device);

}  // namespace wiretape
