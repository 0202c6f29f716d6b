// Option strings: `type=serial,device=/dev/ttyUSB0,baud=115200,timeout=1`.
//
// Syntax (flexiport's): `key=value` pairs separated by commas, spaces, tabs or
// newlines; a bare `key` means `key=1`; a value containing separators is
// written in double quotes, with `\"` and `\\` inside.
//
// Every key of every port type is one row of one table (option_keys()): its
// port types, value type, choices, default and help. Ports read their keys
// through the typed take_* accessors, which check the value against the
// row; finish() then rejects whatever was not consumed, naming the key,
// suggesting the nearest valid one and listing the keys valid for the port
// type. docs/options.md and the CLI's flags are tested against the table.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <unordered_map>
#include <variant>
#include <vector>

#include "wiretape/port.hpp"
#include "wiretape/timeout.hpp"

namespace wiretape {

// What a key's value is.
enum class OptionType {
  boolean,  // true/false, yes/no, on/off, 1/0 (any case); a bare key is 1
  integer,  // a whole number within the row's integer range
  number,   // a finite decimal number within the row's number range
  seconds,  // a timeout: seconds, or -1/none/forever to block
  choice,   // one of the row's choices (any case)
  text,     // free text (a host, a profile name, a fault plan, ...)
  path,     // a file or device path
};

// The name of `type` as the table and docs/options.md spell it.
const char* to_string(OptionType type) noexcept;

// One row of the key table.
struct OptionKey {
  std::string_view name;  // with `prefix`, the prefix: "meta_" for meta_KEY
  // The port types the key applies to (serial, tcp, udp, pty, loopback,
  // replay; flexiport's seriallog, tcplog, udplog for their own keys).
  std::vector<std::string_view> port_types;
  OptionType type = OptionType::text;
  std::vector<std::string_view> choices;  // OptionType::choice
  std::string_view default_value;  // as written in an option string; empty: none
  bool required = false;           // an error when absent (or empty)
  bool prefix = false;             // every key starting with `name` (meta_KEY)
  std::int64_t min_integer = 0;    // OptionType::integer
  std::int64_t max_integer = 0;
  double min_number = 0;           // OptionType::number and seconds
  double max_number = 0;
  std::string_view alias_of;       // flexiport's name of this other key
  std::string_view flag;           // the wiretape CLI's flag that mirrors it
  std::string_view help;           // one line

  bool applies_to(std::string_view port_type) const;
};

// Every key of every port type, common keys first.
const std::vector<OptionKey>& option_keys();
// The port types an option string's `type=` names, after flexiport's
// spellings (logreader, seriallog, tcplog, udplog) are resolved.
const std::vector<std::string_view>& port_types();
// The row of `name` for `port_type` (a prefix row matches every key that
// starts with its prefix); nullptr when the key does not apply to the type.
const OptionKey* find_option_key(std::string_view name, std::string_view port_type);
// The key valid for `port_type` nearest to the unknown `name` (a typo: a
// few letters added, missing, changed or swapped), or nothing.
std::optional<std::string> suggest_key(std::string_view name, std::string_view port_type);
// The one of `candidates` nearest to `name` by the same rule (a channel's
// name for a misspelt channel=), or nothing.
std::optional<std::string> nearest_name(std::string_view name,
                                        const std::vector<std::string>& candidates);

// The one reading of a boolean and of a parity or flow-control name; nothing
// for a spelling that is not one.
std::optional<bool> parse_bool(std::string_view text);
std::optional<Parity> parse_parity(std::string_view text);
std::optional<FlowControl> parse_flow_control(std::string_view text);

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

  // The port type whose rows the typed accessors read (open_port() sets it
  // once it knows the type; take_replay_config sets "replay").
  void set_port_type(std::string_view port_type);
  const std::string& port_type() const noexcept { return port_type_; }

  // Treats `alias` as another spelling of `canonical` (flexiport names);
  // giving both is an error.
  void alias(std::string_view alias, std::string_view canonical);
  // alias() for every row of the port type that is another key's flexiport
  // name (ip for host, dest_port for port, ...).
  void resolve_aliases();

  // Typed accessors: each reads the key's row for the port type, consumes
  // the key and returns its value, or the row's default when it is absent.
  // A bad value, or a required key missing, throws OptionError naming the
  // key and what is valid. A key absent from the table, or a typed read of a
  // row of another type or with no default, is a programming error
  // (std::logic_error).
  std::optional<std::string> take(std::string_view key);
  std::string take_string(std::string_view key);
  std::string take_required(std::string_view key);
  bool take_bool(std::string_view key);
  std::int64_t take_int(std::string_view key);
  double take_double(std::string_view key);
  // The chosen value in lower case.
  std::string take_choice(std::string_view key);
  // Seconds as a float; `-1`, `none` or `forever` means forever.
  Timeout take_timeout(std::string_view key);
  // Every `PREFIX*` key, with the prefix removed (meta_KEY=VALUE).
  std::map<std::string, std::string> take_prefixed(std::string_view prefix);

  // Throws OptionError for the first key never consumed: unknown keys (with
  // the nearest valid key, if one is near) and keys that do not apply to
  // `type` get different messages, both listing the keys valid for `type`.
  void finish(std::string_view type) const;

  // Canonical text: parse(to_string()) gives back the same entries.
  std::string to_string() const;

 private:
  const Entry* find(std::string_view key) const;
  const OptionKey& row(std::string_view key, OptionType type) const;
  void add(std::string key, std::string value);
  void reindex();
  std::vector<Entry> entries_;
  // key -> its position in entries_, so that parsing and taking n keys stays
  // linear instead of scanning every entry per key.
  std::unordered_map<std::string, std::size_t> index_;
  std::set<std::string, std::less<>> consumed_;
  std::string port_type_;
};

// The option string's pairs in order, as Options::parse reads them (the
// same errors); bound to Python as _core.parse_options, so that Python never
// splits an option string itself.
std::vector<Options::Entry> parse_options(std::string_view text);

// A value as it is written in an option string: as is when it needs no
// quotes, else in double quotes with `"` and `\` escaped
// (`log="/home/me/My Runs/a.wtape"`). Quoted: the empty value and values
// holding a separator (comma, space, tab, CR, LF), `=`, `"` or `\`.
// Options::parse gives the value back.
std::string quote_option_value(std::string_view value);

// A value given to option_string(): text as it is, or a number or a boolean
// written by the one rule of format_option_value.
using OptionValue = std::variant<std::string, std::int64_t, double, bool>;

// The text of `value` in an option string, unquoted: text as it is; a whole
// number in decimal; a floating-point number as the shortest text that reads
// back as the same double, without a fraction when it is whole ("2", "0.25",
// "1e-06"); a boolean as true or false. Throws OptionError naming `key` for
// a number that is not finite (no key reads one).
std::string format_option_value(std::string_view key, const OptionValue& value);

// `key=value,...` of `pairs` in order, each value formatted by
// format_option_value and quoted by quote_option_value, so that
// parse_options gives the pairs back. Throws OptionError naming the key for a
// key that is not one (empty, or holding a separator, `=`, `"` or a NUL byte),
// a key given twice, or a value holding a NUL byte.
std::string option_string(const std::vector<std::pair<std::string, OptionValue>>& pairs);

// The option string that a device setting (the CLI's --device, a URL's
// device=, WIRETAPE_DEVICE) stands for: a bare path, with no `=`, means
// `type=serial,device=PATH` (quoted as needed); anything else is an option
// string, returned as given. Surrounding white space is ignored. Throws
// OptionError (key "device") when the setting is empty.
std::string device_options(std::string_view device);

}  // namespace wiretape
